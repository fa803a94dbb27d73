// Path files: round trips of files the test writes, the `ncd chamfer` JSON, dispatch to the
// G-code reader, and errors that name the file and the key.
#include "gcode/path_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "cam/chamfer.hpp"
#include "core/error.hpp"

namespace ncd::toolpath {
namespace {

using nlohmann::json;

std::string temp_file(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "ncd_path_io_" + name;
  std::ofstream(path) << text;
  return path;
}

json vec(const Vec3& v) {
  return json::array({v.x(), v.y(), v.z()});
}

TEST(PathIo, NurbsFileRoundTripsExactly) {
  // A rational cubic with a double interior knot; nlohmann writes the shortest text that
  // reads back to the same double, so the curve must come back bit for bit.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> coord(-80.0, 80.0), wdist(0.3, 3.0);
  std::vector<Vec3> pts(7);
  std::vector<double> w(7);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    pts[i] = Vec3(coord(rng), coord(rng), coord(rng));
    w[i] = wdist(rng);
  }
  const NurbsCurve c(3, {0, 0, 0, 0, 0.3, 0.3, 0.71, 1.5, 1.5, 1.5, 1.5}, pts, w);
  json doc;
  doc["feed_mm_per_min"] = 750.5;
  doc["nurbs"] = {{"degree", c.degree()}, {"knots", c.knots()}, {"weights", c.weights()}};
  doc["nurbs"]["points"] = json::array();
  for (const auto& q : c.points()) doc["nurbs"]["points"].push_back(vec(q));
  const std::string file = temp_file("nurbs.json", doc.dump(2));

  const Path p = read_path_file(file);
  EXPECT_EQ(p.source, file);
  ASSERT_EQ(p.segments.size(), 1u);
  EXPECT_EQ(p.segments[0].feed_mm_per_min, 750.5);
  EXPECT_FALSE(p.segments[0].spindle_rpm);
  EXPECT_FALSE(p.segments[0].rapid);
  const auto& back = std::get<NurbsCurve>(p.segments[0].geometry);
  EXPECT_EQ(back.degree(), 3);
  EXPECT_EQ(back.knots(), c.knots());
  EXPECT_EQ(back.points(), c.points());
  EXPECT_EQ(back.weights(), c.weights());
  EXPECT_EQ(back.eval(0.5).d2, c.eval(0.5).d2);
}

TEST(PathIo, NonRationalNurbsWithoutWeights) {
  const std::string file = temp_file("bspline.json",
                                     R"({"nurbs": {"degree": 2, "knots": [0, 0, 0, 1, 1, 1],
                    "points": [[0, 0, 0], [5, 5, 0], [10, 0, 0]]}})");
  const Path p = read_path_file(file);
  const auto& c = std::get<NurbsCurve>(p.segments.at(0).geometry);
  EXPECT_FALSE(c.rational());
  EXPECT_FALSE(p.segments[0].feed_mm_per_min);
  EXPECT_EQ(c.eval(0.5).p, Vec3(5, 2.5, 0));  // (P0 + 2 P1 + P2) / 4
}

TEST(PathIo, PolylineFileWithNormalsRoundTrips) {
  const double s = std::sqrt(0.5);
  const Polyline pl{{Vec3(0, 0, 0), Vec3(1.25, 0, -0.5), Vec3(1.25, 2, -0.5)},
                    {Vec3(0, 0, 1), Vec3(s, 0, s), Vec3(0, -s, s)}};
  json doc;
  doc["polyline"]["points"] = json::array();
  doc["polyline"]["normals"] = json::array();
  for (std::size_t i = 0; i < pl.points.size(); ++i) {
    doc["polyline"]["points"].push_back(vec(pl.points[i]));
    doc["polyline"]["normals"].push_back(vec(pl.normals[i]));
  }
  doc["feed_mm_per_min"] = 120;
  doc["spindle_rpm"] = 9000;
  const Path p = read_path_file(temp_file("polyline.json", doc.dump()));
  ASSERT_EQ(p.segments.size(), 1u);
  const auto& back = std::get<Polyline>(p.segments[0].geometry);
  EXPECT_EQ(back.points, pl.points);
  EXPECT_EQ(back.normals, pl.normals);
  EXPECT_EQ(p.segments[0].feed_mm_per_min, 120.0);
  EXPECT_EQ(p.segments[0].spindle_rpm, 9000.0);
}

// The fields app/chamfer_report.cpp writes, built here from a generated chamfer path.
json chamfer_json(const ChamferPath& path, double feed, double spindle) {
  json in = {{"pipe_radius_mm", path.spec.pipe_radius_mm},
             {"drill_radius_mm", path.spec.drill_radius_mm},
             {"ball_radius_mm", path.spec.ball_radius_mm},
             {"width_mm", path.spec.width_mm},
             {"rod_radius_mm", nullptr},
             {"feed_mm_per_min", feed},
             {"spindle_rpm", spindle},
             {"program_point", "tip"}};
  json pts = json::array();
  for (const auto& p : path.points) {
    pts.push_back({{"theta", p.theta_rad},
                   {"xp", vec(p.xp)},
                   {"cl", vec(p.cl)},
                   {"e", vec(p.e)},
                   {"alpha", p.alpha},
                   {"delta", p.delta_mm},
                   {"inv_ke", std::isfinite(p.inv_ke_mm) ? json(p.inv_ke_mm) : json()}});
  }
  return {{"input", in},
          {"segments", path.points.size()},
          {"points", pts},
          {"checks", {{"local", {{"ok", true}}}}},
          {"elapsed_ms", 1.5}};
}

TEST(PathIo, ChamferJsonBecomesAClosedLoopWithContactNormals) {
  const ChamferPath chamfer = generate_chamfer(ChamferSpec{});
  const std::string file = temp_file("chamfer.json", chamfer_json(chamfer, 300.0, 3000.0).dump(1));
  const Path p = read_path_file(file);
  ASSERT_EQ(p.segments.size(), 1u);
  const PathSegment& seg = p.segments[0];
  EXPECT_EQ(seg.feed_mm_per_min, 300.0);
  EXPECT_EQ(seg.spindle_rpm, 3000.0);
  EXPECT_FALSE(seg.rapid);
  const auto& pl = std::get<Polyline>(seg.geometry);
  const std::size_t n = chamfer.points.size();
  ASSERT_EQ(pl.points.size(), n + 1);
  ASSERT_EQ(pl.normals.size(), n + 1);
  for (std::size_t i = 0; i <= n; ++i) {
    EXPECT_EQ(pl.points[i], chamfer.points[i % n].cl);
    EXPECT_EQ(pl.normals[i], -chamfer.points[i % n].e);
  }
}

TEST(PathIo, SmallHandWrittenChamferJson) {
  const std::string file = temp_file("chamfer_small.json", R"({
    "input": {"feed_mm_per_min": 250.0, "spindle_rpm": 2400.0},
    "segments": 3,
    "points": [
      {"theta": 0.0, "cl": [10, 0, 11], "e": [1, 0, 0], "inv_ke": null},
      {"theta": 2.0, "cl": [-5, 8.66, 11], "e": [0, 1, 0]},
      {"theta": 4.0, "cl": [-5, -8.66, 11], "e": [0, 0, 1]}
    ]})");
  const Path p = read_path_file(file);
  const auto& pl = std::get<Polyline>(p.segments.at(0).geometry);
  EXPECT_EQ(pl.points,
            (std::vector<Vec3>{{10, 0, 11}, {-5, 8.66, 11}, {-5, -8.66, 11}, {10, 0, 11}}));
  EXPECT_EQ(pl.normals, (std::vector<Vec3>{{-1, 0, 0}, {0, -1, 0}, {0, 0, -1}, {-1, 0, 0}}));
  EXPECT_EQ(p.segments[0].feed_mm_per_min, 250.0);
  EXPECT_EQ(p.segments[0].spindle_rpm, 2400.0);
}

TEST(PathIo, AnythingElseIsGcode) {
  const std::string file =
      temp_file("prog.ngc", "  \n(not json)\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\nM2\n");
  const Path p = read_path_file(file);
  EXPECT_EQ(p.source, file);
  ASSERT_EQ(p.segments.size(), 1u);
  EXPECT_EQ(std::get<Polyline>(p.segments[0].geometry).points,
            (std::vector<Vec3>{{0, 0, 5}, {0, 0, 0}, {10, 0, 0}}));
}

void expect_path_error(const std::string& name, const std::string& text,
                       const std::vector<std::string>& needles) {
  const std::string file = temp_file(name, text);
  try {
    read_path_file(file);
    ADD_FAILURE() << "no InputError for " << text;
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.rfind(file, 0), 0u) << "message does not start with the file: " << m;
    for (const auto& n : needles) EXPECT_NE(m.find(n), std::string::npos) << n << " in: " << m;
  }
}

TEST(PathIo, ErrorsNameTheFileTheKeyAndTheWayOut) {
  expect_path_error("bad1.json",
                    R"({"points": [{"cl": [0, 0, 0], "e": [1, 0, 0]}, {"cl": [1, 0, 0]}]})",
                    {"\"points[1].e\" is missing"});
  expect_path_error(
      "bad2.json",
      R"({"points": [{"cl": [0, 0, "x"], "e": [1, 0, 0]}, {"cl": [1, 0, 0], "e": [1, 0, 0]}]})",
      {"\"points[0].cl[2]\"", "not a number"});
  expect_path_error("bad3.json", R"({"points": [{"cl": [0, 0], "e": [1, 0, 0]}]})",
                    {"\"points[0].cl\"", "[x, y, z]"});
  expect_path_error(
      "bad4.json",
      R"({"input": {"feed_mm_per_min": -3}, "points": [{"cl": [0, 0, 0], "e": [1, 0, 0]},
                  {"cl": [1, 0, 0], "e": [1, 0, 0]}]})",
      {"\"input.feed_mm_per_min\"", "-3", "greater than 0"});
  expect_path_error("bad5.json", R"({"points": [{"cl": [0, 0, 0], "e": [1, 0, 0]}]})",
                    {"\"points\" has 1 point"});
  expect_path_error("bad6.json", R"({"nurbs": {"degree": 2, "knots": [0, 0, 0, 0.5, 1, 1],
               "points": [[0, 0, 0], [1, 1, 0], [2, 0, 0]]}})",
                    {"\"nurbs\" is invalid", "knot[3] = 0.5", "clamped"});
  expect_path_error("bad7.json", R"({"nurbs": {"degree": 2.5, "knots": [], "points": []}})",
                    {"\"nurbs.degree\"", "2.5"});
  expect_path_error("bad8.json", R"({"nurbs": {"degree": 1, "knots": [0, 0, 1, 1],
               "points": [[0, 0, 0], [1, 0, 0]], "weights": [1, 0]}})",
                    {"weight[1] = 0"});
  expect_path_error("bad9.json", R"({"polyline": {"points": [[0, 0, 0], [0, 0, 0]]}})",
                    {"point[1] = (0, 0, 0) repeats point[0]"});
  expect_path_error("bad10.json", R"({"polyline": {"points": [[0, 0, 0], [1, 0, 0]]}, "feed": 5})",
                    {"\"feed\" is not a known key", "feed_mm_per_min"});
  expect_path_error("bad11.json", R"({"polyline": {"pts": []}})", {"\"polyline.pts\""});
  expect_path_error("bad12.json", R"({"polyline": {"points": []}, "nurbs": {}})",
                    {"exactly one of \"nurbs\" and \"polyline\""});
  expect_path_error("bad13.json", R"({"what": 1})", {"neither \"points\""});
  expect_path_error("bad14.json", "{\"points\": [1, 2,", {"not valid JSON"});
  expect_path_error("bad15.ngc", "G0 X0 Y0 Z0\nG2 X1 Y1 R0.1 F10\n", {":2:", "R0.1 is too small"});
  expect_path_error("empty.ngc", " \n\n", {"the file is empty"});
  try {
    read_path_file("/nonexistent/dir/path.json");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open /nonexistent/dir/path.json (path file)"),
              std::string::npos)
        << e.what();
  }
}

// Issue 11's path reproducers: each an InputError naming the key (or the byte offset), never an
// escaped nlohmann exception, a stack overflow or a path of zero length.
TEST(PathIo, NumbersNestingAndZeroLengthAreInputErrors) {
  expect_path_error("n1.json", R"({"nurbs":1e400})", {"n1.json: \"nurbs\" is out of range"});
  expect_path_error("n2.json", R"({"polyline":{"points":[[0,0,0],[-1e999,0,0]]}})",
                    {"\"polyline.points[1][0]\" is out of range"});
  expect_path_error("n3.json", R"({"polyline":{"points":)" + std::string(100000, '['),
                    {"n3.json: line 1, column 85 (byte offset 84)", "nesting deeper than 64"});
  expect_path_error(
      "n4.json",
      R"({"nurbs":{"degree":2,"knots":[0,0,0,1,1,1],"points":[[1,2,3],[1,2,3],[1,2,3]]}})",
      {"\"nurbs.points\" are all the same point", "zero length"});
  expect_path_error("n5.json", R"({"nurbs": {"degree": 4.9, "knots": [], "points": []}})",
                    {"\"nurbs.degree\" = 4.9 is not a whole number", "from 1 to 7"});
  expect_path_error("n6.json", R"({"nurbs": {"degree": 3e9, "knots": [], "points": []}})",
                    {"\"nurbs.degree\" = 3000000000 is out of range"});
  expect_path_error("n7.json",
                    R"({"polyline":{"points":[[0,0,0],[1,0,0]]},"feed_mm_per_min":0.0001})",
                    {"\"feed_mm_per_min\" = 0.0001 is outside the plausible range [0.1, 120000]"});
  expect_path_error(
      "n8.json", R"({"polyline":{"points":[[0,0,0],[1,0,0]]},"spindle_rpm":1e9})",
      {"\"spindle_rpm\" = 1000000000 is outside the plausible range [1, 200000] rpm"});
  expect_path_error("n9.json", R"({"polyline":{"points":[[0,0,0],[1e6,0,0]]}})",
                    {"\"polyline.points[1][0]\" = 1000000.0 is outside", "[-100000, 100000] mm"});
  // A repeated end control point (zero parametric speed at that end) is a valid curve.
  const Path p = read_path_text(
      R"({"nurbs":{"degree":2,"knots":[0,0,0,1,1,1],"points":[[0,0,0],[0,0,0],[10,0,0]]}})",
      "ok.json");
  EXPECT_EQ(p.segments.size(), 1u);
}

}  // namespace
}  // namespace ncd::toolpath
