// A CLI test that streams to `ncd sim-controller` as a separate process on a real pty: starts it
// with the test's flags (its link and log in the test's folder, --exit-at-end) and reads its log
// once it has exited.
#pragma once

#include <csignal>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_fixture.hpp"
#include "tests/common/process.hpp"

namespace ncd::test {

class SimControllerCli : public Cli {
 protected:
  // Starts the simulated controller with extra flags; waits for its link to appear.
  std::unique_ptr<Process> controller(const std::string& flags) {
    link_ = (dir_ / "cnc").string();
    log_ = (dir_ / "cnc.json").string();
    std::vector<std::string> argv{NCD_EXE, "sim-controller", "--link", link_, "--log",
                                  log_,    "--exit-at-end"};
    std::istringstream in(flags);
    for (std::string f; in >> f;) argv.push_back(f);
    auto p =
        std::make_unique<Process>(argv, (dir_ / "cnc.out").string(), (dir_ / "cnc.err").string());
    EXPECT_TRUE(wait_for_path(link_, 5.0)) << slurp(dir_ / "cnc.err");
    return p;
  }

  // Waits for the controller to exit (0 expected; stopped after timeout_s) and returns its log.
  nlohmann::json controller_log(Process& p, double timeout_s = 30.0) {
    const int status = p.wait(timeout_s);
    EXPECT_EQ(status, 0) << slurp(dir_ / "cnc.err");
    if (status == -2) {
      p.signal(SIGTERM);
      p.wait(5.0);
    }
    return nlohmann::json::parse(slurp(log_));
  }

  std::string link_, log_;  // the controller's link and log, in the test's folder
};

}  // namespace ncd::test
