// Robot touch points (toolpath/robot): the file, then the rigid fit of what was read.
#include "cam/robot.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ncd::fuzz::text_of(data, size);
  ncd::fuzz::expect_input_error_or_value([&] {
    const auto touches = ncd::toolpath::parse_touch_points(text, "fuzz.txt");
    (void)ncd::toolpath::fit_touch_points(touches);
  });
  return 0;
}
