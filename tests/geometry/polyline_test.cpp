// Polyline validation and measures.
#include "geometry/polyline.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/error.hpp"

namespace ncd::toolpath {
namespace {

std::string error_of(const Polyline& pl) {
  try {
    validate(pl, "test polyline");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Polyline, LengthAndSegmentCountOfARightTriangle) {
  const Polyline pl{{Vec3(0, 0, 0), Vec3(3, 0, 0), Vec3(3, 4, 0), Vec3(0, 0, 0)}, {}};
  EXPECT_NO_THROW(validate(pl));
  EXPECT_EQ(segment_count(pl), 3u);
  EXPECT_DOUBLE_EQ(length_mm(pl), 3.0 + 4.0 + 5.0);
  EXPECT_EQ(segment_count(Polyline{}), 0u);
  EXPECT_EQ(length_mm(Polyline{}), 0.0);
}

TEST(Polyline, AcceptsUnitNormals) {
  const double s = std::sqrt(0.5);
  const Polyline pl{{Vec3(0, 0, 0), Vec3(1, 0, 0)}, {Vec3(0, 0, 1), Vec3(s, 0, s)}};
  EXPECT_EQ(error_of(pl), "");
}

TEST(Polyline, RejectsTooFewPoints) {
  const std::string e = error_of(Polyline{{Vec3(1, 2, 3)}, {}});
  EXPECT_NE(e.find("test polyline has 1 point"), std::string::npos) << e;
}

TEST(Polyline, RejectsConsecutiveDuplicatesNamingTheIndex) {
  const std::string e =
      error_of(Polyline{{Vec3(0, 0, 0), Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(0, 0, 0)}, {}});
  EXPECT_NE(e.find("point[2] = (1, 2, 3) repeats point[1]"), std::string::npos) << e;
  // The same point again later (a closed loop) is fine.
  EXPECT_EQ(error_of(Polyline{{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 0)}, {}}), "");
}

TEST(Polyline, RejectsNonFinitePoints) {
  const std::string e = error_of(Polyline{{Vec3(0, 0, 0), Vec3(0, std::nan(""), 0)}, {}});
  EXPECT_NE(e.find("point[1] = (0, nan, 0)"), std::string::npos) << e;
}

TEST(Polyline, RejectsWrongNormalCountAndNonUnitNormals) {
  const Polyline pts{{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)}, {}};
  Polyline a = pts;
  a.normals = {Vec3(0, 0, 1)};
  EXPECT_NE(error_of(a).find("1 normals for 3 points"), std::string::npos) << error_of(a);
  Polyline b = pts;
  b.normals = {Vec3(0, 0, 1), Vec3(0, 0, 2), Vec3(0, 0, 1)};
  EXPECT_NE(error_of(b).find("normal[1] = (0, 0, 2) has length 2"), std::string::npos)
      << error_of(b);
  Polyline c = pts;
  c.normals = {Vec3(0, 0, 1), Vec3(0, 0, 1), Vec3(0, HUGE_VAL, 1)};
  EXPECT_NE(error_of(c).find("normal[2]"), std::string::npos) << error_of(c);
}

}  // namespace
}  // namespace ncd::toolpath
