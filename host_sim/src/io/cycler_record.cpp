// Joining the files of one cell (cycler_formats.hpp): folders expanded, files ordered by their
// absolute start, overlaps refused, cycles numbered on, logging gaps marked as segment starts.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "io/cycler_formats.hpp"
#include "io/delimited_table.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace {

namespace fs = std::filesystem;

struct Listed {
  fs::path file;
  CyclerLayoutGuess guess;
};

struct Inputs {
  std::vector<Listed> series;        // time-series files
  std::vector<fs::path> index;       // NASA PCoE index files
  std::vector<std::string> skipped;  // in folders: files of no time-series layout
};

Inputs list_inputs(const std::vector<fs::path>& paths) {
  Inputs in;
  for (const fs::path& p : paths) {
    std::error_code ec;
    if (fs::is_directory(p, ec)) {
      std::vector<fs::path> files;
      for (const auto& e : fs::directory_iterator(p, ec))
        if (e.is_regular_file()) files.push_back(e.path());
      if (ec) throw InputError(fmt::format("{}: cannot list the folder: {}", p.string(), ec.message()));
      std::sort(files.begin(), files.end());
      for (const fs::path& f : files) {
        const CyclerLayoutGuess g = detect_cycler_layout_of(f);
        if (g.layout == CyclerLayout::nasa_index) in.index.push_back(f);
        else if (g.layout == CyclerLayout::none || g.layout == CyclerLayout::arbin_statistics)
          in.skipped.push_back(f.filename().string());
        else in.series.push_back({f, g});
      }
      continue;
    }
    if (!fs::exists(p, ec)) throw InputError(fmt::format("{}: cannot read: no such file or folder", p.string()));
    const CyclerLayoutGuess g = detect_cycler_layout_of(p);
    if (g.layout == CyclerLayout::nasa_index) in.index.push_back(p);
    else if (g.layout == CyclerLayout::none || g.layout == CyclerLayout::arbin_statistics)
      throw InputError(fmt::format("{}: line 1: not a cycler time series of a known layout ({}); the readers know "
                                   "Arbin, Maccor, Neware, BioLogic .mpt and NASA PCoE",
                                   p.string(), cycler_layout_name(g.layout)));
    else in.series.push_back({p, g});
  }
  return in;
}

// MATLAB date vector "[2010.  7.  21.  15.  0.  35.093]" or a date and time.
bool parse_start_time(std::string_view s, double& epoch_s) {
  if (parse_date_time_s(s, epoch_s)) return true;
  std::string text(s);
  std::replace(text.begin(), text.end(), '[', ' ');
  std::replace(text.begin(), text.end(), ']', ' ');
  double v[6];
  int used = 0;
  if (std::sscanf(text.c_str(), "%lf %lf %lf %lf %lf %lf %n", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &used) != 6)
    return false;
  const std::string iso = fmt::format("{:04d}-{:02d}-{:02d} 00:00:00", static_cast<int>(v[0]), static_cast<int>(v[1]),
                                      static_cast<int>(v[2]));
  if (!parse_date_time_s(iso, epoch_s)) return false;
  epoch_s += v[3] * 3600.0 + v[4] * 60.0 + v[5];
  return true;
}

// File name -> start time, from every index given or found as metadata.csv beside the files.
std::map<std::string, double> nasa_index(Inputs& in) {
  if (in.index.empty() && !in.series.empty()) {
    for (const fs::path& dir : {in.series.front().file.parent_path(), in.series.front().file.parent_path().parent_path()}) {
      const fs::path m = dir / "metadata.csv";
      std::error_code ec;
      if (fs::is_regular_file(m, ec) && detect_cycler_layout_of(m).layout == CyclerLayout::nasa_index) {
        in.index.push_back(m);
        break;
      }
    }
  }
  std::map<std::string, double> starts;
  for (const fs::path& f : in.index) {
    const CyclerLayoutGuess g = detect_cycler_layout_of(f);
    const DelimitedTable t(read_text_file(f), f.string(), g.header_line, g.delimiter);
    const std::size_t name_c = t.find("filename"), start_c = t.find("start_time");
    if (name_c == DelimitedTable::npos || start_c == DelimitedTable::npos)
      throw InputError(fmt::format("{}: line {}: an index needs 'filename' and 'start_time' columns", f.string(),
                                   g.header_line + 1));
    for (std::size_t r = 0; r < t.rows(); ++r) {
      double s = 0.0;
      if (!parse_start_time(t.cell(r, start_c), s))
        throw InputError(fmt::format("{}: not a start time (a date and time or a MATLAB date vector): '{}'",
                                     t.where(r, start_c), t.cell(r, start_c)));
      starts[fs::path(std::string(t.cell(r, name_c))).filename().string()] = s;
    }
  }
  return starts;
}

double median_step(const std::vector<double>& t) {
  std::vector<double> d;
  for (std::size_t i = 1; i < t.size(); ++i) d.push_back(t[i] - t[i - 1]);
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

// Cycles numbered on across files: a file's first cycle follows the previous file's last.
// NASA records (one file each, no cycle index): a charge record starts the next cycle.
void renumber_cycles(CyclerFile& f, int& last_cycle) {
  if (f.layout == CyclerLayout::nasa) {
    double q = 0.0;
    for (double i : f.current_a) q += i;
    if (q < 0.0 || last_cycle == 0) ++last_cycle;
    std::fill(f.cycle.begin(), f.cycle.end(), last_cycle);
    return;
  }
  if (f.cycle.empty()) return;
  const int first = *std::min_element(f.cycle.begin(), f.cycle.end());
  const int offset = last_cycle - first + 1;
  for (int& c : f.cycle) c += offset;
  for (auto& s : f.cycle_stats) s.cycle += offset;
  last_cycle = *std::max_element(f.cycle.begin(), f.cycle.end());
}

void append(CyclerRecord& rec, CyclerFile& f, double offset_s, double max_current_a) {
  const double step = median_step(f.t_s);
  const std::size_t first = rec.t_s.size();
  rec.file_starts.push_back(first);
  for (std::size_t r = 0; r < f.t_s.size(); ++r) {
    const double t = f.t_s[r] + offset_s;
    if (!rec.t_s.empty()) {
      const double dt = t - rec.t_s.back();
      if (dt > kCyclerGapFactor * step && dt > step + 1.0) {
        rec.segment_starts.push_back(rec.t_s.size());
        ++rec.gaps;
        rec.longest_gap_s = std::max(rec.longest_gap_s, dt);
        const double under = 0.05 * max_current_a;
        const double before = r > 0 ? f.current_a[r - 1] : rec.current_a.back();
        if (std::abs(before) > under || std::abs(f.current_a[r]) > under) {
          ++rec.gaps_under_current;
          rec.longest_gap_under_current_s = std::max(rec.longest_gap_under_current_s, dt);
        }
      }
    } else {
      rec.segment_starts.push_back(0);
    }
    rec.t_s.push_back(t);
  }
  rec.current_a.insert(rec.current_a.end(), f.current_a.begin(), f.current_a.end());
  rec.voltage_v.insert(rec.voltage_v.end(), f.voltage_v.begin(), f.voltage_v.end());
  rec.cycle.insert(rec.cycle.end(), f.cycle.begin(), f.cycle.end());
  rec.step.insert(rec.step.end(), f.step.begin(), f.step.end());
  for (auto s : f.cycle_stats) {
    s.t_end_s += offset_s;
    rec.cycle_stats.push_back(s);
  }
  rec.files.push_back(f.name);
}

// Every file read (one at a time; each file's text is freed once parsed), in time order.
std::vector<CyclerFile> read_all(Inputs& in, CurrentSign sign) {
  const CyclerLayout layout = in.series.front().guess.layout;
  for (const Listed& l : in.series)
    if (l.guess.layout != layout)
      throw InputError(fmt::format("{}: line {}: {} layout among {} files ({}): one cell's files share a layout",
                                   l.file.string(), l.guess.header_line + 1, cycler_layout_name(l.guess.layout),
                                   cycler_layout_name(layout), in.series.front().file.string()));
  const std::map<std::string, double> starts = layout == CyclerLayout::nasa ? nasa_index(in) : std::map<std::string, double>{};
  std::vector<CyclerFile> files;
  for (const Listed& l : in.series) {
    files.push_back(parse_cycler_file(read_text_file(l.file), l.file.string(), sign));
    CyclerFile& f = files.back();
    if (layout == CyclerLayout::nasa) {
      const auto it = starts.find(l.file.filename().string());
      if (it != starts.end()) f.start_epoch_s = it->second;
    }
    if (std::isnan(f.start_epoch_s) && in.series.size() > 1)
      throw InputError(fmt::format(
          "{}: line 1: no absolute start time ({}), so it cannot be ordered among {} files; {}", f.name,
          layout == CyclerLayout::nasa     ? "not in the index"
          : f.no_start_why.empty() ? "no date/time column or acquisition date"
                                   : f.no_start_why.c_str(),
          in.series.size(),
          layout == CyclerLayout::nasa ? "give the index (a CSV with filename and start_time) as --data too"
                                       : "read it alone"));
  }
  std::stable_sort(files.begin(), files.end(),
                   [](const CyclerFile& a, const CyclerFile& b) { return a.start_epoch_s < b.start_epoch_s; });
  for (std::size_t k = 1; k < files.size(); ++k) {
    const CyclerFile& a = files[k - 1];
    const CyclerFile& b = files[k];
    if (!(b.start_epoch_s + b.t_s.front() > a.start_epoch_s + a.t_s.back()))
      throw InputError(fmt::format("{}: line {}, column '{}': starts {} s before the end of {} (overlapping records: "
                                   "the same data twice?)",
                                   b.name, b.line.front(), b.time_column,
                                   a.start_epoch_s + a.t_s.back() - b.start_epoch_s - b.t_s.front(), a.name));
  }
  return files;
}

}  // namespace

CyclerRecord read_cycler_record(const std::vector<fs::path>& paths, CurrentSign sign) {
  Inputs in = list_inputs(paths);
  if (in.series.empty())
    throw InputError(fmt::format("{}: no cycler time series found{}", paths.empty() ? "--data" : paths.front().string(),
                                 in.skipped.empty() ? "" : fmt::format(" (skipped: {})", fmt::join(in.skipped, ", "))));
  std::vector<CyclerFile> files = read_all(in, sign);
  CyclerRecord rec;
  rec.layout = std::string(cycler_layout_name(files.front().layout));
  rec.start_epoch_s = files.front().start_epoch_s + files.front().t_s.front();
  double imax = 0.0;
  bool all_temperature = true, any_step_time = false;
  for (const CyclerFile& f : files) {
    for (double i : f.current_a) imax = std::max(imax, std::abs(i));
    all_temperature = all_temperature && !f.temperature_k.empty();
    any_step_time = any_step_time || !f.step_time_s.empty();
  }
  std::vector<std::string> signs;
  for (const CyclerFile& f : files)
    if (std::find(signs.begin(), signs.end(), f.sign_note) == signs.end()) signs.push_back(f.sign_note);
  int last_cycle = 0;
  for (CyclerFile& f : files) {
    renumber_cycles(f, last_cycle);
    const double offset = std::isnan(f.start_epoch_s) ? -f.t_s.front() : f.start_epoch_s - rec.start_epoch_s;
    append(rec, f, offset, imax);
    if (all_temperature) rec.temperature_k.insert(rec.temperature_k.end(), f.temperature_k.begin(), f.temperature_k.end());
    if (any_step_time && f.step_time_s.empty()) f.step_time_s.assign(f.t_s.size(), std::nan(""));
    if (any_step_time) rec.step_time_s.insert(rec.step_time_s.end(), f.step_time_s.begin(), f.step_time_s.end());
    f = CyclerFile{};  // free the file's columns
  }
  rec.note = fmt::format("{} layout, {} file(s), {} samples over {:.1f} h, {} cycles; current {}; {} logging gap(s) "
                         "({} under current, longest {:.0f} s) split the record into {} segments{}",
                         rec.layout, rec.files.size(), rec.t_s.size(), (rec.t_s.back() - rec.t_s.front()) / 3600.0,
                         last_cycle, fmt::join(signs, " / "), rec.gaps,
                         rec.gaps_under_current, rec.longest_gap_s, rec.segment_starts.size(),
                         in.skipped.empty() ? "" : fmt::format("; skipped {} other file(s)", in.skipped.size()));
  return rec;
}

MeasuredProfile to_measured_profile(const CyclerRecord& record) {
  MeasuredProfile p;
  p.t_s = record.t_s;
  p.current_a = record.current_a;
  p.voltage_v = record.voltage_v;
  p.temperature_k = record.temperature_k;
  p.source = record.files.size() == 1 ? record.files.front() : fmt::format("{} files", record.files.size());
  p.layout = record.layout;
  return p;
}

}  // namespace bms
