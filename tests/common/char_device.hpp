// A character device to feed readers that must refuse one. /dev/null is not used: on a machine
// where something replaced it with a regular file (a write-then-rename run as root does that),
// it is no longer a device.
#pragma once

#include <sys/stat.h>

#include <initializer_list>
#include <string>

namespace ncd::test {

inline std::string character_device() {
  for (const char* path : {"/dev/zero", "/dev/urandom", "/dev/full", "/dev/random", "/dev/null"}) {
    struct stat st {};
    if (::stat(path, &st) == 0 && S_ISCHR(st.st_mode)) return path;
  }
  return "/dev/zero";
}

}  // namespace ncd::test
