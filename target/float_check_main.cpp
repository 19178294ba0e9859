// Host tool: the firmware's tick in float and in double, side by side, over the measured
// columns of a truth.csv (bmssim simulate), with the best profile (paper_cell_config). The
// float build of the tick is what the Cortex-M4F runs; the host's float arithmetic with
// -ffp-contract=off reproduces it to the last bits of libm (docs/results/target.md), so
// several cycles of a blind truth can be measured here where the board replay holds one.
//
//   bms_float_check TRUTH.csv > OUT.txt
//
// Reads only t_s, current_meas_a and voltage_meas_v (the information rule: no truth column
// reaches the estimator); target/tools/float_check.py scores OUT.txt against the truth.
// Output: a "# columns" line, one line per sample, "# name value" summary lines.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <bms/fw/estimation/bms_core.hpp>
#include <bms/fw/config/make_config.hpp>
#include <bms/fw/model/reduced_cell.hpp>

namespace {

// The model in one precision behind the interface of another: which part of the firmware loses
// the signal in float (the model or the core's estimator), measured by mixing the two.
template <typename Outer, typename InnerScalar>
class PrecisionAdapter {
 public:
  using Inner = bms::fw::ReducedCell<InnerScalar>;
  using State = typename Inner::State;
  explicit PrecisionAdapter(const Inner& m) : m_(m) {}
  bms::fw::ModelTickResult<Outer> step_current(Outer i, Outer r, Outer dt) {
    return out(m_.step_current(InnerScalar(i), InnerScalar(r), InnerScalar(dt)));
  }
  bms::fw::ModelTickResult<Outer> step_voltage(Outer v, Outer r, Outer dt) {
    return out(m_.step_voltage(InnerScalar(v), InnerScalar(r), InnerScalar(dt)));
  }
  Outer inventory_probe_voltage(Outer i, Outer r, Outer dt, Outer d) const {
    return Outer(m_.inventory_probe_voltage(InnerScalar(i), InnerScalar(r), InnerScalar(dt), InnerScalar(d)));
  }
  bool resync(Outer v, Outer i, Outer r, Outer dt, Outer inv) {
    return m_.resync(InnerScalar(v), InnerScalar(i), InnerScalar(r), InnerScalar(dt), InnerScalar(inv));
  }
  Outer li_loss_ah() const { return Outer(m_.li_loss_ah()); }
  Outer li_loss_mol() const { return Outer(m_.li_loss_mol()); }
  const State& state() const { return m_.state(); }
  bool restore(const State& s) { return m_.restore(s); }

 private:
  static bms::fw::ModelTickResult<Outer> out(const bms::fw::ModelTickResult<InnerScalar>& r) {
    return {Outer(r.voltage_v), Outer(r.current_a), Outer(r.j_side_a_m3), Outer(r.markov_v_per_ohm_m2),
            r.newton_iterations, r.converged, r.valid};
  }
  Inner m_;
};

template <typename Scalar, typename ModelScalar = Scalar>
struct Firmware {
  using Model = std::conditional_t<std::is_same<Scalar, ModelScalar>::value, bms::fw::ReducedCell<Scalar>,
                                   PrecisionAdapter<Scalar, ModelScalar>>;
  using Core = bms::fw::BmsCore<Scalar, Model>;
  Firmware() : model(initial()), core(bms::fw::paper_cell_config<Core>(bms::fw::Profile::best), model) {}
  static Model initial() {
    bms::fw::ReducedCell<ModelScalar> m;
    m.init_default();
    return Model(m);
  }
  Model model;
  Core core;
  std::uint32_t status_or = 0u;
  std::uint32_t cap_hits = 0u;
};

struct Sample {
  double voltage_v;
  double current_a;
};

// Column index of `name` in a CSV header, or -1.
int column(const std::string& header, const char* name) {
  std::stringstream ss(header);
  std::string field;
  for (int i = 0; std::getline(ss, field, ','); ++i) {
    if (field == name) return i;
  }
  return -1;
}

// Reads the measured columns; exits 2 naming the file and line on bad input.
std::vector<Sample> read_measured(const char* path) {
  std::ifstream in(path);
  if (!in) {
    std::fprintf(stderr, "bms_float_check: %s: cannot open\n", path);
    std::exit(2);
  }
  std::string line;
  std::getline(in, line);
  const int iv = column(line, "voltage_meas_v"), ii = column(line, "current_meas_a");
  if (iv < 0 || ii < 0) {
    std::fprintf(stderr, "bms_float_check: %s: line 1: no voltage_meas_v or current_meas_a column\n", path);
    std::exit(2);
  }
  std::vector<Sample> out;
  for (std::size_t n = 2; std::getline(in, line); ++n) {
    std::stringstream ss(line);
    std::string field;
    Sample s{NAN, NAN};
    for (int i = 0; std::getline(ss, field, ','); ++i) {
      if (i == iv) s.voltage_v = std::strtod(field.c_str(), nullptr);
      if (i == ii) s.current_a = std::strtod(field.c_str(), nullptr);
    }
    if (!std::isfinite(s.voltage_v) || !std::isfinite(s.current_a)) {
      std::fprintf(stderr, "bms_float_check: %s: line %zu: voltage_meas_v or current_meas_a not a number\n", path, n);
      std::exit(2);
    }
    out.push_back(s);
  }
  return out;
}

template <typename Fw>
typename Fw::Core::Output step(Fw& fw, const Sample& s) {
  using Scalar = decltype(fw.core.config().dt_s);
  const auto out = fw.core.tick({static_cast<Scalar>(s.voltage_v), static_cast<Scalar>(s.current_a), true});
  fw.status_or |= out.status;
  if (bms::fw::has_status(out.status, bms::fw::FwStatus::kModelNotConverged)) ++fw.cap_hits;
  return out;
}

template <typename Fw>
void summary(const char* name, const Fw& fw) {
  const auto& id = fw.core.identifier();
  std::printf("# %s_theta %.9g %.9g %.9g\n", name, static_cast<double>(id.theta()(0)),
              static_cast<double>(id.theta()(1)), static_cast<double>(id.theta()(2)));
  std::printf("# %s_resyncs %u\n", name, static_cast<unsigned>(fw.core.resync_count()));
  std::printf("# %s_status_or 0x%08x\n", name, static_cast<unsigned>(fw.status_or));
  std::printf("# %s_newton_cap_hits %u\n", name, static_cast<unsigned>(fw.cap_hits));
}

template <typename Fw>
int run(const std::vector<Sample>& data, Fw& f, Firmware<double>& d) {
  std::printf("# columns tick mode_f mode_d active_f active_d r_film_f r_film_d gain_f gain_d nu_f nu_d z_f z_d\n");
  for (std::size_t k = 0; k < data.size(); ++k) {
    const auto of = step(f, data[k]);
    const auto od = step(d, data[k]);
    std::printf("%zu %u %u %u %u %.9g %.17g %.9g %.17g %.9g %.17g %.9g %.17g\n", k, static_cast<unsigned>(of.mode),
                static_cast<unsigned>(od.mode), of.rcsi_active ? 1u : 0u, od.rcsi_active ? 1u : 0u,
                static_cast<double>(of.r_film_est_ohm_m2), od.r_film_est_ohm_m2, static_cast<double>(of.growth_gain),
                od.growth_gain, static_cast<double>(of.inventory_deviation), od.inventory_deviation,
                static_cast<double>(of.z_v), od.z_v);
  }
  summary("float", f);
  summary("double", d);
  std::printf("# ticks %zu\n", data.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // --mix: which parts run in float (the "float" columns): all (the M4F build), the core only
  // (model-double), or the model only (model-float).
  const char* mix = argc == 4 && std::strcmp(argv[1], "--mix") == 0 ? argv[2] : "all";
  const char* path = argc == 4 ? argv[3] : (argc == 2 ? argv[1] : nullptr);
  const bool mix_ok = std::strcmp(mix, "all") == 0 || std::strcmp(mix, "model-double") == 0 ||
                      std::strcmp(mix, "model-float") == 0;
  if (path == nullptr || !mix_ok || std::strcmp(path, "--help") == 0) {
    std::fprintf(stderr, "usage: bms_float_check [--mix all|model-double|model-float] TRUTH.csv > OUT.txt\n");
    return 2;
  }
  const std::vector<Sample> data = read_measured(path);
  if (data.empty()) {
    std::fprintf(stderr, "bms_float_check: %s: no samples\n", path);
    return 2;
  }
  std::printf("# mix %s\n", mix);
  static Firmware<double> d;
  if (std::strcmp(mix, "model-double") == 0) {
    static Firmware<float, double> f;
    return run(data, f, d);
  }
  if (std::strcmp(mix, "model-float") == 0) {
    static Firmware<double, float> f;
    return run(data, f, d);
  }
  static Firmware<float> f;
  return run(data, f, d);
}
