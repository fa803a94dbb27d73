// ncd: a PC-NC service for deburring and chamfering drilled holes. One subcommand per use.
// Exit status: 0 success, 2 invalid input (the message says what and how to fix it), 3 a run
// refused for a limit violation (nothing streamed), 1 an I/O error or an internal failure, 4 a
// drip stream sent whole to a controller that never answered (docs/cmd-stream.md).
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "app/cli_guide.hpp"
#include "app/commands.hpp"
#include "core/error.hpp"
#include "ncd_commit.hpp"  // NCD_COMMIT, written at build time

int main(int argc, char** argv) {
  CLI::App app{
      "ncd: toolpaths for deburring and chamfering drilled holes, walked in a 4 ms cycle at a "
      "roughness-bounded feed and streamed to a CNC over RS-232 DNC"};
  app.set_version_flag("--version",
                       std::string("ncd ") + NCD_VERSION + " (commit " + NCD_COMMIT + ")");
  app.require_subcommand(1);
  ncd::app::Runner run;
  ncd::app::register_chamfer(app, run);
  ncd::app::register_replay(app, run);
  ncd::app::register_bench(app, run);
  ncd::app::register_serve(app, run);
  ncd::app::register_stream(app, run);
  ncd::app::register_sim_controller(app, run);
  ncd::app::register_teach(app, run);
  ncd::app::register_robot(app, run);
  ncd::app::register_simulate(app, run);
  ncd::app::register_check(app, run);
  // `ncd help CMD`, -V, and a misspelt command or flag named before CLI11 parses.
  const ncd::app::GuidedArgs guided =
      ncd::app::guide_args(app, std::vector<std::string>(argv + 1, argv + argc));
  if (guided.error) {
    std::cerr << "ncd: error: " << *guided.error << "\n";
    return 2;
  }
  std::vector<const char*> args{argv[0]};
  for (const std::string& a : guided.args) args.push_back(a.c_str());
  try {
    app.parse(static_cast<int>(args.size()), args.data());
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  try {
    return run ? run() : 2;
  } catch (const ncd::InputError& e) {
    std::cerr << "ncd: error: " << e.what() << "\n";
    return 2;
  } catch (const ncd::LimitError& e) {
    std::cerr << "ncd: refused: " << e.what() << "\n";
    return 3;
  } catch (const ncd::IoError& e) {
    std::cerr << "ncd: I/O error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "ncd: internal error: " << e.what() << "\n";
    return 1;
  }
}
