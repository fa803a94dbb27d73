// RS-232 line settings as a machine's DNC port expects them (docs/dnc-link.md): speed, frame
// (data bits, parity, stop bits, written "7E2"), flow control, end of block, `%` framing and
// a NUL leader, and the DNC protocol spoken over the line. One character costs
// 1 + data + parity + stop bits on the wire, so 7E2 at 19 200 baud carries 1745 characters/s.
#pragma once

#include <string>

namespace ncd::comms {

enum class Parity { None, Even, Odd };
enum class Flow { None, XonXoff, RtsCts };
enum class EndOfBlock { Lf, CrLf };
// Drip: the controller paces with DC1/DC3 (or CTS). Ack: grbl-type `ok` / `error:N` per line.
enum class Protocol { Drip, Ack };

inline constexpr char kXon = 0x11;   // DC1: the controller asks for data
inline constexpr char kXoff = 0x13;  // DC3: the controller's buffer is nearly full
inline constexpr char kNak = 0x15;   // NAK: sent by a Fanuc after DC3 on reset or alarm
inline constexpr char kSyn = 0x16;   // SYN: likewise

struct LineSettings {
  std::string device;  // the serial device or pseudo-terminal link, e.g. /dev/ttyS0
  int baud = 19200;
  int data_bits = 7;
  Parity parity = Parity::Even;
  int stop_bits = 2;
  Flow flow = Flow::XonXoff;
  EndOfBlock eob = EndOfBlock::Lf;
  bool percent_framing = true;  // `%` on a line of its own opens and closes the program
  int nul_leader = 0;           // NUL characters sent before the program
  Protocol protocol = Protocol::Drip;
};

// Bits one character takes on the wire: start + data + parity + stop.
int bits_per_char(const LineSettings& line);
// Characters per second the line carries at its baud and frame.
double chars_per_s(const LineSettings& line);
// "\n" or "\r\n".
const char* eob_text(EndOfBlock eob);

// Parsers for the command-line and TOML spellings; each throws InputError naming the value and
// the accepted forms.
void parse_frame(const std::string& text, LineSettings& line);  // "8N1", "7E2", "8O1", ...
Flow parse_flow(const std::string& text);                       // none | xonxoff | rtscts
EndOfBlock parse_eob(const std::string& text);                  // lf | crlf
Protocol parse_protocol(const std::string& text);               // drip | ack
// Throws InputError unless baud is one of the standard rates libserial can set (300 … 115200).
void check_baud(int baud);

// "19200 7E2 xonxoff drip LF" for logs and reports.
std::string frame_text(const LineSettings& line);
std::string describe(const LineSettings& line);
std::string to_string(Flow flow);
std::string to_string(Protocol protocol);

}  // namespace ncd::comms
