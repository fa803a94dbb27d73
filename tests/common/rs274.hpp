// LinuxCNC's standalone interpreter `rs274`, the judge of every G-code ncd reads or writes.
//
// rs274 keeps the tool table in a memory-mapped file, $HOME/.tool.mmap, which it creates and
// truncates at start. Two rs274 at once (ctest -j2 runs the conformance and block suites side by
// side) then share one file and one of them fails with "tool_mmap_creator() lseek fail: Bad file
// descriptor"; without a writable HOME every run fails so. Each call gets its own HOME, the
// caller's folder, so a run depends on nothing outside it.
#pragma once

#include <array>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

namespace ncd::test {

inline constexpr const char* kRs274 = "/usr/bin/rs274";

// The shell command that runs `rs274 <args>` with HOME = `home`, its three prompts answered with
// empty lines and at most 60 s of run time.
inline std::string rs274_command(const std::filesystem::path& home, const std::string& args) {
  return "printf '\\n\\n\\n' | HOME='" + home.string() + "' timeout 60 " + kRs274 + " " + args;
}

// The moves of rs274's canonical output (`rs274 -g`): the end point of every STRAIGHT_TRAVERSE
// and STRAIGHT_FEED, in order, and whether PROGRAM_END was reached.
struct CanonicalMoves {
  std::vector<std::array<double, 3>> end;  // mm, as printed (4 decimals)
  std::vector<bool> feed;                  // true for STRAIGHT_FEED
  bool program_end = false;
};

inline CanonicalMoves canonical_moves(const std::string& out) {
  CanonicalMoves c;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    const bool traverse = line.find("STRAIGHT_TRAVERSE(") != std::string::npos;
    const bool feed = line.find("STRAIGHT_FEED(") != std::string::npos;
    if (line.find("PROGRAM_END") != std::string::npos) c.program_end = true;
    if (!traverse && !feed) continue;
    std::array<double, 3> p{};
    const std::size_t open = line.find('(');
    if (std::sscanf(line.c_str() + open + 1, "%lf, %lf, %lf", &p[0], &p[1], &p[2]) != 3) continue;
    c.end.push_back(p);
    c.feed.push_back(feed);
  }
  return c;
}

// What rs274 complains of in its log or output: "rror" (error), "arning" (warning) or a program
// that ends with neither `%` nor a program end; empty when it says none of these.
inline std::string rs274_complaint(const std::string& text) {
  for (const char* bad : {"rror", "arning", "ended with no percent"}) {
    if (text.find(bad) != std::string::npos) return bad;
  }
  return {};
}

}  // namespace ncd::test
