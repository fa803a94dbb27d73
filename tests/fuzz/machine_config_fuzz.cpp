// The machine file (TOML, app/machine_config).
#include "fuzz_common.hpp"
#include "service/machine_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ncd::fuzz::text_of(data, size);
  ncd::fuzz::expect_input_error_or_value(
      [&] { (void)ncd::service::parse_machine_config(text, "fuzz.toml"); });
  return 0;
}
