// Every program we have, walked by the real executable: tests/ngc/*.ngc and LinuxCNC's sample
// programs (/usr/share/linuxcnc/ncfiles, from the linuxcnc-uspace package that
// scripts/install-judges.sh installs; without it they are not listed, and the summary test says
// so). Each is replayed whole and --path-only on a fast machine (F15000, 3000 mm/s², 60 000
// mm/s³: the limits under which flowsnake.ngc's landing once wrote past the planner's buffers),
// with a tool table (T1–T20: the diameters of LinuxCNC's sim table, lengths of 19–100 mm), a
// parameter file (G28/G30 homes) and the program's folder on the subroutine path. A run is either
// accepted (exit 0: walked to its end with 0 limit violations) or refused with a message naming the
// program (exit 2). Never a crash, a sanitizer report (the debug tree's ncd is built with ASan and
// UBSan and aborts on one), an internal error (exit 1) or a limit violation (exit 3). In the
// Release suite the same program replayed twice gives the same setpoints, byte for byte.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_fixture.hpp"
#include "tests/common/sanitized.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path kSamples = "/usr/share/linuxcnc/ncfiles";

std::vector<fs::path> programs() {
  std::vector<fs::path> out;
  for (const fs::path& dir : {fs::path(NCD_SOURCE_DIR) / "tests" / "ngc", kSamples}) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      if (e.path().extension() == ".ngc") out.push_back(e.path());
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

using ncd::test::slurp;

constexpr const char* kToolTable =
    "T1 P1 Z75.5 D0.25\nT2 P2 Z-0.25 D0.5\nT3 P3 Z28.575 D0.125\nT4 P4 Z19.05 D0.375\n"
    "T5 P5 Z50 D0.1\nT7 P7 Z60 D0.2\nT10 P10 Z100 D0.3\nT20 P20 Z50.8 D1\n";
constexpr const char* kVarFile = "5161 1.0\n5162 2.0\n5163 30.0\n5181 -1.0\n5182 -2.0\n5183 25.0\n";

struct WalkReplay {
  int status = -1;  // exit status; -1 on a signal
  std::string err;
  std::string setpoints;
};

class WalkProgram : public ::testing::TestWithParam<fs::path> {
 protected:
  void SetUp() override {
    const std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    dir_ = fs::temp_directory_path() / ("ncd_walk_" + std::to_string(getpid()) + "_" +
                                        std::to_string(std::hash<std::string>{}(name)));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "tool.tbl") << kToolTable;
    std::ofstream(dir_ / "homes.var") << kVarFile;
    std::ofstream(dir_ / "machine.toml")
        << "max_feed_mm_per_min = 15000\nmax_accel_mm_per_s2 = 3000\n"
           "max_jerk_mm_per_s3 = 60000\n[program]\ntool_table = \""
        << (dir_ / "tool.tbl").string() << "\"\nparameter_file = \""
        << (dir_ / "homes.var").string() << "\"\nsubroutine_path = [\""
        << GetParam().parent_path().string() << "\"]\n";
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  WalkReplay replay(const std::string& mode, int k) {
    const fs::path sp = dir_ / ("sp_" + mode + std::to_string(k) + ".csv");
    const fs::path err = dir_ / "stderr";
    const std::string cmd = "cd '" + dir_.string() + "' && " + std::string(NCD_EXE) + " replay '" +
                            GetParam().string() + "' --machine machine.toml -q" +
                            (mode == "path" ? " --path-only" : "") + " --setpoints '" +
                            sp.string() + "' 2>'" + err.string() + "' >/dev/null";
    const int raw = std::system(cmd.c_str());
    WalkReplay r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.err = slurp(err);
    if (r.status == 0) r.setpoints = slurp(sp);
    return r;
  }

  fs::path dir_;
};

TEST_P(WalkProgram, IsWalkedOrRefusedWithAMessageNeverCrashes) {
  const std::string file = GetParam().filename().string();
  for (const std::string mode : {"whole", "path"}) {
    const WalkReplay a = replay(mode, 0);
    ASSERT_TRUE(a.status == 0 || a.status == 2)
        << file << " (" << mode << "): exit " << a.status << "\n"
        << a.err;
    if (a.status == 2) {
      EXPECT_TRUE(a.err.find(file) != std::string::npos || a.err.find(".ngc:") != std::string::npos)
          << file << " (" << mode << "): the refusal names no program file:\n"
          << a.err;
      EXPECT_EQ(a.err.find("internal"), std::string::npos) << a.err;
      continue;
    }
    if (a.setpoints.empty()) {
      // A program that moves nothing (a subroutine library, a parameter demo) replays as "no
      // motion", exit 0, and says so without -q.
      const fs::path err = dir_ / "stderr_loud";
      const std::string cmd = "cd '" + dir_.string() + "' && " + std::string(NCD_EXE) +
                              " replay '" + GetParam().string() + "' --machine machine.toml 2>'" +
                              err.string() + "' >/dev/null";
      EXPECT_EQ(std::system(cmd.c_str()), 0) << file;
      EXPECT_NE(slurp(err).find("replay: no motion: "), std::string::npos)
          << file << " (" << mode << "): exit 0 without setpoints and without 'no motion':\n"
          << slurp(err);
      continue;
    }
    if (ncd::test::kSanitized) continue;  // determinism is the Release suite's check
    const WalkReplay b = replay(mode, 1);
    ASSERT_EQ(b.status, 0) << file << " (" << mode << "), second run:\n" << b.err;
    EXPECT_TRUE(a.setpoints == b.setpoints)
        << file << " (" << mode << "): two replays gave different setpoints";
  }
}

std::string test_name(const ::testing::TestParamInfo<fs::path>& info) {
  std::string n =
      (info.param.parent_path() == kSamples ? "linuxcnc_" : "ngc_") + info.param.stem().string();
  for (char& c : n) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return n;
}

INSTANTIATE_TEST_SUITE_P(EveryProgram, WalkProgram, ::testing::ValuesIn(programs()), test_name);

// The samples are part of the suite only where LinuxCNC's package is installed: say so.
TEST(WalkPrograms, LinuxCncSamplesAreListed) {
  std::size_t samples = 0;
  for (const fs::path& p : programs()) samples += p.parent_path() == kSamples ? 1 : 0;
  if (samples == 0) {
    GTEST_SKIP() << kSamples << " has no programs: install linuxcnc-uspace "
                 << "(scripts/install-judges.sh) to walk LinuxCNC's samples too";
  }
  EXPECT_GE(samples, 50u);
}

}  // namespace
