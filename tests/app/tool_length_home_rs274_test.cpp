// Safe at the machine (docs/whole-program.md, "Tool length" and "Moves the blocks add";
// docs/ngc-interpreter.md, "G28 and G30"), judged by LinuxCNC's own interpreter `rs274 -g`:
//   - every program ncd writes for a controller with a tool table (the chamfer program, the
//     teach program, the blocks of `ncd replay --blocks`, also of an NGC program with two tool
//     changes) takes the tool's length (rs274's USE_TOOL_LENGTH_OFFSET, here 75.5 mm) before its
//     first move; a rewritten program whose tool change has no offset is refused;
//   - G28/G30 with no stored position known are refused naming file:line; with a parameter file
//     the blocks go where rs274 goes for the program;
//   - the motion of the blocks is the program's own, move by move (rs274 on both), apart from
//     the moves the blocks' header lists.
// Without /usr/bin/rs274 (linuxcnc-uspace) the suite is skipped.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_fixture.hpp"
#include "tests/common/rs274.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;

const std::string kTlhMachine = std::string(NCD_SOURCE_DIR) + "/config/chamfer-exp3.toml";
const std::string kGeometry =
    "--pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01";
constexpr double kLength1Mm = 75.5, kLength2Mm = 42.25;  // tools 1 (and 4) and 2
// Written and printed with 4 (rs274) or 3 (blocks) decimals, plus the encoder's chord
// tolerance for a blocks' feed point against the program's path.
constexpr double kPrintMm = 1e-3;
constexpr double kChordMm = 0.002;
// Under a plain G64 ncd rounds a corner by at most the machine's blend tolerance (0.01 mm, the
// default of config/machine.example.toml; LinuxCNC's plain G64 has no bound at all).
constexpr double kBlendMm = 0.01;
constexpr double kFeedTolMm = kBlendMm + kChordMm + kPrintMm;

struct P3 {
  double x = 0, y = 0, z = 0;
};
double dist(const P3& a, const P3& b) {
  return std::hypot(a.x - b.x, a.y - b.y, a.z - b.z);
}
double dist_to_segment(const P3& p, const P3& a, const P3& b) {
  const P3 ab{b.x - a.x, b.y - a.y, b.z - a.z};
  const double l2 = ab.x * ab.x + ab.y * ab.y + ab.z * ab.z;
  double t = l2 > 0 ? ((p.x - a.x) * ab.x + (p.y - a.y) * ab.y + (p.z - a.z) * ab.z) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return dist(p, {a.x + t * ab.x, a.y + t * ab.y, a.z + t * ab.z});
}
double dist_to_polyline(const P3& p, const std::vector<P3>& line) {
  double d = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k + 1 < line.size(); ++k) {
    d = std::min(d, dist_to_segment(p, line[k], line[k + 1]));
  }
  return line.size() == 1 ? dist(p, line[0]) : d;
}

// rs274's canonical output in order: moves (their end points), tool length offsets (Z), tool
// changes; moves of no length (rs274 prints a G28's intermediate point where the tool stands)
// are left out.
struct Item {
  char kind = 'T';  // T traverse, F feed, L length offset, C tool change
  P3 p;             // T, F: the end; L: the offset
};
struct Canonical {
  int status = -1;
  std::string out, log;
  std::vector<Item> items;
  bool program_end = false;
};

std::vector<Item> items_of(const std::string& out) {
  std::vector<Item> items;
  std::istringstream in(out);
  std::string line;
  P3 at;  // rs274 starts at the origin
  while (std::getline(in, line)) {
    const auto open = line.find('(');
    if (open == std::string::npos) continue;
    const char* args = line.c_str() + open + 1;
    Item it;
    if (line.find("STRAIGHT_TRAVERSE(") != std::string::npos ||
        line.find("STRAIGHT_FEED(") != std::string::npos) {
      it.kind = line.find("FEED(") != std::string::npos ? 'F' : 'T';
      if (std::sscanf(args, "%lf, %lf, %lf", &it.p.x, &it.p.y, &it.p.z) != 3) continue;
      if (dist(it.p, at) < 1e-9) continue;
      at = it.p;
    } else if (line.find("USE_TOOL_LENGTH_OFFSET(") != std::string::npos) {
      it.kind = 'L';
      if (std::sscanf(args, "%lf %lf %lf", &it.p.x, &it.p.y, &it.p.z) != 3) continue;
    } else if (line.find("CHANGE_TOOL(") != std::string::npos) {
      it.kind = 'C';
    } else {
      continue;
    }
    items.push_back(it);
  }
  return items;
}

// The offsets rs274 applies before each move: for each move, the Z of the last offset.
double offset_before_first(const std::vector<Item>& items, char kind) {
  double z = 0.0;
  for (const Item& it : items) {
    if (it.kind == 'L') z = it.p.z;
    if (it.kind == kind) return z;
  }
  return std::nan("");
}

// The header's notes of moves the blocks add: "(ncd: line 5's rapid from an unknown position:
// G0 Z5. first, then G0 X10. Y10.)".
std::size_t listed_added_moves(const std::string& blocks) {
  std::size_t n = 0;
  for (std::size_t at = 0; (at = blocks.find("(ncd: ", at)) != std::string::npos; ++at) {
    const std::size_t end = blocks.find(')', at);
    if (blocks.substr(at, end - at).find("rapid from an unknown position: G0 Z") !=
        std::string::npos) {
      ++n;
    }
  }
  return n;
}

// Compares the motion of the blocks (rs274 on them) with the program's (rs274 on it), move by
// move: each rapid of the program is a rapid of the blocks to the same point, or (a listed
// split) a rapid to its Z and then the rapid; each run of feeds ends at the same point, every
// point of the blocks' run lies within the blend and chord tolerances of the program's path,
// and the middle of every feed of the program within them of the blocks' path. The tool length
// offsets come in the same order with the same lengths. Returns what differs (empty: nothing), and
// the number of splits found.
std::string motion_diff(const std::vector<Item>& prog, const std::vector<Item>& blocks,
                        std::size_t& splits) {
  splits = 0;
  std::vector<double> prog_l, blocks_l;  // the offsets that change the one in force (0 at start)
  std::vector<Item> a, b;
  const auto split = [](const std::vector<Item>& in, std::vector<double>& l, std::vector<Item>& m) {
    double now = 0.0;
    for (const Item& it : in) {
      if (it.kind != 'L') {
        m.push_back(it);
      } else if (std::abs(it.p.z - now) > 1e-9) {
        l.push_back(now = it.p.z);
      }
    }
  };
  split(prog, prog_l, a);
  split(blocks, blocks_l, b);
  if (prog_l.size() != blocks_l.size()) {
    return std::to_string(prog_l.size()) + " length offsets in the program, " +
           std::to_string(blocks_l.size()) + " in the blocks";
  }
  for (std::size_t k = 0; k < prog_l.size(); ++k) {
    if (std::abs(prog_l[k] - blocks_l[k]) > kPrintMm) return "length offset differs";
  }
  const auto is_move = [](const Item& it) { return it.kind == 'T' || it.kind == 'F'; };
  std::erase_if(a, [&](const Item& it) { return !is_move(it); });
  std::erase_if(b, [&](const Item& it) { return !is_move(it); });
  std::size_t i = 0, j = 0;
  P3 at_a, at_b;
  while (i < a.size() && j < b.size()) {
    if (a[i].kind == 'T') {
      if (b[j].kind == 'T' && dist(a[i].p, b[j].p) <= kPrintMm) {
        at_a = a[i++].p;
        at_b = b[j++].p;
        continue;
      }
      if (b[j].kind == 'T' && j + 1 < b.size() && b[j + 1].kind == 'T' &&
          std::abs(b[j].p.z - a[i].p.z) <= kPrintMm && dist(b[j + 1].p, a[i].p) <= kPrintMm) {
        ++splits;
        at_b = b[j + 1].p;
        at_a = a[i++].p;
        j += 2;
        continue;
      }
      char m[160];
      std::snprintf(m, sizeof m,
                    "program rapid %zu to (%.4f, %.4f, %.4f), blocks move %zu to "
                    "(%.4f, %.4f, %.4f)",
                    i, a[i].p.x, a[i].p.y, a[i].p.z, j, b[j].p.x, b[j].p.y, b[j].p.z);
      return m;
    }
    // A run of feeds on both sides.
    if (b[j].kind != 'F') return "program feed " + std::to_string(i) + ", blocks rapid";
    std::vector<P3> ra{at_a}, rb{at_b};
    while (i < a.size() && a[i].kind == 'F') ra.push_back(a[i++].p);
    while (j < b.size() && b[j].kind == 'F') rb.push_back(b[j++].p);
    // The corner into the next rapid is rounded like any other (LinuxCNC's G64 does so too):
    // the blocks' feeds end on the rapid's line, at the end of the rounding.
    std::vector<P3> reach = ra;
    if (i < a.size()) reach.push_back(a[i].p);
    if (dist_to_polyline(rb.back(), reach) > kFeedTolMm) return "a feed run ends elsewhere";
    for (const P3& p : rb) {
      const double d = dist_to_polyline(p, reach);
      if (d > kFeedTolMm) return "a blocks feed " + std::to_string(d) + " mm off the path";
    }
    // Every feed of the program is in the blocks: its middle lies on their path (a corner
    // itself may lie farther: a rounding within P of both lines passes a 90° corner at P·√2).
    for (std::size_t k = 0; k + 1 < ra.size(); ++k) {
      const P3 mid{0.5 * (ra[k].x + ra[k + 1].x), 0.5 * (ra[k].y + ra[k + 1].y),
                   0.5 * (ra[k].z + ra[k + 1].z)};
      const double d = dist_to_polyline(mid, rb);
      if (d > kFeedTolMm) {
        char m[160];
        std::snprintf(m, sizeof m,
                      "the middle (%.4f, %.4f, %.4f) of a program feed is %.4f mm "
                      "off the blocks' path",
                      mid.x, mid.y, mid.z, d);
        return m;
      }
    }
    at_a = ra.back();
    at_b = rb.back();
  }
  if (i != a.size() || j != b.size()) {
    return "the program has " + std::to_string(a.size() - i) + " moves left, the blocks " +
           std::to_string(b.size() - j);
  }
  return {};
}

// The lines of a program that are not comments, and its comments joined (a long header line
// is split over several comment lines for grbl).
std::string code_of(const std::string& text) {
  std::istringstream in(text);
  std::string out;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.front() != '(') out += line + "\n";
  }
  return out;
}
std::string comments_of(const std::string& text) {
  std::istringstream in(text);
  std::string out;
  for (std::string line; std::getline(in, line);) {
    if (line.size() >= 2 && line.front() == '(') out += line.substr(1, line.size() - 2);
  }
  return out;
}

class ToolLengthHome : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    if (!fs::exists(ncd::test::kRs274)) GTEST_SKIP() << "rs274 not installed (linuxcnc-uspace)";
    // rs274's machine units are inches: the same lengths as ncd's table in mm.
    char t[160];
    std::snprintf(t, sizeof t, "T1 P1 Z%.12f D0.25\nT2 P2 Z%.12f D0.2\nT4 P4 Z%.12f D0.25\n",
                  kLength1Mm / 25.4, kLength2Mm / 25.4, kLength1Mm / 25.4);
    rs274_table_ = write("rs274.tbl", t);
    std::snprintf(t, sizeof t, "T1 P1 Z%.4f D6\nT2 P2 Z%.4f D5\nT4 P4 Z%.4f D6\n", kLength1Mm,
                  kLength2Mm, kLength1Mm);
    ncd_table_ = write("ncd.tbl", t);
  }
  Canonical canonical(const std::string& file, const std::string& options = "") {
    const fs::path out = dir_ / "canon.out", log = dir_ / "canon.log";
    const std::string cmd = ncd::test::rs274_command(dir_, "-t " + rs274_table_ + " " + options +
                                                               " -g " + file + " " + out.string()) +
                            " >" + log.string() + " 2>&1";
    const int raw = std::system(cmd.c_str());
    Canonical c;
    c.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    c.out = slurp(out);
    c.log = slurp(log);
    c.items = items_of(c.out);
    c.program_end = c.out.find("PROGRAM_END") != std::string::npos;
    return c;
  }
  static void expect_clean(const Canonical& c, const std::string& what) {
    EXPECT_EQ(c.status, 0) << what << "\n" << c.log;
    EXPECT_EQ(ncd::test::rs274_complaint(c.log), "") << what << ": " << c.log;
    EXPECT_TRUE(c.program_end) << what << ": no PROGRAM_END";
  }
  // The exp3 machine with `extra` after its [tool] programmed point and `program` as its
  // [program] table; the dialect replaced by `dialect`.
  std::string machine(const std::string& extra, const std::string& program = "",
                      const std::string& dialect = "iso") {
    std::string text = slurp(kTlhMachine);
    const std::string key = "programmed_point = \"tip\"";
    const std::size_t at = text.find(key);
    EXPECT_NE(at, std::string::npos);
    text.insert(at + key.size(), "\n" + extra);
    const std::string iso = "dialect = \"iso\"";
    text.replace(text.find(iso), iso.size(), "dialect = \"" + dialect + "\"");
    EXPECT_EQ(text.find("[program]"), std::string::npos);
    if (!program.empty()) text += "\n[program]\n" + program + "\n";
    return write("m-" + dialect + ".toml", text);
  }
  // The tool length rs274 applies before the first feed and the first rapid of `file`.
  void expect_length_first(const std::string& file, double length_mm, const std::string& what) {
    const Canonical c = canonical(file);
    expect_clean(c, what);
    const double before_feed = offset_before_first(c.items, 'F');
    const double before_rapid = offset_before_first(c.items, 'T');
    std::printf(
        "rs274 %-34s tool length %.4f mm before the first feed, %.4f before the first "
        "rapid\n",
        what.c_str(), before_feed, before_rapid);
    EXPECT_NEAR(before_feed, length_mm, 1e-3) << what << "\n" << c.out;
    EXPECT_NEAR(before_rapid, length_mm, 1e-3) << what << "\n" << c.out;
  }
  std::string rs274_table_, ncd_table_;
};

// `ncd chamfer --format ngc` and the blocks of its JSON, for tool 4 of a machine with a tool
// table (iso): G43 H4 before the first move, so rs274 drives the tip by tool 4's 75.5 mm.
TEST_F(ToolLengthHome, ChamferProgramAndItsBlocksTakeTheToolLengthBeforeTheFirstMove) {
  const std::string m = machine("number = 4");
  const std::string ngc = (dir_ / "c.ngc").string(), json_path = (dir_ / "c.json").string();
  ASSERT_EQ(ncd("chamfer " + kGeometry + " --machine " + m + " -q --format ngc -o " + ngc).status,
            0);
  EXPECT_NE(slurp(ngc).find("\nT4 M6\nG43 H4\n"), std::string::npos) << slurp(ngc);
  expect_length_first(ngc, kLength1Mm, "chamfer program (iso, tool 4)");
  ASSERT_EQ(ncd("chamfer " + kGeometry + " --machine " + m + " -q -o " + json_path).status, 0);
  const std::string blocks = (dir_ / "b.ngc").string();
  const CmdResult r = ncd("replay " + json_path + " --machine " + m + " -q --blocks " + blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(slurp(blocks).find("T4M6\nN3G43H4\n"), std::string::npos) << slurp(blocks);
  expect_length_first(blocks, kLength1Mm, "blocks of the chamfer (iso, tool 4)");
}

// For grbl (no tool table, G43 H is its error:20) neither writes G43 H; both headers say how
// the length is set.
TEST_F(ToolLengthHome, ForGrblTheHeaderSaysHowTheLengthIsSet) {
  const std::string m = machine("number = 4", "", "grbl");
  const std::string ngc = (dir_ / "c.ngc").string(), json_path = (dir_ / "c.json").string();
  ASSERT_EQ(ncd("chamfer " + kGeometry + " --machine " + m + " -q --format ngc -o " + ngc).status,
            0);
  ASSERT_EQ(ncd("chamfer " + kGeometry + " --machine " + m + " -q -o " + json_path).status, 0);
  const std::string blocks = (dir_ / "b.ngc").string();
  ASSERT_EQ(ncd("replay " + json_path + " --machine " + m + " -q --blocks " + blocks).status, 0);
  for (const std::string& text : {slurp(ngc), slurp(blocks)}) {
    EXPECT_EQ(code_of(text).find("G43"), std::string::npos) << text;
    EXPECT_NE(comments_of(text).find("tool length: no tool table; set work Z0 at tool 4's tip or "
                                     "give G43.1 Z"),
              std::string::npos)
        << text;
  }
}

// `ncd teach` changes no tool: it takes the length of the tool in the spindle (--tool, 1 by
// default) before its first move; --no-length-offset leaves it out and says so. Its blocks
// (replayed for the iso machine) carry the same offset.
TEST_F(ToolLengthHome, TeachProgramAndItsBlocksTakeTheToolLengthBeforeTheFirstMove) {
  const std::string ex = std::string(NCD_SOURCE_DIR) + "/examples/";
  const std::string args = "teach " + ex + "teach-burr.txt --frame-points " + ex +
                           "teach-burr-frame.txt --tool-diameter 10 --depth 0.2 --feed 300 "
                           "--spindle 2000 -q";
  const std::string ngc = (dir_ / "t.ngc").string(), two = (dir_ / "t2.ngc").string();
  ASSERT_EQ(ncd(args + " -o " + ngc).status, 0);
  EXPECT_NE(slurp(ngc).find("\nG43H1\n"), std::string::npos);
  expect_length_first(ngc, kLength1Mm, "teach program (tool 1)");
  ASSERT_EQ(ncd(args + " --tool 2 -o " + two).status, 0);
  expect_length_first(two, kLength2Mm, "teach program (--tool 2)");
  const std::string m = machine("", "tool_table = \"" + ncd_table_ + "\"");
  const std::string blocks = (dir_ / "b.ngc").string();
  const CmdResult r = ncd("replay " + two + " --machine " + m + " -q --blocks " + blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  expect_length_first(blocks, kLength2Mm, "blocks of the teach program");
  std::size_t splits = 0;
  EXPECT_EQ(motion_diff(canonical(two).items, canonical(blocks).items, splits), "");
  EXPECT_EQ(splits, listed_added_moves(slurp(blocks)));
  const std::string none = (dir_ / "t0.ngc").string();
  ASSERT_EQ(ncd(args + " --no-length-offset -o " + none).status, 0);
  EXPECT_EQ(code_of(slurp(none)).find("G43"), std::string::npos);
  EXPECT_NE(slurp(none).find("(tool length: no G43 H; set the work offset Z for tool 1)"),
            std::string::npos);
  EXPECT_EQ(ncd(args + " --tool -1 -o " + none).status, 2);
}

const char* const kTwoTools =
    "%\n(two tools, each with its own length)\nG21 G90 G94 G17 G40 G49 G54\nT1 M6\nG43 H1\n"
    "S2000 M3\nG0 X0 Y0\nG0 Z10\nG1 Z-1 F300\nG1 X20\nG1 Y10\nG0 Z10\nT2 M6\nG43 H2\n"
    "S2500 M3\nG0 X5 Y5\nG0 Z8\nG1 Z-2 F200\nG1 X15 Y8\nG0 Z10\nM5\nM2\n%\n";

// An NGC program with two tool changes, replayed with --blocks for a machine whose tool table
// holds their lengths: the blocks write each G43 H after its change and their coordinates
// without the length (the controller adds its own); rs274 applies 75.5 mm and then 42.25 mm,
// each before the cut that follows its change, and the motion is the program's own.
TEST_F(ToolLengthHome, RewrittenProgramWithTwoToolChangesTakesEachLengthBeforeItsCut) {
  const std::string prog = write("two.ngc", kTwoTools);
  const std::string m = machine("", "tool_table = \"" + ncd_table_ + "\"");
  const std::string blocks = (dir_ / "b.ngc").string();
  const CmdResult r = ncd("replay " + prog + " --machine " + m + " -q --blocks " + blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  const Canonical c = canonical(blocks);
  expect_clean(c, "blocks of two tools");
  // Each change, then its length, then a feed.
  std::vector<double> at_feed;  // the offset in force at the first feed after each change
  double z = 0.0;
  bool changed = false;
  for (const Item& it : c.items) {
    if (it.kind == 'C') changed = true;
    if (it.kind == 'L') z = it.p.z;
    if (it.kind == 'F' && changed) {
      at_feed.push_back(z);
      changed = false;
    }
  }
  ASSERT_EQ(at_feed.size(), 2u) << c.out;
  EXPECT_NEAR(at_feed[0], kLength1Mm, 1e-3);
  EXPECT_NEAR(at_feed[1], kLength2Mm, 1e-3);
  const Canonical p = canonical(prog);
  expect_clean(p, "two tools");
  std::size_t splits = 0;
  EXPECT_EQ(motion_diff(p.items, c.items, splits), "") << slurp(blocks);
  EXPECT_EQ(splits, 0u);
  EXPECT_EQ(listed_added_moves(slurp(blocks)), 0u);
}

// A tool change followed by a cut with no length offset is refused for a controller with a tool
// table, naming both lines and the way out; nothing is written. A G49 after the change (the
// length in the work offset) is the programmer's word and is taken.
TEST_F(ToolLengthHome, ToolChangeWithoutLengthOffsetIsRefused) {
  const std::string m = machine("", "tool_table = \"" + ncd_table_ + "\"");
  const std::string bad = write("bad.ngc",
                                "G21 G90 G49\nT2 M6\nS1000 M3\nG0 X0 Y0\nG0 Z5\nG1 Z-1 F100\n"
                                "G0 Z5\nM2\n");
  const std::string blocks = (dir_ / "b.ngc").string();
  const CmdResult r = ncd("replay " + bad + " --machine " + m + " -q --blocks " + blocks);
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("bad.ngc:2: the tool change to T2"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("bad.ngc:5"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("Add G43 H2 after the M6"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(blocks));
  const std::string ok = write("ok.ngc",
                               "G21 G90\nT2 M6\nG49\nS1000 M3\nG0 X0 Y0\nG0 Z5\nG1 Z-1 F100\n"
                               "G0 Z5\nM2\n");
  const CmdResult g = ncd("replay " + ok + " --machine " + m + " -q --blocks " + blocks);
  EXPECT_EQ(g.status, 0) << g.err;
}

const char* const kHome =
    "G21 G90 G17\nG91 G28 Z0\nG90\nG0 X10 Y10\nG0 Z5\nG1 Z-1 F100\nG1 X20\nG1 Y15\nG0 Z5\n"
    "G91 G28 Z0\nG90\nG30 X0\nM2\n";

// G91 G28 Z0 with no stored position known: a rapid to "Z0" would go into the part. `ncd check`
// and `ncd replay` refuse it (exit 2) naming file:line, the parameter and the way out.
TEST_F(ToolLengthHome, G28WithNoHomeKnownIsRefusedNamingTheLine) {
  const std::string prog = write("home.ngc", kHome);
  const CmdResult c = ncd("check " + prog);
  EXPECT_EQ(c.status, 2) << c.out << c.err;
  EXPECT_NE(c.err.find("home.ngc:2: G28 moves Z to the stored G28 position, but no parameter "
                       "5163 is known"),
            std::string::npos)
      << c.err;
  EXPECT_NE(c.err.find("[program] parameter_file"), std::string::npos) << c.err;
  const std::string blocks = (dir_ / "b.ngc").string();
  const CmdResult r = ncd("replay " + prog + " -q --blocks " + blocks);
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("home.ngc:2:"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(blocks));
  // A parameter file without the G30 position: the G30 X0 of line 12 is refused.
  const std::string var = write("g28.var", "5161 0.5\n5162 0.25\n5163 2.0\n5220 1\n");
  const std::string m = machine("", "machine_units = \"inch\"\nparameter_file = \"" + var + "\"");
  const CmdResult g30 = ncd("check " + prog + " --machine " + m);
  EXPECT_EQ(g30.status, 2);
  EXPECT_NE(g30.err.find("home.ngc:12: G30 moves X to the stored G30 position, but no parameter "
                         "5181 is known: the parameter file"),
            std::string::npos)
      << g30.err;
}

// With the positions in a parameter file (inches, as rs274's machine units), the blocks go where
// rs274 goes for the program given the same file: through the intermediate point to the stored
// Z, and no X0 Y0 the program never asked for. The program's rs274 run gets a copy of the file
// (rs274 writes it back).
TEST_F(ToolLengthHome, G28WithAStoredPositionMatchesRs274MoveByMove) {
  const std::string var_text =
      "5161 0.5\n5162 0.25\n5163 2.0\n5181 -1.0\n5182 1.5\n5183 1.75\n5220 1\n";
  const std::string var = write("g28.var", var_text);
  const std::string prog = write("home.ngc", kHome);
  const std::string m = machine("", "machine_units = \"inch\"\nparameter_file = \"" + var + "\"");
  const std::string blocks = (dir_ / "b.ngc").string();
  const CmdResult r = ncd("replay " + prog + " --machine " + m + " -q --blocks " + blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string b = slurp(blocks);
  EXPECT_EQ(b.find("X0.Y0."), std::string::npos) << b;
  const std::string copy = write("rs274.var", var_text);
  const Canonical p = canonical(prog, "-v " + copy);
  expect_clean(p, "G28 program with a parameter file");
  const Canonical c = canonical(blocks);
  expect_clean(c, "blocks of the G28 program");
  // rs274 goes to Z 50.8 (2 in) twice and ends at the G30 X (-25.4).
  ASSERT_GE(p.items.size(), 3u);
  EXPECT_NEAR(p.items[0].p.z, 50.8, 1e-4);
  EXPECT_NEAR(p.items.back().p.x, -25.4, 1e-4);
  std::size_t splits = 0;
  EXPECT_EQ(motion_diff(p.items, c.items, splits), "") << b << "\n" << p.out << "\n" << c.out;
  EXPECT_EQ(splits, listed_added_moves(b));
  std::printf("G28 program: %zu canonical moves and offsets in the program, %zu in the blocks\n",
              p.items.size(), c.items.size());
}

// A first rapid from where the tool stands that moves both across and in Z is the one move the
// blocks write differently: Z first, then across. The header lists it, and it is the only
// difference rs274 sees between the program and its blocks.
TEST_F(ToolLengthHome, TheOnlyMovesTheBlocksAddAreListedInTheirHeader) {
  const std::string prog = write("diag.ngc",
                                 "G21 G90\nT1 M6\nG43 H1\nS1000 M3\nG0 X10 Y10 Z5\nG1 Z-1 F100\n"
                                 "G1 X20 Y12\nG0 Z5\nG0 X0 Y0 Z20\nM2\n");
  const std::string m = machine("", "tool_table = \"" + ncd_table_ + "\"");
  const std::string blocks = (dir_ / "b.ngc").string();
  const CmdResult r = ncd("replay " + prog + " --machine " + m + " -q --blocks " + blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string b = slurp(blocks);
  EXPECT_NE(b.find("(ncd: line 5's rapid from an unknown position: G0 Z5. first, then G0 X10. "
                   "Y10.)"),
            std::string::npos)
      << b;
  const Canonical p = canonical(prog), c = canonical(blocks);
  expect_clean(p, "diag program");
  expect_clean(c, "blocks of diag");
  std::size_t splits = 0;
  EXPECT_EQ(motion_diff(p.items, c.items, splits), "") << b;
  EXPECT_EQ(splits, 1u);
  EXPECT_EQ(listed_added_moves(b), 1u);
}

}  // namespace
