// Path files (toolpath/path_io): chamfer JSON, JSON path files, and G-code by dispatch.
#include "fuzz_common.hpp"
#include "gcode/path_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ncd::fuzz::text_of(data, size);
  ncd::fuzz::expect_input_error_or_value(
      [&] { (void)ncd::toolpath::read_path_text(text, "fuzz"); });
  return 0;
}
