#include "diagnosis/plots.hpp"

#include <fmt/format.h>

#include <system_error>

#include "io/atomic_file.hpp"
#include "io/gnuplot.hpp"

namespace bms::diagnosis {

PlotOutcome draw_residual_plots(const std::filesystem::path& dir, int cases, std::size_t samples) {
  PlotOutcome out;
  // About 5000 points per curve keep the plots light at any record length.
  const std::size_t every = std::max<std::size_t>(1, samples / 5000);
  const char* names[] = {"residual_time.png", "residual_soc.png", "residual_current.png"};
  std::string gp = fmt::format(
      "# Made by bmssim diagnose; run in this folder: gnuplot plots.gp\n"
      "set datafile separator ','\nset key autotitle columnhead\nset terminal pngcairo size 1200,800 noenhanced\n"
      "set grid\nN = {}\nE = {}\n",
      cases, every);
  // residual.csv columns: 1 case, 2 t_s, 3 mode, 4 current_meas_a, 5 voltage_meas_v,
  // 6 voltage_before_v, 7 voltage_after_v, 8 residual_before_mv, 9 residual_after_mv, 10 soc, 11 split
  gp += fmt::format(
      "set output '{0}.tmp'\nset multiplot layout 2,1 title 'Measured and model voltage; residual = model - measured'\n"
      "set ylabel 'voltage (V)'\n"
      "plot for [c=0:N-1] 'residual.csv' every E using 2:($1==c?$5:1/0) with lines lw 2 title sprintf('measured, case %d', c), "
      "for [c=0:N-1] '' every E using 2:($1==c?$6:1/0) with lines title sprintf('model before, case %d', c), "
      "for [c=0:N-1] '' every E using 2:($1==c?$7:1/0) with lines dt 2 title sprintf('model fitted, case %d', c)\n"
      "set ylabel 'residual (mV)'; set xlabel 'time (s)'\n"
      "plot for [c=0:N-1] 'residual.csv' every E using 2:($1==c?$8:1/0) with lines title sprintf('before, case %d', c), "
      "for [c=0:N-1] '' every E using 2:($1==c?$9:1/0) with lines title sprintf('fitted, case %d', c)\n"
      "unset multiplot\n",
      names[0]);
  gp += fmt::format(
      "set output '{0}.tmp'\nset title 'Residual against state of charge (coulomb counting)'\n"
      "set xlabel 'state of charge'; set ylabel 'residual (mV)'\n"
      "plot 'residual.csv' every E using 10:8 with points pt 7 ps 0.3 title 'before', "
      "'' every E using 10:9 with points pt 7 ps 0.3 title 'fitted'\n",
      names[1]);
  gp += fmt::format(
      "set output '{0}.tmp'\nset title 'Residual against measured current (positive = discharge)'\n"
      "set xlabel 'current (A)'; set ylabel 'residual (mV)'\n"
      "plot 'residual.csv' every E using 4:8 with points pt 7 ps 0.3 title 'before', "
      "'' every E using 4:9 with points pt 7 ps 0.3 title 'fitted'\n",
      names[2]);
  AtomicFileWriter script(dir / "plots.gp");
  script.append(gp);
  script.commit();
  GnuplotOptions gnuplot;
  gnuplot.working_dir = dir;
  const int rc = run_gnuplot("plots.gp", gnuplot);
  if (rc != 0) {
    out.problem = rc == kGnuplotMissing ? "gnuplot is not installed (Debian package gnuplot-nox)"
                            : fmt::format("gnuplot failed (exit status {})", rc);
    for (const char* n : names) {
      std::error_code ec;
      std::filesystem::remove(dir / (std::string(n) + ".tmp"), ec);
    }
    return out;
  }
  for (const char* n : names) {
    std::error_code ec;
    std::filesystem::rename(dir / (std::string(n) + ".tmp"), dir / n, ec);
    if (ec) {
      out.problem = fmt::format("{}: {}", n, ec.message());
      return out;
    }
    out.pngs.emplace_back(n);
  }
  return out;
}

}  // namespace bms::diagnosis
