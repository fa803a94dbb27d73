// The chamfer path as the JSON contract, CSV, a human summary and a Fig. 14-style plot.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "app/svg_plot.hpp"
#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"

namespace ncd::app {

// non_knife_angle_deg echoes the flag as given (2β is held in radians inside).
nlohmann::ordered_json chamfer_json(const toolpath::ChamferPath& path,
                                    const toolpath::NgcOptions& ngc,
                                    std::optional<double> non_knife_angle_deg, double elapsed_ms);
std::string chamfer_csv(const toolpath::ChamferPath& path);
std::string chamfer_summary(const toolpath::ChamferPath& path, double elapsed_ms);
Figure chamfer_figure(const toolpath::ChamferPath& path);

}  // namespace ncd::app
