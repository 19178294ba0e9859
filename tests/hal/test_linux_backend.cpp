// The Linux backend: SocketCAN (on a kernel without CAN: a clear error, no crash),
// file-backed NVM, timerfd ticks, CLOCK_MONOTONIC, stderr log sink, logging watchdog.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <net/if.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <csignal>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <string>

#include "bms/fw/can/can_protocol.hpp"
#include "bms/hal/fake/fake_log.hpp"
#include "bms/hal/fake/fake_time.hpp"
#include "bms/hal/linux/file_nvm.hpp"
#include "bms/hal/linux/linux_clock.hpp"
#include "bms/hal/linux/socketcan.hpp"
#include "bms/hal/linux/stderr_log.hpp"
#include "bms/hal/linux/timerfd_tick.hpp"

namespace hal = bms::hal;
namespace lnx = bms::hal::lnx;
namespace can = bms::fw::can;
using hal::Status;

namespace {

class TempDir {
 public:
  TempDir() {
    std::string tmpl = ::testing::TempDir() + "bms_hal_XXXXXX";
    path_ = ::mkdtemp(tmpl.data()) != nullptr ? tmpl : std::string();
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace

// ---------------------------------------------------------------- SocketCAN

TEST(SocketCan, OpeningVcan0FailsCleanlyWithoutKernelCan) {
  lnx::SocketCanBus bus;
  const Status s = bus.open("vcan0");
  if (s == Status::ok) GTEST_SKIP() << "this kernel has SocketCAN and vcan0: see SocketCan.Vcan0Loopback";
  if (s == Status::not_found) {
    EXPECT_NE(std::string(bus.last_error()).find("ip link add dev vcan0 type vcan"), std::string::npos);
    GTEST_SKIP() << "this kernel has SocketCAN but no vcan0: " << bus.last_error();
  }
  EXPECT_EQ(s, Status::unsupported) << bus.last_error();
  EXPECT_STREQ(bus.last_error(), "this kernel has no SocketCAN (EAFNOSUPPORT): use --bus uml or load vcan");
  EXPECT_FALSE(bus.is_open());
  // Everything else on the unopened bus reports not_open instead of crashing.
  hal::CanFrame f{};
  f.id = 0x110;
  f.len = 8;
  EXPECT_EQ(bus.send(f), Status::not_open);
  EXPECT_EQ(bus.receive(f, 0), Status::not_open);
  const hal::CanFilter filt = hal::can_filter_exact(0x110);
  EXPECT_EQ(bus.set_filters(&filt, 1), Status::not_open);
  EXPECT_EQ(bus.set_receive_own(true), Status::not_open);
}

TEST(SocketCan, RejectsBadInterfaceNames) {
  lnx::SocketCanBus bus;
  EXPECT_EQ(bus.open(""), Status::invalid_argument);
  const std::string too_long(IFNAMSIZ + 3, 'x');
  EXPECT_EQ(bus.open(too_long.c_str()), Status::invalid_argument);
  EXPECT_NE(std::string(bus.last_error()).find("too long"), std::string::npos);
  const Status s = bus.open("nosuchcan9");
  EXPECT_TRUE(s == Status::unsupported || s == Status::not_found) << hal::status_name(s) << ": " << bus.last_error();
}

// Runs where the kernel has vcan0 (a user's machine, or inside User-Mode Linux).
TEST(SocketCan, Vcan0Loopback) {
  lnx::SocketCanBus a, b;
  const Status s = a.open("vcan0");
  if (s != Status::ok) GTEST_SKIP() << "no vcan0 here: " << a.last_error();
  ASSERT_EQ(b.open("vcan0"), Status::ok) << b.last_error();
  const hal::CanFilter filt = hal::can_filter_exact(can::id::kMeasurement);
  ASSERT_EQ(b.set_filters(&filt, 1), Status::ok) << b.last_error();
  hal::CanFrame f{};
  EXPECT_EQ(b.receive(f, 0), Status::timeout);
  f.id = 0x123;  // filtered out at b
  f.len = 2;
  ASSERT_EQ(a.send(f), Status::ok) << a.last_error();
  can::Measurement m;
  m.seq = 9;
  m.voltage_v = 3.3;
  m.current_a = -2.5;
  can::encode(m, 4, f);
  ASSERT_EQ(a.send(f), Status::ok) << a.last_error();
  hal::CanFrame g{};
  ASSERT_EQ(b.receive(g, 1000), Status::ok) << b.last_error();
  EXPECT_EQ(g.id, can::id::kMeasurement);
  EXPECT_EQ(g.len, 8);
  EXPECT_EQ(std::memcmp(g.data, f.data, 8), 0);
  can::Receiver rx;
  can::RxMessage msg;
  EXPECT_EQ(rx.accept(g, msg), can::RxResult::accepted);
  EXPECT_EQ(msg.measurement.seq, 9);
  EXPECT_EQ(b.receive(g, 50), Status::timeout);
  // Own frames are not received unless asked for.
  EXPECT_EQ(a.receive(g, 20), Status::timeout);
  // Extended ids pass through.
  hal::CanFrame e{};
  e.id = 0x1ABCDEF0u | hal::kCanIdExtended;
  e.len = 1;
  e.data[0] = 0x5A;
  ASSERT_EQ(b.set_filters(nullptr, 0), Status::ok);
  lnx::SocketCanBus c;
  ASSERT_EQ(c.open("vcan0"), Status::ok);
  ASSERT_EQ(a.send(e), Status::ok);
  ASSERT_EQ(c.receive(g, 1000), Status::ok);
  EXPECT_EQ(g.id, e.id);
  EXPECT_EQ(g.data[0], 0x5A);
  EXPECT_EQ(b.receive(g, 20), Status::timeout) << "no filters: nothing delivered";
}

// ---------------------------------------------------------------- file NVM

TEST(FileNvm, CreatesErasedFilePersistsWritesAndRefusesOtherSizes) {
  TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  const std::string path = dir.path() + "/nvm.bin";
  {
    lnx::FileNvm nvm;
    ASSERT_EQ(nvm.open(path.c_str(), 4096, 1024), Status::ok) << nvm.last_error();
    struct stat st {};
    ASSERT_EQ(::stat(path.c_str(), &st), 0);
    EXPECT_EQ(st.st_size, 4096);
    std::uint8_t b[8];
    ASSERT_EQ(nvm.read(4088, b, 8), Status::ok);
    for (auto x : b) EXPECT_EQ(x, 0xFF);
    const char rec[] = "theta=1,-2.37e-10";
    ASSERT_EQ(nvm.write(1000, rec, sizeof rec), Status::ok) << nvm.last_error();
    EXPECT_EQ(nvm.write(4090, rec, sizeof rec), Status::out_of_range);
    EXPECT_EQ(nvm.erase(1, 1024), Status::invalid_argument);
  }
  {
    lnx::FileNvm nvm;
    ASSERT_EQ(nvm.open(path.c_str(), 4096, 1024), Status::ok) << nvm.last_error();
    char back[18];
    ASSERT_EQ(nvm.read(1000, back, sizeof back), Status::ok);
    EXPECT_STREQ(back, "theta=1,-2.37e-10");
    ASSERT_EQ(nvm.erase(0, 1024), Status::ok);
    ASSERT_EQ(nvm.read(1000, back, 18), Status::ok);
    EXPECT_EQ(static_cast<std::uint8_t>(back[0]), 0xFF);  // erased page 0 (bytes 0..1023)
    EXPECT_EQ(static_cast<std::uint8_t>(back[17]), 0xFF);
  }
  lnx::FileNvm nvm;
  EXPECT_EQ(nvm.open(path.c_str(), 8192, 1024), Status::invalid_argument);
  EXPECT_NE(std::string(nvm.last_error()).find("has 4096 bytes, expected 8192"), std::string::npos) << nvm.last_error();
  EXPECT_NE(std::string(nvm.last_error()).find(path), std::string::npos);
  EXPECT_EQ(nvm.open(path.c_str(), 1000, 512), Status::invalid_argument);
  EXPECT_EQ(nvm.open((dir.path() + "/no/such/dir/nvm.bin").c_str(), 1024, 512), Status::not_found);
  std::uint8_t x = 0;
  EXPECT_EQ(nvm.read(0, &x, 1), Status::not_open);
}

// A process killed while it creates the NVM file must not stop every later start
// (the file was filled in place, so a kill left a short file that open() then refused). The
// child creates a 4 MiB file over and over; it is SIGKILLed at 40 moments spread over the
// creation; after each kill the file is either absent or whole, and opening it works.
TEST(FileNvm, AProcessKilledWhileCreatingTheFileLeavesNoBrokenFile) {
  TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  const std::string path = dir.path() + "/nvm.bin";
  constexpr std::size_t kSize = 4u << 20;
  int partial_seen = 0, opened = 0;
  for (int k = 0; k < 40; ++k) {
    ::unlink(path.c_str());
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      for (;;) {
        lnx::FileNvm nvm;
        if (nvm.open(path.c_str(), kSize, 4096) != Status::ok) ::_exit(3);
        nvm.close();
        ::unlink(path.c_str());
      }
    }
    ::usleep(static_cast<useconds_t>(200 + 150 * k));
    ::kill(pid, SIGKILL);
    int st = 0;
    ::waitpid(pid, &st, 0);
    ASSERT_TRUE(WIFSIGNALED(st)) << "the child failed to create the file (exit " << WEXITSTATUS(st) << ")";
    struct stat sb {};
    if (::stat(path.c_str(), &sb) == 0 && static_cast<std::size_t>(sb.st_size) != kSize) ++partial_seen;
    lnx::FileNvm nvm;
    ASSERT_EQ(nvm.open(path.c_str(), kSize, 4096), Status::ok) << "after kill " << k << ": " << nvm.last_error();
    ++opened;
    std::uint8_t b[4];
    ASSERT_EQ(nvm.read(kSize - 4, b, 4), Status::ok);
    for (auto x : b) EXPECT_EQ(x, 0xFF);
  }
  EXPECT_EQ(partial_seen, 0);
  EXPECT_EQ(opened, 40);
}

// ---------------------------------------------------------------- time

TEST(LinuxClock, IsMonotonicAndInNanoseconds) {
  lnx::LinuxMonotonicClock clock;
  const std::uint64_t t0 = clock.now_ns();
  ::usleep(2000);
  const std::uint64_t t1 = clock.now_ns();
  EXPECT_GE(t1 - t0, 2'000'000u);
  EXPECT_LT(t1 - t0, 2'000'000'000u);
}

TEST(TimerfdTick, TicksAtThePeriod) {
  lnx::TimerfdTickSource ticks;
  std::uint32_t k = 0;
  EXPECT_EQ(ticks.wait_next_tick(k, 0), Status::not_open);
  lnx::LinuxMonotonicClock clock;
  const std::uint64_t t0 = clock.now_ns();
  ASSERT_EQ(ticks.open(5'000'000), Status::ok) << ticks.last_error();  // 5 ms
  EXPECT_EQ(ticks.period_ns(), 5'000'000u);
  std::uint32_t last = 0;
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(ticks.wait_next_tick(k, 1000), Status::ok) << ticks.last_error();
    if (i > 0) {
      EXPECT_GT(k, last);
    }
    last = k;
  }
  const std::uint64_t dt = clock.now_ns() - t0;
  EXPECT_GE(dt, 4 * 5'000'000u);
  EXPECT_EQ(last, 3u + ticks.missed_ticks());
  // Late caller: the skipped ticks are counted.
  ::usleep(30'000);
  ASSERT_EQ(ticks.wait_next_tick(k, 1000), Status::ok);
  EXPECT_GE(ticks.missed_ticks(), 4u);
  // Polling before the first tick is due.
  ASSERT_EQ(ticks.open(1'000'000'000), Status::ok);
  EXPECT_EQ(ticks.wait_next_tick(k, 0), Status::timeout);
  EXPECT_EQ(ticks.wait_next_tick(k, 5), Status::timeout);
  EXPECT_EQ(ticks.open(0), Status::invalid_argument);
}

// ---------------------------------------------------------------- log, watchdog

TEST(StderrLog, WritesOneLinePerMessageAboveTheLevel) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  hal::fake::ManualClock clock(12'345'678'000u);
  {
    lnx::StderrLogSink sink(hal::LogLevel::info, &clock, fds[1]);
    sink.write(hal::LogLevel::debug, "hidden");
    sink.write(hal::LogLevel::warning, "measurement stale");
    std::string big(500, 'x');
    sink.write(hal::LogLevel::error, big.c_str());
  }
  ::close(fds[1]);
  std::string out;
  char buf[512];
  ssize_t n = 0;
  while ((n = ::read(fds[0], buf, sizeof buf)) > 0) out.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  EXPECT_EQ(out.find("hidden"), std::string::npos);
  EXPECT_NE(out.find("[    12.345678] warning: measurement stale\n"), std::string::npos) << out;
  EXPECT_NE(out.find("error: xxx"), std::string::npos);
  EXPECT_EQ(out.back(), '\n');
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 2);
}

TEST(LoggingWatchdog, ReportsLateKicks) {
  hal::fake::ManualClock clock;
  hal::fake::RecordingLogSink log;
  lnx::LoggingWatchdog wd(clock, 300, &log);
  wd.kick();
  clock.advance_ns(200'000'000);
  wd.kick();
  EXPECT_EQ(wd.late_kicks(), 0u);
  clock.advance_ns(450'000'000);
  wd.kick();
  EXPECT_EQ(wd.late_kicks(), 1u);
  EXPECT_EQ(wd.kicks(), 3u);
  EXPECT_TRUE(log.contains("watchdog: kick came 450 ms after the previous one (timeout 300 ms)", hal::LogLevel::warning));
  lnx::LoggingWatchdog noop(clock, 0, &log);
  noop.kick();
  clock.advance_ns(10'000'000'000u);
  noop.kick();
  EXPECT_EQ(noop.late_kicks(), 0u);
}

// Batched sending (sendmmsg at flush) and batched receiving (one recvmmsg, handed out one
// by one) keep every frame and its order; more than one batch's worth goes out whole.
TEST(SocketCan, Vcan0BatchesKeepEveryFrameInOrder) {
  lnx::SocketCanBus a, b;
  const Status s = a.open("vcan0");
  if (s != Status::ok) GTEST_SKIP() << "no vcan0 here: " << a.last_error();
  ASSERT_EQ(b.open("vcan0"), Status::ok) << b.last_error();
  constexpr int kFrames = 37;  // more than two send and receive batches
  for (int i = 0; i < kFrames; ++i) {
    hal::CanFrame f{};
    f.id = 0x200u + static_cast<std::uint32_t>(i % 3);
    f.len = 8;
    f.data[1] = static_cast<std::uint8_t>(i);
    ASSERT_EQ(a.send_deferred(f), Status::ok) << a.last_error();
  }
  // Full batches went out as they filled; the last, partial one waits for flush().
  ASSERT_EQ(a.flush(), Status::ok) << a.last_error();
  hal::CanFrame g{};
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_EQ(b.receive(g, 1000), Status::ok) << "frame " << i << ": " << b.last_error();
    EXPECT_EQ(g.id, 0x200u + static_cast<std::uint32_t>(i % 3));
    EXPECT_EQ(g.data[1], i);
  }
  EXPECT_EQ(b.receive(g, 30), Status::timeout);
  EXPECT_EQ(b.receive(g, 0), Status::timeout);
}
