// The rotary index axis in the machine file (docs/planner.md §3g): [axis.a] or [axis.b] declares
// it (defaults for every key), its keys are range-checked with errors naming the key, the value,
// the range and a way out; both tables, an unknown key, or a table that is not one are refused;
// the JSON echo holds it only when declared; the interpreter's options get the axis.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/error.hpp"
#include "service/machine_config.hpp"

namespace ncd::app {
namespace {

std::string rotary_error_of(const std::string& toml) {
  try {
    (void)service::parse_machine_config(toml, "m.toml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

void rotary_expect_all(const std::string& what, const std::vector<std::string>& parts) {
  for (const std::string& p : parts)
    EXPECT_NE(what.find(p), std::string::npos) << "'" << p << "' in: " << what;
}

TEST(RotaryAxisConfig, TheTableDeclaresTheAxisWithDefaults) {
  const service::MachineConfig none =
      service::parse_machine_config("max_feed_mm_per_min = 6000\n", "m.toml");
  EXPECT_FALSE(none.limits.rotary.present());
  EXPECT_EQ(none.program.rotary_axis, 0);
  EXPECT_FALSE(to_json(none).contains("rotary_axis"));

  const service::MachineConfig a = service::parse_machine_config("[axis.a]\n", "m.toml");
  EXPECT_EQ(a.limits.rotary.axis, 'a');
  EXPECT_EQ(a.program.rotary_axis, 'a');
  EXPECT_EQ(a.limits.rotary.max_feed_deg_per_min, feed::RotaryLimits{}.max_feed_deg_per_min);
  EXPECT_FALSE(a.limits.has_axis_limits());  // X, Y, Z keep no limits of their own

  const service::MachineConfig b = service::parse_machine_config(
      "[axis.b]\nmax_feed_deg_per_min = 7200\nmax_accel_deg_per_s2 = 900\nmax_jerk_deg_per_s3 = "
      "9000\n",
      "m.toml");
  EXPECT_EQ(b.limits.rotary.axis, 'b');
  EXPECT_EQ(b.limits.rotary.max_feed_deg_per_min, 7200.0);
  EXPECT_EQ(b.limits.rotary.max_accel_deg_per_s2, 900.0);
  EXPECT_EQ(b.limits.rotary.max_jerk_deg_per_s3, 9000.0);
  const auto j = to_json(b);
  ASSERT_TRUE(j.contains("rotary_axis"));
  EXPECT_EQ(j["rotary_axis"]["axis"], "b");
  EXPECT_EQ(j["rotary_axis"]["max_jerk_deg_per_s3"].get<double>(), 9000.0);
}

TEST(RotaryAxisConfig, BadValuesAreRefusedNamingKeyValueRangeAndWayOut) {
  rotary_expect_all(
      rotary_error_of("[axis.a]\nmax_feed_deg_per_min = 0\n"),
      {"m.toml", "axis.a.max_feed_deg_per_min", "0", "360000", "deg/min", "leave the key out"});
  rotary_expect_all(rotary_error_of("[axis.b]\nmax_accel_deg_per_s2 = 2e6\n"),
                    {"axis.b.max_accel_deg_per_s2", "deg/s^2"});
  rotary_expect_all(rotary_error_of("[axis.a]\nmax_jerk_deg_per_s3 = -5\n"),
                    {"axis.a.max_jerk_deg_per_s3"});
  rotary_expect_all(rotary_error_of("[axis.a]\nmax_feed_deg_per_min = \"fast\"\n"),
                    {"axis.a.max_feed_deg_per_min", "must be a number"});
  rotary_expect_all(rotary_error_of("[axis.a]\nmax_feed_mm_per_min = 100\n"),
                    {"unknown key", "axis.a.max_feed_mm_per_min", "max_feed_deg_per_min"});
  rotary_expect_all(rotary_error_of("[axis.a]\n[axis.b]\n"),
                    {"[axis.a] and [axis.b]", "one rotary index axis"});
  rotary_expect_all(rotary_error_of("[axis.c]\n"),
                    {"[axis.c]", "[axis.a] (about X) or [axis.b] (about Y)"});
  rotary_expect_all(rotary_error_of("[axis]\na = 3\n"), {"axis.a must be a table"});
}

}  // namespace
}  // namespace ncd::app
