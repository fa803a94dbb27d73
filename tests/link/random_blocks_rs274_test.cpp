// The planner's random programs (tests/common/random_program.hpp, the generator of the motion
// suite's Property test; seed pinned and printed, NCD_TEST_SEED runs another) walked and written as
// blocks by the block encoder, as `ncd replay --blocks` writes them (the modal preamble, the
// positioning block, the G1 blocks, M2), then read back by LinuxCNC's `rs274 -g`
// (docs/whole-program.md, "Checked by rs274"). Every program must parse with no error and no
// warning and reach PROGRAM_END, and every canonical end point must lie within the encoder's
// chord tolerance (plus rs274's 4-decimal print) of the polyline of the setpoints the planner
// emitted, in the order the plan reached them: a block ends at a setpoint, or at the turning
// point of a cusp between two, rounded to the encoder's decimals. The end points are matched
// walking forward along the polyline's segments, each from the segment where the last one
// matched; its distance is that of the nearest segment of the stretch within the tolerance.
// The programs mix reversals, zero-length and 1 µm moves, dense runs of 0.01 mm, NURBS of degree
// 1–5, rapids, exact stops and blends. Without /usr/bin/rs274 (linuxcnc-uspace) it is skipped.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "link/block_encoder.hpp"
#include "motion/job.hpp"
#include "tests/common/random_program.hpp"
#include "tests/common/rs274.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"
#include "tests/common/temp_dir.hpp"

namespace ncd::comms {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

double distance_to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

// The machine of the Property suite: single pass, a roughness target that never binds.
motion::JobConfig random_machine() {
  motion::JobConfig c;
  c.cutting.pick_feed_mm = 0.0;
  c.cutting.roughness_target_um = 1000.0;
  return c;
}

TEST(RandomBlocksRs274, EveryProgramParsesAndEndsOnThePlannedSetpoints) {
  if (!fs::exists(test::kRs274)) GTEST_SKIP() << test::kRs274 << " not installed";
  // The suite pins a seed (NCD_TEST_SEED runs another): over random seeds the largest distance
  // came within 0.08 µm of the tolerance (0.00201 mm), closer than the rounding alone explains
  // (docs/whole-program.md), so a fresh seed each run could make CI flaky.
  const std::uint64_t seed = test::seed(2594859229u);
  const int programs = test::sweep_cases(40);
  test::TempDir dir("ncd_random_rs274_");
  test::RandomProgram gen{std::mt19937_64(seed)};
  const motion::JobConfig cfg = random_machine();
  EncoderSettings enc;  // chord tolerance 2 µm, 3 decimals: the machine file's defaults
  // A point printed with 4 decimals is within half a unit of the last digit on each axis.
  const double tolerance_mm = enc.chord_tolerance_mm + std::sqrt(3.0) * 5e-5 + 1e-9;
  double worst_mm = 0.0;
  long moves = 0, blocks = 0;
  for (int i = 0; i < programs; ++i) {
    SCOPED_TRACE("program " + std::to_string(i) + " of seed " + std::to_string(seed));
    gen.at = Vec3::Zero();
    gen.heading = Vec3::UnitX();
    gen.max_feed_mm_per_min = 0.0;
    const toolpath::Path path = gen.program();
    motion::Job job(path, cfg);
    std::string text;
    long written = 0;
    BlockEncoder e(enc, [&](const EncodedBlock& b) {
      text += b.text + "\n";
      ++written;
    });
    std::vector<Vec3> sp;
    e.words("G21G90G94G17G40G49");
    motion::Setpoint start;
    start.p = job.walker().position();
    e.push(start);
    sp.push_back(start.p);
    for (long k = 0;; ++k) {
      ASSERT_LT(k, 10'000'000) << "the walk does not end";
      job.prepare();
      const motion::Setpoint s = job.step();
      ASSERT_EQ(s.fault, motion::StepFault::None) << job.fault_message();
      e.push(s);
      sp.push_back(s.p);
      if (s.done) break;
    }
    e.words("M2");
    e.finish();
    blocks += written;
    const fs::path ngc = dir / ("p" + std::to_string(i) + ".ngc");
    const fs::path out = dir / "canon.out", log = dir / "canon.log";
    std::ofstream(ngc, std::ios::binary) << text;
    const std::string cmd =
        test::rs274_command(dir.path(), "-g " + ngc.string() + " " + out.string()) + " >" +
        log.string() + " 2>&1";
    const int raw = std::system(cmd.c_str());
    const std::string canon = slurp(out), said = slurp(log);
    ASSERT_TRUE(WIFEXITED(raw) && WEXITSTATUS(raw) == 0) << said << "\n" << ngc;
    ASSERT_EQ(test::rs274_complaint(said), "") << said;
    ASSERT_EQ(test::rs274_complaint(canon), "");
    const test::CanonicalMoves c = test::canonical_moves(canon);
    ASSERT_TRUE(c.program_end) << "no PROGRAM_END";
    ASSERT_GE(c.end.size(), 2u);
    // Walk forward: each canonical end point on the first segment from the last match on that
    // lies within the tolerance (the true one lies at or after it, so none is ever skipped).
    // Segment j joins setpoints j and j + 1 (a single setpoint: the point itself).
    const std::size_t segments = sp.size() > 1 ? sp.size() - 1 : 1;
    const auto seg = [&](std::size_t j, const Vec3& q) {
      return distance_to_segment(q, sp[j], sp[std::min(j + 1, sp.size() - 1)]);
    };
    std::size_t k = 0;
    for (std::size_t m = 0; m < c.end.size(); ++m) {
      const Vec3 q(c.end[m][0], c.end[m][1], c.end[m][2]);
      std::size_t j = k;
      double nearest = std::numeric_limits<double>::infinity();
      while (j < segments) {
        const double d = seg(j, q);
        nearest = std::min(nearest, d);
        if (d <= tolerance_mm) break;
        ++j;
      }
      ASSERT_LT(j, segments) << "canonical move " << m + 1 << " ends at (" << q.transpose()
                             << ") mm, " << nearest
                             << " mm from the setpoints' polyline after the last match";
      // Its distance: the nearest segment of the stretch within the tolerance from there.
      double d = seg(j, q);
      for (std::size_t t = j + 1; t < segments && seg(t, q) <= tolerance_mm; ++t) {
        d = std::min(d, seg(t, q));
      }
      worst_mm = std::max(worst_mm, d);
      k = j;
    }
    moves += static_cast<long>(c.end.size());
  }
  std::printf(
      "[ measured ] %d random programs, %ld blocks, %ld canonical moves: all parsed by rs274 "
      "with no error or warning; largest distance of an end point from the setpoints' polyline "
      "%.5f mm "
      "(tolerance %.5f mm, rounding to 3 decimals %.5f mm)\n",
      programs, blocks, moves, worst_mm, tolerance_mm, rounding_error_mm(enc.decimals));
}

}  // namespace
}  // namespace ncd::comms
