// Path files: dispatch on content, then a strict JSON reader (every key checked, every error
// names the key as a path such as points[3].cl[2]) or the G-code reader.
#include "gcode/path_io.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/decimal.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/input_ranges.hpp"
#include "core/json_input.hpp"
#include "gcode/gcode_reader.hpp"

namespace ncd::toolpath {
namespace {

using nlohmann::json;

class JsonReader {
 public:
  explicit JsonReader(const std::string& file) : file_(file) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw InputError(file_ + ": " + (key.empty() ? "the document " : "\"" + key + "\" ") + what);
  }

  const json& member(const json& obj, const std::string& key, const std::string& path) const {
    const auto it = obj.find(key);
    if (it == obj.end()) fail(path, "is missing; add it");
    return *it;
  }

  void only_keys(const json& obj, const std::string& path,
                 std::initializer_list<const char*> allowed) const {
    for (const auto& [key, value] : obj.items()) {
      bool ok = false;
      for (const char* a : allowed) ok = ok || key == a;
      if (!ok) {
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        fail(path.empty() ? key : path + "." + key,
             "is not a known key here; the keys read are " + list + " (check the spelling)");
      }
    }
  }

  double number(const json& j, const std::string& path) const {
    if (!j.is_number()) fail(path, "= " + j.dump() + " is not a number; write a number");
    return j.get<double>();
  }

  double positive(const json& j, const std::string& path) const {
    const double v = number(j, path);
    if (!(v > 0.0)) fail(path, "= " + j.dump() + " must be greater than 0; give a positive number");
    return v;
  }

  // A number within a documented range (core/input_ranges.hpp, docs/input-ranges.md).
  double in_range(const json& j, const std::string& path, const ranges::Range& r,
                  const std::string& way_out) const {
    const double v = positive(j, path);
    try {
      return checked_range(v, r.lo, r.hi, "\"" + path + "\"", r.unit, way_out);
    } catch (const InputError& e) {
      throw InputError(file_ + ": " + e.what());
    }
  }

  double coordinate(const json& j, const std::string& path) const {
    const double v = number(j, path);
    if (v < ranges::kCoordinateMm.lo || v > ranges::kCoordinateMm.hi) {
      fail(path, "= " + j.dump() + " is outside the plausible range [" +
                     number_text(ranges::kCoordinateMm.lo) + ", " +
                     number_text(ranges::kCoordinateMm.hi) +
                     "] mm; check the units (mm) (ranges: docs/input-ranges.md)");
    }
    return v;
  }

  Vec3 vec3(const json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3) {
      fail(path, "= " + j.dump() + " is not a point; write [x, y, z] in mm");
    }
    return Vec3(coordinate(j[0], path + "[0]"), coordinate(j[1], path + "[1]"),
                coordinate(j[2], path + "[2]"));
  }

  double feed(const json& j, const std::string& path) const {
    return in_range(j, path, ranges::kProgramFeedMmPerMin, "give the feed in mm/min");
  }

  double spindle(const json& j, const std::string& path) const {
    return in_range(j, path, ranges::kProgramSpindleRpm, "give the spindle speed in rpm");
  }

  const json& array(const json& j, const std::string& path) const {
    if (!j.is_array()) fail(path, "is not an array; write [ ... ]");
    return j;
  }

  std::vector<Vec3> vec3s(const json& j, const std::string& path) const {
    std::vector<Vec3> out;
    const json& a = array(j, path);
    for (std::size_t i = 0; i < a.size(); ++i) {
      out.push_back(vec3(a[i], path + "[" + std::to_string(i) + "]"));
    }
    return out;
  }

  std::vector<double> numbers(const json& j, const std::string& path) const {
    std::vector<double> out;
    const json& a = array(j, path);
    for (std::size_t i = 0; i < a.size(); ++i) {
      out.push_back(number(a[i], path + "[" + std::to_string(i) + "]"));
    }
    return out;
  }

  // The tool and the checks of a chamfer JSON: "input.ball_radius_mm" and every
  // "checks.*.ok"; a chamfer without them (an older file) counts as failed, since nothing says
  // it passed.
  ChamferOrigin chamfer_origin(const json& doc) const {
    ChamferOrigin o;
    const auto in = doc.find("input");
    if (in != doc.end() && in->is_object() && in->contains("ball_radius_mm")) {
      o.ball_radius_mm = positive((*in)["ball_radius_mm"], "input.ball_radius_mm");
    }
    if (in != doc.end() && in->is_object()) {
      // One of two words, or absent (the default); anything else names the key.
      const auto word = [&](const char* key, const char* a, const char* b, const char* def) {
        const auto w = in->find(key);
        if (w == in->end() || w->is_null()) return std::string(def);
        if (!w->is_string() || (*w != a && *w != b)) {
          fail(std::string("input.") + key,
               std::string("must be \"") + a + "\" or \"" + b + "\"; regenerate the chamfer");
        }
        return w->get<std::string>();
      };
      o.inner_edge = word("edge", "inner", "outer", "inner") == "inner";
      o.lower_side = word("side", "upper", "lower", "upper") == "lower";
      o.safe_z_for_tip = word("program_point", "tip", "centre", "tip") == "tip";
      const bool drill = word("frame", "drill", "pipe", "drill") == "drill";
      if (const auto z = in->find("safe_z_mm"); drill && z != in->end() && !z->is_null()) {
        o.safe_z_mm = number(*z, "input.safe_z_mm");
      }
    }
    const auto checks = doc.find("checks");
    if (checks == doc.end() || !checks->is_object() || checks->empty()) {
      o.checks_ok = false;
      o.failed_checks = "none recorded";
      return o;
    }
    for (const auto& [name, check] : checks->items()) {
      const auto ok = check.is_object() ? check.find("ok") : check.end();
      if (!check.is_object() || ok == check.end() || !ok->is_boolean()) {
        fail("checks." + name, "has no \"ok\": true or false; regenerate the chamfer");
      }
      if (!ok->get<bool>()) {
        o.checks_ok = false;
        o.failed_checks += (o.failed_checks.empty() ? "" : ", ") + name;
      }
    }
    return o;
  }

  // (a) `ncd chamfer` JSON.
  Path chamfer(const json& doc) const {
    const json& pts = array(member(doc, "points", "points"), "points");
    Polyline pl;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const std::string key = "points[" + std::to_string(i) + "]";
      if (!pts[i].is_object()) {
        fail(key, "is not an object; write {\"cl\": [x, y, z], \"e\": [x, y, z]}");
      }
      pl.points.push_back(vec3(member(pts[i], "cl", key + ".cl"), key + ".cl"));
      const Vec3 e = vec3(member(pts[i], "e", key + ".e"), key + ".e");
      pl.normals.push_back(-e);
    }
    if (pl.points.size() < 2) {
      fail("points", "has " + std::to_string(pl.points.size()) +
                         " point(s); a chamfer loop needs at least 2; regenerate it");
    }
    pl.points.push_back(pl.points.front());  // close the loop
    pl.normals.push_back(pl.normals.front());
    PathSegment seg;
    if (const auto in = doc.find("input"); in != doc.end()) {
      if (!in->is_object()) {
        fail("input", "is not an object; write {\"feed_mm_per_min\": F, \"spindle_rpm\": S}");
      }
      if (const auto f = in->find("feed_mm_per_min"); f != in->end() && !f->is_null()) {
        seg.feed_mm_per_min = feed(*f, "input.feed_mm_per_min");
      }
      if (const auto s = in->find("spindle_rpm"); s != in->end() && !s->is_null()) {
        seg.spindle_rpm = spindle(*s, "input.spindle_rpm");
      }
    }
    validate(pl, file_ + ": chamfer loop \"points\"");
    seg.geometry = std::move(pl);
    Path path;
    path.segments.push_back(std::move(seg));
    path.chamfer = chamfer_origin(doc);
    return path;
  }

  // (b) JSON path file.
  Path path_file(const json& doc) const {
    only_keys(doc, "", {"nurbs", "polyline", "feed_mm_per_min", "spindle_rpm"});
    const bool has_nurbs = doc.contains("nurbs"), has_polyline = doc.contains("polyline");
    if (has_nurbs == has_polyline) {
      fail("", "must hold exactly one of \"nurbs\" and \"polyline\"; split the file in two");
    }
    PathSegment seg;
    if (const auto f = doc.find("feed_mm_per_min"); f != doc.end()) {
      seg.feed_mm_per_min = feed(*f, "feed_mm_per_min");
    }
    if (const auto s = doc.find("spindle_rpm"); s != doc.end()) {
      seg.spindle_rpm = spindle(*s, "spindle_rpm");
    }
    if (has_nurbs) {
      const json& n = doc["nurbs"];
      if (!n.is_object()) {
        fail("nurbs",
             "is not an object; write {\"degree\": p, \"knots\": [...], \"points\": [...]}");
      }
      only_keys(n, "nurbs", {"degree", "knots", "points", "weights"});
      int d = 0;
      try {
        d = static_cast<int>(json_integer(member(n, "degree", "nurbs.degree"),
                                          NurbsCurve::kMinDegree, NurbsCurve::kMaxDegree,
                                          "\"nurbs.degree\""));
      } catch (const InputError& e) {
        throw InputError(file_ + ": " + e.what() + "; re-approximate the curve");
      }
      std::vector<double> weights;
      if (n.contains("weights")) weights = numbers(n["weights"], "nurbs.weights");
      try {
        seg.geometry = NurbsCurve(d, numbers(member(n, "knots", "nurbs.knots"), "nurbs.knots"),
                                  vec3s(member(n, "points", "nurbs.points"), "nurbs.points"),
                                  std::move(weights));
      } catch (const InputError& e) {
        if (std::string(e.what()).rfind(file_, 0) == 0) throw;
        fail("nurbs", std::string("is invalid: ") + e.what());
      }
      // A curve whose control points all coincide has no length and no direction (its
      // chord length is 0): nothing to walk. (A zero parametric speed at one end, from a
      // repeated end point, is a valid curve that the planner walks.)
      const auto& pts = std::get<NurbsCurve>(seg.geometry).points();
      if (std::all_of(pts.begin(), pts.end(), [&](const Vec3& p) { return p == pts.front(); })) {
        fail("nurbs.points",
             "are all the same point: the curve has zero length; give the "
             "control points of a curve that moves, or remove the segment");
      }
    } else {
      const json& p = doc["polyline"];
      if (!p.is_object())
        fail("polyline", "is not an object; write {\"points\": [[x, y, z], ...]}");
      only_keys(p, "polyline", {"points", "normals"});
      Polyline pl;
      pl.points = vec3s(member(p, "points", "polyline.points"), "polyline.points");
      if (p.contains("normals")) pl.normals = vec3s(p["normals"], "polyline.normals");
      validate(pl, file_ + ": \"polyline\"");
      seg.geometry = std::move(pl);
    }
    Path path;
    path.segments.push_back(std::move(seg));
    return path;
  }

 private:
  std::string file_;
};

}  // namespace

Path read_path_text(const std::string& text, const std::string& name, const InterpretOptions& ngc) {
  const std::size_t first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) {
    throw InputError(name + ": the file is empty; give a chamfer JSON, a JSON path or G-code");
  }
  Path path;
  if (text[first] == '{') {
    const json doc = parse_json_input(
        text, name, "fix the syntax, or if it is G-code make sure it does not start with '{'");
    const JsonReader r(name);
    if (!doc.is_object()) r.fail("", "is not a JSON object; write { ... }");
    if (doc.contains("nurbs") || doc.contains("polyline")) {
      path = r.path_file(doc);
    } else if (doc.contains("points")) {
      path = r.chamfer(doc);
    } else {
      r.fail("",
             "has neither \"points\" (an `ncd chamfer` result) nor \"nurbs\" or "
             "\"polyline\" (a path file); give one of them");
    }
  } else {
    std::istringstream in(text);
    path = read_gcode(in, name, ngc);
  }
  path.source = name;
  return path;
}

Path read_path_file(const std::string& filename, const InterpretOptions& ngc) {
  return read_path_text(read_input_file(filename, "path file"), filename, ngc);
}

}  // namespace ncd::toolpath
