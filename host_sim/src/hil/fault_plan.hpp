#pragma once
// Bus faults for the host-in-the-loop (bmssim hil --fault SPEC): what the host does to the
// measurement stream in each tick. The plan is fixed before the run (seeded), so a faulty
// run is as repeatable as a clean one.
//
// SPEC: comma-separated KEY=VALUE, keys may repeat:
//   rate faults, P = probability per tick (0..1), drawn independently:
//     drop=P      the measurement frame is lost (the clock still ticks: a HOST_Control
//                 TickTrigger frame is sent in its place, as the firmware's timer would)
//     dup=P       the measurement frame is sent twice
//     reorder=P   this tick's frame and the next one's are swapped
//     crc=P       one payload bit flipped after the CRC was computed
//     length=P    the frame arrives one byte short (plus a TickTrigger, as for drop)
//     unknown=P   an extra frame with an identifier nobody uses (0x555) before it
//   window faults, START:TICKS (START = tick number, or MODE+SECONDS = that many seconds
//   into the first phase of MODE, e.g. cc_charge+600):
//     burst=W     every measurement frame in the window is lost (TickTrigger sent instead)
//     stale=W     the alive counter is frozen (the frames are otherwise valid)
//     range=W     the measured voltage reads 7 V (outside the cell's window)
//     nan=W       the measured voltage is NaN (the encoder puts raw 0 = 0 V on the bus)
//     busdown=W   the interface is set down for the window (ip link set IFACE down / up)
//     kill=W      the firmware is killed (SIGKILL) at START and restarted after TICKS
//   seed=K        random stream of the rate faults (default 1)
#include <cstdint>
#include <string>
#include <vector>

#include "bms/fw/estimation/operating_mode.hpp"

namespace bms::hil {

enum class WindowKind : std::uint8_t { burst, stale, range, nan, busdown, kill };
const char* window_kind_name(WindowKind k);

struct FaultWindow {
  WindowKind kind;
  std::string start_text;  // as given, for messages and the summary
  std::size_t start_tick;  // resolved by FaultPlan::resolve
  std::size_t ticks;
};

struct FaultSpec {
  double drop = 0, dup = 0, reorder = 0, crc = 0, length = 0, unknown = 0;
  std::vector<FaultWindow> windows;
  std::uint64_t seed = 1;
  std::string text;  // the spec as given
  bool any() const;
};

// Throws InputError naming --fault and the offending item.
FaultSpec parse_fault_spec(const std::string& text);

// What happens to tick k's measurement.
struct TickFaults {
  bool drop = false, dup = false, reorder = false, crc = false, length = false, unknown = false;
  bool stale = false, range = false, nan = false;
  bool bus_down = false;   // the interface is down during this tick
  bool fw_down = false;    // the firmware process is dead during this tick
  bool kill_now = false;   // kill the firmware at the start of this tick
  bool restart_now = false;  // restart it at the start of this tick
  bool down_now = false, up_now = false;  // set the interface down / up at the start of this tick
};

class FaultPlan {
 public:
  // Resolves window starts against the run's modes (InputError when a window does not fit)
  // and draws the rate faults for every tick.
  FaultPlan(FaultSpec spec, const std::vector<fw::Mode>& modes, double dt_s);
  const TickFaults& at(std::size_t k) const { return ticks_[k]; }
  const FaultSpec& spec() const { return spec_; }
  std::size_t size() const { return ticks_.size(); }

 private:
  FaultSpec spec_;
  std::vector<TickFaults> ticks_;
};

}  // namespace bms::hil
