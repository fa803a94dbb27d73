// Events and rapids of a whole program into the block encoder (program_blocks.hpp).
#include "comms/program_blocks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace ncd::comms {
namespace {

constexpr double kAtMm = 1e-6;  // a setpoint this near an event's arc length is at it

std::string number(double v, int decimals) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  std::string s = b;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
  }
  return s == "-0." ? "0." : s;
}

}  // namespace

std::string event_words(const toolpath::Event& event, int decimals, bool length_offset) {
  using namespace toolpath;
  return std::visit(
      [&](const auto& e) -> std::string {
        using T = std::decay_t<decltype(e)>;
        if constexpr (std::is_same_v<T, SpindleEvent>) {
          if (e.dir == SpindleDir::off) return "M5";
          return (e.dir == SpindleDir::cw ? "M3S" : "M4S") + number(e.rpm, 0);
        } else if constexpr (std::is_same_v<T, CoolantEvent>) {
          if (!e.mist && !e.flood) return "M9";
          return std::string(e.mist ? "M7" : "") + (e.flood ? "M8" : "");
        } else if constexpr (std::is_same_v<T, DwellEvent>) {
          return "G4P" + number(e.seconds, decimals);
        } else if constexpr (std::is_same_v<T, ToolChangeEvent>) {
          const std::string t = std::to_string(e.tool);
          return "T" + t + "M6" + (length_offset ? "G43H" + t : std::string());
        } else if constexpr (std::is_same_v<T, StopEvent>) {
          return e.kind == StopKind::program_stop    ? "M0"
                 : e.kind == StopKind::optional_stop ? "M1"
                                                     : "M60";
        } else if constexpr (std::is_same_v<T, EndEvent>) {
          return e.m == 30 ? "M30" : "M2";
        } else {
          return "";  // units, tool offset, path control, messages (comments)
        }
      },
      event);
}

ProgramBlocks::ProgramBlocks(const toolpath::Program& program, BlockEncoder& encoder)
    : encoder_(encoder), decimals_(encoder.settings().decimals) {
  using namespace toolpath;
  // The same walk as to_path(): planned motions add their length; rapids from an unknown
  // position, and events before the first planned motion, are written by begin().
  double s = 0.0;
  bool planned = false;
  Vec3 at = Vec3::Zero();
  for (const Step& step : program.steps) {
    if (const auto* ev = std::get_if<Event>(&step.item)) {
      Mark m;
      m.kind = planned ? Kind::Event : Kind::Pre;
      m.s0_mm = m.s1_mm = s;
      m.at = at;
      m.event = *ev;
      marks_.push_back(std::move(m));
      continue;
    }
    const Motion& mo = std::get<Motion>(step.item);
    const double k = mm_per_unit(mo.units);
    const Vec3 end = (motion_end(mo) + mo.offset) * k;
    if (!mo.start_known) {
      if (mo.rapid) {
        Mark m;
        m.kind = Kind::Pre;
        m.at = at;
        m.end = end;
        m.rapid = true;
        marks_.push_back(std::move(m));
        at = end;
      }
      continue;
    }
    const double len = motion_length(mo) * k;
    if (len < 1e-9) continue;  // to_path's kMinMoveMm
    planned = true;
    if (mo.rapid) {
      Mark m;
      m.kind = Kind::Rapid;
      m.s0_mm = s;
      m.s1_mm = s + len;
      m.at = (mo.start + mo.offset) * k;
      m.end = end;
      marks_.push_back(std::move(m));
    }
    s += len;
    at = end;
  }
}

void ProgramBlocks::write_event(const toolpath::Event& e) {
  if (const auto* msg = std::get_if<toolpath::MessageEvent>(&e)) {
    encoder_.comment("MSG, " + msg->text);
    return;
  }
  const std::string w = event_words(e, decimals_, length_offset_);
  if (w.empty()) return;
  const double dwell = std::holds_alternative<toolpath::DwellEvent>(e)
                           ? std::get<toolpath::DwellEvent>(e).seconds
                           : 0.0;
  encoder_.words(w, dwell);
}

void ProgramBlocks::begin(const std::vector<std::string>& header) {
  encoder_.percent_line();
  for (const std::string& h : header) encoder_.comment(h);
  encoder_.words("G21G90G94G17G40G49");
  while (next_ < marks_.size() && marks_[next_].kind == Kind::Pre) {
    const Mark& m = marks_[next_++];
    if (m.rapid) {
      // From an unknown position: up to the target's Z first, then across.
      encoder_.words("G0Z" + number(m.end.z(), decimals_));
      encoder_.rapid(m.end, 0.0, 0.0);
    } else {
      write_event(m.event);
    }
  }
}

double ProgramBlocks::time_at(double s_mm, const motion::Setpoint& sp) const {
  if (sp.s_mm - seen_s_mm_ <= 0.0) return sp.t_s;
  const double f = std::clamp((s_mm - seen_s_mm_) / (sp.s_mm - seen_s_mm_), 0.0, 1.0);
  return seen_t_s_ + f * (sp.t_s - seen_t_s_);
}

void ProgramBlocks::push_at(const Vec3& p, double s_mm, double t_s) {
  if (s_mm <= pushed_s_mm_ + kAtMm || t_s <= pushed_t_s_) return;  // already there
  motion::Setpoint q;
  q.p = p;
  q.s_mm = s_mm;
  q.t_s = t_s;
  encoder_.push(q);
  pushed_s_mm_ = s_mm;
  pushed_t_s_ = t_s;
}

void ProgramBlocks::push(const motion::Setpoint& sp) {
  if (first_) {
    first_ = false;
    // The start of the path: where the rapids of begin() left the tool, or (none) the
    // positioning block.
    bool pre_rapid = false;
    for (std::size_t i = 0; i < next_; ++i) pre_rapid |= marks_[i].rapid;
    if (!pre_rapid) encoder_.push(sp);
    pushed_s_mm_ = seen_s_mm_ = sp.s_mm;
    pushed_t_s_ = seen_t_s_ = sp.t_s;
  }
  bool consumed = sp.t_s <= pushed_t_s_;
  while (next_ < marks_.size()) {
    const Mark& m = marks_[next_];
    if (in_rapid_) {
      if (sp.s_mm < m.s1_mm - kAtMm && !sp.done) break;  // still on its way
      const bool here = std::abs(sp.s_mm - m.s1_mm) <= kAtMm;
      const double t = here ? sp.t_s : time_at(m.s1_mm, sp);
      encoder_.rapid(m.end, t, m.s1_mm);
      pushed_s_mm_ = m.s1_mm;
      pushed_t_s_ = t;
      consumed |= here;
      in_rapid_ = false;
      ++next_;
      continue;
    }
    if (m.s0_mm > sp.s_mm + kAtMm && !sp.done) break;  // ahead
    // The tool reached or passed the mark: close the blocks before it at its place.
    if (!consumed && std::abs(sp.s_mm - m.s0_mm) <= kAtMm) {
      encoder_.push(sp);
      pushed_s_mm_ = sp.s_mm;
      pushed_t_s_ = sp.t_s;
      consumed = true;
    } else {
      push_at(m.at, m.s0_mm, time_at(m.s0_mm, sp));
    }
    if (m.kind == Kind::Rapid) {
      in_rapid_ = true;
      continue;
    }
    write_event(m.event);
    ++next_;
  }
  if (!consumed && !in_rapid_) {
    encoder_.push(sp);
    pushed_s_mm_ = sp.s_mm;
    pushed_t_s_ = sp.t_s;
  }
  seen_s_mm_ = sp.s_mm;
  seen_t_s_ = sp.t_s;
}

void ProgramBlocks::end() {
  for (; next_ < marks_.size(); ++next_) {
    const Mark& m = marks_[next_];
    if (m.kind == Kind::Rapid) {
      encoder_.rapid(m.end, pushed_t_s_, m.s1_mm);
    } else {
      write_event(m.event);
    }
  }
  encoder_.finish();
  encoder_.percent_line();
}

}  // namespace ncd::comms
