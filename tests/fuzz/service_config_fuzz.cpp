// The service config (TOML, app/service_config). A "machine" key names a file, which is then
// read: the harness runs in a scratch directory, so only the paths the fuzzer invents are read.
#include "api/service_config.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ncd::fuzz::text_of(data, size);
  ncd::fuzz::expect_input_error_or_value(
      [&] { (void)ncd::api::parse_service_config(text, "fuzz.toml"); });
  return 0;
}
