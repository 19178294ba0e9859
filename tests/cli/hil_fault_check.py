#!/usr/bin/python3
"""Checks the host-in-the-loop runs with bus faults and in real time (tests/cli/hil_inside.sh).

usage: hil_fault_check.py CLEAN_DIR FAULT_DIR REALTIME_DIR

Fault run (bmssim hil --fault ..., every fault kind in one lock-step cycle):
1. The firmware's receive counters (BMS_RxStats, summed by the host) equal what the
   protocol's receiver rules (firmware/can/bms.dbc comment), re-implemented here, give for
   the host frames in can.log: ignored ids, wrong length, bad CRC, bad alive counter, and
   frames inferred lost from counter gaps. The kill window's frames reached no firmware and
   the restarted firmware starts its counters afresh. The frames are taken batch by batch as
   the lock-step firmware sees them (up to each tick trigger), with the tick's sequence window.
2. Against the injection: ignored ids = unknown-id frames, length drops = short frames, CRC
   drops = corrupted frames, counter drops >= duplicates + reorders + frozen-counter frames.
3. Windows of missing or rejected measurements (burst, stale, range, nan): the estimate is
   frozen over the window (equal to the tick before it, RCSI not learning); from the third
   tick without a valid measurement on the stale fault bit is set (range/nan, where the frames
   do arrive: the voltage-range bit in every tick); within 2 ticks after the window the fault bits clear and RCSI learns again.
4. Bus down and firmware killed: the firmware answers no tick in those windows and every tick
   outside them; the killed firmware is restarted once and reports its state restored from NVM
   in every answer; its first estimate lies within the estimates of the minute before the kill
   (+-2 %: the state is committed every 60 s), not at the initial value.
Real-time run: BMS_Status arrives at 5 per second of wall time (the 0.2 s timer) within 2 %,
and at least 90 % of the firmware's ticks had a measurement.
Prints one line per check; exit 0 when all pass.
"""
import csv
import json
import sys

STALE, V_RANGE, I_RANGE = 1, 4, 8
NO_ANSWER, NOT_ASKED = 1 << 8, 1 << 9
EPOCH, TICK_S = 1700000000.0, 0.2


def crc8(can_id, data):
    c = 0xFF
    for b in [can_id & 0xFF, can_id >> 8] + list(data[1:]):
        c ^= b
        for _ in range(8):
            c = ((c << 1) ^ 0x1D) & 0xFF if c & 0x80 else (c << 1) & 0xFF
    return c ^ 0xFF


class Triggers:
    """The lock-step trigger rule (LockstepTicks and SeqTracker, firmware/include/bms/fw/
    can_protocol.hpp and can_sequence.hpp): which host frame makes the firmware run a tick,
    and the Seq the tick's measurement must carry (-1: none, a tick run on a corrupted frame)."""
    MAX_STEP, RESYNC, HALF = 50, 3, 0x7FF

    def __init__(self):
        self.have = self.seq_have = self.last_unconfirmed = False
        self.last_seq = self.run = self.cand = self.unconfirmed = self.last_tick = self.anchor = 0

    def observe(self, seq):
        if not self.seq_have:
            self.seq_have, self.last_seq, self.run = True, seq, 0
            return "first", 0
        ahead = (seq - self.last_seq) & 0xFFF
        if 1 <= ahead <= min(self.MAX_STEP, self.HALF):
            self.last_seq, self.run = seq, 0
            return "in", ahead
        self.run = self.run + 1 if self.run > 0 and seq == (self.cand + 1) & 0xFFF else 1
        self.cand = seq
        if self.run < self.RESYNC:
            return "rejected", 0
        self.last_seq, self.run = seq, 0
        return ("jump", ahead) if 1 <= ahead <= self.HALF else ("restart", 1)

    def classify(self, can_id, data):
        if can_id == 0x110 and len(data) == 8:
            if data[0] != crc8(can_id, data):
                if not self.have or self.unconfirmed >= 1:
                    return None
                self.unconfirmed += 1
                self.last_unconfirmed = True
                self.last_tick += 1
                return -1
            seq = first = seq_of(data)
        elif can_id == 0x100 and len(data) == 8 and data[0] == crc8(can_id, data) and (data[1] >> 6) & 1:
            first = int.from_bytes(data[4:8], "little")
            seq = first & 0xFFF
        else:
            return None
        verdict, step = self.observe(seq)
        if verdict == "first":
            self.anchor = first
        elif verdict in ("in", "jump"):
            self.anchor += step
        elif verdict == "restart":
            self.anchor = self.last_tick + 1
        else:
            return None
        if self.have and self.anchor <= self.last_tick:
            return None
        self.have, self.unconfirmed, self.last_unconfirmed, self.last_tick = True, 0, False, self.anchor
        return seq


def seq_of(data):
    return ((data[1] >> 4) | (data[2] << 4)) & 0xFFF


def protocol_counters(log, kill_windows):
    """The receiver rules of the DBC comment applied to the host's frames in can.log, batch by
    batch as the firmware sees them: a batch ends with a tick trigger (Triggers), and the
    batch's measurement must carry the trigger's Seq (else a sequence drop, which BMS_RxStats
    counts in DropCounter, before the alive counter is looked at)."""
    dlc = {0x100: 8, 0x110: 8, 0x111: 4}
    n = dict(ignored_ids=0, dropped_length=0, dropped_crc=0, dropped_counter=0, lost_frames=0)
    last, triggers, batch = {}, Triggers(), []
    for line in open(log):
        stamp, _, frame = line.split()
        can_id, hexdata = frame.split("#")
        can_id, data = int(can_id, 16), bytes.fromhex(hexdata)
        if 0x200 <= can_id <= 0x2FF:
            continue  # the firmware's own frames
        tick = round((float(stamp[1:-1]) - EPOCH) / TICK_S)
        if any(a <= tick < b for a, b in kill_windows):
            last, triggers, batch = {}, Triggers(), []  # nobody listening; the restarted firmware starts afresh
            continue
        batch.append((can_id, data))
        window = triggers.classify(can_id, data)
        if window is None:
            continue
        for can_id, data in batch:
            receive(n, last, dlc, can_id, data, window)
        batch = []
    return n


def receive(n, last, dlc, can_id, data, window):
    if can_id not in dlc:
        n["ignored_ids"] += 1
    elif len(data) != dlc[can_id]:
        n["dropped_length"] += 1
    elif data[0] != crc8(can_id, data):
        n["dropped_crc"] += 1
    elif can_id == 0x110 and seq_of(data) != window:
        n["dropped_counter"] += 1
    else:
        c = data[1] & 0x0F
        if can_id in last:
            step = (c - last[can_id]) & 0x0F
            if step == 0:
                n["dropped_counter"] += 1
                return
            if step > 7:
                last[can_id] = c
                n["dropped_counter"] += 1
                return
            n["lost_frames"] += step - 1
        last[can_id] = c


def report(ok, text):
    print(f"{'PASS' if ok else 'FAIL'} {text}")
    return ok


def main():
    clean, faults, realtime = sys.argv[1:4]
    s = json.load(open(faults + "/summary.json"))["hil"]
    f = s["faults"]
    inj, fwc = f["injected"], f["firmware_counters"]
    rows = list(csv.DictReader(open(faults + "/estimates.csv")))
    est = [float(r["r_film_est_ohm_m2"]) for r in rows]
    status = [int(r["status"]) for r in rows]
    active = [int(r["rcsi_active"]) for r in rows]
    windows = f["windows"]
    kills = [(w["start_tick"], w["start_tick"] + w["ticks"]) for w in windows if w["kind"] == "kill"]
    ok = True

    model = protocol_counters(faults + "/can.log", kills)
    ok &= report(model == fwc, f"firmware receive counters equal the protocol rules applied to can.log: firmware {fwc}, "
                               f"rules {model}")
    rel = (fwc["ignored_ids"] == inj["unknown"] and fwc["dropped_length"] == inj["length"]
           and fwc["dropped_crc"] == inj["crc"] and fwc["dropped_counter"] >= inj["dup"] + inj["reorder"] + inj["stale"]
           and inj["unknown"] > 0 and inj["length"] > 0 and inj["crc"] > 0 and inj["dup"] > 0 and inj["reorder"] > 0)
    ok &= report(rel, f"every injected bad frame counted: unknown {inj['unknown']} -> ignored {fwc['ignored_ids']}, "
                      f"short {inj['length']} -> length {fwc['dropped_length']}, corrupted {inj['crc']} -> crc "
                      f"{fwc['dropped_crc']}, dup {inj['dup']} + reorder {inj['reorder']} + frozen {inj['stale']} <= "
                      f"counter {fwc['dropped_counter']}")

    for w in windows:
        a, b = w["start_tick"], w["start_tick"] + w["ticks"]
        kind = w["kind"]
        if kind in ("burst", "stale", "range", "nan"):
            frozen = all(est[k] == est[a - 1] and not active[k] for k in range(a, b))
            if kind in ("burst", "stale"):
                bits = all((status[k] & STALE) == 0 for k in range(a, a + 2)) and \
                       all(status[k] & STALE for k in range(a + 2, b))
            elif kind == "range":  # the frames arrive (not stale); the sample is rejected
                bits = all(status[k] & V_RANGE for k in range(a, b))
            else:  # nan: voltage and current in turn; NaN is sent as a raw value outside the range
                bits = all(status[k] & (V_RANGE | I_RANGE) for k in range(a, b)) and \
                       any(status[k] & I_RANGE for k in range(a, b))
            rec = w["recover_ticks_after_window"]
            resumed = 0 <= rec <= 2 and any(active[k] for k in range(b, b + 3))
            ok &= report(frozen and bits and resumed,
                         f"{kind} {w['ticks']} ticks at tick {a}: estimate frozen {frozen}, fault bits {bits}, "
                         f"fault bits clear {rec} ticks after, RCSI learning again {resumed}")
    down = [(w["start_tick"], w["start_tick"] + w["ticks"]) for w in windows if w["kind"] in ("busdown", "kill")]
    silent = [k for k in range(len(rows)) if status[k] & NO_ANSWER]
    expect = [k for a, b in down for k in range(a, b)]
    ok &= report(sorted(silent) == sorted(expect) and len(expect) > 0,
                 f"no answer exactly in the bus-down and killed windows: {len(silent)} ticks, expected {len(expect)}")
    for a, b in kills:
        # The state was committed at most 60 s (300 ticks, --persist-every-s) before the kill:
        # the first estimate after the restart lies within what the estimate was in that minute.
        recent = est[max(0, a - 301):a]
        cont = min(recent) * 0.98 <= est[b] <= max(recent) * 1.02 and est[b] != est[0]
        asked_after = sum(1 for k in range(b, len(rows)) if not status[k] & (NO_ANSWER | NOT_ASKED))
        ok &= report(f["firmware_starts"] == 2 and s["answers_after_nvm_restore"] >= asked_after and cont,
                     f"firmware killed at tick {a}, restarted at {b}: starts {f['firmware_starts']}, answers with "
                     f"'restored from NVM' {s['answers_after_nvm_restore']} (ticks asked after restart {asked_after}), "
                     f"estimate {est[b]:.6g} after, {min(recent):.6g}..{max(recent):.6g} in the minute before")

    rt = json.load(open(realtime + "/summary.json"))["hil"]
    span = rt["last_status_wall_s"] - rt["first_status_wall_s"]
    rate = (rt["status_frames"] - 1) / span if span > 0 else 0.0
    committed = rt["firmware_tick_count_last"] - rt["firmware_tick_count_first"] + 1
    paced = abs(rate - 5.0) <= 0.1 and committed >= 0.9 * (rt["status_frames"])
    ok &= report(paced, f"real time: {rt['status_frames']} firmware ticks in {span:.3f} s = {rate:.4f} per s "
                        f"(5 +- 0.1), {committed} of them with a measurement; host {rt['ticks']} frames in "
                        f"{rt['wall_s']:.3f} s")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
