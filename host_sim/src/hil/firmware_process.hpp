#pragma once
// The firmware process (bms-firmware) as the host sees it: started with its arguments,
// ready once it printed its "ready" line (its CAN socket is bound), stopped politely
// (SIGTERM: it commits its state and exits 0) or killed (SIGKILL: a power cut, for the
// restart test), and started again with the same arguments.
#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace bms::hil {

class FirmwareProcess {
 public:
  // Throws InputError when the binary does not exist, RuntimeFailure when it does not
  // become ready.
  FirmwareProcess(std::filesystem::path exe, std::vector<std::string> args);
  ~FirmwareProcess();
  FirmwareProcess(const FirmwareProcess&) = delete;
  FirmwareProcess& operator=(const FirmwareProcess&) = delete;

  // SIGTERM and wait; returns the exit code (128 + signal when killed by one).
  int stop();
  // SIGKILL and wait: no chance to commit anything.
  void kill_hard();
  void start();
  bool running() const { return pid_ > 0; }
  int starts() const { return starts_; }

 private:
  int reap();
  std::filesystem::path exe_;
  std::vector<std::string> args_;
  pid_t pid_ = -1;
  int exit_code_ = 0;
  int starts_ = 0;
};

std::filesystem::path default_firmware_path();

}  // namespace bms::hil
