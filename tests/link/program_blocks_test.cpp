// Whole programs through the block encoder (link/program_blocks.hpp, docs/whole-program.md):
// a cut wrapped by toolpath::whole_job, planned and walked by motion::Job, encoded with its
// events. Checked against the program itself: the order of the events, every G0 at the end point
// of its rapid (exact, within the rounding), no F on a G0, the first G1 after M3 and after the
// approach from the clearance plane, and the framing knobs.
#include "link/program_blocks.hpp"

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <string>
#include <vector>

#include "cam/whole_program.hpp"
#include "core/error.hpp"
#include "motion/job.hpp"

namespace ncd::comms {
namespace {

struct ProgramEncoded {
  std::vector<std::string> lines;
  EncoderStats stats;
};

toolpath::Program square_job(double dwell_s) {
  toolpath::Polyline cut;
  cut.points = {{10, 0, -1}, {10, 10, -1}, {0, 10, -1}, {0, 0, -1}, {10, 0, -1}};
  toolpath::PathSegment seg;
  seg.geometry = cut;
  seg.feed_mm_per_min = 600.0;
  toolpath::Path path;
  path.segments.push_back(seg);
  path.source = "square";
  toolpath::JobFrame f;
  f.spindle_rpm = 1000.0;
  f.spindle_dwell_s = dwell_s;
  f.tool = 3;
  f.clearance_z_mm = 20.0;
  f.axis_xy = Vec3(5, 5, 0);  // like an inner edge: down at (5, 5), then out to the start
  return toolpath::whole_job(path, f);
}

ProgramEncoded encode_program(const toolpath::Program& program, EncoderSettings s = {}) {
  const toolpath::Path path = toolpath::to_path(program);
  motion::JobConfig cfg;
  cfg.cutting.pick_feed_mm = 0.0;
  motion::Job job(path, cfg);
  ProgramEncoded run;
  BlockEncoder enc(s, [&run](const EncodedBlock& b) { run.lines.push_back(b.text); });
  ProgramBlocks blocks(program, enc, job.segment_starts_mm());
  blocks.begin({"a header"});
  motion::Setpoint start;
  start.p = job.walker().position();
  blocks.push(start);
  for (int i = 0; i < 10'000'000; ++i) {
    job.prepare();
    const motion::Setpoint sp = job.step();
    EXPECT_EQ(sp.fault, motion::StepFault::None);
    blocks.push(sp);
    if (sp.done) break;
  }
  blocks.end();
  run.stats = enc.stats();
  return run;
}

std::size_t index_of(const std::vector<std::string>& lines, const std::string& part) {
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].find(part) != std::string::npos) return i;
  }
  return lines.size();
}

TEST(ProgramBlocks, EventsAndRapidsComeOutAtTheirPlace) {
  const ProgramEncoded r = encode_program(square_job(2.5));
  ASSERT_GT(r.lines.size(), 10u);
  EXPECT_EQ(r.lines[0], "(a header)");
  EXPECT_EQ(r.lines[1], "N1G21G90G94G17G40G49G64P0.002");
  EXPECT_EQ(r.lines[2], "N2T3M6");
  EXPECT_EQ(r.lines[3], "N3G43H3");  // the tool's length, from the controller's table
  EXPECT_EQ(r.lines[4], "N4M3S1000");
  EXPECT_EQ(r.lines[5], "N5G4P2.5");
  EXPECT_EQ(r.lines[6], "N6G0Z20.");    // rise first, from wherever the tool stands
  EXPECT_EQ(r.lines[7], "N7G0X5.Y5.");  // then over the approach point
  EXPECT_EQ(r.lines[8], "N8G0Z0.");     // down the axis to 1 mm above the cut's height
  std::size_t first_g1 = r.lines.size();
  for (std::size_t i = 0; i < r.lines.size() && first_g1 == r.lines.size(); ++i) {
    const std::size_t at = r.lines[i].find("G1");
    if (at != std::string::npos &&
        (at + 2 == r.lines[i].size() || !std::isdigit(r.lines[i][at + 2]))) {
      first_g1 = i;
    }
  }
  EXPECT_EQ(first_g1, 9u);
  EXPECT_EQ(r.lines[r.lines.size() - 2].substr(r.lines[r.lines.size() - 2].find('M')), "M5");
  EXPECT_EQ(r.lines.back().substr(r.lines.back().find('M')), "M2");
  // The retract: back to the axis at the cut's height, then up to the clearance plane.
  const std::string& retract = r.lines[r.lines.size() - 3];
  EXPECT_NE(retract.find("G0Z20."), std::string::npos) << retract;
  // A G0 never carries F, and F is written again after it (G1 again).
  for (std::size_t i = 0; i < r.lines.size(); ++i) {
    if (r.lines[i].find("G0") != std::string::npos) {
      EXPECT_EQ(r.lines[i].find('F'), std::string::npos) << r.lines[i];
    }
  }
  EXPECT_NE(r.lines[first_g1].find('F'), std::string::npos) << r.lines[first_g1];
  // The cut's corners are block ends (the encoder closes at a turn, rest or chord), the loop
  // closes at the start: X10 Y0 Z-1 appears as an end after the corners.
  EXPECT_NE(index_of(r.lines, "X10.Y0."), r.lines.size());
  // Rapids: the rise, over the approach point, down, up.
  EXPECT_EQ(r.stats.closed_by[static_cast<int>(BlockClose::Rapid)], 4);
  // Words: preamble, T M6, G43 H, M3, G4, M5, M2.
  EXPECT_EQ(r.stats.closed_by[static_cast<int>(BlockClose::Words)], 7);
  EXPECT_LE(r.stats.chord_error_max_mm, EncoderSettings{}.chord_tolerance_mm);
}

TEST(ProgramBlocks, NoDwellWhenNoneIsConfigured) {
  const ProgramEncoded r = encode_program(square_job(0.0));
  EXPECT_EQ(index_of(r.lines, "G4P"), r.lines.size());
  EXPECT_EQ(r.lines[5], "N5G0Z20.");
}

TEST(ProgramBlocks, FramingKnobs) {
  EncoderSettings s;
  s.numbers = false;
  s.comments = false;
  s.percent = true;
  const ProgramEncoded r = encode_program(square_job(0.0), s);
  EXPECT_EQ(r.lines.front(), "%");
  EXPECT_EQ(r.lines.back(), "%");
  EXPECT_EQ(r.lines[1], "G21G90G94G17G40G49G64P0.002");
  for (const std::string& l : r.lines) {
    EXPECT_NE(l.front(), 'N') << l;
    EXPECT_NE(l.front(), '(') << l;
  }
  EXPECT_EQ(r.lines[r.lines.size() - 2], "M2");
}

TEST(ProgramBlocks, ALineLongerThanTheControllerTakesIsAnErrorNamingIt) {
  EncoderSettings s;
  s.max_line_chars = 12;
  try {
    encode_program(square_job(0.0), s);
    FAIL() << "a 20-character line passed a 12-character limit";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("N1G21G90G94G17G40G49G64P0.002"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("12"), std::string::npos) << e.what();
  }
}

// A header longer than the dialect's line takes is split over comment lines that, joined,
// give the text back; grbl's rules set the width (apply_dialect), and grbl takes every one.
TEST(ProgramBlocks, LongCommentsAreSplitToTheDialectsWidth) {
  EncoderSettings s;
  apply_dialect(s, Dialect::grbl);
  ASSERT_EQ(s.max_comment_chars, static_cast<std::size_t>(rules(Dialect::grbl).max_line_chars));
  const toolpath::Program program = square_job(0.0);
  const toolpath::Path path = toolpath::to_path(program);
  motion::JobConfig cfg;
  cfg.cutting.pick_feed_mm = 0.0;
  motion::Job job(path, cfg);
  std::vector<std::string> lines;
  BlockEncoder enc(s, [&lines](const EncodedBlock& b) { lines.push_back(b.text); });
  ProgramBlocks blocks(program, enc, job.segment_starts_mm());
  std::string header;
  for (int i = 0; i < 30; ++i) header += "word" + std::to_string(i) + " ";
  header += std::string(150, 'x');  // no space to break at: cut at the width
  // A space just past a full piece: the piece keeps its width (the space starts the next one).
  const std::string edge = std::string(s.max_comment_chars - 2, 'a') + " bbb";
  blocks.begin({header, edge});
  blocks.end();
  std::string joined, program_text;
  for (const std::string& l : lines) {
    EXPECT_NE(l.front(), 'N') << l;
    if (l.front() != '(') continue;
    program_text += l + "\n";
    EXPECT_LE(l.size(), s.max_comment_chars) << l;
    joined += l.substr(1, l.size() - 2);
  }
  EXPECT_EQ(joined, header + edge);
  EXPECT_FALSE(check_program(Dialect::grbl, program_text).has_value()) << program_text;
}

TEST(ProgramBlocks, ClearancePlaneBelowTheCutIsRefused) {
  toolpath::Polyline cut;
  cut.points = {{0, 0, 5}, {1, 0, 5}};
  toolpath::PathSegment seg;
  seg.geometry = cut;
  toolpath::Path path;
  path.segments.push_back(seg);
  toolpath::JobFrame f;
  f.clearance_z_mm = 5.0;  // equal to the cut's height: not above it
  EXPECT_THROW(toolpath::whole_job(path, f), InputError);
}

}  // namespace
}  // namespace ncd::comms

namespace ncd::comms {
namespace {

// The chamfer job of experiment 3 (defaults of ChamferSpec): the loop in the tip as
// chamfer_program() writes it, the approach down the drill axis (X0 Y0) from options.safe_z_mm.
TEST(ChamferJob, Exp3IsTheNgcLoopWithItsApproach) {
  toolpath::ChamferSpec spec;  // R 18, r 13, R_B 3, W 0.7: paper 000's experiment 3
  const toolpath::ChamferPath path = toolpath::generate_chamfer(spec);
  toolpath::NgcOptions o;
  o.safe_z_mm = toolpath::default_safe_z_mm(spec);
  o.spindle_dwell_s = 1.0;
  o.tool = 2;
  const toolpath::Program p = toolpath::chamfer_job(path, o);
  std::vector<toolpath::Motion> moves;
  for (const auto& step : p.steps) {
    if (const auto* m = std::get_if<toolpath::Motion>(&step.item)) moves.push_back(*m);
  }
  ASSERT_GE(moves.size(), 6u);
  const Vec3 first = toolpath::program_point(spec, path.points[0], toolpath::ProgramPoint::Tip);
  EXPECT_NEAR(first.z(), path.points[0].cl.z() - 3.0, 1e-12);  // the tip: centre less R_B
  // Rapid over the axis at the clearance plane, rapid down to 1 mm above, feed down, feed out.
  EXPECT_TRUE(moves[0].rapid && !moves[0].start_known);
  EXPECT_NEAR((toolpath::motion_end(moves[0]) - Vec3(0, 0, o.safe_z_mm)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((toolpath::motion_end(moves[1]) - Vec3(0, 0, first.z() + 1.0)).norm(), 0.0, 1e-12);
  EXPECT_FALSE(moves[2].rapid);
  EXPECT_NEAR((toolpath::motion_end(moves[2]) - Vec3(0, 0, first.z())).norm(), 0.0, 1e-12);
  EXPECT_NEAR((toolpath::motion_end(moves[3]) - first).norm(), 0.0, 1e-12);
  // The loop closes at its start, then back to the axis and up.
  EXPECT_NEAR((toolpath::motion_end(moves[4]) - first).norm(), 0.0, 1e-12);
  EXPECT_NEAR((toolpath::motion_end(moves[5]) - Vec3(0, 0, first.z())).norm(), 0.0, 1e-12);
  EXPECT_TRUE(moves.back().rapid);
  EXPECT_NEAR(toolpath::motion_end(moves.back()).z(), o.safe_z_mm, 1e-12);
  // Events: G21, T2, G43 H2 (no offset of its own: the path is in the tip already), M3 at the
  // NGC's spindle speed, the dwell; M5 and M2 at the end.
  const auto& ev = [&](std::size_t i) { return std::get<toolpath::Event>(p.steps[i].item); };
  EXPECT_EQ(std::get<toolpath::ToolChangeEvent>(ev(1)).tool, 2);
  EXPECT_EQ(std::get<toolpath::ToolOffsetEvent>(ev(2)).h, 2);
  EXPECT_EQ(std::get<toolpath::ToolOffsetEvent>(ev(2)).offset.norm(), 0.0);
  EXPECT_EQ(std::get<toolpath::SpindleEvent>(ev(3)).rpm, o.spindle_rpm);
  EXPECT_EQ(std::get<toolpath::DwellEvent>(ev(4)).seconds, 1.0);
  EXPECT_EQ(std::get<toolpath::EndEvent>(ev(p.steps.size() - 1)).m, 2);
  EXPECT_EQ(std::get<toolpath::SpindleEvent>(ev(p.steps.size() - 2)).dir,
            toolpath::SpindleDir::off);
}

}  // namespace
}  // namespace ncd::comms
