// A CLI test that streams to `ncd sim-controller` as a separate process on a real pty: starts it
// with the test's flags (its link and log in the test's folder, --exit-at-end) and reads its log
// once it has exited.
#pragma once

#include <chrono>
#include <csignal>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "link/transfer_journal.hpp"

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

  // Waits (up to 30 s) until the journal says `blocks` blocks are known executed: the sender is
  // well into the program. Polled, as a fixed sleep would race a loaded machine.
  void wait_journal(const std::string& journal, long blocks) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    for (;;) {
      std::optional<comms::JournalState> j;
      try {
        j = comms::TransferJournal::read(journal);
      } catch (const std::exception&) {  // being written
      }
      if (j && j->confirmed >= blocks) return;
      ASSERT_LT(std::chrono::steady_clock::now(), end) << "the journal never reached " << blocks;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

  std::string link_, log_;  // the controller's link and log, in the test's folder
};

}  // namespace ncd::test
