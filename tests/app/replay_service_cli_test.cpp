// `ncd replay` runs its job in the service library (docs/service.md, "The cycle on the owner's
// thread"). Its outputs must be those of the loop it had before, which this test writes out as
// the slow reference: a motion::Job stepped directly, prepare() then step(), each setpoint
// recorded with the job's limit and roughness right after its step (motion::record) and written
// through the same setpoints file. The CSV must match byte for byte and the report's numbers
// exactly, on a NURBS path, a rational NURBS circle and an RS-274 program with G5.2.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "gcode/path_io.hpp"
#include "motion/job.hpp"
#include "motion/run_stats.hpp"
#include "service/machine_config.hpp"
#include "service/setpoint_file.hpp"
#include "tests/app/cli_fixture.hpp"

namespace {

using namespace ncd;
using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;

class ReplayOnService : public Cli {};

TEST_F(ReplayOnService, SetpointsAndReportAreThoseOfTheDirectJobLoop) {
  const std::string src = std::string(NCD_SOURCE_DIR);
  for (const std::string& file :
       {src + "/examples/cubic.json", src + "/examples/rational-circle.json",
        src + "/tests/ngc/nurbs_block.ngc"}) {
    SCOPED_TRACE(file);
    const std::string csv = (dir_ / "sp.csv").string(), report = (dir_ / "r.json").string();
    const CmdResult r =
        ncd("replay -q --path-only " + file + " --setpoints " + csv + " --report " + report);
    ASSERT_EQ(r.status, 0) << r.err;
    // The reference: replay's old loop, on the documented defaults (no --machine).
    const service::MachineConfig m;
    const toolpath::Path path = toolpath::read_path_file(file, m.program);
    motion::JobConfig cfg;
    cfg.limits = m.limits;
    cfg.cutting = m.cutting;
    motion::Job job(path, cfg);
    motion::RunStats st;
    st.path_length_mm = job.length_mm();
    const std::string ref_csv = (dir_ / "ref.csv").string();
    {
      service::SetpointFileSink ref(ref_csv);
      for (;;) {
        job.prepare();
        const motion::Setpoint sp = job.step();
        ASSERT_EQ(sp.fault, motion::StepFault::None);
        motion::record(st, cfg, sp, job.limit_here().feed_mm_per_s,
                       job.roughness_here_um(sp.v_mm_per_s), 0.0);
        ref.write(sp);
        if (sp.done) break;
        ASSERT_LT(st.cycles, 10000000) << "the reference never ended";
      }
      ref.commit();
    }
    EXPECT_EQ(slurp(csv), slurp(ref_csv));
    const auto j = nlohmann::json::parse(slurp(report));
    EXPECT_EQ(j["cycles"].get<std::int64_t>(), st.cycles);
    EXPECT_EQ(j["duration_s"].get<double>(), st.duration_s);
    EXPECT_EQ(j["path_length_mm"].get<double>(), st.path_length_mm);
    EXPECT_EQ(j["arc_length_drift_mm"].get<double>(), st.drift_mm());
    EXPECT_EQ(j["feed_error"]["max_rel"].get<double>(), st.feed_error_max_rel);
    EXPECT_EQ(j["feed_error"]["rms_rel"].get<double>(), st.feed_error_rms_rel());
    EXPECT_EQ(j["chord_error_max_mm"].get<double>(), st.chord_error_max_mm);
    EXPECT_EQ(j["roughness_max_um"].get<double>(), st.roughness_max_um);
    EXPECT_EQ(j["limit_violations"].get<std::int64_t>(), st.limit_violations());
    for (std::size_t id = 0; id < st.cycles_by_limit.size(); ++id) {
      if (st.cycles_by_limit[id] == 0) continue;
      const char* name = motion::limit_name(static_cast<std::uint8_t>(id));
      EXPECT_EQ(j["active_limit_share"][name].get<double>(),
                static_cast<double>(st.cycles_by_limit[id]) / static_cast<double>(st.cycles))
          << name;
    }
    EXPECT_EQ(j["lookahead_window_high_water"]["samples"].get<std::int64_t>(),
              static_cast<std::int64_t>(job.planner().window_samples_high_water()));
    EXPECT_TRUE(j["accepted"].get<bool>());
    // Timed by the cycle: the step, and the look-ahead with the first window.
    EXPECT_GT(j["step_time_ns"]["median"].get<double>(), 0.0);
    EXPECT_GT(j["lookahead_sampling_ms"].get<double>(), 0.0);
  }
}

}  // namespace
