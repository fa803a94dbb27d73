// The RS-274/NGC interpreter: the names and modal groups of G and M codes, and why one is refused.
// The reading and execution order is in interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

[[noreturn]] void fail(std::string what) {
  throw Fail{std::move(what)};
}

std::string g_name(int code10) {
  return "G" + std::to_string(code10 / 10) + (code10 % 10 ? "." + std::to_string(code10 % 10) : "");
}

// Longer than the house's 100 lines on purpose: LinuxCNC's modal group table (gees[] in
// interp_array.cc) in full, one case per code.
int g_group(int c) {
  switch (c) {
    case 40:
    case 100:
    case 280:
    case 281:
    case 300:
    case 301:
    case 530:
    case 920:
    case 921:
    case 922:
    case 923:
      return 0;
    case 0:
    case 10:
    case 20:
    case 30:
    case 50:
    case 51:
    case 52:
    case 53:
    case 330:
    case 331:
    case 382:
    case 383:
    case 384:
    case 385:
    case 730:
    case 740:
    case 760:
    case 800:
    case 810:
    case 820:
    case 830:
    case 840:
    case 850:
    case 860:
    case 870:
    case 880:
    case 890:
      return 1;
    case 170:
    case 171:
    case 180:
    case 181:
    case 190:
    case 191:
      return 2;
    case 900:
    case 910:
      return 3;
    case 901:
    case 911:
      return 4;
    case 930:
    case 940:
    case 950:
      return 5;
    case 200:
    case 210:
      return 6;
    case 400:
    case 410:
    case 411:
    case 420:
    case 421:
      return 7;
    case 430:
    case 431:
    case 432:
    case 490:
      return 8;
    case 980:
    case 990:
      return 10;
    case 540:
    case 550:
    case 560:
    case 570:
    case 580:
    case 590:
    case 591:
    case 592:
    case 593:
      return 12;
    case 610:
    case 611:
    case 640:
      return 13;
    case 960:
    case 970:
      return 14;
    case 70:
    case 80:
      return 15;
    case 520:
      return 0;
    default:
      return -1;
  }
}

int coord_system_code(int n) {
  static constexpr int kCodes[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
  return n >= 1 && n <= 9 ? kCodes[n - 1] : 540;
}

int m_group(int c) {
  switch (c) {
    case 0:
    case 1:
    case 2:
    case 30:
    case 60:
      return 4;
    case 6:
    case 61:
      return 6;
    case 3:
    case 4:
    case 5:
    case 19:
      return 7;
    case 7:
    case 8:
    case 9:
      return 8;
    case 48:
    case 49:
    case 50:
    case 51:
    case 52:
    case 53:
      return 9;
    default:
      return c >= 62 && c <= 199 ? 10 : -1;
  }
}

std::string g_refusal(int c) {
  switch (c) {
    case 330:
    case 331:
    case 760:
      return g_name(c) +
             " (spindle-synchronised motion, threading) is not supported; ncd drives "
             "no spindle encoder: remove the threading pass";
    case 382:
    case 383:
    case 384:
    case 385:
      return g_name(c) + " (probing) is not supported; probe on the controller, not in the program";
    case 740:
    case 840:
    case 860:
    case 870:
    case 880:
      return g_name(c) +
             " (tapping/boring cycle needing spindle control) is not supported; use G81, G82, "
             "G83, G85 or G89, or write the moves out";
    case 50:
    case 51:
      return g_name(c) + " (spline) is not supported; use G5.2/G5.3 NURBS, G2/G3 or G1";
    case 950:
      return "G95 (feed per revolution) is not supported; use G94 with F in units per minute";
    case 960:
      return "G96 (constant surface speed) is not supported; use G97 with S in rpm";
    case 171:
    case 181:
    case 191:
      return g_name(c) + " (UVW plane) is not supported; use G17, G18 or G19";
    case 432:
      return "G43.2 (additional tool length offset) is not supported; use G43 H or G43.1";
    case 520:
      return "G52 (local offset) is not supported; use G92 or G10 L2 with G54-G59.3";
    default:
      return {};
  }
}

std::string m_refusal(int c) {
  if (c >= 100 && c <= 199) {
    return "M" + std::to_string(c) +
           " (user M code) is not supported; ncd runs no user "
           "programs: remove it or handle it on the controller";
  }
  switch (c) {
    case 19:
      return "M19 (spindle orient) is not supported; remove it";
    case 61:
      return "M61 (set current tool without a change) is not supported; use T M6";
    case 48:
    case 49:
    case 50:
    case 51:
    case 52:
    case 53:
      return "M" + std::to_string(c) + " (override control) is not supported; remove it";
    default:
      return "M" + std::to_string(c) + " is not supported (I/O, modal state or remap); remove it";
  }
}

}  // namespace ncd::toolpath::ngc
