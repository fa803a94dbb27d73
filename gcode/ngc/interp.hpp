// The RS-274/NGC interpreter's state and the declarations its files share (gcode/ngc/*.cpp:
// one file per concern, as LinuxCNC's interp_read, interp_convert, interp_cycles, interp_o_word).
// The reading and execution order is explained once, in interpreter.cpp. Private to gcode/ngc:
// the rest of ncd includes gcode/ngc/interpreter.hpp.
#pragma once

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "gcode/cutter_comp.hpp"
#include "gcode/lexer.hpp"
#include "gcode/ngc/interpreter.hpp"

namespace ncd::toolpath::ngc {

constexpr int kMaxParam = 5602;
constexpr double kTolEqual = 1e-6;  // LinuxCNC's TOLERANCE_EQUAL for EQ/NE and friends
// Bounds on what a program may ask for (mm, mm/min, rpm, s): beyond them the value is a typo.
constexpr double kMaxCoordMm = 1e6;
constexpr double kMinFeedMmPerMin = 1e-3;
constexpr double kMaxFeedMmPerMin = 1e7;  // an F above the machine's maximum runs at it (LinuxCNC's
                                          // way; 3D_Chips.ngc writes F4.5e6)
constexpr double kMaxSpindleRpm = 1e6;
constexpr double kMaxDwellS = 1e5;
constexpr int kMaxTurns = 10000;
constexpr int kMaxCallDepth = 100;

struct Fail {
  std::string what;
};

[[noreturn]] void fail(std::string what);

std::string g_name(int code10);

struct SourceFile {
  std::string name;
  std::string text;
  std::vector<std::string_view> lines;
};

// One O-word line.
struct OLine {
  std::string label;
  std::string keyword;
  std::size_t args_at = 0;  // position in the normalised line after the keyword
};

struct Block {
  std::array<double, 26> val{};
  std::uint32_t mask = 0;
  std::array<int, 16> g{};
  int ng = 0;
  std::array<int, 8> m{};
  int nm = 0;
  bool has_message = false;
  std::string message;
  std::optional<double> polar_radius, polar_angle_deg;  // @ and ^ (program units, degrees)
  bool has(char c) const { return (mask & (1u << (c - 'a'))) != 0; }
  bool has_polar() const { return polar_radius || polar_angle_deg; }
  bool has_xyz_or_polar() const { return has('x') || has('y') || has('z') || has_polar(); }
  double v(char c) const { return val[static_cast<std::size_t>(c - 'a')]; }
  bool has_g(int code) const {
    for (int i = 0; i < ng; ++i) {
      if (g[static_cast<std::size_t>(i)] == code) return true;
    }
    return false;
  }
  bool has_m(int code) const {
    for (int i = 0; i < nm; ++i) {
      if (m[static_cast<std::size_t>(i)] == code) return true;
    }
    return false;
  }
};

// Modal group of a G code ×10 (LinuxCNC's table), −1 when unknown.
int g_group(int c);

int m_group(int c);
// The G code ×10 of coordinate system n (1 = G54 … 9 = G59.3): 540 … 593.
int coord_system_code(int n);

// Out-of-scope G codes: the refusal text (construct and way out); empty when supported.
std::string g_refusal(int c);

std::string m_refusal(int c);

class Interpreter {
 public:
  Interpreter(const InterpretOptions& o) : opt_(o) {
    params_.assign(kMaxParam + 1, 0.0);
    param_given_.assign(kMaxParam + 1, false);
    machine_k_ = mm_per_unit(opt_.machine_units);
    units_ = opt_.default_units;
    program_.units = units_;
    // LinuxCNC 2.9's peck clearance: 0.010 inch whatever the units.
    params_[5220] = 1.0;
    params_[5599] = 1.0;  // (DEBUG,) messages on, as LinuxCNC starts
  }

  Program run(const std::string& text, const std::string& name);
  std::string where() const;
  std::string line_text() const;

 private:
  // ---- files.cpp: files, tool table, parameters -------------------------------------------------
  static void split_lines(SourceFile& f);
  static std::string read_file(const std::string& path, const char* what);
  void load_tool_table();
  void load_parameters();

 public:
  std::string parameter_file_text() const;

 private:
  static const std::vector<int>& persistent_parameters();
  static std::string format_parameter(double v);
  double param_len(int index) const;

  // ---- o_words.cpp: O-word scanning -------------------------------------------------------------
  static void normalise(std::string_view line, std::string& out, std::string* comment,
                        bool* has_comment);
  static bool parse_oline(const std::string& s, OLine& o);
  bool oline_at(std::size_t file, std::size_t line, OLine& o);
  void scan_subs(std::size_t file);

  std::size_t seek(const std::string& label, std::initializer_list<const char*> keywords,
                   std::string& found);

  // ---- expressions.cpp: expressions -------------------------------------------------------------
  double read_number(const std::string& s, std::size_t& i);
  double read_value(const std::string& s, std::size_t& i);
  static int precedence(int op);
  int read_operator(const std::string& s, std::size_t& i);
  static double apply(int op, double a, double b);
  double read_expression(const std::string& s, std::size_t& i);
  double read_function(const std::string& s, std::size_t& i);
  int param_index(const std::string& s, std::size_t& i);
  std::string read_name(const std::string& s, std::size_t& i);
  bool named_exists(const std::string& name) const;
  bool predefined(const std::string& name, double* out) const;
  double read_parameter(const std::string& s, std::size_t& i);

  // ---- read.cpp: reading a line -----------------------------------------------------------------
  struct Assign {
    int index = 0;     // numbered, or 0 for named
    std::string name;  // named
    double value = 0.0;
  };

  void read_block(const std::string& s, std::size_t i, Block& b);

  // ---- main_loop.cpp: the main loop -------------------------------------------------------------
  struct Loop {
    enum Kind { while_loop, do_loop, repeat_loop } kind = while_loop;
    std::size_t start = 0;
    long remaining = 0;
  };
  // ---- modes.cpp: M70-M73, the modal state saved and restored --------------------------------
  struct SavedModes {
    Units units = Units::mm;
    Plane plane = Plane::xy;
    bool incremental = false, ijk_absolute = false, retract_r = true;
    FeedMode feed_mode = FeedMode::per_minute;
    int coord_sys = 1;
    bool length_on = false;
    Vec3 tool_offset{0, 0, 0};
    int tool_offset_h = -1;
    CutterComp::Side comp = CutterComp::Side::off;
    PathControlEvent control{};
    double feed = 0.0, speed = 0.0;
    SpindleDir spindle = SpindleDir::off;
    bool mist = false, flood = false;
    bool diameter_mode = false;  // G7
  };
  SavedModes current_modes() const;
  void restore_modes(const SavedModes& m, const char* code);
  void save_restore_modes(const Block& b);

  struct Frame {
    std::size_t file = 0;
    std::optional<SavedModes> m70;  // M70 at this call level (M71 clears it, M72 restores it)
    std::optional<SavedModes> m73;  // M73: restored when this call returns
    std::size_t return_line = 0;
    std::string sub;
    std::unordered_map<std::string, double> locals;
    std::array<double, 30> saved{};
    std::map<std::string, Loop> loops;
  };

  void execute_all();
  void execute_line(const std::string* comment);
  static bool comment_is(const std::string& c, const std::string& tag);
  std::string expand_debug(const std::string& text) const;
  bool condition(const OLine& o);
  void execute_oword(const OLine& o);
  void o_return(const OLine& o);
  void o_call(const OLine& o);
  void o_while(const OLine& o);
  void o_repeat(const OLine& o);
  void o_endrepeat(const OLine& o);
  void o_break_or_continue(const OLine& o);
  void branch_skip(const std::string& label);

  std::unordered_map<std::string, std::pair<std::size_t, std::size_t>>::iterator load_sub_file(
      const std::string& label);

  // ---- execute.cpp: execution of a block --------------------------------------------------------
  double k() const;
  Vec3 g5x() const;
  Vec3 total_offset() const;
  void check_block(const Block& b);
  void check_words_used(const Block& b, int motion_word, int nonmodal) const;
  double len_word(const Block& b, char c) const;
  void emit(Event e);

  template <class F>
  void comp_call(F&& f) {
    try {
      f();
    } catch (const CutterCompError& e) {
      fail(e.what);
    }
  }

  void refuse_with_comp(const std::string& what) const;
  SourceRef src() const;
  void emit_motion(Motion&& m);
  Motion base_motion(bool rapid) const;
  void settle_known();
  void line_to(const Vec3& end_mm, bool rapid);
  void execute_block(Block& b);
  std::string missing_tool_way_out(int tool) const;
  void set_feed(const Block& b);
  void set_spindle_and_tool(const Block& b);
  void set_coolant(const Block& b);
  void dwell(const Block& b);
  void set_plane_and_units(const Block& b);
  void set_tool_length_offset(const Block& b);
  void select_coordinate_system(int cs);
  void set_path_control(const Block& b, int pc);
  void set_distance_and_retract_modes(const Block& b);
  bool execute_non_modal(const Block& b, int nonmodal);
  void execute_motion(Block& b, int motion_word, bool axes_used);
  void execute_stops(const Block& b);
  void reread_position();                  // after M6, M61 (execute.cpp)
  void set_lathe_diameter_mode(Block& b);  // G7, G8
  void cutter_comp(const Block& b, int code);
  Vec3 from() const;
  Vec3 target(const Block& b, bool g53);
  void polar_target(const Block& b, const Vec3& base, Vec3& t);
  void polar_point(const Block& b, const Vec3& base, Vec3& t) const;
  void check_polar(const Block& b, int motion, int nonmodal) const;
  void motion(Block& b, int code, bool g53);
  void require_feed(const Block& b, const char* what);
  // ---- rotary.cpp: the rotary index axis (docs/ngc-interpreter.md, "Rotary index axis") -------
  bool rotary_word(const Block& b) const;
  double rot_offset_deg() const;
  double rotary_target_deg(const Block& b, bool g53) const;
  bool index_rotary(const Block& b, int code, bool g53, const Vec3& xyz_target);
  void refuse_rotary_with(const Block& b, int code);
  void check_rotary_words(const Block& b) const;
  void check_rotary_home(int base) const;
  void arc(Block& b, int code);

  // ---- cycles.cpp: canned cycles (LinuxCNC's convert_cycle_xy and its plane variants) -----------
  struct CycleWords {
    double r = 0.0, depth = 0.0, p = 0.0, q = 0.0;  // R, the bottom, dwell P, peck Q
    long repeats = 1;                               // L
  };
  void cycle(Block& b, int code);
  CycleWords cycle_words(const Block& b, int code);
  void cycle_hole(int code, const CycleWords& w, const PlaneAxes& ax, double aa, double bb,
                  double r, double cc, double clear_cc);

  // ---- offsets.cpp: G10, G28/G30, G92 -----------------------------------------------------------
  void g10(const Block& b);
  void home(const Block& b, int base);
  void store_home(int base);
  void g92(const Block& b);

  // ---- nurbs_block.cpp: G5.2 / G5.3 (the block format of the former reader, see docs) -----------
  void open_nurbs(const Block& b);
  void nurbs_order(const Block& b);
  void nurbs_point(const Block& b);
  void nurbs_line(const Block& b, int motion_word);
  void close_nurbs();

 public:
  void finish();

 private:
  struct Tool {
    double z = 0.0;  // machine units
    double diameter = 0.0;
    int orientation = 0;  // Q: lathe tool orientation, 0 for mills
  };
  struct NurbsBlock {
    int line = 0;
    int order = 3;
    Vec3 start{0, 0, 0};
    std::vector<Vec3> points;
    std::vector<double> weights;
  };

  InterpretOptions opt_;
  double machine_k_ = 1.0;
  Program program_;
  std::vector<std::pair<int, std::string>> var_lines_;  // the .var's lines: (number or 0, text)
  std::vector<std::unique_ptr<SourceFile>> files_;
  std::unordered_map<std::string, std::pair<std::size_t, std::size_t>> subs_;
  std::vector<Frame> frames_;
  std::size_t cur_file_ = 0;
  std::size_t cur_line_ = 0;
  std::size_t next_line_ = 0;
  long blocks_ = 0;
  bool ended_ = false;
  bool opened_by_percent_ = false;
  bool skipping_sub_ = false;
  std::string norm_;
  std::vector<Assign> assigns_;
  std::vector<double> params_;
  // Parameters given by the parameter file, an assignment or G28.1/G30.1 (not the start's 0).
  std::vector<bool> param_given_;
  std::unordered_map<std::string, double> globals_;
  double value_ = 0.0;
  bool value_returned_ = false;
  std::map<int, Tool> tools_;

  Vec3 pos_{0, 0, 0};  // program coordinates, mm
  std::array<bool, 3> known_{};
  std::array<bool, 3> pending_known_{};
  Units units_ = Units::mm;
  Plane plane_ = Plane::xy;
  bool incremental_ = false;
  bool ijk_absolute_ = false;
  FeedMode feed_mode_ = FeedMode::per_minute;
  double feed_ = 0.0;  // as programmed
  SpindleDir spindle_ = SpindleDir::off;
  double speed_ = 0.0;
  bool mist_ = false, flood_ = false;
  int tool_ = 0;
  int selected_tool_ = -1;
  Vec3 tool_offset_{0, 0, 0};
  bool length_offset_on_ = false;  // G43 or G43.1 in force (G49: off)
  int tool_offset_h_ = -1;         // its H (ToolOffsetEvent::h)
  int coord_sys_ = 1;
  Vec3 g92_{0, 0, 0};
  int motion_mode_ = -1;   // none, as LinuxCNC starts
  bool retract_r_ = true;  // G99, as rs274 starts
  double cycle_r_ = 0.0, cycle_cc_ = 0.0, cycle_p_ = 0.0, cycle_q_ = 0.0, cycle_il_ = 0.0;
  bool cycle_il_known_ = false;
  PathControlEvent control_{};
  bool nurbs_open_ = false;
  NurbsBlock nurbs_;
  CutterComp comp_{program_.steps};
  bool diameter_mode_ = false;             // G7: X words are diameters (G8, radius: default)
  bool arc_not_allowed_ = false;           // right after G40 ended a compensated path
  std::optional<Vec3> start_override_mm_;  // where the tool stands after G40
  // The rotary index axis (opt_.rotary_axis): where it stands, machine degrees (0 at the start,
  // as rs274), and whether an absolute word has set it (an incremental index needs that).
  double rot_deg_ = 0.0;
  bool rot_known_ = false;
};

}  // namespace ncd::toolpath::ngc
