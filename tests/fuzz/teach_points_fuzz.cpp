// Teach points and frame points (toolpath/teach): the point file, the inline frame points, and
// a frame made of the first three points read.
#include "cam/teach.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ncd::fuzz::text_of(data, size);
  ncd::fuzz::expect_input_error_or_value([&] {
    const auto points = ncd::toolpath::parse_points(text, "fuzz.txt");
    if (points.size() >= 3) {
      (void)ncd::toolpath::make_frame({points[0].p_mm, points[1].p_mm, points[2].p_mm}, "fuzz");
    }
  });
  ncd::fuzz::expect_input_error_or_value(
      [&] { (void)ncd::toolpath::parse_frame_points(text, "--frame-points"); });
  return 0;
}
