// Issue 59, through the real binary: what a hostile file, recording or second process
// gives linksight is refused in one printable line, without a crash, unbounded memory or a
// hang, and loses nothing.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <string>

#include "cli_fixture.hpp"
#include "linksight/io/echo.hpp"

namespace linksight {
namespace {

// A refusal's stderr is one printable line: no escape, carriage return or other control
// byte reaches the terminal, whatever the input held.
void expect_one_printable_line(const CliRun& r) {
  EXPECT_EQ(r.code, 2) << r.err;
  ASSERT_FALSE(r.err.empty());
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
  EXPECT_TRUE(io::is_printable_line(r.err.substr(0, r.err.size() - 1))) << r.err;
}

TEST_F(Cli, ControlBytesInAKeyNeverReachTheTerminal) {
  // A newline (two lines), an escape that clears the screen and a carriage return that
  // would overwrite the message with the attacker's "linksight: all good".
  std::ofstream(dir / "scene.yaml") << "\"a\\nb\\e[2J\\rlinksight: all good\": 1\n";
  const CliRun r = run("run " + (dir / "scene.yaml").string() + " --out " + out.string(), dir);
  expect_one_printable_line(r);
  EXPECT_NE(r.err.find("scene.yaml:1: a\\nb\\x1B[2J\\rlinksight: all good: unknown key"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(out));
}

// score reads a recording and estimates from outside: JSON nested 100,000 deep (which
// crashed linksight when its error echoed the value), an estimate that is a folder, a
// device that never ends or a FIFO that never opens are each refused by name at once.
TEST_F(Cli, ScoreRefusesDeepJsonAndWhatIsNotAFile) {
  const std::string scene = std::string(LINKSIGHT_SCENE_DIR) + "/static.yaml";
  const fs::path rec = dir / "rec";
  ASSERT_EQ(run("render --quiet --scene " + scene + " --frames 2 --out " + rec.string(), dir).code,
            0);
  const std::string args = "score --no-figures --truth " + rec.string() + " --estimate x=";
  const std::string truth = (rec / "truth.csv").string();
  ASSERT_EQ(run(args + truth + " --quiet --out " + (dir / "ok").string(), dir).code, 0);

  const CliRun folder = run(args + dir.string() + " --out " + out.string(), dir);
  expect_one_printable_line(folder);
  EXPECT_NE(folder.err.find(dir.string() + ": a folder, not a CSV file"), std::string::npos)
      << folder.err;
  const CliRun zero = run(args + "/dev/zero --out " + out.string(), dir);
  expect_one_printable_line(zero);
  EXPECT_NE(zero.err.find("/dev/zero: not a regular file"), std::string::npos) << zero.err;
  ASSERT_EQ(::mkfifo((dir / "fifo.csv").c_str(), 0600), 0);
  const CliRun fifo = run(args + (dir / "fifo.csv").string() + " --out " + out.string(), dir);
  expect_one_printable_line(fifo);
  EXPECT_NE(fifo.err.find("fifo.csv: not a regular file"), std::string::npos) << fifo.err;

  const std::string deep = std::string(100000, '[') + std::string(100000, ']');
  const std::string chain = slurp_text(rec / "chain.json");
  std::string bad = chain;
  bad.replace(bad.find("\"count\": 11"), 11, "\"count\": " + deep);
  std::ofstream(rec / "chain.json") << bad;
  const CliRun c = run(args + truth + " --out " + out.string(), dir);
  expect_one_printable_line(c);
  EXPECT_NE(c.err.find("chain.json: JSON nested deeper than 64 levels"), std::string::npos)
      << c.err;
  std::ofstream(rec / "chain.json") << chain;
  const std::string camera = slurp_text(rec / "camera.json");
  std::ofstream(rec / "camera.json") << "{\"fps\": " << deep << "}";
  const CliRun f = run(args + truth + " --out " + out.string(), dir);
  expect_one_printable_line(f);
  EXPECT_NE(f.err.find("camera.json: JSON nested deeper than 64 levels (byte 71)"),
            std::string::npos)
      << f.err;
  // Shallow but not a number: summarized, not dumped.
  std::ofstream(rec / "camera.json") << "{\"fps\": [1, 2, 3, 4, 5]}";
  const CliRun g = run(args + truth + " --out " + out.string(), dir);
  expect_one_printable_line(g);
  EXPECT_NE(g.err.find("camera.json: fps = an array of 5 [1, 2, 3, ...]: must be in (0, 10000]"),
            std::string::npos)
      << g.err;
  std::ofstream(rec / "camera.json") << camera;
  EXPECT_FALSE(fs::exists(out));
}

// Two runs of the same shard at once would remove each other's cell records ("record is
// missing or torn") and leave a .cells/ folder behind: the second is refused, naming the
// process that holds the shard, and the shard runs whole once that one lets go.
TEST_F(Cli, OneShardRunsInOneProcessAtATime) {
  const std::string args = "sweep --scene " + std::string(LINKSIGHT_SCENE_DIR) +
                           "/static.yaml --axis noise.scale=0,1 --frames 1 --compare paper "
                           "--no-figures --quiet --shard 0/2 --out " +
                           out.string();
  fs::create_directories(out);
  const int fd = ::open((out / "shard_0_of_2.lock").c_str(), O_RDWR | O_CREAT, 0644);
  ASSERT_GE(fd, 0);
  struct flock lock {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  ASSERT_EQ(::fcntl(fd, F_SETLK, &lock), 0);
  const CliRun held = run(args, dir);
  expect_one_printable_line(held);
  EXPECT_NE(held.err.find("shard_0_of_2.lock: shard 0/2 is being run by another process (pid " +
                          std::to_string(::getpid()) + "); wait for it, or run another shard"),
            std::string::npos)
      << held.err;
  EXPECT_FALSE(fs::exists(out / "shard_0_of_2.cells"));
  // Another shard of the same sweep runs beside it.
  const CliRun other =
      run(args.substr(0, args.find("--shard")) + "--shard 1/2 --out " + out.string(), dir);
  EXPECT_EQ(other.code, 0) << other.err;
  ::close(fd);  // the kernel releases the lock, as it does when a process ends
  const CliRun now = run(args, dir);
  EXPECT_EQ(now.code, 0) << now.err;
  EXPECT_TRUE(fs::exists(out / "shard_0_of_2.csv"));
  EXPECT_FALSE(fs::exists(out / "shard_0_of_2.cells"));
  const CliRun m = run("sweep merge --no-figures " + out.string(), dir);
  EXPECT_EQ(m.code, 0) << m.err;
}

}  // namespace
}  // namespace linksight
