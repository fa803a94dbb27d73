// Cutter radius compensation (G41/G42, G41.1/G42.1, G40) in the XY or XZ plane, giving the same
// canonical moves as LinuxCNC 2.9's interpreter. The algorithm and the decisions taken are
// explained at the top of cutter_comp.cpp and in docs/ngc-interpreter.md ("Cutter radius
// compensation").
#pragma once

#include <string>
#include <vector>

#include "gcode/program.hpp"

namespace ncd::toolpath {

// A program error found by the compensation (the interpreter adds file:line and the block).
struct CutterCompError {
  std::string what;
};

class CutterComp {
 public:
  enum class Side { off, left, right };

  // Moves and events leave through `out` (the program's steps), in LinuxCNC's canonical order.
  explicit CutterComp(std::vector<Step>& out) : out_(&out) {}

  // G41/G42 at the tool position `at_mm` (program coordinates, mm) in `plane` (XY or XZ). A
  // negative radius switches the side, as LinuxCNC does. The tolerances depend on the program's
  // units (mm per unit).
  void start(Side side, double radius_mm, const Vec3& at_mm, double mm_per_unit, Plane plane);
  // The first move written starts at `at_mm` rather than at start()'s point: after G40 the
  // tool stands at its compensated position while the programmed point is the current one.
  void first_written_from(const Vec3& at_mm) { written_ = to_local(at_mm); }
  // G40: the pending move is written and compensation ends; returns where the tool is.
  Vec3 stop();
  // M0/M1/M60/M2/M30 and the end of the file: the pending moves and events are written.
  void flush();

  bool on() const { return side_ != Side::off; }
  Side side() const { return side_; }
  // Moves are offset only with a radius above zero (G41 with a tool of diameter 0 changes nothing).
  bool offsetting() const { return on() && radius_mm_ > 0.0; }
  bool first_move() const { return first_; }
  bool pending() const { return !queue_.empty(); }
  // The programmed point (LinuxCNC's program_x/y/z) and the tool's compensated position (mm).
  Vec3 programmed() const { return to_global(prog_); }
  Vec3 tool() const { return to_global(tool_); }

  // A straight move (G0/G1) to the programmed point `end_mm`. `m` carries the move's feed,
  // spindle, source line and so on; its geometry and start are set here.
  void line(const Vec3& end_mm, Motion m);
  // An arc to the programmed `end_mm` about the programmed centre (cx, cy: its coordinates on
  // the plane's first and second axes, Z and X in G18) with LinuxCNC's
  // turns (+ counter-clockwise, − clockwise). For the first move the centre is the one through
  // the tool's position (the programmed one then).
  void arc(const Vec3& end_mm, double cx_mm, double cy_mm, int turns, Motion m);
  // An event (spindle, coolant, dwell) that LinuxCNC queues behind a pending move.
  void event(Step s);

 private:
  struct Entry {
    bool is_move = false;
    Step step;  // events
    Motion motion;
    bool arc = false;
    Vec3 end_mm{0, 0, 0};
    double cx = 0.0, cy = 0.0;  // arc centre, mm
    int turns = 0;
    double dir_x = 0.0, dir_y = 0.0;  // programmed direction of a straight move (gouge test)
    double sweep = 0.0;               // the arc's programmed sweep when queued (0: not checked)
  };
  void enqueue_line(const Vec3& end_mm, double dir_x, double dir_y, const Motion& m);
  void enqueue_arc(const Vec3& end_mm, double cx, double cy, int turns, double sweep,
                   const Motion& m);
  void write_queue();                           // LinuxCNC's dequeue_canons
  void move_end_and_write(double x, double y);  // LinuxCNC's move_endpoint_and_flush
  void entry_arc(const Vec3& end_mm, double cx, double cy, int turns, const Motion& m);
  void concave_arc_corner(const Entry& prev, double cx, double cy, int turns, bool inside,
                          double arc_r, double theta, double beta);
  void set_anchor(double x, double y) {
    anchor_x_ = x;
    anchor_y_ = y;
    anchor_valid_ = true;
  }
  const Entry* front_move() const;
  // Inside, points are (first, second, axis) of the plane: (X, Y, Z) in G17, (Z, X, Y) in G18.
  Vec3 to_local(const Vec3& g) const { return Vec3(g[ax_.first], g[ax_.second], g[ax_.axis]); }
  Vec3 to_global(const Vec3& l) const {
    Vec3 g;
    g[ax_.first] = l.x();
    g[ax_.second] = l.y();
    g[ax_.axis] = l.z();
    return g;
  }

  std::vector<Step>* out_;
  std::vector<Entry> queue_;
  Side side_ = Side::off;
  Plane plane_ = Plane::xy;
  PlaneAxes ax_{0, 1, 2};
  double radius_mm_ = 0.0;
  double mm_per_unit_ = 1.0;
  bool first_ = true;
  Vec3 prog_{0, 0, 0}, tool_{0, 0, 0};
  Vec3 written_{0, 0, 0};  // end of the last move written: the next one's start
  // Start of the first queued move (LinuxCNC's "endpoint"), for the gouge tests.
  double anchor_x_ = 0.0, anchor_y_ = 0.0;
  bool anchor_valid_ = false;
};

}  // namespace ncd::toolpath
