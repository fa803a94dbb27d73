// A setpoint sink of the service tests: keeps every setpoint it is given and, when asked, says
// whether the job committed its output.
#pragma once

#include <vector>

#include "motion/job.hpp"
#include "service/service.hpp"

namespace ncd::test {

class CaptureSink : public service::SetpointSink {
 public:
  explicit CaptureSink(std::vector<motion::Setpoint>& out, bool* committed = nullptr)
      : out_(out), committed_(committed) {}
  void write(const motion::Setpoint& sp) override { out_.push_back(sp); }
  void commit() override {
    if (committed_) *committed_ = true;
  }

 private:
  std::vector<motion::Setpoint>& out_;
  bool* committed_;
};

}  // namespace ncd::test
