#!/usr/bin/env python3
"""Writes cycler exports as real ones come (Arbin, Maccor, Neware, BioLogic .mpt, NASA PCoE,
CALCE) and malformed ones, for the reader review in docs/results/reliability.md section 10.
Usage: cycler_variants.py DIR. Every file is synthetic: one cycle of rest, 1.5 A charge, rest,
2 A discharge at 2 s with a 600 s logging gap in the charge."""
import os
import sys
D = sys.argv[1] if len(sys.argv) > 1 else "cycler_variants"
os.makedirs(D, exist_ok=True)
def cycle(dt=2.0, n_rest=60, n_chg=900, n_dis=900):
    """(t, I charge-positive A, V, kind) rows; thousands of rows."""
    rows, t = [], 0.0
    for k in range(n_rest): rows.append((t, 0.0, 3.40, 'R')); t += dt
    for k in range(n_chg): rows.append((t, 1.5, 3.55 + 0.55 * k / n_chg, 'C')); t += dt
    for k in range(n_rest): rows.append((t, 0.0, 4.05 - 0.0005 * k, 'R')); t += dt
    for k in range(n_dis): rows.append((t, -2.0, 3.95 - 0.85 * k / n_dis, 'D')); t += dt
    return rows
C = cycle()
GAP_AT, GAP = 500, 600.0   # a logging gap under current (charge)
def timed(rows):
    return [(t + (GAP if i >= GAP_AT else 0), I, V, k) for i, (t, I, V, k) in enumerate(rows)]
R = timed(C)
def hms(t):
    s = int(t); return "%02d:%02d:%02d.%03d" % (s // 3600, s // 60 % 60, s % 60, round((t - s) * 1000))
def date(t, base=14 * 3600):
    s = int(t) + base
    return "2021-03-%02d %02d:%02d:%02d" % (4 + s // 86400, s // 3600 % 24, s // 60 % 60, s % 60)
def w(name, text, enc="utf-8"):
    with open(os.path.join(D, name), "w", newline="", encoding=enc) as f: f.write(text)

# --- Arbin MITS Pro CSV, charge-positive, with Aux temperature, Date_Time
def arbin(rows, sep=",", dec=".", eol="\n", bom="", quote=False, unitI="A", scaleI=1.0, tcol="Test_Time(s)", tscale=1.0, aux=True):
    h = ["Data_Point", "Date_Time", tcol, "Step_Time(s)", "Step_Index", "Cycle_Index", "Current(%s)" % unitI, "Voltage(V)",
         "Charge_Capacity(Ah)", "Discharge_Capacity(Ah)", "dV/dt(V/s)", "Internal_Resistance(Ohm)"]
    if aux: h.append("Aux_Temperature_1(C)")
    out = [sep.join(h)]
    step = {'R': 1, 'C': 2, 'D': 4}
    for i, (t, I, V, k) in enumerate(rows):
        cells = [str(i + 1), date(t), "%.7f" % (t / tscale), "0", str(step[k]), "1", "%.6f" % (I * scaleI), "%.5f" % V, "0", "0", "0", "0.05"]
        if aux: cells.append("%.2f" % (25 + 0.001 * i))
        cells = [c.replace(".", dec) if j != 1 else c for j, c in enumerate(cells)]
        if quote: cells = ['"%s"' % c for c in cells]
        out.append(sep.join(cells))
    return bom + eol.join(out) + eol
w("arbin.csv", arbin(R))
w("arbin_crlf_bom_trailing.csv", arbin(R, eol="\r\n", bom="\ufeff") + "\r\n")
w("arbin_quoted.csv", arbin(R, quote=True))
w("arbin_semicolon_deccomma.csv", arbin(R, sep=";", dec=","))
w("arbin_mA.csv", arbin(R, unitI="mA", scaleI=1000))
w("arbin_minutes.csv", arbin(R, tcol="Test_Time(min)", tscale=60))
w("arbin_hours.csv", arbin(R, tcol="Test_Time(h)", tscale=3600))
w("arbin_notimeunit.csv", arbin(R, tcol="Test_Time"))
# duplicate timestamp, time back, non-numeric, NaN, empty
def edit(text, line, col, val, sep=","):
    L = text.split("\n"); c = L[line - 1].split(sep); c[col - 1] = val; L[line - 1] = sep.join(c); return "\n".join(L)
A = arbin(R)
L = A.split("\n"); tprev = L[1200].split(",")[2]
w("arbin_dup.csv", edit(A, 1202, 3, tprev))   # line 1202 same time as line 1201
w("arbin_back.csv", edit(A, 1202, 3, "10.000"))
w("arbin_nonnum.csv", edit(A, 1500, 8, "3.9x"))
w("arbin_nan.csv", edit(A, 1500, 7, "NaN"))
w("arbin_empty.csv", edit(A, 1500, 7, ""))
w("arbin_auxempty.csv", edit(A, 1500, 13, ""))

# --- Maccor text, tab, metadata line, unsigned Amps, State
def maccor(rows, time_fmt="sec", signed=False, dec=".", extra_header_lines=0, state_other_at=None):
    out = ["Today's Date\t03/05/2021  \tDate of Test:\t03/04/2021\tFilename:\tC:\\Data\\cell01.001\tProcedure:\tcccv.000\tComment/Barcode:\t"]
    tname = "Test (Sec)" if time_fmt == "sec" else ("Test Time" if time_fmt == "hms" else "Test (Hr)")
    out.append("\t".join(["Rec#", "Cyc#", "Step", tname, "Step (Sec)", "Amp-hr", "Watt-hr", "Amps", "Volts", "State", "ES", "DPt Time", "Temp 1"]))
    step = {'R': 1, 'C': 2, 'D': 4}
    for i, (t, I, V, k) in enumerate(rows):
        tv = "%.2f" % t if time_fmt == "sec" else (hms(t) if time_fmt == "hms" else "%.6f" % (t / 3600))
        amps = I if signed else abs(I)
        s = int(t) + 14 * 3600
        st = k
        if state_other_at is not None and i == state_other_at: st = 'O'
        cells = [str(i + 1), "0", str(step[k]), tv, "0", "0", "0", "%.5f" % amps, "%.5f" % V, st, "0",
                 "03/04/2021 %d:%02d:%02d %s" % ((s // 3600 - 1) % 12 + 1, s // 60 % 60, s % 60, "PM" if s // 3600 % 24 >= 12 else "AM"), "%.2f" % 24.8]
        cells = [c.replace(".", dec) if j != 11 else c for j, c in enumerate(cells)]
        out.append("\t".join(cells))
    return "\r\n".join(out) + "\r\n"
w("maccor_unsigned.txt", maccor(R))
w("maccor_signed.txt", maccor(R, signed=True))
w("maccor_hms.txt", maccor(R, time_fmt="hms"))
w("maccor_hours.txt", maccor(R, time_fmt="hr"))
w("maccor_deccomma.txt", maccor(R, dec=","))
# Maccor's "O" state with current flowing (unsigned): which direction?
M = maccor(R).split("\r\n")
for ln in range(800, 805):
    c = M[ln].split("\t"); c[9] = "O"; M[ln] = "\t".join(c)   # rows in the charge, O state
w("maccor_other_state.txt", "\r\n".join(M))

# --- Neware CSV
def neware(rows, time="total", unitI="mA", scaleI=1000.0, sep=",", dec=".", names=None):
    names = names or {'R': "Rest", 'C': "CC_Chg", 'D': "CC_DChg"}
    h = ["Record ID", "Realtime", "Time" if time == "steptime" else "Total Time", "Step ID", "Cycle ID", "Step Type", "Current(%s)" % unitI, "Voltage(V)", "Capacity(mAh)"]
    out = [sep.join(h)]
    step0 = {}
    sid = {'R': 1, 'C': 2, 'D': 4}
    for i, (t, I, V, k) in enumerate(rows):
        step0.setdefault((k, sid[k]), t)
        tv = hms(t) if time != "steptime" else hms(t - step0[(k, sid[k])])
        cells = [str(i + 1), date(t), tv, str(sid[k]), "1", names[k], "%.3f" % (I * scaleI), "%.4f" % V, "0"]
        cells = [c.replace(".", dec) if j not in (1, 2) else c for j, c in enumerate(cells)]
        out.append(sep.join(cells))
    return "\n".join(out) + "\n"
w("neware.csv", neware(R))
w("neware_semicolon.csv", neware(R, sep=";", dec=","))
w("neware_steptime_only.csv", neware(R, time="steptime"))
w("neware_cccv.csv", neware(R, names={'R': "Rest", 'C': "CCCV_Chg", 'D': "CC_DChg"}))
# .NET TimeSpan style total time (d.hh:mm:ss) past one day
LONG = [(t * 50, I, V, k) for (t, I, V, k) in C]   # 100 s steps -> > 1 day
def tspan(t):
    s = int(t); d = s // 86400
    return ("%d.%02d:%02d:%02d" % (d, s // 3600 % 24, s // 60 % 60, s % 60)) if d else "%02d:%02d:%02d" % (s // 3600, s // 60 % 60, s % 60)
out = ["Record ID,Total Time,Step ID,Cycle ID,Step Type,Current(A),Voltage(V)"]
for i, (t, I, V, k) in enumerate(LONG):
    out.append("%d,%s,1,1,%s,%.3f,%.4f" % (i + 1, tspan(t), {'R': "Rest", 'C': "CC_Chg", 'D': "CC_DChg"}[k], I, V))
w("neware_dotnet_days.csv", "\n".join(out) + "\n")

# --- BioLogic .mpt
def biologic(rows, dec=".", ccol="<I>/mA", vcol="Ewe/V", enc="utf-8"):
    hdr = ["EC-Lab ASCII FILE", "Nb header lines : 6", "", "Acquisition started on : 03/04/2021 14:00:00.000", "Temperature/°C inside the header",
           "\t".join(["mode", "ox/red", "error", "control/V/mA", "time/s", vcol, ccol, "cycle number", "Ns", "Temperature/°C"])]
    out = list(hdr)
    for i, (t, I, V, k) in enumerate(rows):
        cells = ["1" if k != 'R' else "3", "1" if I > 0 else "0", "0", "%.4f" % (I * 1000), "%.4f" % t, "%.6f" % V, "%.4f" % (I * 1000), "0", str({'R': 0, 'C': 1, 'D': 3}[k]), "25.10"]
        out.append("\t".join(c.replace(".", dec) for c in cells))
    return "\r\n".join(out) + "\r\n"
w("biologic.mpt", biologic(R))
w("biologic_deccomma.mpt", biologic(R, dec=","))
w("biologic_ecell_I.mpt", biologic(R, ccol="I/mA", vcol="Ecell/V"))
w("biologic_latin1.mpt", biologic(R), enc="latin-1")

# --- NASA PCoE (one file per charge/discharge)
def nasa(rows, bom=""):
    out = ["Voltage_measured,Current_measured,Temperature_measured,Current_load,Voltage_load,Time"]
    t0 = rows[0][0]
    for (t, I, V, k) in rows:
        out.append("%.6f,%.6f,%.4f,%.4f,%.3f,%.3f" % (V, I, 24.5, I, V, t - t0))
    return bom + "\n".join(out) + "\n"
ch = [r for r in R if r[3] == 'C']; dis = [r for r in R if r[3] == 'D']
w("nasa_charge.csv", nasa(ch))
w("nasa_discharge.csv", nasa(dis))
w("nasa_bom.csv", nasa(dis, bom="\ufeff"))
# --- CALCE: Arbin converted by pandas with its index column
txt = arbin(R, aux=False).split("\n")
w("calce_pandas_index.csv", "\n".join([("," + txt[0])] + ["%d,%s" % (i, l) for i, l in enumerate(txt[1:-1])]) + "\n")
w("calce_cs2_txt.txt", arbin(R, sep="\t", aux=False))

# --- dates, Maccor's other export
# Neware with Realtime only, crossing midnight on 4->5 March, written DD/MM/YYYY and DD.MM.YYYY
def d2(t, fmt):
    s = int(t) + 23 * 3600  # starts 23:00 on 4 March
    day, hh, mm, ss = 4 + s // 86400, s // 3600 % 24, s // 60 % 60, s % 60
    return fmt % (day, 3, 2021, hh, mm, ss)
for name, fmt in (("neware_realtime_ddmm.csv", "%02d/%02d/%04d %02d:%02d:%02d"), ("neware_realtime_dotted.csv", "%02d.%02d.%04d %02d:%02d:%02d")):
    out = ["Record ID,Realtime,Step ID,Cycle ID,Step Type,Current(A),Voltage(V)"]
    for i, (t, I, V, k) in enumerate(R):
        out.append("%d,%s,1,1,%s,%.3f,%.4f" % (i + 1, d2(t, fmt), {'R': "Rest", 'C': "CC_Chg", 'D': "CC_DChg"}[k], I, V))
    w(name, "\n".join(out) + "\n")
# Maccor's other export: Rec / TestTime (d hh:mm:ss) / Current [A] / Voltage [V] / Md, unsigned current
out = ["Rec\tCycle P\tCycle C\tStep\tTestTime\tStepTime\tCap. [Ah]\tEner. [Wh]\tCurrent [A]\tVoltage [V]\tMd\tES\tDPT Time"]
for i, (t, I, V, k) in enumerate(R):
    s = int(t)
    out.append("%d\t1\t1\t1\t%dd %02d:%02d:%02d.00\t0d 00:00:00.00\t0\t0\t%.4f\t%.4f\t%s\t0\t04.03.2021 14:00:00" % (i + 1, s // 86400, s // 3600 % 24, s // 60 % 60, s % 60, abs(I), V, k))
w("maccor_rec_variant.txt", "\n".join(out) + "\n")
# Arbin hours with enough digits

rows, t = [], 0
for k in range(30): rows.append((t, 0.0, 3.30, 'R')); t += 2
for k in range(300): rows.append((t, 1.0, 3.25 - 0.0002 * k, 'D')); t += 2
for k in range(60): rows.append((t, 0.0, 3.27, 'R')); t += 2
for k in range(200): rows.append((t, 1.0, 3.35 + 0.0002 * k, 'C')); t += 2
out = ["Today's Date\t03/05/2021\tDate of Test:\t03/04/2021", "Rec#\tCyc#\tStep\tTest (Sec)\tStep (Sec)\tAmp-hr\tWatt-hr\tAmps\tVolts\tState\tES\tDPt Time"]
for i, (t, I, V, k) in enumerate(rows):
    out.append("%d\t0\t1\t%.2f\t0\t0\t0\t%.4f\t%.4f\t%s\t0\t03/04/2021 2:00:00 PM" % (i + 1, t, I, V, k))
w("maccor_short.txt", "\r\n".join(out) + "\r\n")
L = neware(R).split("\n")
out = [",".join(c for j, c in enumerate(r.split(",")) if j != 1) for r in L if r]
out[0] = out[0].replace("Total Time", "Time")
w("neware_steptime_norealtime.csv", "\n".join(out) + "\n")
