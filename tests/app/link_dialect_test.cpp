// `[link] dialect` in the machine file: read, written back in the config JSON, and refused
// with the value and the choices named.
#include <gtest/gtest.h>

#include <string>

#include "core/error.hpp"
#include "service/machine_config.hpp"

namespace ncd::app {
namespace {

TEST(LinkDialect, ReadFromTheMachineFile) {
  const service::MachineConfig none =
      service::parse_machine_config("[link]\nbaud = 19200\n", "m.toml");
  EXPECT_FALSE(none.link.dialect);
  const service::MachineConfig grbl =
      service::parse_machine_config("[link]\ndialect = \"grbl\"\n", "m.toml");
  ASSERT_TRUE(grbl.link.dialect);
  EXPECT_EQ(*grbl.link.dialect, comms::Dialect::grbl);
  try {
    (void)service::parse_machine_config("[link]\ndialect = \"fanuc\"\n", "m.toml");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("link.dialect"), std::string::npos) << what;
    EXPECT_NE(what.find("'fanuc'"), std::string::npos) << what;
    EXPECT_NE(what.find("linuxcnc"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace ncd::app
