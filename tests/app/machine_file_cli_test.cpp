// One machine file drives every command (docs/cmd-stream.md, "One machine file"): `ncd stream
// --machine FILE` and `ncd sim-controller --machine FILE` take the port and every line setting
// from the file's [link], a flag wins over the file and says so, a [link] key the command does
// not use is named; and `ncd serve` starts a path job where the controller says it stands
// (docs/service.md, "Where a job starts"). Real processes on real pseudo-terminals: the
// controller's log is the independent record of what ran.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "tests/app/serve_fixture.hpp"
#include "tests/common/process.hpp"

namespace ncd::test {
namespace {

using nlohmann::json;

// The program's blocks as the controller logs them: every line but `%` and empty ones.
std::vector<std::string> blocks_of(const std::string& path) {
  std::vector<std::string> out;
  std::istringstream in(slurp(path));
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line != "%") out.push_back(line);
  }
  return out;
}

std::vector<std::string> executed(const json& log) {
  std::vector<std::string> out;
  for (const auto& e : log["executed"]) out.push_back(e["text"].get<std::string>());
  return out;
}

// The stderr lines of a command that contain `part`.
std::string lines_with(const std::string& text, const std::string& part) {
  std::istringstream in(text);
  std::string out;
  for (std::string line; std::getline(in, line);) {
    if (line.find(part) != std::string::npos) out += line + "\n";
  }
  return out;
}

class MachineFile : public ServeFixture {
 protected:
  // Starts `ncd sim-controller --machine FILE` plus `extra` flags (no line flag); waits for the
  // link the file names.
  std::unique_ptr<Process> controller(const std::string& machine, const std::string& extra) {
    std::vector<std::string> argv{NCD_EXE, "sim-controller", "--machine", machine, "--log", log_};
    std::istringstream in(extra);
    for (std::string f; in >> f;) argv.push_back(f);
    auto p =
        std::make_unique<Process>(argv, (dir_ / "cnc.out").string(), (dir_ / "cnc.err").string());
    EXPECT_TRUE(wait_for_path(link(), 5.0)) << slurp(dir_ / "cnc.err");
    return p;
  }
  json stop_controller(Process& p) {
    p.signal(SIGTERM);
    EXPECT_EQ(p.wait(10.0), 0) << slurp(dir_ / "cnc.err");
    return json::parse(slurp(log_));
  }
  std::string link() const { return (dir_ / "cnc").string(); }
  // A grbl machine whose [link] names the test's link; `more` adds [link] keys.
  std::string grbl_machine(const std::string& more = "") {
    return write("grbl.toml",
                 "max_feed_mm_per_min = 6000.0\nmax_accel_mm_per_s2 = 1000.0\n"
                 "max_jerk_mm_per_s3 = 20000.0\n\n[link]\ndevice = \"" +
                     link() +
                     "\"\nbaud = 115200\nframe = \"8N1\"\nflow = \"none\"\nprotocol = \"ack\"\n"
                     "eob = \"lf\"\npercent = false\ndialect = \"grbl\"\nrx_buffer_bytes = 128\n" +
                     more);
  }
  std::string log_;  // the controller's log, in the test's folder
  void SetUp() override {
    ServeFixture::SetUp();
    log_ = (dir_ / "cnc.json").string();
  }
};

// A slot milled at the demo's machine file (config/chamfer-exp3.toml: its roughness law caps the
// feed to about 120-200 mm/min), its blocks written by `ncd replay --machine FILE --blocks`, then
// streamed with the machine file's [link] and no other flag, to a simulated controller configured
// by the same file: every block arrives and is executed, in order, once; the stream exits 0. The
// program runs 6.6 s and is 1722 bytes, so the 256-byte buffer holds it back with DC3 as the
// demo's does (the demo streams the 33 s chamfer itself, Demo.RunsEndToEnd).
TEST_F(MachineFile, StreamAndControllerTakeTheLinkFromTheFile) {
  const std::string exp3 = std::string(NCD_SOURCE_DIR) + "/config/chamfer-exp3.toml";
  const std::string slot = write("slot.ngc",
                                 "G21 G90 G94\nG0 Z5\nS1000 M3\nG0 X0 Y0\nG1 Z-1 F300\n"
                                 "G1 X5 Y0\nG3 X5 Y5 I0 J2.5\nG1 X0 Y5\nG3 X0 Y0 I0 J-2.5\n"
                                 "G0 Z5\nM5\nM2\n");
  const std::string program = (dir_ / "slot-dnc.ngc").string();
  const CmdResult r = ncd("replay " + slot + " --machine " + exp3 + " -q --blocks " + program);
  ASSERT_EQ(r.status, 0) << r.err;
  // The demo's machine file, its [link] naming the port (the simulated controller's link).
  std::string text = slurp(exp3);
  const std::string table = "[link]\n";
  ASSERT_NE(text.find(table), std::string::npos);
  text.insert(text.find(table) + table.size(), "device = \"" + link() + "\"\n");
  const std::string machine = write("machine.toml", text);

  auto cnc = controller(machine, "--exit-at-end");
  const CmdResult s = ncd("stream " + program + " --machine " + machine);
  EXPECT_EQ(s.status, 0) << s.err << s.out;
  const int status = cnc->wait(120.0);
  ASSERT_EQ(status, 0) << slurp(dir_ / "cnc.err");
  const json log = json::parse(slurp(log_));
  EXPECT_TRUE(log["errors"].empty()) << log["errors"].dump();
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"].dump();
  EXPECT_TRUE(log["program_end_executed"].get<bool>());
  const std::vector<std::string> want = blocks_of(program);
  EXPECT_EQ(executed(log), want) << "every block executed, once, in order";
  // The controller ran at the file's line, as the sender did.
  const json& set = log["settings"];
  EXPECT_EQ(set["baud"], 19200) << set.dump();
  EXPECT_EQ(set["frame"], "7E2") << set.dump();
  EXPECT_EQ(set["flow"], "xonxoff") << set.dump();
  EXPECT_EQ(set["protocol"], "drip") << set.dump();
  EXPECT_EQ(set["dialect"], "iso") << set.dump();
  EXPECT_EQ(set["buffer_bytes"], 256) << set.dump();
  EXPECT_EQ(set["link"], link()) << set.dump();
  // Byte for byte: the controller's checksum of what it received is the program's.
  const auto sha = s.out.find("sha256 ");
  ASSERT_NE(sha, std::string::npos) << s.out;
  EXPECT_EQ(log["program_sha256"], s.out.substr(sha + 7, 64)) << s.out;
  std::printf("slot-dnc.ngc: %zu blocks executed; stream: %s", want.size(),
              lines_with(s.out, "done:").c_str());
  // Both say where the values came from: the file, and the port among them.
  const std::string from_file = "(machine file " + machine + " [link])";
  EXPECT_NE(lines_with(s.err, from_file).find("device " + link()), std::string::npos) << s.err;
  EXPECT_NE(lines_with(s.err, from_file).find("baud 19200"), std::string::npos) << s.err;
  const std::string cnc_err = slurp(dir_ / "cnc.err");
  EXPECT_NE(lines_with(cnc_err, from_file).find("rx_buffer_bytes 256"), std::string::npos)
      << cnc_err;
}

// A flag wins over the file and says so; the values of each origin are named; --quiet silences
// it; a missing port names both ways to give one; the journal key, which ncd stream does not
// use, is named.
TEST_F(MachineFile, FlagsWinAndSaySo) {
  const std::string machine = grbl_machine("journal = \"live.journal\"\n");
  const std::string program = write("p.ngc", "G21 G90\nG0 X1\nM2\n");
  // No controller: the port is a missing file, refused (exit 2) after the values are chosen.
  CmdResult r = ncd("stream " + program + " --machine " + machine + " --baud 57600 --eob lf");
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("--baud 57600 overrides baud = 115200 of " + machine + " [link]"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("baud 57600 (--baud), eob lf (--eob)"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("overrides eob"), std::string::npos) << "the same value overrides nothing";
  EXPECT_NE(r.err.find("max_queued_chars 16"), std::string::npos) << r.err;
  EXPECT_NE(lines_with(r.err, "(default").find("xoff_timeout_s"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not used by this command: link.journal"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no such file: " + link() + " (device in " + machine + " [link])"),
            std::string::npos)
      << r.err;
  r = ncd("stream " + program + " --machine " + machine + " --baud 57600 -q");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err.find("overrides"), std::string::npos) << "--quiet: " << r.err;
  // --port wins over device.
  r = ncd("stream " + program + " --machine " + machine + " --port " + (dir_ / "x").string());
  EXPECT_NE(r.err.find("--port " + (dir_ / "x").string() + " overrides device"), std::string::npos)
      << r.err;
  // A file without a device and no --port.
  const std::string bare = write("bare.toml", "[link]\nbaud = 9600\n");
  r = ncd("stream " + program + " --machine " + bare);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("no port: give --port DEVICE"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("or device = \"/dev/ttyS0\" in " + bare + " [link]"), std::string::npos)
      << r.err;
  r = ncd("sim-controller --machine " + bare);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("no link: give --link PATH"), std::string::npos) << r.err;
  // A bad value in the file names the file and the key, and nothing runs.
  const std::string bad = write("bad.toml", "[link]\nbaud = 12345\n");
  r = ncd("stream " + program + " --machine " + bad + " --port /dev/null");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(bad + ": link.baud"), std::string::npos) << r.err;
  // A bad flag value is still the flag's error.
  r = ncd("stream " + program + " --machine " + machine + " --frame 9Q1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("9Q1"), std::string::npos) << r.err;
}

// sim-controller: the sender's keys are named as not used; its flags win as stream's do.
TEST_F(MachineFile, ControllerNamesTheSendersKeys) {
  const std::string machine =
      grbl_machine("max_queued_chars = 8\nxoff_timeout_s = 2.0\njournal = \"j\"\n");
  auto cnc = controller(machine, "--buffer 1024");
  stop_controller(*cnc);
  const std::string err = slurp(dir_ / "cnc.err");
  EXPECT_NE(err.find("not used by this command: link.max_queued_chars (the sender's"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("link.xoff_timeout_s"), std::string::npos) << err;
  EXPECT_NE(err.find("link.journal"), std::string::npos) << err;
  EXPECT_NE(err.find("--buffer 1024 overrides rx_buffer_bytes = 128 of " + machine),
            std::string::npos)
      << err;
  EXPECT_NE(slurp(dir_ / "cnc.out").find("buffer 1024 B"), std::string::npos)
      << slurp(dir_ / "cnc.out");
}

// ncd check --machine: the reader's values by origin; --start and --tool-table win and say so.
TEST_F(MachineFile, CheckSaysWhereItsValuesCameFrom) {
  const std::string machine =
      write("m.toml", "max_feed_mm_per_min = 3000.0\n[program]\nstart_mm = [0.0, 0.0, 50.0]\n");
  const std::string program = write("p.ngc", "G21 G90\nG1 X1 Y2 Z3 F100\nM2\n");
  CmdResult r = ncd("check " + program + " --machine " + machine + " --summary");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("max_feed_mm_per_min 3000 (feed cap, rapid rate), program.start_mm [0, 0, "
                       "50] (machine file " +
                       machine + ")"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("program.tool_table none, program.parameter_file none, "
                       "program.default_units mm (default: not in " +
                       machine),
            std::string::npos)
      << r.err;
  r = ncd("check " + program + " --machine " + machine + " --summary --start 1,2,40");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("program.start_mm [1, 2, 40] (--start)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--start 1,2,40 overrides program.start_mm = [0, 0, 50] of " + machine),
            std::string::npos)
      << r.err;
  // The summary follows the value used: from 1,2,40 down to Z3.
  EXPECT_NE(r.out.find("Z from 3.0000 to 40.0000"), std::string::npos) << r.out;
  r = ncd("check " + program + " --machine " + machine + " --summary -q");
  EXPECT_EQ(r.status, 0);
  EXPECT_EQ(r.err, "") << "-q";
}

// The service starts a program whose first move is a G1 (from an unknown position) where the
// controller (grbl, ack) reports it stands: the controller was first moved to 5,3,10 by a
// program of its own (no M2: the simulated controller runs one program), then the job's first
// setpoint is there, and every feed move the controller ran lies on the programmed lines from
// there. Without a controller that reports (no port), the same program is refused unless the
// request gives "start_mm"; and a controller moved between submit and start refuses the start.
TEST_F(MachineFile, ServedJobStartsWhereTheControllerStands) {
  const std::string machine = grbl_machine();
  auto cnc = controller(machine, "");
  const std::string to_start = write("to-start.ngc", "G21 G90\nG0 X5 Y3 Z10\n");
  CmdResult r = ncd("stream " + to_start + " --machine " + machine + " -q --no-journal");
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  const std::string program =
      write("g1-first.ngc", "G21 G90 G94\nS1000 M3\nG1 X8 Y3 Z10 F600\nG1 X8 Y6 Z10\nM5\nM2\n");
  launch("wall", "machine = \"" + machine + "\"\n");
  ServeClient c(socket_);

  // No port, no start: refused, naming the request's key.
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", program}}}, {"port", ""}}),
               "\"start_mm\" in an ncd serve submit", "a G1 from an unknown position");
  // No port, the request's start: accepted from there.
  json reply = c.request(
      {{"cmd", "submit"}, {"job", {{"path", program}}}, {"port", ""}, {"start_mm", {5, 3, 10}}});
  ASSERT_TRUE(reply["ok"].get<bool>()) << reply.dump();
  EXPECT_EQ(reply["start"]["from"], "request") << reply.dump();
  expect_error(c.request({{"cmd", "submit"},
                          {"job", {{"path", program}}},
                          {"port", ""},
                          {"start_mm", {5, "3", 10}}}),
               "\"start_mm\" must be three numbers", "a bad start_mm");

  // The controller's position wins over a request's start that differs, and says so.
  reply = c.request({{"cmd", "submit"},
                     {"job", {{"path", program}}},
                     {"start_mm", {0, 0, 0}},
                     {"setpoints", (dir_ / "sp.csv").string()}});
  ASSERT_TRUE(reply["ok"].get<bool>()) << reply.dump();
  EXPECT_EQ(reply["start"]["from"], "controller") << reply.dump();
  EXPECT_EQ(reply["start"]["position_mm"], json::array({5.0, 3.0, 10.0})) << reply.dump();
  EXPECT_NE(reply["start"].value("note", "").find("not the request's"), std::string::npos)
      << reply.dump();

  // Moved between submit and start: the start is refused.
  const std::string nudge = write("nudge.ngc", "G0 X6\n");
  r = ncd("stream " + nudge + " --machine " + machine + " -q --no-journal");
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  expect_error(c.request({{"cmd", "start"}}), "the controller moved since the job was submitted",
               "a start after the controller moved");
  r = ncd("stream " + write("back.ngc", "G0 X5\n") + " --machine " + machine + " -q --no-journal");
  ASSERT_EQ(r.status, 0) << r.err << r.out;

  // Back at 5,3,10: submit again and run.
  reply = c.request(
      {{"cmd", "submit"}, {"job", {{"path", program}}}, {"setpoints", (dir_ / "sp.csv").string()}});
  ASSERT_TRUE(reply["ok"].get<bool>()) << reply.dump();
  EXPECT_EQ(reply["start"]["from"], "controller") << reply.dump();
  ASSERT_TRUE(c.request({{"cmd", "start"}})["ok"].get<bool>());
  wait_for(c, "done");
  const json log = stop_controller(*cnc);
  // The only lines refused: the wake-up line each grbl sender sends when no banner came (the
  // half-line flush "))", docs/dnc-link.md), one per connection.
  for (const json& e : log["errors"]) EXPECT_EQ(e["text"], "))") << e.dump();
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"].dump();
  EXPECT_TRUE(log["program_end_executed"].get<bool>());

  // The first setpoint is the controller's position (the CSV's first row: t_s, x_mm, y_mm, z_mm,
  // …).
  std::istringstream csv(slurp(dir_ / "sp.csv"));
  std::string header, first;
  std::getline(csv, header);
  std::getline(csv, first);
  ASSERT_FALSE(first.empty()) << header;
  std::vector<double> row;
  std::istringstream cells(first);
  for (std::string cell; row.size() < 4 && std::getline(cells, cell, ',');) {
    row.push_back(std::stod(cell));
  }
  ASSERT_EQ(row.size(), 4U) << header;
  // On the first line, at most j T^3 / 6 (20000 mm/s^3, 4 ms: 0.000213 mm) from its start: one
  // period from rest under the jerk limit.
  const double one_period_mm = 20000.0 * std::pow(0.004, 3) / 6.0;
  EXPECT_GE(row[1], 5.0) << header << "\n" << first;
  EXPECT_LE(row[1], 5.0 + one_period_mm + 1e-6) << header << "\n" << first;
  EXPECT_NEAR(row[2], 3.0, 1e-9) << first;
  EXPECT_NEAR(row[3], 10.0, 1e-9) << first;

  // Every feed move the controller ran ends on 5,3,10 → 8,3,10 → 8,6,10, within the corner's
  // blend (blend_tolerance_mm, 0.01 by default) and the encoder's chord (0.002), and the last at
  // 8,6,10.
  int feeds = 0;
  json last;
  for (const json& m : log["moves"]) {
    if (m["g"].get<int>() != 1) continue;
    ++feeds;
    const double x = m["p"][0], y = m["p"][1], z = m["p"][2];
    const double off_first = std::hypot(y - 3.0, z - 10.0) + std::max(0.0, 5.0 - x);
    const double off_second = std::hypot(x - 8.0, z - 10.0) + std::max(0.0, 3.0 - y);
    EXPECT_LT(std::min(off_first, off_second), 0.01 + 0.002) << m.dump();
    last = m;
  }
  EXPECT_GT(feeds, 1);
  EXPECT_NEAR(last["p"][0].get<double>(), 8.0, 1e-3) << last.dump();
  EXPECT_NEAR(last["p"][1].get<double>(), 6.0, 1e-3) << last.dump();
  std::printf("served g1-first.ngc from the controller's 5,3,10: %d feed moves on the lines\n",
              feeds);
  EXPECT_NE(slurp(dir_ / "serve.err").find("starts at [5.000, 3.000, 10.000] (controller)"),
            std::string::npos)
      << slurp(dir_ / "serve.err");
}

// An Arduino grbl resets when the port opens: its position after the reset tells nothing, so
// the job starts at the request's "start_mm", and the reply says why the controller's was not
// used; without "start_mm" the G1-first program is refused.
TEST_F(MachineFile, ControllerThatResetsOnOpenLeavesTheRequestsStart) {
  const std::string machine = grbl_machine();
  auto cnc = controller(machine, "--reset-on-open --boot-s 0.2");
  const std::string program =
      write("g1-first.ngc", "G21 G90 G94\nS1000 M3\nG1 X8 Y3 Z10 F600\nM5\nM2\n");
  launch("wall", "machine = \"" + machine + "\"\n");
  ServeClient c(socket_);
  expect_error(c.request({{"cmd", "submit"}, {"job", {{"path", program}}}}), "unknown position",
               "no start known");
  const json reply =
      c.request({{"cmd", "submit"}, {"job", {{"path", program}}}, {"start_mm", {5, 3, 10}}});
  ASSERT_TRUE(reply["ok"].get<bool>()) << reply.dump();
  EXPECT_EQ(reply["start"]["from"], "request") << reply.dump();
  EXPECT_EQ(reply["start"]["position_mm"], json::array({5.0, 3.0, 10.0})) << reply.dump();
  EXPECT_NE(reply["start"].value("note", "").find("reset when the port opened"), std::string::npos)
      << reply.dump();
  const json log = stop_controller(*cnc);
  EXPECT_EQ(log["executed"].size(), 0U) << "asking where it stands runs nothing";
}

}  // namespace
}  // namespace ncd::test
