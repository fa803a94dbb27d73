// Events and rapids of a whole program into the block encoder (program_blocks.hpp).
#include "comms/program_blocks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

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

std::vector<std::string> ending_blocks(const toolpath::SafeRetract& r,
                                       const std::optional<Vec3>& at, int decimals,
                                       int feed_decimals, bool after_reset) {
  std::vector<std::string> out;
  if (after_reset) out.push_back("G21G90");
  const double tol_mm = 0.5 * std::pow(10.0, -decimals);  // a move shorter is not written
  if (at && at->z() < r.clearance_z_mm - tol_mm) {
    bool to_axis = false;  // in the bore: the rise starts from the drill axis
    if (r.axis_xy) {
      const double off_mm = std::hypot(at->x() - r.axis_xy->x(), at->y() - r.axis_xy->y());
      if (off_mm <= r.bore_radius_mm + 0.01) {  // in the bore: back to the axis first
        if (after_reset && r.spindle_rpm > 0.0) {
          out.push_back("M3S" + number(r.spindle_rpm, 0));
          if (r.spindle_dwell_s > 0.0) out.push_back("G4P" + number(r.spindle_dwell_s, decimals));
        }
        to_axis = true;
        if (off_mm > tol_mm) {
          // Z written: a controller whose parser lost the position in a reset keeps it level.
          out.push_back("G1X" + number(r.axis_xy->x(), decimals) + "Y" +
                        number(r.axis_xy->y(), decimals) + "Z" + number(at->z(), decimals) + "F" +
                        number(r.feed_mm_per_min, feed_decimals));
        }
      }
    }
    // X Y written: straight up from where the tool is, whatever the controller's parser thinks.
    const Vec3 xy = to_axis ? *r.axis_xy : *at;
    out.push_back("G0X" + number(xy.x(), decimals) + "Y" + number(xy.y(), decimals) + "Z" +
                  number(r.clearance_z_mm, decimals));
  }
  out.push_back("M5");
  out.push_back("M9");
  out.push_back(r.end_m == 30 ? "M30" : "M2");
  return out;
}

ProgramBlocks::ProgramBlocks(const toolpath::Program& program, BlockEncoder& encoder,
                             const std::vector<double>& segment_start_mm)
    : encoder_(encoder), decimals_(encoder.settings().decimals) {
  using namespace toolpath;
  // Where to_path() puts each step: an event at the start of a segment, a rapid as a segment
  // of its own. Their places on the walked path are that segment's start and end there.
  std::vector<std::size_t> place;
  ToPathOptions options;
  options.segment_of_step = &place;
  const std::size_t segments = to_path(program, options).segments.size();
  if (segment_start_mm.size() != segments + 1) {
    throw std::logic_error("ProgramBlocks: " + std::to_string(segment_start_mm.size()) +
                           " segment starts for a program of " + std::to_string(segments) +
                           " segments");
  }
  for (std::size_t i = 0; i < program.steps.size(); ++i) {
    const Step& step = program.steps[i];
    const std::size_t k = place[i];
    if (const auto* ev = std::get_if<Event>(&step.item)) {
      Mark m;
      m.kind = k > 0 ? Kind::Event : Kind::Pre;  // events before the first planned motion: begin()
      m.s0_mm = m.s1_mm = segment_start_mm[k];
      m.event = *ev;
      marks_.push_back(std::move(m));
      continue;
    }
    const Motion& mo = std::get<Motion>(step.item);
    if (!mo.rapid) continue;
    Mark m;
    m.end = (motion_end(mo) + mo.offset) * mm_per_unit(mo.units);
    if (!mo.start_known) {  // from an unknown position: written by begin()
      m.kind = Kind::Pre;
      m.rapid = true;
      marks_.push_back(std::move(m));
    } else if (k != kNoSegment) {
      m.kind = Kind::Rapid;
      m.s0_mm = segment_start_mm[k];
      m.s1_mm = segment_start_mm[k + 1];
      marks_.push_back(std::move(m));
    }
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
  const EncoderSettings& e = encoder_.settings();
  encoder_.words("G21G90G94G17G40G49" +
                 (e.path_blending ? "G64P" + number(e.chord_tolerance_mm, 6) : std::string()));
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

// Where s_mm lies between the last setpoint received and sp, 0..1.
double ProgramBlocks::fraction_at(double s_mm, const motion::Setpoint& sp) const {
  if (sp.s_mm - seen_s_mm_ <= 0.0) return 1.0;
  return std::clamp((s_mm - seen_s_mm_) / (sp.s_mm - seen_s_mm_), 0.0, 1.0);
}

// The walked point at s_mm (between the last setpoint and sp), unless the encoder has it.
void ProgramBlocks::push_at(double s_mm, const motion::Setpoint& sp) {
  const double f = fraction_at(s_mm, sp);
  const double t_s = seen_t_s_ + f * (sp.t_s - seen_t_s_);
  if (s_mm <= pushed_s_mm_ + kAtMm || t_s <= pushed_t_s_) return;  // already there
  motion::Setpoint q;
  q.p = seen_p_ + f * (sp.p - seen_p_);
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
    seen_p_ = sp.p;
  }
  bool consumed = sp.t_s <= pushed_t_s_;
  while (next_ < marks_.size()) {
    const Mark& m = marks_[next_];
    if (in_rapid_) {
      if (sp.s_mm < m.s1_mm - kAtMm && !sp.done) break;  // still on its way
      const bool here = std::abs(sp.s_mm - m.s1_mm) <= kAtMm;
      const double t = here ? sp.t_s : seen_t_s_ + fraction_at(m.s1_mm, sp) * (sp.t_s - seen_t_s_);
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
      push_at(m.s0_mm, sp);
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
  seen_p_ = sp.p;
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
