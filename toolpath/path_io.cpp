// Path files: dispatch on content, then a strict JSON reader (every key checked, every error
// names the key as a path such as points[3].cl[2]) or the G-code reader.
#include "toolpath/path_io.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.hpp"
#include "toolpath/gcode_reader.hpp"

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

  Vec3 vec3(const json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3) {
      fail(path, "= " + j.dump() + " is not a point; write [x, y, z] in mm");
    }
    return Vec3(number(j[0], path + "[0]"), number(j[1], path + "[1]"), number(j[2], path + "[2]"));
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
        seg.feed_mm_per_min = positive(*f, "input.feed_mm_per_min");
      }
      if (const auto s = in->find("spindle_rpm"); s != in->end() && !s->is_null()) {
        seg.spindle_rpm = positive(*s, "input.spindle_rpm");
      }
    }
    validate(pl, file_ + ": chamfer loop \"points\"");
    seg.geometry = std::move(pl);
    Path path;
    path.segments.push_back(std::move(seg));
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
      seg.feed_mm_per_min = positive(*f, "feed_mm_per_min");
    }
    if (const auto s = doc.find("spindle_rpm"); s != doc.end()) {
      seg.spindle_rpm = positive(*s, "spindle_rpm");
    }
    if (has_nurbs) {
      const json& n = doc["nurbs"];
      if (!n.is_object()) {
        fail("nurbs",
             "is not an object; write {\"degree\": p, \"knots\": [...], \"points\": [...]}");
      }
      only_keys(n, "nurbs", {"degree", "knots", "points", "weights"});
      const double d = number(member(n, "degree", "nurbs.degree"), "nurbs.degree");
      if (d != std::floor(d) || d < NurbsCurve::kMinDegree || d > NurbsCurve::kMaxDegree) {
        fail("nurbs.degree", "= " + n["degree"].dump() +
                                 " is out of range: it must be an integer "
                                 "from 1 to 7; re-approximate the curve");
      }
      std::vector<double> weights;
      if (n.contains("weights")) weights = numbers(n["weights"], "nurbs.weights");
      try {
        seg.geometry = NurbsCurve(
            static_cast<int>(d), numbers(member(n, "knots", "nurbs.knots"), "nurbs.knots"),
            vec3s(member(n, "points", "nurbs.points"), "nurbs.points"), std::move(weights));
      } catch (const InputError& e) {
        if (std::string(e.what()).rfind(file_, 0) == 0) throw;
        fail("nurbs", std::string("is invalid: ") + e.what());
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
    json doc;
    try {
      doc = json::parse(text);
    } catch (const json::parse_error& e) {
      throw InputError(name + ": not valid JSON (" + e.what() +
                       "); fix the syntax, or if it is G-code make sure it does not start "
                       "with '{'");
    }
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
  std::ifstream in(filename, std::ios::binary);
  if (!in) {
    throw InputError(filename + ": cannot open (" + std::strerror(errno) +
                     "); check the path and its permissions");
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError(filename + ": read error; check the file");
  return read_path_text(text.str(), filename, ngc);
}

}  // namespace ncd::toolpath
