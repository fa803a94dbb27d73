// cyclictest: its histogram file read into percentiles, and the program run as a child process
// with its output in a temporary folder. The file format is drawn in cyclictest.hpp.
#include "app/cyclictest.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

extern char** environ;

namespace ncd::app {
namespace {

namespace fs = std::filesystem;

// Whitespace-separated unsigned integers of s; false if any token is not one.
bool parse_integers(std::string_view s, std::vector<std::int64_t>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r')) ++i;
    if (i == s.size()) break;
    std::size_t j = i;
    while (j < s.size() && s[j] != ' ' && s[j] != '\t' && s[j] != '\r') ++j;
    std::int64_t v = 0;
    const auto r = std::from_chars(s.data() + i, s.data() + j, v);
    if (r.ec != std::errc() || r.ptr != s.data() + j || v < 0) return false;
    out.push_back(v);
    i = j;
  }
  return true;
}

// The integers after "# <key>:" when line starts with it.
bool summary_values(std::string_view line, std::string_view key, std::vector<std::int64_t>& out,
                    std::size_t line_no) {
  if (line.substr(0, key.size()) != key) return false;
  if (!parse_integers(line.substr(key.size()), out)) {
    throw std::runtime_error("cyclictest histogram, line " + std::to_string(line_no) +
                             ": expected numbers after '" + std::string(key) + "'");
  }
  return true;
}

// The whole file, empty if it cannot be read.
std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The first non-blank line of text.
std::string first_line(const std::string& text) {
  const std::size_t start = text.find_first_not_of(" \n");
  if (start == std::string::npos) return "";
  return text.substr(start, text.find('\n', start) - start);
}

// Words joined by single spaces (the command line for the report).
std::string join(const std::vector<std::string>& words) {
  std::string s;
  for (const std::string& w : words) s += (s.empty() ? "" : " ") + w;
  return s;
}

struct ChildResult {
  int spawn_errno = 0;   // posix_spawnp failed with this
  int exit_status = -1;  // -1 when killed by a signal
  std::string out, err;
};

// Runs argv (looked up on PATH) with stdout and stderr into files of dir, and waits.
ChildResult run_child(const std::vector<std::string>& argv, const fs::path& dir) {
  const fs::path out = dir / "stdout", err = dir / "stderr";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0600);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  ChildResult r;
  r.spawn_errno = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (r.spawn_errno != 0) return r;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  r.exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

// A fresh private folder under the temporary directory, removed with the object.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "ncd_cyclictest_XXXXXX").string();
    if (mkdtemp(tmpl.data()) == nullptr) {
      throw std::runtime_error("cannot create a temporary folder " + tmpl + ": " +
                               std::strerror(errno));
    }
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

}  // namespace

std::int64_t CyclictestHistogram::samples() const {
  std::int64_t n = overflows;
  for (std::int64_t c : count_per_us) n += c;
  return n;
}

CyclictestHistogram parse_cyclictest_histogram(std::string_view text) {
  CyclictestHistogram h;
  bool have_max = false, have_total = false;
  std::int64_t total = 0;
  std::vector<std::int64_t> v;
  std::size_t line_no = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.find_first_not_of(" \t") == std::string_view::npos) continue;
    if (line[0] == '#') {
      if (summary_values(line, "# Total:", v, line_no)) {
        have_total = true;
        for (std::int64_t x : v) total += x;
      } else if (summary_values(line, "# Max Latencies:", v, line_no) && !v.empty()) {
        have_max = true;
        h.max_us = static_cast<double>(*std::max_element(v.begin(), v.end()));
      } else if (summary_values(line, "# Histogram Overflows:", v, line_no)) {
        for (std::int64_t x : v) h.overflows += x;
      }
      continue;
    }
    if (!parse_integers(line, v) || v.size() < 2) {
      throw std::runtime_error("cyclictest histogram, line " + std::to_string(line_no) +
                               ": expected '<latency us> <count>...', got '" + std::string(line) +
                               "'");
    }
    const auto bucket = static_cast<std::size_t>(v[0]);
    if (bucket >= h.count_per_us.size()) h.count_per_us.resize(bucket + 1, 0);
    for (std::size_t k = 1; k < v.size(); ++k) h.count_per_us[bucket] += v[k];
  }
  const std::int64_t in_buckets = h.samples() - h.overflows;
  if (have_total && total != in_buckets) {
    throw std::runtime_error("cyclictest histogram: '# Total: " + std::to_string(total) +
                             "' but the buckets hold " + std::to_string(in_buckets) + " samples");
  }
  if (!have_max) {
    for (std::size_t i = h.count_per_us.size(); i-- > 0;) {
      if (h.count_per_us[i] > 0) {
        h.max_us = static_cast<double>(i);
        break;
      }
    }
  }
  return h;
}

CyclictestPercentiles cyclictest_percentiles(const CyclictestHistogram& histogram) {
  CyclictestPercentiles p;
  const std::int64_t n = histogram.samples();
  if (n == 0) return p;
  const auto at = [&](double q) {
    const auto rank = std::max<std::int64_t>(
        1, static_cast<std::int64_t>(std::ceil(q * static_cast<double>(n) - 1e-9)));
    std::int64_t seen = 0;
    for (std::size_t i = 0; i < histogram.count_per_us.size(); ++i) {
      seen += histogram.count_per_us[i];
      if (seen >= rank) return static_cast<double>(i);
    }
    p.overflowed = true;
    return histogram.max_us;
  };
  p.us = {at(0.5), at(0.99), at(0.999), histogram.max_us};
  return p;
}

CyclictestRun run_cyclictest(const CyclictestOptions& o) {
  CyclictestRun run;
  TempDir dir;
  const std::string histfile = (dir.path() / "histogram").string();
  for (const bool mlock : {true, false}) {
    std::vector<std::string> argv = {o.executable};
    if (mlock) argv.emplace_back("-m");
    for (const std::string& a :
         {std::string("-q"), std::string("-t1"), "-p" + std::to_string(o.priority),
          "-i" + std::to_string(o.interval_us), "-D" + std::to_string(o.seconds) + "s",
          "-h" + std::to_string(o.histogram_max_us), "--histfile=" + histfile}) {
      argv.push_back(a);
    }
    run.command = join(argv);
    std::error_code ignored;
    fs::remove(histfile, ignored);
    const ChildResult child = run_child(argv, dir.path());
    if (child.spawn_errno != 0) {
      run.reason = "cannot run " + o.executable + ": " + std::strerror(child.spawn_errno) +
                   (child.spawn_errno == ENOENT
                        ? " (Debian package rt-tests; scripts/install-deps.sh installs it)"
                        : "");
      return run;
    }
    if (child.exit_status != 0 || !fs::exists(histfile)) {
      const std::string why = first_line(child.err + "\n" + child.out);
      run.reason = "`" + run.command + "` exited with status " + std::to_string(child.exit_status) +
                   (why.empty() ? "" : ": " + why);
      if (mlock) {
        run.notes.push_back("with -m (mlockall) it failed (" + run.reason + "); ran without -m");
        continue;
      }
      return run;
    }
    run.histogram = parse_cyclictest_histogram(slurp(histfile));
    if (run.histogram.samples() == 0) {
      run.reason = "`" + run.command + "` wrote an empty histogram";
      return run;
    }
    if (child.out.find("/dev/cpu_dma_latency set to 0us") != std::string::npos) {
      run.notes.push_back(
          "cyclictest held /dev/cpu_dma_latency at 0 us (no deep C-states) during its run, as "
          "ncd's cycle does when it may (see the realtime line)");
    }
    run.percentiles = cyclictest_percentiles(run.histogram);
    if (run.percentiles.overflowed) {
      run.notes.push_back("some percentiles lay beyond the histogram's " +
                          std::to_string(o.histogram_max_us) + " us and are given as the maximum");
    }
    run.ok = true;
    run.reason.clear();
    return run;
  }
  return run;
}

}  // namespace ncd::app
