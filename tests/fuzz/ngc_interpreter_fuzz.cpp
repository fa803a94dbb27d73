// libFuzzer harness of the RS-274/NGC interpreter (docs/ngc-interpreter.md): any bytes are a
// program; the interpreter either returns a program or throws InputError, never crashes or
// hangs (loops are bounded by InterpretOptions::max_blocks), and no move it returns carries a
// NaN or an infinity; to_path keeps that property. The machine has a rotary index axis for a
// third of the inputs each ([axis.a], [axis.b]; by the input's length), so A and B words are
// read as indexes as often as they are refused, and an index carries no NaN either.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "core/error.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "gcode/program.hpp"

namespace {

bool finite(const ncd::Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ncd::toolpath;
  const std::string text(reinterpret_cast<const char*>(data), size);
  InterpretOptions opt;
  opt.max_blocks = 20000;  // a fuzzed endless loop ends quickly
  opt.rotary_axis = size % 3 == 1 ? 'a' : size % 3 == 2 ? 'b' : '\0';
  Program p;
  try {
    p = interpret_ngc(text, "fuzz.ngc", opt);
  } catch (const ncd::InputError&) {
    return 0;
  }
  for (const Step& s : p.steps) {
    if (const auto* e = std::get_if<Event>(&s.item)) {
      if (const auto* ix = std::get_if<RotaryIndexMove>(e)) {
        if (!std::isfinite(ix->from_deg) || !std::isfinite(ix->to_deg) ||
            !std::isfinite(ix->feed_deg_per_min) || ix->axis != opt.rotary_axis) {
          std::abort();
        }
      }
    }
    if (const auto* m = std::get_if<Motion>(&s.item)) {
      if (!finite(m->start) || !finite(motion_end(*m)) || !std::isfinite(m->feed)) std::abort();
      if (const auto* a = std::get_if<ArcMove>(&m->geometry)) {
        if (!finite(a->centre)) std::abort();
      }
    }
  }
  try {
    const ncd::toolpath::Path path = to_path(p);
    for (const auto& seg : path.segments) {
      if (seg.feed_mm_per_min && !std::isfinite(*seg.feed_mm_per_min)) std::abort();
    }
  } catch (const ncd::InputError&) {
  }
  return 0;
}
