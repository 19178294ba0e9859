#include "io/bpx_writer.hpp"

#include <fmt/format.h>

#include <cstdlib>

#include "io/atomic_file.hpp"
#include "io/bpx_reader.hpp"
#include "io/input_error.hpp"

namespace bms {

nlohmann::json& bpx_field(nlohmann::json& bpx, const char* section, const char* key) {
  auto& p = bpx.at("Parameterisation");
  if (!p.contains(section)) p[section] = nlohmann::json::object();
  return p[section][key];
}

void scale_bpx_value(nlohmann::json& v, double f, const std::string& where) {
  if (v.is_number()) {
    v = v.get<double>() * f;
  } else if (v.is_string()) {
    v = fmt::format("{:.12g} * ({})", f, v.get<std::string>());
  } else if (v.is_object() && v.contains("y") && v["y"].is_array()) {
    for (auto& y : v["y"]) y = y.get<double>() * f;
  } else {
    throw InputError("template: field '" + where + "' is neither a number, an expression nor a table");
  }
}

double bpx_number(const nlohmann::json& v, const std::string& where) {
  if (v.is_number()) return v.get<double>();
  if (v.is_string()) {
    char* end = nullptr;
    const std::string s = v.get<std::string>();
    const double d = std::strtod(s.c_str(), &end);
    if (!s.empty() && *end == '\0') return d;
  }
  throw InputError("template: field '" + where + "' must be a number");
}

void write_bpx_cell(const std::filesystem::path& file, nlohmann::json cell, const std::string& title,
                    const std::string& description) {
  cell["Header"]["Title"] = title;
  cell["Header"]["Description"] = description;
  const std::string text = cell.dump(1) + "\n";
  try {
    (void)read_bpx_text(text, file.string());
  } catch (const InputError& e) {
    throw RuntimeFailure(fmt::format("the cell to write is not one the BPX reader accepts ({}); nothing written",
                                     e.what()));
  }
  AtomicFileWriter w(file);
  w.append(text);
  w.commit();
}

}  // namespace bms
