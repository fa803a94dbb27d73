// The current G-code reader (toolpath/gcode_reader), fed directly.
#include <sstream>

#include "fuzz_common.hpp"
#include "gcode/gcode_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(ncd::fuzz::text_of(data, size));
  ncd::fuzz::expect_input_error_or_value([&] { (void)ncd::toolpath::read_gcode(in, "fuzz.ngc"); });
  return 0;
}
