// A service chamfer job becomes its path without JSON text (service/chamfer_job.hpp). The
// reference is the route it replaced and `ncd replay` still takes: the chamfer's JSON
// (app/chamfer_report.hpp) read back by toolpath::read_path_text. Both must give the same path
// bit for bit: points, tool axes, feed, spindle speed, ball radius and the failed checks, for a
// chamfer whose checks pass and one whose checks fail.
#include <gtest/gtest.h>

#include "app/chamfer_report.hpp"
#include "core/error.hpp"
#include "gcode/path_io.hpp"
#include "service/chamfer_job.hpp"

namespace {

using namespace ncd;

void expect_same(const toolpath::Path& a, const toolpath::Path& b) {
  ASSERT_EQ(a.segments.size(), 1u);
  ASSERT_EQ(b.segments.size(), 1u);
  const auto& pa = std::get<toolpath::Polyline>(a.segments[0].geometry);
  const auto& pb = std::get<toolpath::Polyline>(b.segments[0].geometry);
  ASSERT_EQ(pa.points.size(), pb.points.size());
  ASSERT_EQ(pa.normals.size(), pb.normals.size());
  for (std::size_t k = 0; k < pa.points.size(); ++k) {
    ASSERT_EQ(pa.points[k], pb.points[k]) << k;
    ASSERT_EQ(pa.normals[k], pb.normals[k]) << k;
  }
  EXPECT_EQ(a.segments[0].feed_mm_per_min, b.segments[0].feed_mm_per_min);
  EXPECT_EQ(a.segments[0].spindle_rpm, b.segments[0].spindle_rpm);
  EXPECT_EQ(a.source, b.source);
  ASSERT_TRUE(a.chamfer && b.chamfer);
  EXPECT_EQ(a.chamfer->ball_radius_mm, b.chamfer->ball_radius_mm);
  EXPECT_EQ(a.chamfer->checks_ok, b.chamfer->checks_ok);
  EXPECT_EQ(a.chamfer->failed_checks, b.chamfer->failed_checks);
  EXPECT_EQ(a.chamfer->inner_edge, b.chamfer->inner_edge);
  EXPECT_EQ(a.chamfer->lower_side, b.chamfer->lower_side);
  EXPECT_EQ(a.chamfer->safe_z_mm, b.chamfer->safe_z_mm);
  EXPECT_EQ(a.chamfer->safe_z_for_tip, b.chamfer->safe_z_for_tip);
}

service::ChamferJob experiment(double ball_radius_mm) {
  service::ChamferJob j;
  j.spec.pipe_radius_mm = 18;
  j.spec.drill_radius_mm = 13;
  j.spec.ball_radius_mm = ball_radius_mm;
  j.spec.width_mm = 0.7;
  j.spec.rod_radius_mm = 1.8;
  j.feed_mm_per_min = 240;
  j.spindle_rpm = 4500;
  return j;
}

TEST(ChamferJobPath, EqualsTheChamferJsonReadBack) {
  for (const double ball : {3.0, 12.0}) {
    const service::ChamferJob job = experiment(ball);
    const toolpath::ChamferPath chamfer = toolpath::generate_chamfer(job.spec);
    toolpath::NgcOptions ngc;
    ngc.feed_mm_per_min = job.feed_mm_per_min;
    ngc.spindle_rpm = job.spindle_rpm;
    ngc.safe_z_mm = toolpath::default_safe_z_mm(job.spec);  // as `ncd chamfer` without --safe-z
    const toolpath::Path via_json = toolpath::read_path_text(
        app::chamfer_json(chamfer, ngc, std::nullopt, 0.0).dump(), "chamfer job");
    const toolpath::Path direct = service::chamfer_job_path(job);
    SCOPED_TRACE("ball radius " + std::to_string(ball));
    expect_same(direct, via_json);
    EXPECT_EQ(direct.chamfer->checks_ok, ball == 3.0);  // 12 mm: the failing case
    EXPECT_TRUE(direct.chamfer->inner_edge);
    EXPECT_FALSE(direct.chamfer->lower_side);
  }
}

// The whole job around the loop needs the edge, the side and the clearance plane: an outer
// lower edge with its own safe Z, for the ball centre, reads back as the job gives it.
TEST(ChamferJobPath, EdgeSideAndClearanceEqualTheJsonReadBack) {
  service::ChamferJob job = experiment(3.0);
  job.spec.edge = toolpath::Edge::Outer;
  job.spec.side = toolpath::Side::Lower;
  job.spec.rod_radius_mm.reset();
  job.point = toolpath::ProgramPoint::Centre;
  job.safe_z_mm = 31.5;
  const toolpath::ChamferPath chamfer = toolpath::generate_chamfer(job.spec);
  toolpath::NgcOptions ngc;
  ngc.feed_mm_per_min = job.feed_mm_per_min;
  ngc.spindle_rpm = job.spindle_rpm;
  ngc.point = job.point;
  ngc.safe_z_mm = *job.safe_z_mm;
  const toolpath::Path via_json = toolpath::read_path_text(
      app::chamfer_json(chamfer, ngc, std::nullopt, 0.0).dump(), "chamfer job");
  const toolpath::Path direct = service::chamfer_job_path(job);
  expect_same(direct, via_json);
  EXPECT_FALSE(direct.chamfer->inner_edge);
  EXPECT_TRUE(direct.chamfer->lower_side);
  EXPECT_EQ(direct.chamfer->safe_z_mm, 31.5);
  EXPECT_FALSE(direct.chamfer->safe_z_for_tip);
}

// A chamfer JSON whose edge or side is neither of its two words is refused naming the key.
TEST(ChamferJobPath, AnUnknownEdgeWordInTheJsonIsRefused) {
  const service::ChamferJob job = experiment(3.0);
  toolpath::NgcOptions ngc;
  ngc.safe_z_mm = 40.0;
  nlohmann::ordered_json j =
      app::chamfer_json(toolpath::generate_chamfer(job.spec), ngc, std::nullopt, 0.0);
  j["input"]["edge"] = "inside";
  try {
    toolpath::read_path_text(j.dump(), "bad.json");
    ADD_FAILURE() << "edge \"inside\" was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("input.edge"), std::string::npos) << e.what();
  }
}

TEST(ChamferJobPath, AFeedOutsideItsRangeIsRefusedNamingIt) {
  service::ChamferJob job = experiment(3.0);
  job.feed_mm_per_min = 0.0;
  EXPECT_THROW(service::chamfer_job_path(job), InputError);
  job.feed_mm_per_min = 1e9;
  try {
    service::chamfer_job_path(job);
    ADD_FAILURE() << "a feed of 1e9 mm/min was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("feed"), std::string::npos) << e.what();
  }
}

}  // namespace
