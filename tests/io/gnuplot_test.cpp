// The one plotting runner (io/gnuplot) and the process runner's working folder.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "io/child_process.hpp"
#include "io/gnuplot.hpp"
#include "io/text_file.hpp"

namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / (name + "-" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// PATH set for one test and put back afterwards.
class PathOverride {
 public:
  explicit PathOverride(const std::string& path) {
    const char* old = std::getenv("PATH");
    had_ = old != nullptr;
    if (had_) old_ = old;
    setenv("PATH", path.c_str(), 1);
  }
  ~PathOverride() {
    if (had_) setenv("PATH", old_.c_str(), 1);
    else unsetenv("PATH");
  }
  PathOverride(const PathOverride&) = delete;
  PathOverride& operator=(const PathOverride&) = delete;

 private:
  bool had_ = false;
  std::string old_;
};

}  // namespace

TEST(ChildProcess, RunsInTheGivenWorkingFolder) {
  const fs::path dir = fresh_dir("bms-child-cwd");
  bms::SpawnOptions o;
  o.search_path = true;
  o.working_dir = dir;
  ASSERT_EQ(bms::run_process({"sh", "-c", "pwd > where.txt"}, o), 0);
  const std::string where = bms::read_text_file(dir / "where.txt");
  EXPECT_EQ(fs::canonical(where.substr(0, where.find('\n'))), fs::canonical(dir));
  fs::remove_all(dir);
}

TEST(Gnuplot, MissingProgramIsReportedAsMissing) {
  const fs::path dir = fresh_dir("bms-gnuplot-missing");
  PathOverride path(dir.string());  // a folder without gnuplot
  EXPECT_EQ(bms::run_gnuplot(dir / "none.gp"), bms::kGnuplotMissing);
  fs::remove_all(dir);
}

// A stand-in gnuplot (a shell script first in PATH) shows the argument, the working folder
// and the log the runner passes, and its exit code comes back unchanged.
TEST(Gnuplot, PassesScriptFolderAndLogAndReturnsTheExitCode) {
  const fs::path dir = fresh_dir("bms-gnuplot-fake");
  const fs::path bin = dir / "bin", work = dir / "work";
  fs::create_directories(bin);
  fs::create_directories(work);
  {
    std::ofstream f(bin / "gnuplot");
    f << "#!/bin/sh\necho \"script=$1 cwd=$(pwd)\"\nexit 3\n";
  }
  fs::permissions(bin / "gnuplot", fs::perms::owner_all);
  PathOverride path(bin.string() + ":/usr/bin:/bin");
  bms::GnuplotOptions o;
  o.working_dir = work;
  o.log = dir / "gnuplot.log";
  EXPECT_EQ(bms::run_gnuplot("plots.gp", o), 3);
  const std::string log = bms::read_text_file(dir / "gnuplot.log");
  EXPECT_NE(log.find("script=plots.gp"), std::string::npos) << log;
  EXPECT_NE(log.find("cwd=" + fs::canonical(work).string()), std::string::npos) << log;
  fs::remove_all(dir);
}
