// Machine file reader on toml11. Integers are accepted where a real number is expected
// (`period_s = 1` is 1.0 s); anything else of the wrong type, an unknown key or table, and a
// value out of range are InputErrors naming the file and the key.
#include "app/machine_config.hpp"

#include <fstream>
#include <sstream>
#include <toml.hpp>

#include "core/error.hpp"

namespace ncd::app {
namespace {

double as_real(const toml::value& v, const std::string& where) {
  if (v.is_floating()) return v.as_floating();
  if (v.is_integer()) return static_cast<double>(v.as_integer());
  throw InputError(where + " must be a number, not " + toml::format(v));
}

int as_int(const toml::value& v, const std::string& where) {
  if (!v.is_integer() || v.as_integer() < 1 || v.as_integer() > 1000) {
    throw InputError(where + " must be a whole number from 1 to 1000, not " + toml::format(v));
  }
  return static_cast<int>(v.as_integer());
}

}  // namespace

MachineConfig parse_machine_config(const std::string& text, const std::string& name) {
  toml::value root;
  try {
    std::istringstream in(text);
    root = toml::parse(in, name);
  } catch (const std::exception& e) {
    throw InputError("cannot read machine file " + name + ": " + e.what());
  }
  MachineConfig c;
  c.source = name;
  auto& l = c.limits;
  auto& k = c.cutting;
  for (const auto& [key, value] : root.as_table()) {
    const std::string where = name + ": " + key;
    if (key == "period_s")
      l.period_s = as_real(value, where);
    else if (key == "max_feed_mm_per_min")
      l.max_feed_mm_per_min = as_real(value, where);
    else if (key == "max_accel_mm_per_s2")
      l.max_accel_mm_per_s2 = as_real(value, where);
    else if (key == "max_jerk_mm_per_s3")
      l.max_jerk_mm_per_s3 = as_real(value, where);
    else if (key == "chord_tolerance_mm")
      l.chord_tolerance_mm = as_real(value, where);
    else if (key == "feed_tolerance_rel")
      l.feed_tolerance_rel = as_real(value, where);
    else if (key == "cutting") {
      if (!value.is_table()) throw InputError(where + " must be a table: [cutting]");
      for (const auto& [ck, cv] : value.as_table()) {
        const std::string cwhere = name + ": cutting." + ck;
        if (ck == "ball_radius_mm")
          k.ball_radius_mm = as_real(cv, cwhere);
        else if (ck == "pick_feed_mm")
          k.pick_feed_mm = as_real(cv, cwhere);
        else if (ck == "teeth")
          k.teeth = as_int(cv, cwhere);
        else if (ck == "spindle_rpm")
          k.spindle_rpm = as_real(cv, cwhere);
        else if (ck == "roughness_target_um")
          k.roughness_target_um = as_real(cv, cwhere);
        else {
          throw InputError("unknown key " + cwhere +
                           "; [cutting] takes ball_radius_mm, pick_feed_mm, teeth, spindle_rpm, "
                           "roughness_target_um");
        }
      }
    } else {
      throw InputError("unknown key " + where +
                       "; the machine file takes period_s, max_feed_mm_per_min, "
                       "max_accel_mm_per_s2, max_jerk_mm_per_s3, chord_tolerance_mm, "
                       "feed_tolerance_rel and a [cutting] table");
    }
  }
  try {
    interpolator::validate(c.limits);
    interpolator::validate(c.cutting);
  } catch (const InputError& e) {
    throw InputError(name + ": " + e.what());
  }
  return c;
}

MachineConfig load_machine_config(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot open machine file " + path + " (--machine)");
  std::stringstream text;
  text << in.rdbuf();
  return parse_machine_config(text.str(), path);
}

nlohmann::ordered_json to_json(const MachineConfig& c) {
  nlohmann::ordered_json j;
  j["source"] = c.source;
  j["period_s"] = c.limits.period_s;
  j["max_feed_mm_per_min"] = c.limits.max_feed_mm_per_min;
  j["max_accel_mm_per_s2"] = c.limits.max_accel_mm_per_s2;
  j["max_jerk_mm_per_s3"] = c.limits.max_jerk_mm_per_s3;
  j["chord_tolerance_mm"] = c.limits.chord_tolerance_mm;
  j["feed_tolerance_rel"] = c.limits.feed_tolerance_rel;
  j["cutting"] = {{"ball_radius_mm", c.cutting.ball_radius_mm},
                  {"pick_feed_mm", c.cutting.pick_feed_mm},
                  {"teeth", c.cutting.teeth},
                  {"spindle_rpm", c.cutting.spindle_rpm},
                  {"roughness_target_um", c.cutting.roughness_target_um}};
  return j;
}

}  // namespace ncd::app
