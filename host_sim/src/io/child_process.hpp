#pragma once
// The host tools' one way to run a child process, and their interrupt handling. Every child
// runs in a process group of its own; SIGINT, SIGTERM and SIGHUP to bmssim are forwarded to
// every running child's group and recorded, and long loops call throw_if_interrupted(), so an
// interrupted command stops its children, unwinds (removing its unfinished output) and exits
// 128 + the signal.
#include <sys/types.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace bms {

class Interrupted : public std::runtime_error {
 public:
  explicit Interrupted(int signal);
  int signal() const { return signal_; }

 private:
  int signal_;
};

void install_interrupt_handlers();
int interrupt_signal();  // 0 when no interrupt arrived
void throw_if_interrupted();

struct SpawnOptions {
  std::filesystem::path log;  // stdout and stderr appended here; empty: inherited
  bool search_path = false;   // look argv[0] up in PATH
  std::filesystem::path working_dir;  // the child's working folder; empty: inherited
  // The signal the kernel sends the child when bmssim dies, even by SIGKILL
  // (PR_SET_PDEATHSIG); 0: none. A child serving bmssim (the HIL's firmware) must not
  // outlive it.
  int parent_death_signal = 0;
  // When set, the child's stdout is a pipe and its read end is stored here (the caller
  // closes it), e.g. to wait for a "ready" line. Not together with `log`.
  int* stdout_pipe = nullptr;
};

// Starts argv (argv[0] = the program) in a process group of its own. RuntimeFailure when it
// cannot be started.
pid_t spawn_process(const std::vector<std::string>& argv, const SpawnOptions& options = {});
// Waits for one child (or any, pid = -1), retrying on EINTR; returns {pid, exit code} with
// 128 + N for a child killed by signal N.
std::pair<pid_t, int> wait_process(pid_t pid = -1);
// Runs argv to its end: spawn + wait. Returns the exit code.
int run_process(const std::vector<std::string>& argv, const SpawnOptions& options = {});

}  // namespace bms
