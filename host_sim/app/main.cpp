// bmssim: the host simulator and tools (contract: ../shared/contract.md).
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "commands.hpp"
#include "io/child_process.hpp"
#include "io/input_error.hpp"
#include "io/output_folder.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "bmssim - battery truth simulator (DFN + Ramadass SEI), RCSI estimator and studies.\n"
      "Currents are positive on discharge; SI units throughout. Exit codes: 0 ok, 1 runtime failure, "
      "2 bad input."};
  app.require_subcommand(1);
  std::vector<std::pair<CLI::App*, bms::app::Runner>> commands;
  auto add = [&](auto fn) {
    const auto before = app.get_subcommands({}).size();
    auto runner = fn(app);
    commands.emplace_back(app.get_subcommands({})[before], runner);
  };
  add(bms::app::add_simulate);
  add(bms::app::add_validate);
  add(bms::app::add_estimate);
  add(bms::app::add_hil);
  add(bms::app::add_study);
  add(bms::app::add_baseline);
  add(bms::app::add_diagnose);
  add(bms::app::add_cell_config);
  add(bms::app::add_fit);
  bms::install_interrupt_handlers();
  bms::adopt_output_folder_owner();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, as every other bad input: the message, then where the options are explained.
    std::string where = "bmssim --help";
    for (auto& [sub, run] : commands)
      if (sub->parsed()) where = "bmssim " + sub->get_name() + " --help";
    std::fprintf(stderr, "bmssim: %s (see '%s')\n", e.what(), where.c_str());
    return 2;
  }
  try {
    for (auto& [sub, run] : commands)
      if (sub->parsed()) return run();
  } catch (const bms::Interrupted& e) {
    std::fprintf(stderr, "bmssim: %s; unfinished output removed\n", e.what());
    return 128 + e.signal();
  } catch (const bms::InputError& e) {
    std::fprintf(stderr, "bmssim: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bmssim: failure: %s\n", e.what());
    return 1;
  }
  return 2;
}
