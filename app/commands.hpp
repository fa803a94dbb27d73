// The ncd subcommands. Each registers its flags on the CLI and, when chosen, sets `run`, which
// main() calls after parsing: 0 on success; InputError → exit 2; other exceptions → exit 1.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace ncd::app {

using Runner = std::function<int()>;

void register_chamfer(CLI::App& app, Runner& run);
void register_replay(CLI::App& app, Runner& run);
void register_bench(CLI::App& app, Runner& run);
void register_serve(CLI::App& app, Runner& run);
void register_stream(CLI::App& app, Runner& run);
void register_sim_controller(CLI::App& app, Runner& run);
void register_teach(CLI::App& app, Runner& run);
void register_robot(CLI::App& app, Runner& run);
void register_simulate(CLI::App& app, Runner& run);
void register_check(CLI::App& app, Runner& run);

}  // namespace ncd::app
