#include "diagnosis/characterise.hpp"
#include "io/statistics.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>

namespace bms::diagnosis {

namespace {

// Accumulates the samples of one group.
struct Acc {
  std::size_t n = 0;
  double sum = 0.0, sum2 = 0.0;
  void add(double x) {
    ++n;
    sum += x;
    sum2 += x * x;
  }
};

void emit(std::vector<ResidualGroup>& out, const std::string& dim, const std::vector<std::string>& labels,
          const std::vector<Acc>& acc) {
  for (std::size_t g = 0; g < acc.size(); ++g) {
    if (acc[g].n == 0) continue;
    const double n = static_cast<double>(acc[g].n);
    out.push_back({dim, labels[g], acc[g].n, acc[g].sum / n, std::sqrt(acc[g].sum2 / n)});
  }
}

double quantile(const std::vector<double>& v, double q) { return v.empty() ? 0.0 : stats::quantile(v, q); }

// Groups by |dV/dt| of the measured voltage, quartiles.
void group_by_voltage_rate(const Record& r, const std::vector<double>& res, std::vector<ResidualGroup>& groups) {
  const std::size_t n = res.size();
  std::vector<double> rate(n, 0.0);
  for (std::size_t k = 1; k < n; ++k)
    rate[k] = 1e3 * std::abs(r.voltage_v[k] - r.voltage_v[k - 1]) / (r.t_s[k] - r.t_s[k - 1]);
  rate[0] = n > 1 ? rate[1] : 0.0;
  const double q1 = quantile(rate, 0.25), q2 = quantile(rate, 0.5), q3 = quantile(rate, 0.75);
  const std::vector<std::string> labels{fmt::format("<= {:.3g} mV/s", q1), fmt::format("{:.3g}-{:.3g} mV/s", q1, q2),
                                        fmt::format("{:.3g}-{:.3g} mV/s", q2, q3), fmt::format("> {:.3g} mV/s", q3)};
  std::vector<Acc> acc(4);
  for (std::size_t k = 0; k < n; ++k)
    acc[rate[k] <= q1 ? 0 : rate[k] <= q2 ? 1 : rate[k] <= q3 ? 2 : 3].add(res[k]);
  emit(groups, "dvdt", labels, acc);
}

// Signature: least squares of the residual on [1, I, sign(I)] outside rest.
ResidualSignature current_signature(const Record& r, const std::vector<double>& res, double rest, const Excitation& ex) {
  const std::size_t n = res.size();
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    const double i = r.current_a[k];
    if (std::abs(i) <= rest) continue;
    const Eigen::Vector3d a(1.0, i, i > 0 ? 1.0 : -1.0);
    ata += a * a.transpose();
    atb += a * res[k];
  }
  // Needs both current signs and more than one level per sign to separate R from h.
  Eigen::FullPivLU<Eigen::Matrix3d> lu(ata);
  lu.setThreshold(1e-9);
  if (ex.has_charge && ex.has_discharge && lu.rank() == 3) {
    const Eigen::Vector3d x = lu.solve(atb);
    return {x(0), x(1), x(2), true};
  }
  return {};
}

}  // namespace

Characterisation characterise(const Record& r, const std::vector<double>& res, const std::vector<double>& soc) {
  Characterisation c;
  const std::size_t n = res.size();
  const Excitation ex = analyse_excitation(r);
  const double rest = 0.01 * ex.max_abs_current_a + 1e-6;

  {  // by mode
    const Mode modes[] = {Mode::rest, Mode::cc_discharge, Mode::cv_discharge, Mode::cc_charge, Mode::cv_charge};
    std::vector<std::string> labels;
    for (Mode m : modes) labels.emplace_back(mode_name(m));
    std::vector<Acc> acc(5);
    for (std::size_t k = 0; k < n; ++k) {
      const auto m = static_cast<std::size_t>(r.mode[k]);
      if (m < 5) acc[m].add(res[k]);
    }
    emit(c.groups, "mode", labels, acc);
  }
  {  // by state of charge, tenths
    std::vector<std::string> labels;
    for (int d = 0; d < 10; ++d) labels.push_back(fmt::format("{:.1f}-{:.1f}", d / 10.0, (d + 1) / 10.0));
    std::vector<Acc> acc(10);
    for (std::size_t k = 0; k < n; ++k) {
      const int d = std::clamp(static_cast<int>(std::floor(soc[k] * 10.0)), 0, 9);
      acc[static_cast<std::size_t>(d)].add(res[k]);
    }
    emit(c.groups, "soc", labels, acc);
  }
  {  // by current: charge / rest / discharge, each split at half the largest current
    const double h = 0.5 * ex.max_abs_current_a;
    const std::vector<std::string> labels{fmt::format("charge, |I| > {:.3g} A", h),
                                          fmt::format("charge, |I| <= {:.3g} A", h), "rest",
                                          fmt::format("discharge, I <= {:.3g} A", h),
                                          fmt::format("discharge, I > {:.3g} A", h)};
    std::vector<Acc> acc(5);
    for (std::size_t k = 0; k < n; ++k) {
      const double i = r.current_a[k];
      const std::size_t g = i < -h ? 0 : i < -rest ? 1 : i <= rest ? 2 : i <= h ? 3 : 4;
      acc[g].add(res[k]);
    }
    emit(c.groups, "current", labels, acc);
  }
  {  // by time since the last current step: fast, intermediate and slow dynamics
    const std::vector<double> since = time_since_step_s(r);
    const std::vector<std::string> labels{"< 10 s", "10-60 s", "60-600 s", "> 600 s"};
    std::vector<Acc> acc(4);
    for (std::size_t k = 0; k < n; ++k) {
      const double s = since[k];
      acc[s < 10 ? 0 : s < 60 ? 1 : s < 600 ? 2 : 3].add(res[k]);
    }
    emit(c.groups, "since_step", labels, acc);
  }
  group_by_voltage_rate(r, res, c.groups);
  c.signature = current_signature(r, res, rest, ex);
  return c;
}

}  // namespace bms::diagnosis
