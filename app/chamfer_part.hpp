// `ncd chamfer --part FILE`: every hole of a part file in one program, indexed on a rotary axis
// (cam/part.hpp, docs/part.md); its report, JSON and plot.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "cam/part.hpp"

namespace ncd::app {

struct PartArgs {
  std::string part;     // the part file
  std::string machine;  // optional machine file: dialect, programmed point, rapid limits
  std::optional<std::string> point;  // --program-point
  std::string format = "ngc";        // ngc | json
  std::string output, plot;
  bool quiet = false;
};

int run_chamfer_part(const PartArgs& args);

nlohmann::ordered_json part_json(const toolpath::PartProgram& program, double elapsed_ms);
std::string part_summary(const toolpath::PartProgram& program, double elapsed_ms);
// The pipe unrolled (station across, angle around up), each hole's edge and its number in the
// cutting order, the air path between them.
std::string part_svg(const toolpath::PartProgram& program);

}  // namespace ncd::app
