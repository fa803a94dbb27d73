// NurbsCurve against a slow, independent reference and against exact identities.
//
// Reference: Cox–de Boor recursion (The NURBS Book eq. 2.5) on the curve parameter carried as a
// second-order jet (value, d/du, d²/du²), so that the derivatives of the basis functions, of
// the homogeneous sums and of the quotient A/w come out of the product rule alone, with no
// derivative formula shared with the implementation (A2.3 + eq. 4.8). The quotient is taken as
// A · (1/w) with the jet of the reciprocal, not the quotient rule the implementation uses.
#include "geometry/nurbs.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <new>
#include <random>
#include <string>

#include "core/error.hpp"
#include "tests/common/count_allocations.hpp"
#include "tests/common/seed.hpp"

namespace ncd::toolpath {
namespace {

// Second-order jet: f, f', f'' with respect to u, in long double (64-bit mantissa on x86-64)
// so that the reference's own rounding is far below the tolerance.
using Real = long double;
struct Jet {
  Real v = 0, d = 0, dd = 0;
};
Jet operator+(Jet a, Jet b) {
  return {a.v + b.v, a.d + b.d, a.dd + b.dd};
}
Jet operator*(Jet a, Jet b) {
  return {a.v * b.v, a.d * b.v + a.v * b.d, a.dd * b.v + 2 * a.d * b.d + a.v * b.dd};
}
Jet operator*(Real s, Jet a) {
  return {s * a.v, s * a.d, s * a.dd};
}
Jet reciprocal(Jet a) {
  const Real r = 1 / a.v;
  return {r, -a.d * r * r, 2 * a.d * a.d * r * r * r - a.dd * r * r};
}

// N_{i,p}(u) by the Cox–de Boor recursion, 0/0 = 0. The degree-0 functions use the half-open
// span [u_i, u_{i+1}), except that u = u_end belongs to the last non-empty span.
Jet basis(const std::vector<double>& U, std::size_t i, int p, Real u) {
  const auto knot = [&U](std::size_t k) { return Real(U[k]); };  // every sum in long double
  if (p == 0) {
    const Real last = knot(U.size() - 1);
    bool in = knot(i) <= u && u < knot(i + 1);
    if (u == last && knot(i) < knot(i + 1) && knot(i + 1) == last) in = true;
    return {in ? Real(1) : Real(0), 0, 0};
  }
  const auto pi = static_cast<std::size_t>(p);
  Jet sum;
  const Real d1 = knot(i + pi) - knot(i);
  if (d1 != 0) sum = sum + (1 / d1) * (Jet{u - knot(i), 1, 0} * basis(U, i, p - 1, u));
  const Real d2 = knot(i + pi + 1) - knot(i + 1);
  if (d2 != 0)
    sum = sum + (1 / d2) * (Jet{knot(i + pi + 1) - u, -1, 0} * basis(U, i + 1, p - 1, u));
  return sum;
}

// P, P', P'' of the reference, and for each the size of the terms that the implementation sums
// (Σ|N_i^(k)| w_i (|P_i| + |C|) plus the weight-derivative terms of the quotient rule, over w):
// the scale of its rounding error, which a plain relative error misjudges where terms cancel.
struct Reference {
  CurvePoint c;
  std::array<double, 3> scale{};
};

Reference reference(const NurbsCurve& c, double u) {
  const auto& P = c.points();
  const auto& W = c.weights();
  std::array<Jet, 3> A{};
  Jet w;
  std::vector<Jet> N(P.size());
  for (std::size_t i = 0; i < P.size(); ++i) {
    N[i] = basis(c.knots(), i, c.degree(), Real(u));
    const Jet Nw = Real(W[i]) * N[i];
    for (std::size_t k = 0; k < 3; ++k) {
      A[k] = A[k] + Real(P[i][static_cast<Eigen::Index>(k)]) * Nw;
    }
    w = w + Nw;
  }
  const Jet r = reciprocal(w);
  Reference out;
  for (std::size_t k = 0; k < 3; ++k) {
    const Jet q = A[k] * r;
    const auto e = static_cast<Eigen::Index>(k);
    out.c.p[e] = static_cast<double>(q.v);
    out.c.d1[e] = static_cast<double>(q.d);
    out.c.d2[e] = static_cast<double>(q.dd);
  }
  const double C = out.c.p.norm(), C1 = out.c.d1.norm();
  std::array<double, 3> mag{};
  for (std::size_t i = 0; i < P.size(); ++i) {
    const double size = W[i] * (P[i].norm() + C);
    mag[0] += std::abs(static_cast<double>(N[i].v)) * size;
    mag[1] += std::abs(static_cast<double>(N[i].d)) * size;
    mag[2] += std::abs(static_cast<double>(N[i].dd)) * size +
              2 * std::abs(static_cast<double>(N[i].d)) * W[i] * C1;
  }
  for (std::size_t k = 0; k < 3; ++k) out.scale[k] = mag[k] / static_cast<double>(w.v);
  return out;
}

// A random clamped NURBS on [0, L] with interior knots repeated up to the degree.
NurbsCurve random_curve(std::mt19937_64& rng, int degree, bool rational) {
  std::uniform_int_distribution<int> extra(0, 12);
  std::uniform_real_distribution<double> coord(-100.0, 100.0), unit(0.0, 1.0), wdist(0.2, 5.0);
  const auto p = static_cast<std::size_t>(degree);
  const double L = 0.1 + 10.0 * unit(rng);
  std::vector<double> interior;
  const int n_distinct = extra(rng);
  while (interior.size() < static_cast<std::size_t>(n_distinct)) {
    const double k = L * (0.02 + 0.96 * unit(rng));
    const int mult = std::uniform_int_distribution<int>(1, degree)(rng);
    for (int m = 0; m < mult; ++m) interior.push_back(k);
  }
  std::sort(interior.begin(), interior.end());
  std::vector<double> knots(p + 1, 0.0);
  knots.insert(knots.end(), interior.begin(), interior.end());
  knots.insert(knots.end(), p + 1, L);
  const std::size_t n_points = knots.size() - p - 1;
  std::vector<Vec3> points(n_points);
  std::vector<double> weights;
  for (auto& q : points) q = Vec3(coord(rng), coord(rng), coord(rng));
  if (rational) {
    for (std::size_t i = 0; i < n_points; ++i) weights.push_back(wdist(rng));
  }
  return NurbsCurve(degree, knots, points, weights);
}

// |got − want| ≤ tol · (|want| + scale): relative to the value, or to the size of the terms
// summed where they cancel.
void expect_close(const Vec3& got, const Vec3& want, double scale, double tol,
                  const std::string& what) {
  EXPECT_LE((got - want).norm(), tol * (want.norm() + scale))
      << what << ": got " << got.transpose() << ", want " << want.transpose();
}

TEST(NurbsCurve, MatchesCoxDeBoorJetReferenceInRandomSweeps) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int checked = 0;
  for (int degree = 1; degree <= 7; ++degree) {
    for (bool rational : {false, true}) {
      for (int trial = 0; trial < 40; ++trial) {
        const NurbsCurve c = random_curve(rng, degree, rational);
        const double L = c.u_end() - c.u_begin();
        std::vector<double> us = c.knots();  // every knot, ends included
        for (int k = 0; k < 25; ++k) us.push_back(L * unit(rng));
        for (double u : us) {
          const CurvePoint got = c.eval(u);
          const Reference want = reference(c, u);
          const std::string what = "degree " + std::to_string(degree) +
                                   (rational ? " rational" : "") + " u = " + std::to_string(u);
          expect_close(got.p, want.c.p, want.scale[0], 1e-12, what + " P");
          expect_close(got.d1, want.c.d1, want.scale[1], 1e-12, what + " P'");
          expect_close(got.d2, want.c.d2, want.scale[2], 1e-12, what + " P''");
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 7 * 2 * 40 * 25);
}

// derivative() skips the second derivative's work but must give eval(u).d1 bit for bit (the
// sampler's and the walkers' arc lengths use it, and setpoints must not change): every degree,
// rational or not, at every knot (a span's end and the next one's start) and at random u,
// clamped ends included. The span-hinted derivative too, whatever the hint.
TEST(NurbsCurve, DerivativeIsEvalsFirstDerivativeBitForBit) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> unit(-0.1, 1.1);
  int checked = 0;
  for (int degree = 1; degree <= 7; ++degree) {
    for (bool rational : {false, true}) {
      for (int trial = 0; trial < 20; ++trial) {
        const NurbsCurve c = random_curve(rng, degree, rational);
        std::vector<double> us = c.knots();
        for (int k = 0; k < 50; ++k) us.push_back(c.u_end() * unit(rng));
        // The span hint: carried from the previous u (a sweep), or any index at all.
        std::size_t carried = 0;
        std::uniform_int_distribution<std::size_t> any_index(0, c.knots().size() + 2);
        for (const double u : us) {
          std::size_t random_hint = any_index(rng);
          const Vec3 d = c.derivative(u), e = c.eval(u).d1;
          const Vec3 dc = c.derivative(u, carried), dr = c.derivative(u, random_hint);
          for (int i = 0; i < 3; ++i) {
            ASSERT_EQ(d[i], e[i]) << "degree " << degree << (rational ? " rational" : "")
                                  << " u = " << u << " component " << i;
            ASSERT_EQ(dc[i], e[i]) << "carried hint, degree " << degree << " u = " << u;
            ASSERT_EQ(dr[i], e[i]) << "random hint, degree " << degree << " u = " << u;
          }
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 7 * 2 * 20 * 50);
}

TEST(NurbsCurve, EvalDoesNotAllocate) {
  std::mt19937_64 rng(7);
  const NurbsCurve c = random_curve(rng, 7, true);
  const long before = ncd::test::g_allocations.load();
  double sink = 0.0;
  for (int i = 0; i <= 1000; ++i) sink += c.eval(c.u_end() * i / 1000.0).d2.norm();
  EXPECT_EQ(ncd::test::g_allocations.load(), before);
  EXPECT_TRUE(std::isfinite(sink));
  // The counter works: a vector allocates.
  std::vector<double> v(10);
  EXPECT_GT(ncd::test::g_allocations.load(), before);
}

// Quarter circle of radius r: P0 = (r, 0), P1 = (r, r), P2 = (0, r), weights 1, c, 1 with
// c = √2/2 (The NURBS Book eq. 7.7). With D = (1−u)² + 2c u(1−u) + u², the speed is
// |P'| = r dθ/du = 2 r (c(1−u)² + u(1−u) + c u²) / D², obtained from x y' − y x' on the circle
// with t = u / (1 − u).
double quarter_speed(double r, double u) {
  const double c = std::sqrt(0.5);
  const double D = (1 - u) * (1 - u) + 2 * c * u * (1 - u) + u * u;
  return 2 * r * (c * (1 - u) * (1 - u) + u * (1 - u) + c * u * u) / (D * D);
}

TEST(NurbsCurve, RationalQuarterCircleIsExact) {
  const double r = 25.0, c = std::sqrt(0.5);
  const NurbsCurve q(2, {0, 0, 0, 1, 1, 1}, {Vec3(r, 0, 3), Vec3(r, r, 3), Vec3(0, r, 3)},
                     {1, c, 1});
  EXPECT_TRUE(q.rational());
  for (int i = 0; i <= 1000; ++i) {
    const double u = i / 1000.0;
    const CurvePoint e = q.eval(u);
    EXPECT_NEAR(e.p.head<2>().norm(), r, 1e-14 * r) << "u = " << u;
    EXPECT_DOUBLE_EQ(e.p.z(), 3.0);
    EXPECT_NEAR(e.d1.norm(), quarter_speed(r, u), 1e-14 * quarter_speed(r, u)) << "u = " << u;
    // On a circle the tangent is perpendicular to the radius.
    EXPECT_NEAR(e.p.head<2>().dot(e.d1.head<2>()), 0.0, 1e-12 * r * e.d1.norm());
  }
}

TEST(NurbsCurve, RationalFullCircleIsExact) {
  // Nine points, knots doubled at the quarters (The NURBS Book Fig. 7.16 with four arcs).
  const double r = 10.0, c = std::sqrt(0.5);
  std::vector<Vec3> pts = {{r, 0, 0},   {r, r, 0},  {0, r, 0},  {-r, r, 0}, {-r, 0, 0},
                           {-r, -r, 0}, {0, -r, 0}, {r, -r, 0}, {r, 0, 0}};
  const NurbsCurve circle(2, {0, 0, 0, .25, .25, .5, .5, .75, .75, 1, 1, 1}, pts,
                          {1, c, 1, c, 1, c, 1, c, 1});
  EXPECT_EQ(circle.breakpoints(), (std::vector<double>{0, .25, .5, .75, 1}));
  for (int i = 0; i <= 4000; ++i) {
    const double u = i / 4000.0;
    const CurvePoint e = circle.eval(u);
    EXPECT_NEAR(e.p.norm(), r, 1e-14 * r) << "u = " << u;
    const double local = std::min(4.0 * u - std::floor(std::min(4.0 * u, 3.0)), 1.0);
    const double want = 4.0 * quarter_speed(r, local);
    EXPECT_NEAR(e.d1.norm(), want, 1e-14 * want) << "u = " << u;
  }
}

TEST(NurbsCurve, DegreeOneIsThePolyline) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> coord(-50.0, 50.0), unit(0.0, 1.0);
  for (int trial = 0; trial < 50; ++trial) {
    const std::size_t n = 2 + static_cast<std::size_t>(trial % 9);
    std::vector<Vec3> pts(n);
    for (auto& q : pts) q = Vec3(coord(rng), coord(rng), coord(rng));
    std::vector<double> t(n);
    t[0] = 0.0;
    for (std::size_t i = 1; i < n; ++i) t[i] = t[i - 1] + 0.1 + unit(rng);
    std::vector<double> knots = {t.front()};
    knots.insert(knots.end(), t.begin(), t.end());
    knots.push_back(t.back());
    const NurbsCurve c(1, knots, pts,
                       trial % 2 ? std::vector<double>(n, 2.5) : std::vector<double>{});
    for (std::size_t i = 0; i + 1 < n; ++i) {
      for (double f : {0.0, 0.3, 0.77}) {
        const double u = t[i] + f * (t[i + 1] - t[i]);
        const CurvePoint e = c.eval(u);
        const Vec3 want = pts[i] + f * (pts[i + 1] - pts[i]);
        const Vec3 slope = (pts[i + 1] - pts[i]) / (t[i + 1] - t[i]);
        EXPECT_LE((e.p - want).norm(), 1e-13 * 50.0);
        EXPECT_LE((e.d1 - slope).norm(), 1e-12 * slope.norm());
        EXPECT_EQ(e.d2, Vec3::Zero());
      }
    }
    EXPECT_LE((c.eval(t.back()).p - pts.back()).norm(), 1e-13 * 50.0);
  }
}

TEST(NurbsCurve, PartitionOfUnityReproducesAConstant) {
  // Σ N_i = 1 and Σ N_i' = Σ N_i'' = 0: with every control point at q the curve is q, whatever
  // the weights, and both derivatives vanish.
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Vec3 q(12.5, -3.25, 7.0);
  for (int degree = 1; degree <= 7; ++degree) {
    for (bool rational : {false, true}) {
      const NurbsCurve shape = random_curve(rng, degree, rational);
      const NurbsCurve c(degree, shape.knots(), std::vector<Vec3>(shape.points().size(), q),
                         rational ? shape.weights() : std::vector<double>{});
      // The derivative sums cancel terms as large as |N^(k)| ≤ (2p/h)^k (eq. 2.9 applied k
      // times, h the shortest non-empty span), so that is the scale of their rounding error.
      double h = c.u_end();
      for (std::size_t i = 0; i + 1 < c.knots().size(); ++i) {
        const double span = c.knots()[i + 1] - c.knots()[i];
        if (span > 0.0) h = std::min(h, span);
      }
      const double s1 = 2.0 * degree / h;
      for (int k = 0; k < 200; ++k) {
        const CurvePoint e = c.eval(c.u_end() * unit(rng));
        EXPECT_LE((e.p - q).norm(), 1e-14 * q.norm() * 4) << "degree " << degree;
        EXPECT_LE(e.d1.norm(), 1e-13 * q.norm() * s1) << "degree " << degree;
        EXPECT_LE(e.d2.norm(), 1e-13 * q.norm() * s1 * s1) << "degree " << degree;
      }
    }
  }
}

TEST(NurbsCurve, InterpolatesEndPointsAndClampsTheParameter) {
  std::mt19937_64 rng(11);
  const NurbsCurve c = random_curve(rng, 5, true);
  EXPECT_LE((c.eval(c.u_begin()).p - c.points().front()).norm(), 1e-12 * 100);
  EXPECT_LE((c.eval(c.u_end()).p - c.points().back()).norm(), 1e-12 * 100);
  EXPECT_EQ(c.eval(c.u_end() + 1.0).p, c.eval(c.u_end()).p);
  EXPECT_EQ(c.eval(c.u_begin() - 1.0).d1, c.eval(c.u_begin()).d1);
}

TEST(NurbsCurve, BreakpointsAreTheDistinctKnots) {
  const NurbsCurve c(3, {0, 0, 0, 0, 1, 1, 2.5, 4, 4, 4, 4}, std::vector<Vec3>(7, Vec3(1, 2, 3)));
  EXPECT_EQ(c.breakpoints(), (std::vector<double>{0, 1, 2.5, 4}));
  EXPECT_EQ(c.u_begin(), 0.0);
  EXPECT_EQ(c.u_end(), 4.0);
  EXPECT_FALSE(c.rational());
  EXPECT_EQ(c.weights(), std::vector<double>(7, 1.0));
}

// Each invalid input throws InputError whose message contains the offending value.
void expect_error(const std::function<void()>& make, const std::string& needle) {
  try {
    make();
    ADD_FAILURE() << "no InputError; expected one mentioning " << needle;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "message \"" << e.what() << "\" does not contain \"" << needle << "\"";
  }
}

TEST(NurbsCurve, RejectsInvalidInputNamingTheValue) {
  const std::vector<Vec3> four(4, Vec3(1, 0, 0));
  const std::vector<Vec3> six(6, Vec3(1, 0, 0));
  const std::vector<double> k3 = {0, 0, 0, 0, 1, 1, 1, 1};  // degree 3, 4 points
  expect_error([&] { NurbsCurve(0, {0, 1, 2, 3, 4}, four); }, "degree = 0");
  expect_error([&] { NurbsCurve(8, std::vector<double>(21, 0.0), std::vector<Vec3>(12)); },
               "degree = 8");
  expect_error(
      [&] {
        NurbsCurve(3, {0, 0, 0, 1, 1, 1}, {Vec3::Zero(), Vec3::Zero()});
      },
      "has 2 control");
  expect_error([&] { NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1}, four); }, "has 7 knots");
  // Interior knot 0.5 three times at degree 2.
  expect_error(
      [&] {
        NurbsCurve(2, {0, 0, 0, .5, .5, .5, 1, 1, 1}, six);
      },
      "knot 0.5 is repeated 3 times");
  // Four equal end knots at degree 2 (an empty span).
  expect_error([&] { NurbsCurve(2, {0, 0, 0, 0, .5, 1, 1, 1, 1}, six); }, "knot 0 is repeated 4");
  expect_error([&] { NurbsCurve(3, {0, 0, 0.25, 0, 1, 1, 1, 1}, four); }, "0.25");  // decreasing
  expect_error([&] { NurbsCurve(3, {0, 0, 0, 0.1, 1, 1, 1, 1}, four); }, "= 0.1");  // unclamped
  expect_error(
      [&] {
        NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1.5}, four);
      },
      "end knot 1.5");  // unclamped
  expect_error([&] { NurbsCurve(3, {0, 0, 0, 0, std::nan(""), 1, 1, 1}, four); }, "nan");
  expect_error([&] { NurbsCurve(3, k3, four, {1, 0, 1, 1}); }, "weight[1] = 0");
  expect_error([&] { NurbsCurve(3, k3, four, {1, 1, -2.5, 1}); }, "weight[2] = -2.5");
  expect_error([&] { NurbsCurve(3, k3, four, {1, 1, 1, std::nan("")}); }, "weight[3] = nan");
  expect_error([&] { NurbsCurve(3, k3, four, {1, 1, 1}); }, "3 weights");
  expect_error(
      [&] {
        NurbsCurve(3, k3, {Vec3::Zero(), Vec3(HUGE_VAL, 0, 0), Vec3::Zero(), Vec3::Zero()});
      },
      "point[1] = (inf");
  // Multiplicity equal to the degree is allowed (C0 corner).
  EXPECT_NO_THROW(NurbsCurve(2, {0, 0, 0, .5, .5, 1, 1, 1}, std::vector<Vec3>(5)));
}

}  // namespace
}  // namespace ncd::toolpath

namespace ncd::toolpath {
namespace {

// Weights within one span may differ by at most 100 (a near-corner beyond, see
// docs/feedrate.md §5.1); the rule is per span, not over the whole curve.
TEST(NurbsCurve, WeightRatioWithinASpanIsLimitedAndNamed) {
  const std::vector<Vec3> three = {Vec3(0, 0, 0), Vec3(10, 10, 0), Vec3(20, 0, 0)};
  const std::vector<double> k = {0, 0, 0, 1, 1, 1};
  EXPECT_NO_THROW(NurbsCurve(2, k, three, {1, 100, 1}));   // exactly the limit
  EXPECT_NO_THROW(NurbsCurve(2, k, three, {0.5, 50, 1}));  // 100 again, from below
  expect_error(
      [&] {
        NurbsCurve(2, k, three, {1, 100.5, 1});
      },
      "weight[1] = 100.5 is 100.5 times "
      "weight[0] = 1");
  expect_error([&] { NurbsCurve(2, k, three, {1, 0.7, 1576461}); }, "at most 100");
  expect_error([&] { NurbsCurve(2, k, three, {1, 0.7, 1576461}); }, "points 0..2");
  // 1 and 200 are never in one span's window of 3 points: accepted.
  const std::vector<Vec3> five = {Vec3(0, 0, 0), Vec3(10, 10, 0), Vec3(20, 0, 0), Vec3(30, 10, 0),
                                  Vec3(40, 0, 0)};
  EXPECT_NO_THROW(NurbsCurve(2, {0, 0, 0, 1, 2, 3, 3, 3}, five, {1, 10, 10, 10, 200}));
  expect_error(
      [&] {
        NurbsCurve(2, {0, 0, 0, 1, 2, 3, 3, 3}, five, {1, 10, 10, 1, 200});
      },
      "points 2..4");
}

}  // namespace
}  // namespace ncd::toolpath
