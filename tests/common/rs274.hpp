// LinuxCNC's standalone interpreter `rs274`, the judge of every G-code ncd reads or writes.
//
// rs274 keeps the tool table in a memory-mapped file, $HOME/.tool.mmap, which it creates and
// truncates at start. Two rs274 at once (ctest -j2 runs the conformance and block suites side by
// side) then share one file and one of them fails with "tool_mmap_creator() lseek fail: Bad file
// descriptor"; without a writable HOME every run fails so. Each call gets its own HOME, the
// caller's folder, so a run depends on nothing outside it.
#pragma once

#include <filesystem>
#include <string>

namespace ncd::test {

inline constexpr const char* kRs274 = "/usr/bin/rs274";

// The shell command that runs `rs274 <args>` with HOME = `home`, its three prompts answered with
// empty lines and at most 60 s of run time.
inline std::string rs274_command(const std::filesystem::path& home, const std::string& args) {
  return "printf '\\n\\n\\n' | HOME='" + home.string() + "' timeout 60 " + kRs274 + " " + args;
}

}  // namespace ncd::test
