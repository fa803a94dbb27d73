// The block encoder against independent checks: a brute-force distance scan of every setpoint
// to the polyline of written end points (the chord error), the sagitta of a circle, the budget
// formula of docs/block-encoder.md recomputed from the text as written, the program read back by a
// parser written here and by our G-code reader, and a random sweep over curves, tolerances,
// decimals and links.
#include "link/block_encoder.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "core/error.hpp"
#include "gcode/gcode_reader.hpp"
#include "gcode/path_io.hpp"
#include "motion/job.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"

namespace ncd::comms {
namespace {

using motion::Setpoint;

constexpr double kPeriodS = 0.004;

// A full circle of radius r in the XY plane at height z, rational quadratic NURBS.
std::string circle_json(double r, double z, double feed_mm_per_min) {
  const double w = std::sqrt(0.5);
  std::ostringstream j;
  j.precision(17);
  j << R"({"feed_mm_per_min": )" << feed_mm_per_min << R"(, "nurbs": {"degree": 2,
    "knots": [0,0,0,0.25,0.25,0.5,0.5,0.75,0.75,1,1,1], "points": [)";
  const double pts[9][2] = {{r, 0},   {r, r},  {0, r},  {-r, r}, {-r, 0},
                            {-r, -r}, {0, -r}, {r, -r}, {r, 0}};
  for (int i = 0; i < 9; ++i) {
    j << (i ? "," : "") << "[" << pts[i][0] << "," << pts[i][1] << "," << z << "]";
  }
  j << R"(], "weights": [1,)" << w << ",1," << w << ",1," << w << ",1," << w << ",1]}}";
  return j.str();
}

motion::JobConfig machine() {
  motion::JobConfig c;  // 100 mm/s, 1000 mm/s², 2e4 mm/s³, 4 ms: the defaults
  c.cutting.ball_radius_mm = 5.0;
  c.cutting.pick_feed_mm = 0.5;
  c.cutting.teeth = 4;
  c.cutting.spindle_rpm = 12000.0;
  c.cutting.roughness_target_um = 10.0;
  return c;
}

// Every setpoint of a job, the start at rest at t = 0 first (as replay pushes it).
std::vector<Setpoint> walk(const toolpath::Path& path, const motion::JobConfig& config) {
  motion::Job job(path, config);
  std::vector<Setpoint> out;
  Setpoint start;
  start.p = job.walker().position();
  out.push_back(start);
  for (;;) {
    job.prepare();
    out.push_back(job.step());
    if (out.back().done) break;
  }
  return out;
}

// Setpoints along a straight line from p0 in direction dir (unit), v(t) given, s integrated.
template <typename V>
std::vector<Setpoint> line(const Vec3& p0, const Vec3& dir, int periods, V v_of_t) {
  std::vector<Setpoint> out;
  double s = 0.0;
  for (int k = 0; k <= periods; ++k) {
    const double t = k * kPeriodS;
    if (k > 0) s += 0.5 * (v_of_t(t - kPeriodS) + v_of_t(t)) * kPeriodS;
    Setpoint sp;
    sp.t_s = t;
    sp.p = p0 + s * dir;
    sp.s_mm = s;
    sp.v_mm_per_s = v_of_t(t);
    out.push_back(sp);
  }
  return out;
}

struct Encoded {
  std::vector<EncodedBlock> blocks;
  EncoderStats stats;
};

Encoded encode(const EncoderSettings& settings, const std::vector<Setpoint>& setpoints) {
  Encoded e;
  BlockEncoder enc(settings, [&e](const EncodedBlock& b) { e.blocks.push_back(b); });
  for (const Setpoint& sp : setpoints) enc.push(sp);
  enc.finish();
  e.stats = enc.stats();
  return e;
}

EncoderSettings link(int baud, const std::string& frame = "7E2") {
  EncoderSettings s;
  s.line.baud = baud;
  parse_frame(frame, s.line);
  return s;
}

double dist_to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 == 0.0 ? 0.0 : std::clamp((p - a).dot(ab) / l2, 0.0, 1.0);
  return (a + t * ab - p).norm();
}

// One block as parsed here from its text, modal state carried.
struct Parsed {
  long n = -1;
  Vec3 p = Vec3::Zero();
  double f = 0.0;  // modal feed after the block
  bool g0 = false, g1 = false, has_f = false;
};

// A minimal parser of the encoder's dialect: letters followed by numbers, nothing else.
std::vector<Parsed> parse(const std::vector<EncodedBlock>& blocks) {
  std::vector<Parsed> out;
  Parsed state;
  for (const EncodedBlock& b : blocks) {
    Parsed cur = state;
    cur.n = -1;
    cur.g0 = cur.g1 = cur.has_f = false;
    const std::string& t = b.text;
    std::size_t i = 0;
    while (i < t.size()) {
      const char letter = t[i++];
      const std::size_t j0 = i;
      while (i < t.size() &&
             (std::isdigit(static_cast<unsigned char>(t[i])) || t[i] == '.' || t[i] == '-')) {
        ++i;
      }
      EXPECT_GT(i, j0) << "word without a number in " << t;
      const std::string num = t.substr(j0, i - j0);
      if (letter != 'N' && letter != 'G') {
        EXPECT_NE(num.find('.'), std::string::npos) << "no decimal point in " << t;
      }
      const double v = std::stod(num);
      switch (letter) {
        case 'N':
          cur.n = std::stol(num);
          break;
        case 'G':
          if (num == "0") cur.g0 = true;
          if (num == "1") cur.g1 = true;
          break;
        case 'X':
          cur.p.x() = v;
          break;
        case 'Y':
          cur.p.y() = v;
          break;
        case 'Z':
          cur.p.z() = v;
          break;
        case 'F':
          cur.f = v;
          cur.has_f = true;
          break;
        default:
          ADD_FAILURE() << "unexpected letter " << letter << " in " << t;
      }
    }
    out.push_back(cur);
    state = cur;
  }
  return out;
}

// Largest distance of any setpoint from the polyline through the written end points, by brute
// force over every segment.
double brute_force_chord_error(const std::vector<Setpoint>& sps,
                               const std::vector<EncodedBlock>& blocks) {
  double worst = 0.0;
  for (const Setpoint& sp : sps) {
    double best = std::numeric_limits<double>::infinity();
    if (blocks.size() == 1) best = (sp.p - blocks[0].end).norm();
    for (std::size_t i = 1; i < blocks.size(); ++i) {
      best = std::min(best, dist_to_segment(sp.p, blocks[i - 1].end, blocks[i].end));
    }
    worst = std::max(worst, best);
  }
  return worst;
}

// The properties every encoding has: numbers, text against the block's fields, the chord
// error by brute force, the feed's time, the link's budget where the feed was lowered.
void check_program(const EncoderSettings& s, const std::vector<Setpoint>& sps, const Encoded& e) {
  ASSERT_FALSE(e.blocks.empty());
  const std::vector<Parsed> parsed = parse(e.blocks);
  const int bits = bits_per_char(s.line);
  const double eob = s.line.eob == EndOfBlock::CrLf ? 2.0 : 1.0;
  EXPECT_TRUE(parsed[0].g0);
  double planned_total = 0.0, written_total = 0.0, max_unit_s = 0.0;
  for (std::size_t i = 0; i < e.blocks.size(); ++i) {
    const EncodedBlock& b = e.blocks[i];
    const Parsed& p = parsed[i];
    EXPECT_EQ(p.n, s.number_start + static_cast<long>(i) * s.number_step) << b.text;
    EXPECT_EQ(b.number, p.n);
    EXPECT_EQ((p.p - b.end).norm(), 0.0) << b.text;
    EXPECT_EQ(b.chars, static_cast<int>(b.text.size() + static_cast<std::size_t>(eob)));
    if (i == 0) continue;
    EXPECT_FALSE(b.positioning);
    EXPECT_EQ(p.g1, i == 1) << b.text;
    // The move as written, from the text alone.
    const double length = (p.p - parsed[i - 1].p).norm();
    EXPECT_GT(length, 0.0) << b.text;
    EXPECT_NEAR(length, b.length_mm, 1e-12);
    EXPECT_EQ(p.f, b.feed_mm_per_min) << b.text;
    const double duration = length / p.f * 60.0;
    EXPECT_NEAR(duration, b.duration_s, 1e-9 * std::max(1.0, duration));
    EXPECT_LE(b.chord_error_mm, s.chord_tolerance_mm * (1 + 1e-12));
    const double f_max = length * s.line.baud * s.link_margin * 60.0 / (b.chars * bits);
    EXPECT_LE(p.f, f_max * (1 + 1e-12)) << "the link cannot carry " << b.text;
    if (b.feed_lowered) {
      // Exactly the formula: no feed on the grid above the one written, up to the planned
      // one, fits the budget with the F word it would be written with (none if modal).
      EXPECT_LT(p.f, b.planned_feed_mm_per_min) << b.text;
      const double unit = std::pow(10.0, -s.feed_decimals);
      const std::size_t f_at = b.text.find('F');
      const std::size_t base =
          (f_at == std::string::npos ? b.text.size() : f_at) + static_cast<std::size_t>(eob);
      const auto written = std::llround(p.f / unit);
      const auto planned = std::llround(b.planned_feed_mm_per_min / unit);
      const auto modal = std::llround(parsed[i - 1].f / unit);
      for (auto u = written + 1; u < std::min(planned, written + 3000); ++u) {
        const double feed = static_cast<double>(u) * unit;
        std::string word;
        if (u != modal || i == 1) {
          std::ostringstream w;
          w.precision(s.feed_decimals);
          w << std::fixed << feed;
          word = "F" + w.str();
          while (word.back() == '0' && word.find('.') != std::string::npos) word.pop_back();
        }
        const double chars = static_cast<double>(base + word.size());
        ASSERT_GT(feed, length * s.line.baud * s.link_margin * 60.0 / (chars * bits))
            << b.text << ": " << word << " would fit the link";
      }
    } else {
      planned_total += b.planned_duration_s;
      written_total += duration;
      // The controller's time stays within the time tolerance of the plan, give or take what
      // one unit of F changes in one block (the rounding is directed back toward the plan,
      // unless the link forbids rounding up).
      const double unit_s = std::pow(10.0, -s.feed_decimals) / p.f * duration;
      max_unit_s = std::max(max_unit_s, unit_s);
      EXPECT_LE(std::abs(written_total - planned_total), s.time_tolerance_s + max_unit_s + 1e-9)
          << b.text;
    }
  }
  const double brute = brute_force_chord_error(sps, e.blocks);
  EXPECT_LE(brute, s.chord_tolerance_mm * (1 + 1e-12));
  EXPECT_LE(brute, e.stats.chord_error_max_mm + 1e-12);  // per block ≥ to the whole polyline
  EXPECT_EQ(e.stats.blocks, static_cast<std::int64_t>(e.blocks.size()));
  EXPECT_EQ(e.stats.setpoints, static_cast<std::int64_t>(sps.size()));
}

// The program as `ncd replay --blocks` writes it, read back by toolpath/gcode_reader.
toolpath::Path read_back(const std::vector<EncodedBlock>& blocks) {
  std::string text;
  for (const EncodedBlock& b : blocks) text += b.text + "\n";
  std::istringstream in(text);
  return toolpath::read_gcode(in, "encoded.ngc");
}

TEST(BlockEncoder, StraightLineAtConstantFeedFillsTheCap) {
  EncoderSettings s = link(115200, "8N1");
  s.max_setpoints_per_block = 1000;
  const Vec3 dir = Vec3(3, 4, 12).normalized();
  const auto sps = line(Vec3(1, 2, 3), dir, 2500, [](double) { return 20.0; });
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);
  // 2500 periods: the cap closes two blocks of 1000 setpoints, the end a third of 500.
  ASSERT_EQ(e.blocks.size(), 4u);
  EXPECT_EQ(e.stats.closed_by[static_cast<int>(BlockClose::Cap)], 2);
  EXPECT_EQ(e.stats.closed_by[static_cast<int>(BlockClose::End)], 1);
  EXPECT_EQ(e.blocks[1].setpoints, 1000u);
  EXPECT_NEAR(e.blocks[1].length_mm, 20.0 * 4.0, 2e-3);
  EXPECT_NEAR(e.blocks[3].length_mm, 20.0 * 2.0, 2e-3);
  // F once, then modal.
  EXPECT_NE(e.blocks[1].text.find("F1200."), std::string::npos) << e.blocks[1].text;
  EXPECT_EQ(e.blocks[2].text.find('F'), std::string::npos) << e.blocks[2].text;
  EXPECT_EQ(e.stats.lowered_blocks, 0);
  EXPECT_LE(e.stats.chord_error_max_mm, rounding_error_mm(3) * 2);
}

TEST(BlockEncoder, ALongestBlockBoundsWhatALiveStreamWaitsFor) {
  EncoderSettings s = link(115200, "8N1");
  s.max_block_s = 0.5;
  const auto sps = line(Vec3::Zero(), Vec3::UnitZ(), 1000, [](double) { return 20.0; });
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);
  ASSERT_EQ(e.blocks.size(), 9u);  // 4 s in blocks of 0.5 s
  for (std::size_t i = 1; i < e.blocks.size(); ++i) {
    EXPECT_NEAR(e.blocks[i].planned_duration_s, 0.5, 1e-9) << e.blocks[i].text;
  }
  EXPECT_EQ(e.stats.closed_by[static_cast<int>(BlockClose::Duration)], 7);
  s.max_block_s = -1.0;
  EXPECT_THROW(BlockEncoder(s, [](const EncodedBlock&) {}), InputError);
}

TEST(BlockEncoder, CircleBlocksKeepTheirSagittaWithinTheTolerance) {
  const double r = 10.0;
  const toolpath::Path path = toolpath::read_path_text(circle_json(r, 1.0, 1200.0), "circle");
  const auto sps = walk(path, machine());
  for (const double tol : {0.001, 0.002, 0.01}) {
    SCOPED_TRACE("tolerance " + std::to_string(tol));
    EncoderSettings s = link(115200, "8N1");
    s.chord_tolerance_mm = tol;
    const Encoded e = encode(s, sps);
    check_program(s, sps, e);
    const double rho = rounding_error_mm(s.decimals);
    std::vector<double> sagitta;
    for (std::size_t i = 1; i < e.blocks.size(); ++i) {
      const EncodedBlock& b = e.blocks[i];
      const double sag = b.length_mm * b.length_mm / (8.0 * r);
      // The setpoint nearest the middle of the arc is at most half a period from it.
      const double half_step = 0.5 * 20.0 * kPeriodS;
      EXPECT_LE(sag, tol + rho + half_step * half_step / (2.0 * r)) << b.text;
      if (b.closed_by == BlockClose::Chord) sagitta.push_back(sag);
    }
    // The tolerance is used: a block closed by the chord test bends nearly as far as allowed.
    ASSERT_FALSE(sagitta.empty());
    std::sort(sagitta.begin(), sagitta.end());
    EXPECT_GE(sagitta[sagitta.size() / 2], 0.5 * (tol - rho));
  }
}

TEST(BlockEncoder, RoundingOfTheEndPointsCountsAsChordError) {
  // A straight line 0.49 µm off the µm grid in Y and Z: the written program is a straight
  // line on the grid, 0.69 µm from every setpoint.
  EncoderSettings s = link(115200, "8N1");
  s.chord_tolerance_mm = 0.001;
  const auto sps = line(Vec3(0, 0.00049, 0.00049), Vec3::UnitX(), 500, [](double) { return 10.0; });
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);
  EXPECT_NEAR(e.stats.chord_error_max_mm, 0.00049 * std::sqrt(2.0), 1e-9);
  EXPECT_EQ(e.blocks.size(), 2u);  // one move: the line lies within the tolerance
  // Below the rounding error the tolerance cannot be met: refused, with the way out.
  s.chord_tolerance_mm = 0.0008;
  try {
    BlockEncoder enc(s, [](const EncodedBlock&) {});
    FAIL() << "a tolerance below the rounding error was accepted";
  } catch (const InputError& err) {
    const std::string m = err.what();
    EXPECT_NE(m.find("rounding error"), std::string::npos) << m;
    EXPECT_NE(m.find("0.000866"), std::string::npos) << m;
    EXPECT_NE(m.find("more decimals"), std::string::npos) << m;
  }
  // With one more decimal it is fine again, and every point within it.
  s.decimals = 4;
  const Encoded e4 = encode(s, sps);
  check_program(s, sps, e4);
  EXPECT_LE(e4.stats.chord_error_max_mm, 0.0008);
}

TEST(BlockEncoder, TheFeedBandSplitsARamp) {
  // 10 → 100 mm/s in 1 s on a straight line: blocks of their own F, each within the band.
  EncoderSettings s = link(115200, "8N1");
  const auto ramp = [](double t) { return 10.0 + 90.0 * std::min(t, 1.0); };
  const auto sps = line(Vec3::Zero(), Vec3::UnitX(), 250, ramp);
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);
  // v grows by a factor of 10: about ln 10 / ln(1.05/0.95) ≈ 23 blocks.
  EXPECT_GE(e.blocks.size(), 15u);
  EXPECT_LE(e.blocks.size(), 40u);
  EXPECT_EQ(e.stats.band_waived, 0);
  for (std::size_t i = 1; i < e.blocks.size(); ++i) {
    const EncodedBlock& b = e.blocks[i];
    const double mean = (b.end_s_mm - b.start_s_mm) / (b.end_t_s - b.start_t_s);
    EXPECT_LE(ramp(b.end_t_s), 1.05 * mean + 1e-9) << b.text;
    EXPECT_GE(ramp(b.start_t_s), 0.95 * mean - 1e-9) << b.text;
    if (i > 1) {
      EXPECT_GT(b.feed_mm_per_min, e.blocks[i - 1].feed_mm_per_min) << b.text;
    }
  }
  // A wider band, fewer blocks.
  s.feed_band = 0.3;
  EXPECT_LT(encode(s, sps).blocks.size(), e.blocks.size() / 2);
}

TEST(BlockEncoder, ASlowLinkLowersTheFeedExactlyToTheBudgetAndSaysWhere) {
  const double r = 10.0;
  const toolpath::Path path = toolpath::read_path_text(circle_json(r, 0.0, 600.0), "circle");
  const auto sps = walk(path, machine());
  const EncoderSettings s = link(1200);  // 7E2: 109 chars/s
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);  // checks every lowered F against the formula
  EXPECT_GT(e.stats.lowered_blocks, e.stats.motion_blocks / 2);
  ASSERT_GE(e.stats.lowered_ranges, 1);
  ASSERT_EQ(e.stats.lowered.size(), static_cast<std::size_t>(e.stats.lowered_ranges));
  const LoweredRange& range = e.stats.lowered.front();
  EXPECT_LE(range.first_block, range.last_block);
  EXPECT_LT(range.s_from_mm, range.s_to_mm);
  EXPECT_LT(range.lowered_feed_min_mm_per_min, range.planned_feed_mm_per_min);
  EXPECT_NE(range.reason.find("chord tolerance of 0.002 mm"), std::string::npos) << range.reason;
  EXPECT_NE(range.reason.find("1200 7E2"), std::string::npos) << range.reason;
  // The ranges cover exactly the lowered blocks, consecutive ones collapsed.
  std::int64_t in_ranges = 0;
  for (const LoweredRange& lr : e.stats.lowered) in_ranges += lr.blocks;
  EXPECT_EQ(in_ranges, e.stats.lowered_blocks);
  for (std::size_t i = 0; i + 1 < e.stats.lowered.size(); ++i) {
    EXPECT_GT(e.stats.lowered[i + 1].first_block, e.stats.lowered[i].last_block + 1);
  }
  for (const EncodedBlock& b : e.blocks) {
    if (!b.feed_lowered) continue;
    const bool covered =
        std::any_of(e.stats.lowered.begin(), e.stats.lowered.end(), [&](const LoweredRange& lr) {
          return lr.first_block <= b.number && b.number <= lr.last_block;
        });
    EXPECT_TRUE(covered) << b.text;
  }
  // The link now keeps up: the controller never waits while moving, at ≤ 80 % of the line.
  EXPECT_EQ(e.stats.queue.underruns, 0);
  EXPECT_LE(e.stats.link_use_peak, s.link_margin * (1 + 1e-12));
  EXPECT_GT(e.stats.duration_s, e.stats.planned_duration_s);
}

TEST(BlockEncoder, AFastLinkLowersNothing) {
  const toolpath::Path path = toolpath::read_path_text(circle_json(10.0, 0.0, 600.0), "circle");
  const auto sps = walk(path, machine());
  const EncoderSettings s = link(115200, "8N1");
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);
  EXPECT_EQ(e.stats.lowered_blocks, 0);
  EXPECT_EQ(e.stats.lowered_ranges, 0);
  EXPECT_EQ(e.stats.queue.underruns, 0);
  EXPECT_NEAR(e.stats.duration_s, e.stats.planned_duration_s, s.time_tolerance_s + 1e-3);
  // The whole run's time, as written, is the interpolator's to within the time tolerance.
  EXPECT_NEAR(e.stats.planned_duration_s + e.stats.unwritten_tail_s, sps.back().t_s, 1e-9);
}

TEST(BlockEncoder, ALinkTooSlowForTheLowestFeedStarvesTheController) {
  // A 1 mm circle at 60 mm/min over 300 baud, written to 10 nm with whole mm/min: a block of
  // one 4 µm setpoint takes longer to send than to run even at F1., the lowest feed written.
  // The encoder says so, and the queue model predicts the dwells.
  const toolpath::Path path = toolpath::read_path_text(circle_json(0.5, 0.0, 60.0), "circle");
  const auto sps = walk(path, machine());
  EncoderSettings s = link(300);
  s.decimals = 5;
  s.feed_decimals = 0;
  s.chord_tolerance_mm = 0.00001;
  const Encoded e = encode(s, sps);
  EXPECT_GT(e.stats.over_budget_blocks, e.stats.motion_blocks / 2);
  EXPECT_GT(e.stats.link_use_peak, 1.0);
  EXPECT_GT(e.stats.queue.underruns, 0);
  EXPECT_GT(e.stats.queue.first_underrun_block, 0);
  EXPECT_GT(e.stats.queue.underrun_time_s, 0.0);
  EXPECT_LE(brute_force_chord_error(sps, e.blocks), s.chord_tolerance_mm);
}

TEST(BlockEncoder, NumbersStartAndStepAsSet) {
  EncoderSettings s = link(19200);
  s.number_start = 100;
  s.number_step = 10;
  s.max_setpoints_per_block = 50;
  const auto sps = line(Vec3::Zero(), Vec3::UnitY(), 400, [](double) { return 5.0; });
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);  // N = start + i·step on every block
  EXPECT_EQ(e.blocks.front().text.rfind("N100G21G90G94G0X0.Y0.Z0.", 0), 0u)
      << e.blocks.front().text;
  EXPECT_EQ(e.stats.first_number, 100);
  EXPECT_EQ(e.stats.last_number, 100 + 10 * (static_cast<long>(e.blocks.size()) - 1));
}

TEST(BlockEncoder, TheProgramReadsBackInOurGcodeReader) {
  const toolpath::Path path = toolpath::read_path_text(circle_json(10.0, -2.5, 900.0), "circle");
  const auto sps = walk(path, machine());
  const EncoderSettings s = link(19200);
  const Encoded e = encode(s, sps);
  check_program(s, sps, e);
  const toolpath::Path back = read_back(e.blocks);
  // The G0 only sets the position; every G1 is a vertex, a new segment where F changes.
  std::vector<Vec3> vertices;
  std::vector<double> feeds;
  for (const toolpath::PathSegment& seg : back.segments) {
    const auto* pl = std::get_if<toolpath::Polyline>(&seg.geometry);
    ASSERT_NE(pl, nullptr);
    ASSERT_TRUE(seg.feed_mm_per_min.has_value());
    EXPECT_FALSE(seg.rapid);
    if (vertices.empty()) vertices.push_back(pl->points.front());
    EXPECT_EQ(vertices.back(), pl->points.front());
    for (std::size_t i = 1; i < pl->points.size(); ++i) {
      vertices.push_back(pl->points[i]);
      feeds.push_back(*seg.feed_mm_per_min);
    }
  }
  ASSERT_EQ(vertices.size(), e.blocks.size());
  for (std::size_t i = 0; i < e.blocks.size(); ++i) {
    EXPECT_EQ(vertices[i], e.blocks[i].end) << e.blocks[i].text;
    if (i > 0) {
      EXPECT_EQ(feeds[i - 1], e.blocks[i].feed_mm_per_min) << e.blocks[i].text;
    }
  }
}

TEST(BlockEncoder, DegenerateInputs) {
  const EncoderSettings s = link(19200);
  // No setpoint: nothing.
  EXPECT_TRUE(encode(s, {}).blocks.empty());
  // One setpoint: the positioning block only.
  Setpoint one;
  one.p = Vec3(1.23456, -0.0004, 7.0);
  Encoded e = encode(s, {one});
  ASSERT_EQ(e.blocks.size(), 1u);
  EXPECT_EQ(e.blocks[0].text, "N1G21G90G94G0X1.235Y0.Z7.");
  EXPECT_TRUE(e.blocks[0].positioning);
  // A path of no length (the machine stands for a second): nothing to move.
  std::vector<Setpoint> still = line(one.p, Vec3::UnitX(), 250, [](double) { return 0.0; });
  e = encode(s, still);
  EXPECT_EQ(e.blocks.size(), 1u);
  EXPECT_EQ(e.stats.motion_blocks, 0);
  EXPECT_LE(e.stats.chord_error_max_mm, rounding_error_mm(3));
  // A stop in the middle of a line (repeated points): the standstill's time goes into the
  // block that carries on, whose F is lower by as much; nothing is lost.
  std::vector<Setpoint> stop = line(Vec3::Zero(), Vec3::UnitX(), 100, [](double) { return 10.0; });
  for (int k = 1; k <= 300; ++k) {
    Setpoint sp = stop.back();
    sp.t_s += kPeriodS;
    sp.v_mm_per_s = 0.0;
    stop.push_back(sp);
  }
  {
    const auto more = line(stop.back().p, Vec3::UnitX(), 100, [](double) { return 10.0; });
    for (std::size_t k = 1; k < more.size(); ++k) {
      Setpoint sp = more[k];
      sp.t_s += stop.back().t_s - more[k - 1].t_s;
      sp.s_mm += stop.back().s_mm - more[k - 1].s_mm;
      stop.push_back(sp);
    }
  }
  EncoderSettings cap = s;
  cap.max_setpoints_per_block = 64;  // the standstill outlasts the buffer
  e = encode(cap, stop);
  check_program(cap, stop, e);
  EXPECT_NEAR(e.stats.planned_duration_s + e.stats.unwritten_tail_s, stop.back().t_s, 1e-9);
  EXPECT_NEAR(e.stats.duration_s, stop.back().t_s, cap.time_tolerance_s + 0.01);
  // A reversal (a cusp): the block ends at the turning point.
  std::vector<Setpoint> back = line(Vec3::Zero(), Vec3::UnitX(), 100, [](double) { return 10.0; });
  const Vec3 turn = back.back().p;
  for (int k = 1; k <= 100; ++k) {
    Setpoint sp = back.back();
    sp.t_s += kPeriodS;
    sp.s_mm += 10.0 * kPeriodS;
    sp.p = turn - Vec3::UnitX() * 10.0 * kPeriodS * k;
    back.push_back(sp);
  }
  e = encode(s, back);
  check_program(s, back, e);
  ASSERT_EQ(e.blocks.size(), 3u);
  EXPECT_EQ(e.blocks[1].closed_by, BlockClose::Turn);
  EXPECT_EQ(e.blocks[1].end, Vec3(4, 0, 0));
  EXPECT_EQ(e.blocks[2].end, Vec3(0, 0, 0));
}

TEST(BlockEncoder, BadInputsAreRefused) {
  EncoderSettings s = link(19200);
  {
    BlockEncoder enc(s, [](const EncodedBlock&) {});
    Setpoint a;
    a.t_s = 1.0;
    enc.push(a);
    Setpoint b = a;  // the same time again
    EXPECT_THROW(enc.push(b), InputError);
    b.t_s = 2.0;
    b.p.x() = std::nan("");
    EXPECT_THROW(enc.push(b), InputError);
    enc.finish();
    enc.finish();  // idempotent
    b.p.x() = 1.0;
    EXPECT_THROW(enc.push(b), std::logic_error);
  }
  const auto refused = [](EncoderSettings bad, const std::string& what) {
    try {
      BlockEncoder enc(bad, [](const EncodedBlock&) {});
      ADD_FAILURE() << what << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  EncoderSettings b = s;
  b.feed_band = 0.0;
  refused(b, "feed_band");
  b = s;
  b.link_margin = 1.5;
  refused(b, "link_margin");
  b = s;
  b.decimals = 9;
  refused(b, "decimals");
  b = s;
  b.number_step = 0;
  refused(b, "number_step");
  b = s;
  b.max_setpoints_per_block = 1;
  refused(b, "max_setpoints_per_block");
  b = s;
  b.line.baud = 12345;
  refused(b, "baud 12345");
  b = s;
  b.chord_tolerance_mm = std::nan("");
  refused(b, "chord_tolerance_mm");
}

// Random curves (cubic NURBS in a box), tolerances from the rounding error up, 2 to 4
// decimals, links from 2400 to 115200 baud: every property of check_program holds.
TEST(BlockEncoder, RandomSweep) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const int bauds[] = {2400, 9600, 19200, 115200};
  for (int round = 0; round < ncd::test::sweep_cases(8); ++round) {  // one under ASan
    std::ostringstream j;
    j.precision(17);
    const int n = 6 + static_cast<int>(u(rng) * 5);
    j << R"({"feed_mm_per_min": )" << 300.0 + 3000.0 * u(rng)
      << R"(, "nurbs": {"degree": 3, "knots": [0,0,0,0)";
    for (int k = 1; k <= n - 4; ++k) j << "," << static_cast<double>(k) / (n - 3);
    j << R"(,1,1,1,1], "points": [)";
    for (int k = 0; k < n; ++k) {
      j << (k ? "," : "") << "[" << 10.0 * k + 5.0 * u(rng) << "," << 20.0 * u(rng) - 10.0 << ","
        << 4.0 * u(rng) << "]";
    }
    j << "]}}";
    const toolpath::Path path = toolpath::read_path_text(j.str(), "random");
    const auto sps = walk(path, machine());
    EncoderSettings s = link(bauds[static_cast<int>(u(rng) * 4) % 4], u(rng) < 0.5 ? "7E2" : "8N1");
    s.decimals = 2 + static_cast<int>(u(rng) * 3) % 3;
    s.chord_tolerance_mm = rounding_error_mm(s.decimals) * (1.0 + 20.0 * u(rng) * u(rng));
    s.feed_band = 0.02 + 0.2 * u(rng);
    s.max_setpoints_per_block = 16 + static_cast<std::size_t>(u(rng) * 2000);
    SCOPED_TRACE("round " + std::to_string(round) + ": baud " + std::to_string(s.line.baud) +
                 ", decimals " + std::to_string(s.decimals) + ", tolerance " +
                 std::to_string(s.chord_tolerance_mm) + "\n" + j.str());
    const Encoded e = encode(s, sps);
    check_program(s, sps, e);
    const toolpath::Path back = read_back(e.blocks);
    EXPECT_FALSE(back.segments.empty());
  }
}

}  // namespace
}  // namespace ncd::comms
