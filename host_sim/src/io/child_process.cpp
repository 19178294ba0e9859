#include "io/child_process.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>

#include "io/input_error.hpp"

extern char** environ;

namespace bms {

namespace {

// Lock-free slots the signal handler can read: the running children's process groups.
constexpr int kMaxChildren = 64;
std::atomic<pid_t> g_children[kMaxChildren];
volatile std::sig_atomic_t g_signal = 0;

void on_interrupt(int sig) {
  g_signal = sig;
  for (auto& c : g_children) {
    const pid_t pid = c.load();
    if (pid > 0) kill(-pid, sig);
  }
}

void remember(pid_t pid) {
  for (auto& c : g_children) {
    pid_t empty = 0;
    if (c.compare_exchange_strong(empty, pid)) return;
  }
}

void forget(pid_t pid) {
  for (auto& c : g_children) {
    pid_t p = pid;
    if (c.compare_exchange_strong(p, 0)) return;
  }
}

int exit_code(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 1;
}

}  // namespace

Interrupted::Interrupted(int signal)
    : std::runtime_error(std::string("interrupted by signal ") + std::to_string(signal) + " (" + strsignal(signal) +
                         ")"),
      signal_(signal) {}

void install_interrupt_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: a blocking wait returns EINTR and sees the flag
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &sa, nullptr);
}

int interrupt_signal() { return g_signal; }

void throw_if_interrupted() {
  if (g_signal != 0) throw Interrupted(g_signal);
}

namespace {

// fork + exec for what posix_spawn cannot ask: PR_SET_PDEATHSIG, set in the child before exec.
pid_t fork_exec(std::vector<char*>& argv, const SpawnOptions& options, int log_fd) {
  int fds[2] = {-1, -1};
  if (options.stdout_pipe != nullptr && pipe(fds) != 0)
    throw RuntimeFailure(std::string("pipe: ") + std::strerror(errno));
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec.
    setpgid(0, 0);
    if (options.parent_death_signal != 0 &&
        (prctl(PR_SET_PDEATHSIG, options.parent_death_signal) != 0 || getppid() != parent))
      _exit(127);
    if (fds[1] >= 0) dup2(fds[1], STDOUT_FILENO);
    if (!options.working_dir.empty() && chdir(options.working_dir.c_str()) != 0) _exit(127);
    if (log_fd >= 0) {
      dup2(log_fd, STDOUT_FILENO);
      dup2(log_fd, STDERR_FILENO);
    }
    if (options.search_path)
      execvp(argv[0], argv.data());
    else
      execve(argv[0], argv.data(), environ);
    _exit(127);
  }
  const int err = errno;
  if (pid > 0) setpgid(pid, pid);  // as the child does: whichever runs first, the group exists
  if (fds[1] >= 0) close(fds[1]);
  if (pid < 0) {
    if (fds[0] >= 0) close(fds[0]);
    throw RuntimeFailure(std::string("cannot start ") + argv[0] + ": " + std::strerror(err));
  }
  if (options.stdout_pipe != nullptr) *options.stdout_pipe = fds[0];
  return pid;
}

pid_t fork_exec_logged(std::vector<char*>& argv, const SpawnOptions& options) {
  int log_fd = -1;
  if (!options.log.empty()) {
    log_fd = open(options.log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (log_fd < 0) throw RuntimeFailure("cannot open " + options.log.string() + ": " + std::strerror(errno));
  }
  try {
    const pid_t pid = fork_exec(argv, options, log_fd);
    if (log_fd >= 0) close(log_fd);
    return pid;
  } catch (...) {
    if (log_fd >= 0) close(log_fd);
    throw;
  }
}

}  // namespace

pid_t spawn_process(const std::vector<std::string>& args, const SpawnOptions& options) {
  if (args.empty()) throw RuntimeFailure("spawn_process: no program");
  if (options.parent_death_signal != 0 || options.stdout_pipe != nullptr) {
    std::vector<std::string> argv_s(args);
    std::vector<char*> argv;
    for (auto& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t pid = fork_exec_logged(argv, options);
    remember(pid);
    if (g_signal != 0) kill(-pid, g_signal);
    return pid;
  }
  std::vector<std::string> argv_s(args);
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  if (!options.log.empty()) {
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, options.log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&fa, STDOUT_FILENO, STDERR_FILENO);
  }
  if (!options.working_dir.empty()) posix_spawn_file_actions_addchdir_np(&fa, options.working_dir.c_str());
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attr, 0);
  pid_t pid = 0;
  const int rc = options.search_path ? posix_spawnp(&pid, argv[0], &fa, &attr, argv.data(), environ)
                                     : posix_spawn(&pid, argv[0], &fa, &attr, argv.data(), environ);
  posix_spawnattr_destroy(&attr);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw RuntimeFailure("cannot start " + args[0] + ": " + std::strerror(rc));
  remember(pid);
  // A signal that arrived between the spawn and remember() did not reach the child.
  if (g_signal != 0) kill(-pid, g_signal);
  return pid;
}

std::pair<pid_t, int> wait_process(pid_t pid) {
  int status = 0;
  pid_t got;
  while ((got = waitpid(pid, &status, 0)) < 0) {
    if (errno != EINTR) throw RuntimeFailure(std::string("waitpid: ") + std::strerror(errno));
  }
  forget(got);
  return {got, exit_code(status)};
}

int run_process(const std::vector<std::string>& argv, const SpawnOptions& options) {
  return wait_process(spawn_process(argv, options)).second;
}

}  // namespace bms
