#pragma once
// The CLI tests' one fixture: the real linksight binary run as a user runs it, and the
// checks every refusal shares (exit code 2, one line on stderr, no output left).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "linksight/io/ply.hpp"
#include "test_support.hpp"

// Not in an anonymous namespace: every test file's TEST_F(Cli, ...) must see one class.
namespace linksight {
namespace fs = std::filesystem;

inline std::string slurp_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct CliRun {
  int code = -1;
  std::string out, err;
};

// `env`: assignments for the command's environment, e.g. "OCL_ICD_VENDORS=/x".
inline CliRun run(const std::string& args, const fs::path& dir, const std::string& env = "") {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = (env.empty() ? "" : "env " + env + " ") + std::string(LINKSIGHT_EXE) +
                          " " + args + " >" + out.string() + " 2>" + err.string();
  const int status = std::system(cmd.c_str());
  CliRun r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  auto slurp = [](const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  };
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

class Cli : public ::testing::Test {
 protected:
  fs::path dir = test::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::path out = dir / "result";

  // A bad input: exit code 2, exactly one line on stderr that names `names`, no output.
  void expect_bad_input(const std::string& args, const std::string& names,
                        const std::string& what) {
    const CliRun r = run("track " + args + " --out " + out.string(), dir);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(names), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out)) << "a failed run must leave no output, not even its directory";
  }

  // `command` (subcommand and arguments, without --out) is bad input: exit code 2, one
  // line on stderr naming `names`, and neither the output nor a staging directory left.
  void expect_refused(const std::string& command, const std::string& names) {
    const CliRun r = run(command + " --out " + out.string(), dir);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(names), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out)) << command;
    for (const auto& e : fs::directory_iterator(dir))
      EXPECT_EQ(e.path().filename().string().find("result.partial"), std::string::npos);
  }
  // An existing output directory is refused by `command` and kept as it was; with --force
  // it is replaced by one holding `written`.
  void expect_existing_out_needs_force(const std::string& command, const fs::path& written) {
    fs::create_directories(out);
    std::ofstream(out / "keep.txt") << "mine";
    const CliRun r = run(command + " --out " + out.string(), dir);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("output directory exists (use --force"), std::string::npos) << r.err;
    EXPECT_TRUE(fs::exists(out / "keep.txt"));
    const CliRun f = run(command + " --quiet --force --out " + out.string(), dir);
    EXPECT_EQ(f.code, 0) << f.err;
    EXPECT_FALSE(fs::exists(out / "keep.txt"));
    EXPECT_TRUE(fs::exists(out / written));
  }

  fs::path good_sequence(int frames) {
    const fs::path seq = dir / "seq";
    const CliRun r =
        run("synth --quiet --frames " + std::to_string(frames) + " --out " + seq.string(), dir);
    EXPECT_EQ(r.code, 0) << r.err;
    return seq;
  }

  fs::path write_ply(const std::string& name, const Cloud& c) {
    const fs::path p = dir / "in" / name;
    fs::create_directories(p.parent_path());
    io::write_ply(p, c);
    return p;
  }
};

}  // namespace linksight
