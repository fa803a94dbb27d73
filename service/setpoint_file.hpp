// The setpoints file of `ncd replay` and of service jobs: CSV, one row per period
// (t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit[,a_deg|b_deg]), written as it comes into a temporary
// file that is renamed when the run succeeds, so a failed run leaves nothing behind.
#pragma once

#include <memory>
#include <string>

#include "core/output_file.hpp"
#include "motion/job.hpp"
#include "service/service.hpp"

namespace ncd::service {

class SetpointFileSink final : public service::SetpointSink {
 public:
  // An empty path writes nothing. Throws InputError if the file cannot be created. With a
  // rotary axis ('a', 'b'; docs/planner.md §3g) each row ends with its position, a_deg or b_deg.
  explicit SetpointFileSink(const std::string& path, char rotary_axis = 0);
  SetpointFileSink(const SetpointFileSink&) = delete;
  SetpointFileSink& operator=(const SetpointFileSink&) = delete;

  void write(const motion::Setpoint& sp) override;  // one row, fixed decimals, no allocation
  void commit() override;                           // flush and rename; throws on failure

 private:
  std::unique_ptr<StreamedFile> file_;  // null when nothing is recorded
  bool rotary_ = false;
};

}  // namespace ncd::service
