#include "hil/firmware_process.hpp"

#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <utility>

#include "io/child_process.hpp"
#include "io/input_error.hpp"

namespace bms::hil {

std::filesystem::path default_firmware_path() {
  if (const char* e = std::getenv("BMS_FIRMWARE")) return e;
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return self.parent_path().parent_path() / "apps" / "bms-firmware";
}

FirmwareProcess::FirmwareProcess(std::filesystem::path exe, std::vector<std::string> args)
    : exe_(std::move(exe)), args_(std::move(args)) {
  if (!std::filesystem::exists(exe_))
    throw InputError("firmware binary not found: " + exe_.string() + " (build it: ./bms build, or set BMS_FIRMWARE)");
  start();
}

FirmwareProcess::~FirmwareProcess() { stop(); }

// The project's runner (io/child_process) with PR_SET_PDEATHSIG: a host killed without
// warning (SIGKILL, a crash) leaves no firmware behind; SIGTERM lets the firmware commit its
// state and exit.
void FirmwareProcess::start() {
  if (pid_ > 0) return;
  std::vector<std::string> argv = {exe_.string()};
  argv.insert(argv.end(), args_.begin(), args_.end());
  int ready_fd = -1;
  SpawnOptions o;
  o.parent_death_signal = SIGTERM;
  o.stdout_pipe = &ready_fd;
  pid_ = spawn_process(argv, o);
  // A frame sent before the firmware's socket is bound would be lost: wait for "ready".
  std::string line;
  char c = 0;
  while (read(ready_fd, &c, 1) == 1 && c != '\n') line += c;
  close(ready_fd);
  if (line.find("ready") == std::string::npos) {
    reap();
    throw RuntimeFailure("the firmware process exited before it was ready (see its message above)");
  }
  ++starts_;
}

int FirmwareProcess::reap() {
  exit_code_ = wait_process(pid_).second;
  pid_ = -1;
  return exit_code_;
}

int FirmwareProcess::stop() {
  if (pid_ <= 0) return exit_code_;
  kill(pid_, SIGTERM);
  return reap();
}

void FirmwareProcess::kill_hard() {
  if (pid_ <= 0) return;
  kill(pid_, SIGKILL);
  reap();
  exit_code_ = 0;  // an intended kill is not the firmware's failure
}

}  // namespace bms::hil
