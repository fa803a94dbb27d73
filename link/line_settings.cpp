// Line settings: parsing of the frame, flow, end-of-block and protocol spellings.
#include "link/line_settings.hpp"

#include <algorithm>
#include <array>
#include <cctype>

#include "core/error.hpp"

namespace ncd::comms {

int bits_per_char(const LineSettings& line) {
  return 1 + line.data_bits + (line.parity == Parity::None ? 0 : 1) + line.stop_bits;
}

double chars_per_s(const LineSettings& line) {
  return static_cast<double>(line.baud) / static_cast<double>(bits_per_char(line));
}

const char* eob_text(EndOfBlock eob) {
  return eob == EndOfBlock::CrLf ? "\r\n" : "\n";
}

void parse_frame(const std::string& text, LineSettings& line) {
  const auto bad = [&] {
    return InputError("frame '" + text +
                      "' is not understood: write data bits (7 or 8), parity (N, E or O) and "
                      "stop bits (1 or 2), e.g. 7E2 or 8N1");
  };
  if (text.size() != 3) throw bad();
  const char data = text[0];
  const char parity = static_cast<char>(std::toupper(static_cast<unsigned char>(text[1])));
  const char stop = text[2];
  if ((data != '7' && data != '8') || (stop != '1' && stop != '2')) throw bad();
  if (parity == 'N') {
    line.parity = Parity::None;
  } else if (parity == 'E') {
    line.parity = Parity::Even;
  } else if (parity == 'O') {
    line.parity = Parity::Odd;
  } else {
    throw bad();
  }
  line.data_bits = data - '0';
  line.stop_bits = stop - '0';
}

Flow parse_flow(const std::string& text) {
  if (text == "none") return Flow::None;
  if (text == "xonxoff") return Flow::XonXoff;
  if (text == "rtscts") return Flow::RtsCts;
  throw InputError("flow control '" + text + "' is not understood: use none, xonxoff or rtscts");
}

EndOfBlock parse_eob(const std::string& text) {
  if (text == "lf" || text == "LF") return EndOfBlock::Lf;
  if (text == "crlf" || text == "CRLF") return EndOfBlock::CrLf;
  throw InputError("end of block '" + text + "' is not understood: use lf or crlf");
}

Protocol parse_protocol(const std::string& text) {
  if (text == "drip") return Protocol::Drip;
  if (text == "ack") return Protocol::Ack;
  throw InputError("protocol '" + text +
                   "' is not understood: use drip (DC1/DC3 or CTS pacing) or ack (grbl-type "
                   "ok/error per line)");
}

void check_baud(int baud) {
  constexpr std::array<int, 10> kRates{300,  600,   1200,  2400,  4800,
                                       9600, 19200, 38400, 57600, 115200};
  if (std::find(kRates.begin(), kRates.end(), baud) == kRates.end()) {
    throw InputError("baud " + std::to_string(baud) +
                     " is not a standard rate: use one of 300, 600, 1200, 2400, 4800, 9600, "
                     "19200, 38400, 57600, 115200");
  }
}

std::string frame_text(const LineSettings& line) {
  const char parity = line.parity == Parity::None ? 'N' : line.parity == Parity::Even ? 'E' : 'O';
  return std::to_string(line.data_bits) + parity + std::to_string(line.stop_bits);
}

std::string to_string(Flow flow) {
  return flow == Flow::None ? "none" : flow == Flow::XonXoff ? "xonxoff" : "rtscts";
}

std::string to_string(Protocol protocol) {
  return protocol == Protocol::Drip ? "drip" : "ack";
}

std::string describe(const LineSettings& line) {
  return std::to_string(line.baud) + " " + frame_text(line) + " " + to_string(line.flow) + " " +
         to_string(line.protocol) + (line.eob == EndOfBlock::CrLf ? " CRLF" : " LF");
}

}  // namespace ncd::comms
