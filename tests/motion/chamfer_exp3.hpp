// The experiment-3 chamfer of paper 000 (rod radius 1.8 mm, non-knife angle 93°, the other
// ChamferSpec defaults) as `ncd chamfer` writes it, F300 at 3000 rpm: only the fields the path
// reader takes.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "cam/chamfer.hpp"

namespace ncd::test {

inline std::string chamfer_exp3_json() {
  toolpath::ChamferSpec s;
  s.rod_radius_mm = 1.8;
  s.non_knife_angle_rad = deg_to_rad(93.0);
  const toolpath::ChamferPath path = toolpath::generate_chamfer(s);
  nlohmann::json j;
  j["input"] = {{"feed_mm_per_min", 300.0}, {"spindle_rpm", 3000.0}};
  for (const auto& p : path.points) {
    j["points"].push_back(
        {{"cl", {p.cl.x(), p.cl.y(), p.cl.z()}}, {"e", {p.e.x(), p.e.y(), p.e.z()}}});
  }
  return j.dump();
}

}  // namespace ncd::test
