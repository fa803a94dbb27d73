// Events and rapids of a whole program into the block encoder (program_blocks.hpp).
#include "link/program_blocks.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <stdexcept>

#include "core/error.hpp"

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

std::string event_words(const toolpath::Event& event, int decimals) {
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
          return "T" + t + "M6";
        } else if constexpr (std::is_same_v<T, StopEvent>) {
          return e.kind == StopKind::program_stop    ? "M0"
                 : e.kind == StopKind::optional_stop ? "M1"
                                                     : "M60";
        } else if constexpr (std::is_same_v<T, EndEvent>) {
          return e.m == 30 ? "M30" : "M2";
        } else if constexpr (std::is_same_v<T, RotaryIndexMove>) {
          return "G0" + std::string(1, static_cast<char>(std::toupper(e.axis))) +
                 number(e.to_deg, decimals);
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
    : encoder_(encoder), decimals_(encoder.settings().decimals), program_(program) {
  using namespace toolpath;
  if (encoder.settings().length_offsets) {
    if (auto missing = change_without_length_offset(program)) throw InputError(*missing);
  }
  for (const Step& step : program.steps) {  // an index the controller cannot take: refused now
    const auto* ev = std::get_if<Event>(&step.item);
    const auto* ix = ev ? std::get_if<RotaryIndexMove>(ev) : nullptr;
    if (!ix) continue;
    if (const std::string why = rotary_refusal(encoder.settings(), ix->axis); !why.empty()) {
      throw InputError(where(program, step.src) + ": " + why);
    }
  }
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
      m.src = step.src;
      m.event = *ev;
      marks_.push_back(std::move(m));
      continue;
    }
    const Motion& mo = std::get<Motion>(step.item);
    if (!mo.rapid) continue;
    Mark m;
    m.end = (motion_end(mo) + mo.offset) * mm_per_unit(mo.units);
    m.src = step.src;
    if (!mo.start_known) {  // from an unknown position: written by begin()
      m.kind = Kind::Pre;
      m.rapid = true;
      m.axes = mo.end_known;
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
  if (const auto* ix = std::get_if<toolpath::RotaryIndexMove>(&e)) {
    encoder_.index(ix->axis, ix->to_deg);
    return;
  }
  if (const auto* msg = std::get_if<toolpath::MessageEvent>(&e)) {
    encoder_.comment("MSG, " + msg->text);
    return;
  }
  if (const auto* off = std::get_if<toolpath::ToolOffsetEvent>(&e)) {
    // The controller's own table gives tool h's length: the blocks leave it out of the
    // coordinates. G43.1 and G49 leave the controller without one (the coordinates hold the
    // program's G43.1 length, as the planned path does).
    if (!encoder_.settings().length_offsets) return;  // grbl: the coordinates hold it
    if (off->h > 0) {
      encoder_.words("G43H" + std::to_string(off->h));
      encoder_.set_offset(off->offset * toolpath::mm_per_unit(off->units));
    } else {
      encoder_.words("G49");
      encoder_.set_offset(Vec3::Zero());
    }
    return;
  }
  const std::string w = event_words(e, decimals_);
  if (w.empty()) return;
  const double dwell = std::holds_alternative<toolpath::DwellEvent>(e)
                           ? std::get<toolpath::DwellEvent>(e).seconds
                           : 0.0;
  encoder_.words(w, dwell);
}

// begin() writes a rapid from an unknown position with the axes its program gave; one that
// moves Z and across goes Z first (the tool never moves sideways below the height the program
// asked for). Which of them write a Z and an X Y is followed here as the encoder will: an axis
// is written when the controller does not hold its value (at the encoder's decimals, in the
// coordinates less the length offset in force).
std::vector<std::string> ProgramBlocks::split_notes() const {
  std::vector<std::string> notes;
  const double scale = std::pow(10.0, decimals_);
  std::array<std::optional<long long>, 3> held;
  Vec3 offset = Vec3::Zero();
  const bool lengths = encoder_.settings().length_offsets;
  for (std::size_t i = 0; i < marks_.size() && marks_[i].kind == Kind::Pre; ++i) {
    const Mark& m = marks_[i];
    if (!m.rapid) {
      if (const auto* off = std::get_if<toolpath::ToolOffsetEvent>(&m.event); off && lengths) {
        offset = off->h > 0 ? Vec3(off->offset * toolpath::mm_per_unit(off->units)) : Vec3::Zero();
        held = {};
      }
      continue;
    }
    std::array<bool, 3> writes{};
    std::array<long long, 3> q{};
    for (std::size_t a = 0; a < 3; ++a) {
      q[a] = std::llround(
          (m.end[static_cast<Eigen::Index>(a)] - offset[static_cast<Eigen::Index>(a)]) * scale);
      writes[a] = m.axes[a] && (!held[a] || *held[a] != q[a]);
      if (writes[a]) held[a] = q[a];
    }
    // A generated job's first rapid is its documented approach (its header says so).
    if (!writes[2] || !(writes[0] || writes[1]) || m.src.line == 0) continue;
    std::string across;
    for (std::size_t a = 0; a < 2; ++a) {
      if (writes[a]) {
        across += std::string(across.empty() ? "" : " ") + "XY"[a] +
                  number(static_cast<double>(q[a]) / scale, decimals_);
      }
    }
    // Short (a line longer than a drip controller's XON level deadlocks its buffer: the
    // simulated controller's 256 B buffer resumes at 96 B); the first header line names the
    // file already.
    const std::string at =
        m.src.file == 0
            ? "line " + std::to_string(m.src.line)
            : std::filesystem::path(toolpath::where(program_, m.src)).filename().string();
    notes.push_back("ncd: " + at + "'s rapid from an unknown position: G0 Z" +
                    number(static_cast<double>(q[2]) / scale, decimals_) + " first, then G0 " +
                    across);
  }
  return notes;
}

void ProgramBlocks::begin(const std::vector<std::string>& header) {
  encoder_.percent_line();
  for (const std::string& h : header) encoder_.comment(h);
  for (const std::string& h : split_notes()) encoder_.comment(h);
  const EncoderSettings& e = encoder_.settings();
  encoder_.words("G21G90G94G17G40G49" +
                 (e.path_blending ? "G64P" + number(e.chord_tolerance_mm, 6) : std::string()));
  while (next_ < marks_.size() && marks_[next_].kind == Kind::Pre) {
    const Mark& m = marks_[next_++];
    if (m.rapid) {
      // From an unknown position, with the axes the program gave: Z first, then across.
      encoder_.rapid(m.end, 0.0, 0.0, {false, false, m.axes[2]});
      encoder_.rapid(m.end, 0.0, 0.0, {m.axes[0], m.axes[1], false});
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
    // A rotary index: the encoder writes it from the periods that make it (BlockEncoder::push),
    // at the one that lands it; the events after it wait for that, in the program's order.
    if (m.kind == Kind::Event && std::holds_alternative<toolpath::RotaryIndexMove>(m.event)) {
      if (!consumed) {
        encoder_.push(sp);
        pushed_s_mm_ = sp.s_mm;
        pushed_t_s_ = sp.t_s;
        consumed = true;
      }
      if (sp.limit_id != motion::kLimitIdIndex || sp.indexing) break;  // not landed yet
      ++next_;
      const bool another = next_ < marks_.size() && marks_[next_].kind == Kind::Event &&
                           std::holds_alternative<toolpath::RotaryIndexMove>(marks_[next_].event);
      if (another) break;  // the next index lands in periods still to come
      continue;
    }
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
