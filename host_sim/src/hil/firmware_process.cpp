#include "hil/firmware_process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <utility>

#include "io/input_error.hpp"

extern char** environ;

namespace bms::hil {

std::filesystem::path default_firmware_path() {
  if (const char* e = std::getenv("BMS_FIRMWARE")) return e;
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return self.parent_path().parent_path() / "hal" / "bms-firmware";
}

FirmwareProcess::FirmwareProcess(std::filesystem::path exe, std::vector<std::string> args)
    : exe_(std::move(exe)), args_(std::move(args)) {
  if (!std::filesystem::exists(exe_))
    throw InputError("firmware binary not found: " + exe_.string() + " (build it: ./bms build, or set BMS_FIRMWARE)");
  start();
}

FirmwareProcess::~FirmwareProcess() { stop(); }

// fork + exec rather than posix_spawn: the child must ask the kernel for SIGTERM when its
// parent dies (PR_SET_PDEATHSIG), so that a host killed without warning (SIGKILL, a crash)
// leaves no firmware behind; SIGTERM lets the firmware commit its state and exit.
void FirmwareProcess::start() {
  if (pid_ > 0) return;
  int fds[2];
  if (pipe(fds) != 0) throw RuntimeFailure("pipe failed");
  std::string exe_s = exe_.string();
  std::vector<std::string> copy = args_;
  std::vector<char*> argv;
  argv.push_back(exe_s.data());
  for (auto& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t parent = getpid();
  pid_ = fork();
  if (pid_ == 0) {
    // Only async-signal-safe calls between fork and exec.
    if (prctl(PR_SET_PDEATHSIG, SIGTERM) != 0 || getppid() != parent) _exit(127);
    dup2(fds[1], STDOUT_FILENO);
    close(fds[0]);
    close(fds[1]);
    execve(exe_s.c_str(), argv.data(), environ);
    _exit(127);
  }
  close(fds[1]);
  if (pid_ < 0) {
    close(fds[0]);
    pid_ = -1;
    throw RuntimeFailure("cannot start " + exe_s);
  }
  // A frame sent before the firmware's socket is bound would be lost: wait for "ready".
  std::string line;
  char c = 0;
  while (read(fds[0], &c, 1) == 1 && c != '\n') line += c;
  close(fds[0]);
  if (line.find("ready") == std::string::npos) {
    reap();
    throw RuntimeFailure("the firmware process exited before it was ready (see its message above)");
  }
  ++starts_;
}

int FirmwareProcess::reap() {
  int st = 0;
  while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
  exit_code_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
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
