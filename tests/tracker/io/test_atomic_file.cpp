// atomic_file.hpp: outputs appear whole or not at all, and what killed runs leave is
// cleaned by the next run into the same directory (issue 19, part 3).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <string>

#include "linksight/io/atomic_file.hpp"
#include "linksight/io/error.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {
namespace fs = std::filesystem;

// A process id that has just ended (a child, reaped).
pid_t dead_pid() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  return child;
}

TEST(StagedDir, RefusesAFileAsTheOutputDirectoryEvenWithForce) {
  const fs::path dir = test::scratch_dir("StagedDir.RefusesAFile");
  const fs::path out = dir / "out";
  std::ofstream(out) << "a file, not a directory\n";
  for (const bool force : {false, true}) {
    const std::string e = test::error_of([&] { StagedDir staged(out, force); });
    EXPECT_NE(e.find(out.string() + ": exists and is not a directory"), std::string::npos) << e;
    ASSERT_TRUE(fs::is_regular_file(out)) << "--force never deletes a file";
  }
}

TEST(StagedDir, AppearsWholeOrNotAtAll) {
  const fs::path dir = test::scratch_dir("StagedDir.AppearsWhole");
  const fs::path out = dir / "out";
  {
    StagedDir staged(out, false);
    std::ofstream(staged.path() / "a.txt") << "a\n";
    EXPECT_FALSE(fs::exists(out));
  }  // not committed: nothing
  EXPECT_FALSE(fs::exists(out));
  EXPECT_TRUE(fs::is_empty(dir)) << "the staging directory is gone too";
  {
    StagedDir staged(out, false);
    std::ofstream(staged.path() / "a.txt") << "a\n";
    staged.commit();
  }
  EXPECT_TRUE(fs::exists(out / "a.txt"));
  EXPECT_NE(test::error_of([&] { StagedDir staged(out, false); }).find("output directory exists"),
            std::string::npos);
  {
    StagedDir staged(out, true);
    std::ofstream(staged.path() / "b.txt") << "b\n";
    staged.commit();
  }
  EXPECT_FALSE(fs::exists(out / "a.txt")) << "replaced whole";
  EXPECT_TRUE(fs::exists(out / "b.txt"));
}

TEST(StagedDir, CleansWhatKilledRunsLeftAndRefusesWhileAnotherRunWrites) {
  const fs::path dir = test::scratch_dir("StagedDir.CleansWhatKilledRunsLeft");
  const std::string dead = std::to_string(dead_pid());
  const std::string live = std::to_string(::getppid());
  for (const std::string& name : {"out.partial-" + dead, "out.old-" + dead, "out.old-" + live,
                                  "other.partial-" + dead, "out.partial-x" + dead}) {
    fs::create_directories(dir / name);
    std::ofstream(dir / name / "frame_0000.ply") << "torn";
  }
  {
    StagedDir staged(dir / "out", false);
    EXPECT_FALSE(fs::exists(dir / ("out.partial-" + dead))) << "a killed run's staging";
    EXPECT_FALSE(fs::exists(dir / ("out.old-" + dead))) << "a killed run's replaced output";
    EXPECT_TRUE(fs::exists(dir / ("out.old-" + live))) << "a live run's own";
    EXPECT_TRUE(fs::exists(dir / ("other.partial-" + dead))) << "another output's";
    EXPECT_TRUE(fs::exists(dir / ("out.partial-x" + dead))) << "not a staging name";
  }
  // A live process staging the same DIR: refused, naming it; its staging untouched.
  fs::create_directories(dir / ("out.partial-" + live));
  const std::string e = test::error_of([&] { StagedDir staged(dir / "out", true); });
  EXPECT_NE(e.find("another process (pid " + live + ") is writing this output directory now"),
            std::string::npos)
      << e;
  EXPECT_TRUE(fs::exists(dir / ("out.partial-" + live)));
}

// Two runs that start at once into the same DIR: the one that finishes second does not
// replace the first's output without --force.
TEST(StagedDir, ADirThatAppearsWhileWritingIsNotReplacedWithoutForce) {
  const fs::path dir = test::scratch_dir("StagedDir.ADirThatAppears");
  for (const bool force : {false, true}) {
    fs::remove_all(dir / "out");
    StagedDir mine(dir / "out", force);
    std::ofstream(mine.path() / "mine.txt") << "mine\n";
    // The other run commits first.
    fs::create_directories(dir / "out");
    std::ofstream(dir / "out" / "theirs.txt") << "theirs\n";
    if (force) {
      mine.commit();
      EXPECT_TRUE(fs::exists(dir / "out" / "mine.txt")) << "--force replaces it whole";
      EXPECT_FALSE(fs::exists(dir / "out" / "theirs.txt"));
    } else {
      const std::string e = test::error_of([&] { mine.commit(); });
      EXPECT_NE(e.find("written by another process while this run was writing it"),
                std::string::npos)
          << e;
      EXPECT_TRUE(fs::exists(dir / "out" / "theirs.txt")) << "theirs kept";
      EXPECT_FALSE(fs::exists(dir / "out" / "mine.txt"));
    }
  }
}

}  // namespace
}  // namespace linksight::io
