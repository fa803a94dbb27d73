// Choi's roughness model against the check values of docs/feedrate.md §1.3 (re-derived from the
// paper's figures), its inverse against the forward law over random inputs, and the input
// errors that must never be clamped.
#include "feed/roughness.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <random>

#include "core/error.hpp"
#include "tests/common/seed.hpp"

namespace ncd::feed {
namespace {

constexpr double kR = 5.0;   // ball radius, mm
constexpr double kFp = 0.5;  // pick feed, mm
constexpr double kFt = 0.5;  // feed per tooth, mm

std::string message_of(const CuttingParams& p) {
  try {
    validate(p);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// --- check values, docs/feedrate.md §1.3 -----------------------------------------------------

TEST(ChoiCheckValues, OutsideDeadCentreIs10_67um) {
  const double um = roughness_mm(kR, kFp, kFt, deg_to_rad(10.0)) * 1e3;
  EXPECT_NEAR(um, 10.67, 0.005);  // paper: 10.7 µm (Fig. 13, α = 10°)
  EXPECT_EQ(um, roughness_outside_mm(kR, kFp, kFt) * 1e3);
}

TEST(ChoiCheckValues, AtZeroInclinationIs25_06um) {
  const double um = roughness_mm(kR, kFp, kFt, 0.0) * 1e3;
  EXPECT_NEAR(um, 25.06, 0.005);  // paper: 24.9 µm simulated (Fig. 14)
  EXPECT_EQ(um, roughness_dead_centre_mm(kR, kFt, 0.0) * 1e3);
}

TEST(ChoiCheckValues, CriticalAngleIs4_34deg) {
  const auto alpha_c = critical_angle_rad(kR, kFp, kFt);
  ASSERT_TRUE(alpha_c.has_value());
  EXPECT_NEAR(rad_to_deg(*alpha_c), 4.34, 0.005);  // paper: 4.3°
  // The branches meet there.
  EXPECT_NEAR(roughness_dead_centre_mm(kR, kFt, *alpha_c), roughness_outside_mm(kR, kFp, kFt),
              1e-15);
}

TEST(ChoiCheckValues, FeedRatioAtZeroInclinationIs0_654) {
  // The table's 0.654 is reproduced from the paper's printed target, 10.7 µm; the model's own
  // unrounded 10.669 µm gives 0.6529. Both round to the paper's "65 %" (Figs. 12, 15).
  EXPECT_NEAR(feed_per_tooth_mm(kR, kFp, 10.7e-3, 0.0) / kFp, 0.654, 0.0005);
  const double model_target_mm = roughness_outside_mm(kR, kFp, kFt);
  EXPECT_NEAR(feed_per_tooth_mm(kR, kFp, model_target_mm, 0.0) / kFp, 0.653, 0.0005);
  EXPECT_NEAR(feed_per_tooth_mm(kR, kFp, model_target_mm, 0.0) / kFp, 0.65, 0.005);
  // Outside the zone the same target allows the full feed back.
  EXPECT_NEAR(feed_per_tooth_mm(kR, kFp, model_target_mm, deg_to_rad(10.0)), kFt, 1e-14);
}

TEST(ChoiCheckValues, NoCriticalAngleBelowAbout0_53PickFeed) {
  // Paper: α_c exists from f_t ≈ 0.53 f_p (0.27 mm/tooth at f_p = 0.5 mm).
  EXPECT_FALSE(critical_angle_rad(kR, kFp, 0.52 * kFp).has_value());
  EXPECT_TRUE(critical_angle_rad(kR, kFp, 0.54 * kFp).has_value());
  // There eq. 2 governs even at α = 0 (α_c = 0 would wrongly pick eq. 3).
  const double ft = 0.4 * kFp;
  EXPECT_GT(roughness_outside_mm(kR, kFp, ft), roughness_dead_centre_mm(kR, ft, 0.0));
  EXPECT_EQ(roughness_mm(kR, kFp, ft, 0.0), roughness_outside_mm(kR, kFp, ft));
}

TEST(ChoiModel, SinglePassIsTheSphericalScallop) {
  for (double ft : {0.05, 0.2, 0.5}) {
    EXPECT_NEAR(roughness_outside_mm(kR, 0.0, ft), ft * ft / (8.0 * kR), 1e-17);
    EXPECT_NEAR(feed_per_tooth_outside_mm(kR, 0.0, ft * ft / (8.0 * kR)), ft, 1e-15);
  }
}

TEST(ChoiModel, OnlyTheMagnitudeOfAlphaMatters) {
  for (double a : {0.01, 0.07, 0.3, 1.2}) {
    EXPECT_EQ(roughness_mm(kR, kFp, 0.4, a), roughness_mm(kR, kFp, 0.4, -a));
    EXPECT_EQ(feed_per_tooth_mm(kR, kFp, 0.01, a), feed_per_tooth_mm(kR, kFp, 0.01, -a));
  }
}

TEST(ChoiModel, FeedIsFeedPerToothTimesTeethTimesSpeed) {
  EXPECT_DOUBLE_EQ(feed_mm_per_min(0.5, 2, 10000.0), 10000.0);
  CuttingParams p;
  p.ball_radius_mm = kR;
  p.pick_feed_mm = kFp;
  p.teeth = 4;
  p.spindle_rpm = 12000.0;
  p.roughness_target_um = 10.0;
  const double ft = feed_per_tooth_mm(kR, kFp, 0.010, deg_to_rad(30.0));
  EXPECT_DOUBLE_EQ(roughness_feed_mm_per_s(p, deg_to_rad(30.0)), ft * 4 * 12000.0 / 60.0);
}

// --- the inverse ------------------------------------------------------------------------------

TEST(ChoiInverse, RoundTripsTheForwardLawOverRandomInputs) {
  std::mt19937_64 rng(ncd::test::seed(20240611));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 20000; ++i) {
    const double r = 0.5 + 9.5 * unit(rng);
    const double fp = (i % 10 == 0) ? 0.0 : 0.3 * r * unit(rng);
    const double alpha = (unit(rng) - 0.5) * kPi;
    // Target: from the pick feed's own cusp up to 50 µm above it.
    const double target = fp * fp / (8.0 * r) + 1e-4 + 0.05 * unit(rng);
    SCOPED_TRACE(testing::Message() << "i=" << i << " r=" << r << " fp=" << fp << " alpha=" << alpha
                                    << " R=" << target);
    const double ft = feed_per_tooth_mm(r, fp, target, alpha);
    EXPECT_NEAR(roughness_mm(r, fp, ft, alpha), target, 1e-12 * std::max(1.0, target / 1e-3));

    // And the other way, where the forward law is invertible (f_t beyond p = f_p / 2π).
    const double p = fp / (2.0 * kPi);
    const double ft2 = p + 0.02 * r + (0.3 * r - p) * unit(rng);
    const double rmax = roughness_mm(r, fp, ft2, alpha);
    EXPECT_NEAR(feed_per_tooth_mm(r, fp, rmax, alpha), ft2, 1e-9 * ft2);
  }
}

TEST(ChoiInverse, BranchesMeetAtTheCriticalAngleSoTheFeedIsContinuous) {
  for (double target_um : {10.67, 20.0, 40.0}) {
    const double target = target_um * 1e-3;
    const double ft_out = feed_per_tooth_outside_mm(kR, kFp, target);
    const auto alpha_c = critical_angle_rad(kR, kFp, ft_out);
    ASSERT_TRUE(alpha_c.has_value()) << target_um;
    EXPECT_NEAR(feed_per_tooth_dead_centre_mm(kR, target, *alpha_c), ft_out, 1e-13 * ft_out);
    const double h = 1e-8;
    const double below = feed_per_tooth_mm(kR, kFp, target, *alpha_c - h);
    const double above = feed_per_tooth_mm(kR, kFp, target, *alpha_c + h);
    EXPECT_LT(below, ft_out);  // dead-centre branch below α_c
    EXPECT_EQ(above, ft_out);  // the outside branch above it
    // Jump across 2h is the slope r² sin α cos α / f_t times 2h, no more.
    EXPECT_LT(ft_out - below, 2.0 * h * kR * kR / ft_out);
  }
}

TEST(ChoiInverse, WithoutACriticalAngleTheOutsideBranchGovernsEverywhere) {
  // 6.5 µm: f_t,out ≈ 0.18 mm < 0.53 f_p, so α_c does not exist and eq. 5 holds at every α.
  const double target = 6.5e-3;
  const double ft_out = feed_per_tooth_outside_mm(kR, kFp, target);
  EXPECT_LT(ft_out, 0.53 * kFp);
  EXPECT_FALSE(critical_angle_rad(kR, kFp, ft_out).has_value());
  for (double deg : {0.0, 1.0, 5.0, 30.0}) {
    EXPECT_EQ(feed_per_tooth_mm(kR, kFp, target, deg_to_rad(deg)), ft_out) << deg;
  }
}

TEST(ChoiInverse, FeedRisesMonotonicallyWithInclinationUpToTheCriticalAngle) {
  double previous = 0.0;
  for (int k = 0; k <= 900; ++k) {
    const double ft = feed_per_tooth_mm(kR, kFp, 0.010, deg_to_rad(0.01 * k));
    EXPECT_GE(ft, previous) << k;
    previous = ft;
  }
}

// --- validation -------------------------------------------------------------------------------

TEST(CuttingParamsValidation, DefaultsAndSinglePassAreValid) {
  EXPECT_NO_THROW(validate(CuttingParams{}));
  CuttingParams p;
  p.pick_feed_mm = 0.0;
  EXPECT_NO_THROW(validate(p));
}

TEST(CuttingParamsValidation, TargetBelowThePickFeedCuspNamesBothNumbersAndTheWayOut) {
  CuttingParams p;
  p.ball_radius_mm = 5.0;
  p.pick_feed_mm = 0.5;
  p.roughness_target_um = 5.0;  // 8 r R = 0.2 < f_p² = 0.25
  EXPECT_THROW(validate(p), InputError);
  const std::string m = message_of(p);
  EXPECT_NE(m.find("roughness_target_um = 5"), std::string::npos) << m;
  EXPECT_NE(m.find("pick_feed_mm = 0.5"), std::string::npos) << m;
  EXPECT_NE(m.find("6.25 um"), std::string::npos) << m;  // the cusp f_p²/(8r)
  EXPECT_NE(m.find("at most sqrt(8 r R) = 0.447214"), std::string::npos) << m;
  // At exactly the cusp height the target is met (f_t,out = p).
  p.roughness_target_um = 6.25;
  EXPECT_NO_THROW(validate(p));
}

TEST(CuttingParamsValidation, ZeroNegativeAndNanAreRejected) {
  const double nan = std::nan("");
  for (double bad : {0.0, -1.0, nan}) {
    CuttingParams p;
    p.ball_radius_mm = bad;
    EXPECT_THROW(validate(p), InputError) << bad;
    p = {};
    p.spindle_rpm = bad;
    EXPECT_THROW(validate(p), InputError) << bad;
    p = {};
    p.roughness_target_um = bad;
    EXPECT_THROW(validate(p), InputError) << bad;
  }
  for (double bad : {-0.1, nan}) {
    CuttingParams p;
    p.pick_feed_mm = bad;
    EXPECT_THROW(validate(p), InputError) << bad;
  }
  for (int bad : {0, -2}) {
    CuttingParams p;
    p.teeth = bad;
    EXPECT_THROW(validate(p), InputError) << bad;
  }
  CuttingParams wide;
  wide.pick_feed_mm = 10.0;  // = ball diameter
  wide.roughness_target_um = 4000.0;
  EXPECT_THROW(validate(wide), InputError);
  CuttingParams deep;
  deep.roughness_target_um = 5000.0;  // = ball radius
  EXPECT_THROW(validate(deep), InputError);
}

// --- inclination ------------------------------------------------------------------------------

TEST(Inclination, FromTheTangentIsTheSlopeSignedUphill) {
  for (double deg : {-60.0, -10.0, 0.0, 4.0, 30.0, 89.0}) {
    const double a = deg_to_rad(deg);
    const Vec3 t(std::cos(a), 0.0, std::sin(a));
    EXPECT_NEAR(inclination_from_tangent_rad(t), a, 1e-15) << deg;
    EXPECT_NEAR(inclination_from_tangent_rad(7.0 * t), a, 1e-15) << deg;  // any length
    EXPECT_NEAR(inclination_from_tangent_rad(t), std::asin(t.z()), 4e-15) << deg;
  }
}

TEST(Inclination, FromANormalAgreesWithTheTangentInTheFeedPlane) {
  std::mt19937_64 rng(ncd::test::seed(20240611));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 1000; ++i) {
    const double slope = (unit(rng) - 0.5) * 0.98 * kPi;
    const double heading = 2.0 * kPi * unit(rng);
    const Vec3 h(std::cos(heading), std::sin(heading), 0.0);
    const Vec3 t = std::cos(slope) * h + std::sin(slope) * Vec3::UnitZ();
    const Vec3 n = -std::sin(slope) * h + std::cos(slope) * Vec3::UnitZ();  // surface → tool
    EXPECT_NEAR(inclination_from_normal_rad(n, t), inclination_from_tangent_rad(t), 1e-12);
    // A sideways tilt of the surface (across the feed) does not enter α.
    const Vec3 side = Vec3::UnitZ().cross(h);
    const Vec3 n_tilted = (n + 0.3 * side).normalized();
    EXPECT_NEAR(inclination_from_normal_rad(n_tilted, t), slope, 1e-12);
  }
}

TEST(Inclination, PlungeUsesTheWholeAngleToTheToolAxis) {
  const Vec3 n = Vec3(std::sin(0.2), 0.0, std::cos(0.2));
  EXPECT_NEAR(inclination_from_normal_rad(n, Vec3::UnitZ()), 0.2, 1e-15);
  // A spindle tilted 0.3 rad towards the feed (+x) over a normal tilted 0.2 rad the same way:
  // relative to the tool the surface leans 0.1 rad against the feed, i.e. climbs.
  const Vec3 axis(std::sin(0.3), 0.0, std::cos(0.3));
  const Vec3 n2(std::sin(0.2), 0.0, std::cos(0.2));
  EXPECT_NEAR(inclination_from_normal_rad(n2, Vec3::UnitX(), axis), 0.1, 1e-12);
}

}  // namespace
}  // namespace ncd::feed
