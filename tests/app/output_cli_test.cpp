// The output rule of every flag that writes a file (core/output_file.hpp, docs/hardening.md):
// rename over regular files only; write through to devices, FIFOs and standard output; follow a
// symbolic link to its target; refuse a directory (exit 2); a write error is an I/O error
// (exit 1); a signal during a write leaves no temporary file. Device nodes are made in the
// test's own folder (mknod, as root) so that a regression can never replace the real /dev/null.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "tests/app/cli_fixture.hpp"
#include "tests/common/process.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;

const std::string kExamples = std::string(NCD_SOURCE_DIR) + "/examples/";
const std::string kChamfer =
    "chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01 -q";

class OutputCli : public Cli {
 protected:
  // Every file in the test's folder whose name holds ".tmp" (a temporary left behind).
  std::vector<std::string> temporaries() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir_)) {
      if (e.path().filename().string().find(".tmp") != std::string::npos) {
        out.push_back(e.path().string());
      }
    }
    return out;
  }
  // A character device node in the test's folder (1,3 is null, 1,7 is full); false if the
  // test may not make one (not root).
  bool make_device(const std::string& name, unsigned minor) {
    return ::mknod((dir_ / name).c_str(), S_IFCHR | 0666, makedev(1, minor)) == 0;
  }
  static bool is_char_device(const fs::path& p) {
    struct stat st {};
    return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
  }
  // A shell line run as written (for redirections); status and standard error.
  CmdResult shell(const std::string& line) {
    const fs::path err = dir_ / "stderr";
    const int raw = std::system((line + " 2>" + err.string()).c_str());
    CmdResult r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.err = slurp(err);
    return r;
  }
  // A long polyline walked slowly: a replay that runs for seconds.
  std::string slow_path() {
    std::string pts;
    for (int i = 0; i <= 200; ++i) {
      pts += (i ? "," : "") + std::string("[") + std::to_string(i % 2 ? 10 : 0) + "," +
             std::to_string(i) + ",0]";
    }
    return write("slow.json", "{\"polyline\":{\"points\":[" + pts + "]},\"feed_mm_per_min\":20}");
  }
};

TEST_F(OutputCli, RegularFileIsReplacedWholeAndKeepsItsMode) {
  const std::string out = write("out.json", "old");
  ::chmod(out.c_str(), 0640);
  const CmdResult r = ncd(kChamfer + " -o " + out);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(nlohmann::json::accept(slurp(out)));
  struct stat st {};
  ASSERT_EQ(::stat(out.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0640u);
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(OutputCli, SymbolicLinkStaysALinkAndItsTargetIsReplaced) {
  const std::string target = write("target.json", "stale");
  fs::create_symlink("target.json", dir_ / "link.json");  // relative, as users make them
  fs::create_directories(dir_ / "sub");
  fs::create_symlink("../target.json", dir_ / "sub" / "up.json");
  fs::create_symlink("new.json", dir_ / "dangling.json");
  ASSERT_EQ(ncd(kChamfer + " -o " + (dir_ / "link.json").string()).status, 0);
  EXPECT_TRUE(fs::is_symlink(dir_ / "link.json"));
  const std::string fresh = slurp(target);
  EXPECT_NE(fresh, "stale");
  EXPECT_TRUE(nlohmann::json::accept(fresh));
  // A link in another folder, relative to its own folder.
  write("target.json", "stale again");
  ASSERT_EQ(ncd(kChamfer + " --format csv -o " + (dir_ / "sub" / "up.json").string()).status, 0);
  EXPECT_TRUE(fs::is_symlink(dir_ / "sub" / "up.json"));
  EXPECT_EQ(slurp(target).rfind("theta_rad,", 0), 0u);
  // A dangling link: its target is created, the link stays.
  ASSERT_EQ(ncd(kChamfer + " -o " + (dir_ / "dangling.json").string()).status, 0);
  EXPECT_TRUE(fs::is_symlink(dir_ / "dangling.json"));
  EXPECT_TRUE(fs::is_regular_file(dir_ / "new.json"));
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(OutputCli, DirectoryIsRefusedWithExit2ForEveryFlag) {
  fs::create_directories(dir_ / "d");
  const std::string d = (dir_ / "d").string();
  const std::string path = kExamples + "cubic.json";
  const std::string teach = "teach " + kExamples + "teach-burr.txt --frame-points " + kExamples +
                            "teach-burr-frame.txt --tool-diameter 10 --depth 0.2 --feed 300 "
                            "--spindle 2000";
  for (const std::string& cmd :
       {kChamfer + " -o " + d, kChamfer + " --plot " + d, "replay -q " + path + " --report " + d,
        "replay -q " + path + " --plot " + d, "replay -q " + path + " --setpoints " + d,
        "replay -q " + path + " --blocks " + d, teach + " -o " + d,
        std::string("robot --cylinder-radius 30 --hole-radius 15 -o ") + d}) {
    const CmdResult r = ncd(cmd);
    EXPECT_EQ(r.status, 2) << cmd << "\n" << r.err;
    EXPECT_NE(r.err.find("is a directory"), std::string::npos) << cmd << "\n" << r.err;
    EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
    EXPECT_TRUE(fs::is_directory(d));
    EXPECT_TRUE(fs::is_empty(d)) << cmd;
  }
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(OutputCli, CharacterDeviceIsWrittenThroughNeverReplaced) {
  if (!make_device("null", 3)) GTEST_SKIP() << "mknod needs root";
  const fs::path null = dir_ / "null";
  EXPECT_EQ(ncd(kChamfer + " -o " + null.string()).status, 0);
  EXPECT_TRUE(is_char_device(null));
  // Every replay flag at once, all into the device.
  const CmdResult r =
      ncd("replay -q " + kExamples + "cubic.json --setpoints " + null.string() + " --report " +
          null.string() + " --plot " + null.string() + " --blocks " + null.string());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(is_char_device(null));
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(OutputCli, FullDeviceIsAnIoErrorWithExit1AndStaysADevice) {
  if (!make_device("full", 7)) GTEST_SKIP() << "mknod needs root";
  const fs::path full = dir_ / "full";
  const CmdResult r = ncd(kChamfer + " -o " + full.string());
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find("I/O error"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
  EXPECT_TRUE(is_char_device(full));
  // Standard output on the full device: the same I/O error, not an internal error.
  const CmdResult s = shell(std::string(NCD_EXE) + " " + kChamfer + " > " + full.string());
  EXPECT_EQ(s.status, 1) << s.err;
  EXPECT_NE(s.err.find("I/O error"), std::string::npos) << s.err;
  EXPECT_EQ(s.err.find("internal error"), std::string::npos) << s.err;
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(OutputCli, FifoIsWrittenThroughToItsReader) {
  const fs::path fifo = dir_ / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string got;
  std::thread reader([&] {
    const int fd = ::open(fifo.c_str(), O_RDONLY);
    if (fd < 0) return;
    char buf[4096];
    for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) {
      got.append(buf, static_cast<std::size_t>(n));
    }
    ::close(fd);
  });
  const CmdResult r = ncd(kChamfer + " -o " + fifo.string());
  reader.join();
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(nlohmann::json::accept(got));
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(OutputCli, SignalDuringAWriteRemovesTheTemporary) {
  const std::string path = slow_path();
  for (const int sig : {SIGINT, SIGTERM}) {
    const fs::path setpoints = dir_ / "sp.csv";
    ncd::test::Process p({NCD_EXE, "replay", "-q", path, "--setpoints", setpoints.string(),
                          "--blocks", (dir_ / "b.ngc").string()},
                         (dir_ / "out").string(), (dir_ / "err").string());
    // Wait until the temporaries exist and have grown, then interrupt.
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    bool writing = false;
    while (!writing && std::chrono::steady_clock::now() < end && p.running()) {
      for (const std::string& t : temporaries()) {
        std::error_code ec;
        writing = writing || fs::file_size(t, ec) > (1u << 20);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ASSERT_TRUE(writing) << "the replay ended before it could be interrupted";
    p.signal(sig);
    const int status = p.wait(30.0);
    EXPECT_NE(status, 0) << sig;
    EXPECT_NE(status, -2) << "still running after the signal";
    EXPECT_TRUE(temporaries().empty()) << temporaries().front();
    EXPECT_FALSE(fs::exists(setpoints));
  }
}

}  // namespace
