// The project's process runner: the fork path (stdout pipe, parent-death signal) that the
// HIL's firmware process uses, beside the posix_spawn path.
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <string>

#include "io/child_process.hpp"

namespace {

std::string read_all(int fd) {
  std::string out;
  char buf[256];
  ssize_t n = 0;
  while ((n = read(fd, buf, sizeof buf)) > 0) out.append(buf, static_cast<std::size_t>(n));
  close(fd);
  return out;
}

}  // namespace

TEST(ChildProcess, StdoutPipeCarriesTheChildsOutput) {
  int fd = -1;
  bms::SpawnOptions o;
  o.search_path = true;
  o.stdout_pipe = &fd;
  o.parent_death_signal = SIGTERM;
  const pid_t pid = bms::spawn_process({"sh", "-c", "echo ready; exit 3"}, o);
  ASSERT_GE(fd, 0);
  EXPECT_EQ(read_all(fd), "ready\n");
  const auto [got, code] = bms::wait_process(pid);
  EXPECT_EQ(got, pid);
  EXPECT_EQ(code, 3);
}

TEST(ChildProcess, ForkPathRunsInItsOwnProcessGroup) {
  int fd = -1;
  bms::SpawnOptions o;
  o.stdout_pipe = &fd;
  const pid_t pid = bms::spawn_process({"/bin/sh", "-c", "ps -o pgid= -p $$"}, o);
  const std::string pgid = read_all(fd);
  EXPECT_EQ(std::stol(pgid), static_cast<long>(pid));
  EXPECT_EQ(bms::wait_process(pid).second, 0);
}

TEST(ChildProcess, KilledChildReportsTheSignal) {
  int fd = -1;
  bms::SpawnOptions o;
  o.stdout_pipe = &fd;
  o.parent_death_signal = SIGTERM;
  const pid_t pid = bms::spawn_process({"/bin/sh", "-c", "echo up; exec sleep 30"}, o);
  char c = 0;
  ASSERT_EQ(read(fd, &c, 1), 1);
  close(fd);
  kill(pid, SIGKILL);
  EXPECT_EQ(bms::wait_process(pid).second, 128 + SIGKILL);
}

TEST(ChildProcess, MissingProgramExits127OnTheForkPath) {
  bms::SpawnOptions o;
  o.parent_death_signal = SIGTERM;
  const pid_t pid = bms::spawn_process({"/nonexistent/program"}, o);
  EXPECT_EQ(bms::wait_process(pid).second, 127);
}
