// Fuzz target: the BPX reader (host_sim/src/io/bpx_reader.*, with nlohmann::json and the
// expression parser and tables behind it). Input: the file's bytes. Every problem must be
// an InputError naming the file; a json type_error or out_of_range escaping, a crash or UB
// is a finding. An accepted file's functions are evaluated across their range.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "io/bpx_reader.hpp"
#include "io/input_error.hpp"

namespace {

void sample(const bms::ScalarFunctionPtr& f) {
  if (!f) return;
  for (double x = -0.25; x <= 1.25; x += 0.125) {
    (void)f->value(x);
    (void)f->derivative(x);
  }
  (void)f->value(1000.0);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const bms::CellParameters p = bms::read_bpx_text(text, "fuzz.json");
    if (!(p.lower_voltage_v < p.upper_voltage_v) || !(p.electrode_area_m2 > 0.0)) std::abort();
    sample(p.negative.ocp_v);
    sample(p.positive.ocp_v);
    sample(p.negative.entropic_v_k);
    sample(p.electrolyte.diffusivity_m2_s);
    sample(p.electrolyte.conductivity_s_m);
  } catch (const bms::InputError& e) {
    if (std::string_view(e.what()).substr(0, 10) != "fuzz.json:") std::abort();  // names the file
  }
  return 0;
}
