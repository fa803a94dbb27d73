// A whole program through the block encoder (docs/whole-program.md, "Events travel"): the
// setpoints of the planned path become G1 blocks as before, and the program's events and rapids
// come out at their place: M3 S, G4 P, T M6 G43 H, M0/M1, M5, M2 as blocks of their own, each
// rapid as one G0 block at the machine's rapid rate (never merged with the feed blocks), the
// rapids from an unknown position before the first planned move as "G0 Z" then "G0 X Y".
//
// Where an event or a rapid begins is known from the program: the arc length of the planned path
// up to it (the motions to_path() keeps, in the same order) and the end point of the move before
// it. The setpoints do not land there (the tool passes it within one period unless it rests
// there, as it does before every event that needs rest: to_path sets stop_before), so the block
// before it is closed at a setpoint made at that exact place and arc length, its time
// interpolated between the setpoints on either side.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "cam/whole_program.hpp"
#include "gcode/program.hpp"
#include "link/block_encoder.hpp"
#include "motion/job.hpp"

namespace ncd::comms {

// The words of an event as a block writes them (no N): "M3S3000", "G4P1.5", "T1M6", "M5",
// "M2"; empty for events the blocks carry otherwise (units: the blocks are always G21; tool
// length offsets: ProgramBlocks writes them as the controller takes them; path control: the
// blocks are within the encoder's chord tolerance).
std::string event_words(const toolpath::Event& event, int decimals = 3);

// The blocks that end a job early (docs/whole-program.md, "Ending early"), without N, from
// `at`, where the blocks sent so far leave the tool (none: not known):
//   after_reset (a controller reset cleared the modes and stopped the spindle): "G21G90", and
//     before a move in the bore "M3S…" and "G4P…" (the program's speed and dwell);
//   in the bore of an inner edge (below the plane, within bore_radius_mm + 0.01 mm of the axis):
//     "G1X…Y…Z…F…", horizontally to the drill axis (Z written: level whatever the controller's
//     parser thinks after a reset);
//   below the plane: "G0X…Y…Z…", straight up (X Y written: where the tool is, whatever the
//     controller's parser thinks after a reset);
//   then "M5", "M9", "M2" (or "M30").
// Nothing moves when `at` is not known, or at or above the plane (never down): the operator
// retracts, and the status says so.
std::vector<std::string> ending_blocks(const toolpath::SafeRetract& retract,
                                       const std::optional<Vec3>& at, int decimals,
                                       int feed_decimals, bool after_reset);

class ProgramBlocks {
 public:
  // Keeps references to both; the program's motions must be those the job plans (to_path of it).
  // segment_start_mm: where each of the job's segments starts on the path it walks, and its
  // length last (motion::Job::segment_starts_mm()); corner blending moves them off the
  // programmed vertices, and the events and rapids go with them.
  ProgramBlocks(const toolpath::Program& program, BlockEncoder& encoder,
                const std::vector<double>& segment_start_mm);
  // Throws InputError when the encoder's controller takes G43 H (EncoderSettings::
  // length_offsets) and a tool change of the program is followed by a cut before its length
  // offset (toolpath::change_without_length_offset).
  //
  // "%", the header comments, then a comment for each move the blocks write that the program
  // did not (a rapid from an unknown position split into Z first, then X Y), the preamble
  // "G21G90G94G17G40G49" (and "G64P<chord tolerance>" where the dialect takes G64), then what
  // comes before the first planned move.
  void begin(const std::vector<std::string>& header);
  void push(const motion::Setpoint& sp);
  // What follows the last planned move (M5, M2), finish(), "%".
  void end();

 private:
  enum class Kind { Event, Rapid, Pre };
  struct Mark {
    Kind kind = Kind::Event;
    double s0_mm = 0.0, s1_mm = 0.0;
    Vec3 end = Vec3::Zero();  // rapids: where they go
    bool rapid = false;       // a Pre mark that is a rapid from an unknown position
    std::array<bool, 3> axes{true, true, true};  // a Pre rapid's axes the program gave
    toolpath::SourceRef src;
    toolpath::Event event;
  };
  // The header comments for the Pre rapids that begin() splits (Z first, then X Y).
  std::vector<std::string> split_notes() const;
  void push_at(double s_mm, const motion::Setpoint& sp);
  double fraction_at(double s_mm, const motion::Setpoint& sp) const;
  void write_event(const toolpath::Event& e);

  BlockEncoder& encoder_;
  std::vector<Mark> marks_;
  std::size_t next_ = 0;
  bool in_rapid_ = false;
  bool first_ = true;
  double pushed_s_mm_ = 0.0, pushed_t_s_ = 0.0;  // the last setpoint handed to the encoder
  double seen_s_mm_ = 0.0, seen_t_s_ = 0.0;      // the last setpoint received
  Vec3 seen_p_ = Vec3::Zero();
  int decimals_ = 3;
  const toolpath::Program& program_;
};

}  // namespace ncd::comms
