// Control request lines (comms/control_server's checks), with and without a token. The checks
// never throw; every refusal is a reply {"ok": false, "error": ...} that serialises as a line.
#include "api/control_server.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string line = ncd::fuzz::text_of(data, size);
  ncd::comms::ServerOptions open, guarded;
  guarded.token = "secret";
  for (const auto* options : {&open, &guarded}) {
    const ncd::comms::RequestCheck c = ncd::comms::check_request(line, *options);
    if (c.to_handler != c.request.is_object()) __builtin_trap();
    if (!c.to_handler) {
      if (!c.reply.is_object() || !c.reply.contains("ok")) __builtin_trap();
      (void)c.reply.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    }
  }
  return 0;
}
