// `ncd robot` as a user meets it: the JSON contract, the documented text program, touch
// points from a file, the rules' figures, and errors that exit 2 and leave no file behind.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

const std::string kPaper = "robot --cylinder-radius 30 --hole-radius 15";
const double kRobotPi = 3.14159265358979323846;

Vec3 vec(const nlohmann::json& j) {
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

// R = Rz(r) Ry(p) Rx(w) from Eigen's angle-axis products, independently of the library.
Mat3 from_wpr_deg(const nlohmann::json& wpr) {
  const double k = kRobotPi / 180.0;
  return (Eigen::AngleAxisd(k * wpr[2].get<double>(), Vec3::UnitZ()) *
          Eigen::AngleAxisd(k * wpr[1].get<double>(), Vec3::UnitY()) *
          Eigen::AngleAxisd(k * wpr[0].get<double>(), Vec3::UnitX()))
      .toRotationMatrix();
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

TEST_F(Cli, RobotHelpListsItsFlags) {
  const CmdResult r = ncd("robot --help");
  EXPECT_EQ(r.status, 0);
  for (const char* flag :
       {"--cylinder-radius", "--hole-radius", "--points", "--depth", "--chamfer-width", "--passes",
        "--speed", "--spindle", "--approach-distance", "--touch-points", "--rule", "--format",
        "--output", "--move-speed", "--bar-radius", "--start-angle"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
}

TEST_F(Cli, RobotJsonContractOfThePaperExperiment) {
  const CmdResult r = ncd(kPaper + " -q");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const auto j = nlohmann::json::parse(r.out);
  const auto& in = j["input"];
  EXPECT_EQ(in["speed_mm_per_s"].get<double>(), 1.0);
  EXPECT_EQ(in["spindle_rpm"].get<double>(), 35000.0);
  EXPECT_EQ(in["depth_mm"].get<double>(), 0.1);
  EXPECT_EQ(in["rule"], "paper");
  EXPECT_EQ(in["points"].get<int>(), 72);

  const auto& a = j["attitude_change_deg"];
  for (const char* key : {"total", "max", "naive_total", "naive_max", "paper_total", "paper_max",
                          "min_change_total", "min_change_max"}) {
    ASSERT_TRUE(a.contains(key)) << key;
  }
  EXPECT_EQ(a["total"].get<double>(), a["paper_total"].get<double>());
  EXPECT_EQ(a["max"].get<double>(), a["paper_max"].get<double>());
  EXPECT_LT(a["paper_total"].get<double>(), a["naive_total"].get<double>());
  EXPECT_LE(a["min_change_total"].get<double>(), a["paper_total"].get<double>());
  EXPECT_LE(a["min_change_max"].get<double>(), a["naive_max"].get<double>());

  const auto& poses = j["poses"];
  ASSERT_EQ(poses.size(), 72u + 1u + 2u);  // the loop closed, approach and retract
  EXPECT_EQ(poses.front()["mode"], "move");
  EXPECT_EQ(poses.back()["mode"], "move");
  double sum_deg = 0.0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto& p = poses[i];
    for (const char* key : {"p", "D", "Tf", "Tg", "wpr_deg", "mode", "speed_mm_per_s"}) {
      ASSERT_TRUE(p.contains(key)) << key;
    }
    const Vec3 d = vec(p["D"]), tf = vec(p["Tf"]), tg = vec(p["Tg"]);
    ASSERT_NEAR(tg.dot(d), 0.0, 1e-15);
    ASSERT_NEAR(tf.dot(d), 0.0, 1e-15);
    Mat3 frame;
    frame << tg, d.cross(tg), d;
    ASSERT_LT((from_wpr_deg(p["wpr_deg"]) - frame).cwiseAbs().maxCoeff(), 1e-12) << i;
    if (i > 0 && i + 1 < poses.size()) {
      EXPECT_EQ(p["mode"], "cut");
      EXPECT_EQ(p["speed_mm_per_s"].get<double>(), 1.0);
    }
    sum_deg += p["attitude_change_deg"].get<double>();
  }
  EXPECT_NEAR(sum_deg, a["total"].get<double>(), 1e-9);
  EXPECT_LT(j["checks"]["wpr_roundtrip_error"].get<double>(), 1e-12);
  EXPECT_NEAR(j["checks"]["wall_angle_deg"][0].get<double>(), 45.0, 1e-9);
  EXPECT_NEAR(j["checks"]["wall_angle_deg"][1].get<double>(), 45.0, 1e-9);
  EXPECT_EQ(j["transform"]["source"], "identity (no --touch-points)");
}

TEST_F(Cli, RobotRuleChoosesWhichFiguresAreTheTotal) {
  const auto paper = nlohmann::json::parse(ncd(kPaper + " -q").out)["attitude_change_deg"];
  for (const char* rule : {"naive", "min-change"}) {
    const auto j = nlohmann::json::parse(ncd(kPaper + " -q --rule " + rule).out);
    const auto& a = j["attitude_change_deg"];
    const std::string key = rule == std::string("naive") ? "naive" : "min_change";
    EXPECT_EQ(a["rule"], rule);
    EXPECT_EQ(a["total"].get<double>(), a[key + "_total"].get<double>());
    EXPECT_EQ(a["max"].get<double>(), a[key + "_max"].get<double>());
    // The figures of every rule are the same whichever is chosen.
    for (const char* k : {"naive_total", "paper_total", "min_change_total"}) {
      EXPECT_EQ(a[k].get<double>(), paper[k].get<double>()) << k;
    }
    if (key == "naive") {
      for (const auto& p : j["poses"]) {
        EXPECT_LT((vec(p["Tg"]) - vec(p["Tf"])).norm(), 1e-15);
      }
    }
  }
}

TEST_F(Cli, RobotTextProgramIsDocumentedAndMatchesTheJson) {
  const CmdResult t = ncd(kPaper + " -q --format text");
  ASSERT_EQ(t.status, 0) << t.err;
  const auto j = nlohmann::json::parse(ncd(kPaper + " -q").out);
  const auto lines = lines_of(t.out);
  std::vector<std::string> data;
  bool columns = false;
  for (const auto& line : lines) {
    if (line.rfind("#", 0) == 0) {
      columns =
          columns || line == "# columns: n mode x_mm y_mm z_mm w_deg p_deg r_deg speed_mm_per_s";
    } else {
      data.push_back(line);
    }
  }
  EXPECT_TRUE(columns);
  for (const char* words :
       {"format: ncd-robot-text 1", "R = Rz(R) Ry(P) Rx(W)", "naive", "min-change",
        "T_g rule: paper", "spindle 35000 rpm", "tool frame: +z along the bar's axis"}) {
    EXPECT_NE(t.out.find(words), std::string::npos) << words;
  }
  ASSERT_EQ(data.size(), j["poses"].size());
  for (std::size_t i = 0; i < data.size(); ++i) {
    std::istringstream in(data[i]);
    std::size_t n = 0;
    std::string mode;
    double x, y, z, w, p, r, speed;
    ASSERT_TRUE(in >> n >> mode >> x >> y >> z >> w >> p >> r >> speed) << data[i];
    std::string extra;
    EXPECT_FALSE(in >> extra);
    const auto& pose = j["poses"][i];
    EXPECT_EQ(n, i + 1);
    EXPECT_EQ(mode, pose["mode"]);
    EXPECT_NEAR(x, pose["p"][0].get<double>(), 0.5e-4);
    EXPECT_NEAR(y, pose["p"][1].get<double>(), 0.5e-4);
    EXPECT_NEAR(z, pose["p"][2].get<double>(), 0.5e-4);
    // Angles to 4 decimals; ±180° may print as either end.
    const auto same_angle = [](double a, double b) {
      return std::abs(std::remainder(a - b, 360.0)) <= 0.5e-4 + 1e-9;
    };
    EXPECT_TRUE(same_angle(w, pose["wpr_deg"][0].get<double>())) << data[i];
    EXPECT_TRUE(same_angle(p, pose["wpr_deg"][1].get<double>())) << data[i];
    EXPECT_TRUE(same_angle(r, pose["wpr_deg"][2].get<double>())) << data[i];
    EXPECT_EQ(speed, pose["speed_mm_per_s"].get<double>());
  }
}

TEST_F(Cli, RobotTouchPointsMoveThePathIntoTheRobotFrame) {
  const std::string file = std::string(NCD_SOURCE_DIR) + "/examples/robot-touch-points.txt";
  const CmdResult r = ncd(kPaper + " -q --touch-points " + file);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto w = nlohmann::json::parse(ncd(kPaper + " -q").out);
  const auto& tr = j["transform"];
  EXPECT_EQ(tr["touches"].get<int>(), 5);
  EXPECT_GT(tr["residual_rms_mm"].get<double>(), 0.0);
  EXPECT_LT(tr["residual_max_mm"].get<double>(), 0.2);
  Mat3 rot;
  for (int i = 0; i < 3; ++i) rot.row(i) = vec(tr["rotation"][i]).transpose();
  const Vec3 t = vec(tr["translation_mm"]);
  // The file's placement: 30° about z, centre at (850, −120, 400) mm, 0.05 mm noise.
  EXPECT_NEAR(tr["wpr_deg"][2].get<double>(), 30.0, 0.2);
  EXPECT_LT((t - Vec3(850, -120, 400)).norm(), 0.2);
  for (std::size_t i = 0; i < j["poses"].size(); ++i) {
    const auto& p = j["poses"][i];
    const auto& q = w["poses"][i];
    ASSERT_LT((vec(p["p"]) - (rot * vec(q["p"]) + t)).norm(), 1e-9);
    ASSERT_LT((vec(p["D"]) - rot * vec(q["D"])).norm(), 1e-12);
    ASSERT_LT((vec(p["Tg"]) - rot * vec(q["Tg"])).norm(), 1e-12);
  }
  // The attitude figures do not depend on where the part lies.
  EXPECT_NEAR(j["attitude_change_deg"]["total"].get<double>(),
              w["attitude_change_deg"]["total"].get<double>(), 1e-9);
  EXPECT_NE(ncd(kPaper + " --format text --touch-points " + file).out.find("5 touch points"),
            std::string::npos);
}

TEST_F(Cli, RobotChamferWidthIsTwiceTheTotalDepth) {
  const auto a = nlohmann::json::parse(ncd(kPaper + " -q --depth 0.1 --passes 3").out);
  const auto b = nlohmann::json::parse(ncd(kPaper + " -q --chamfer-width 0.6 --passes 3").out);
  ASSERT_EQ(a["poses"].size(), b["poses"].size());
  EXPECT_EQ(a["poses"].size(), 3u * 72u + 3u);
  for (std::size_t i = 0; i < a["poses"].size(); ++i) {
    EXPECT_LT((vec(a["poses"][i]["p"]) - vec(b["poses"][i]["p"])).norm(), 1e-12);
  }
  EXPECT_EQ(ncd(kPaper + " --depth 0.1 --chamfer-width 0.2").status, 2);
}

TEST_F(Cli, RobotSameInputsGiveTheSameBytes) {
  EXPECT_EQ(ncd(kPaper + " -q").out, ncd(kPaper + " -q").out);
  EXPECT_EQ(ncd(kPaper + " -q --format text --rule min-change").out,
            ncd(kPaper + " -q --format text --rule min-change").out);
}

TEST_F(Cli, RobotWritesTheOutputFileWhole) {
  const fs::path out = dir_ / "prog.txt";
  const CmdResult r = ncd(kPaper + " --format text -o " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_NE(r.err.find("wrote"), std::string::npos);
  EXPECT_NE(r.err.find("paper"), std::string::npos);
  EXPECT_NE(r.err.find("naive"), std::string::npos);
  EXPECT_EQ(slurp(out), ncd(kPaper + " -q --format text").out);
}

// Each invalid input: exit 2, a message naming the value (and the limit or the way out), and
// no output file.
TEST_F(Cli, RobotInvalidInputExitsTwoAndWritesNothing) {
  const std::string collinear = write("collinear.txt",
                                      "# on one line\n0 0 0 100 0 0\n10 0 0 110 0 0\n"
                                      "20 0 0 120 0 0\n30 0 0 130 0 0\n");
  const std::string duplicate =
      write("duplicate.txt", "0 0 0 0 0 0\n50 0 0 50 0 0\n50 0.5 0 50 0.5 0\n0 40 0 0 40 0\n");
  const std::string malformed = write("malformed.txt", "0 0 0 0 0 0\n\n50, 0, 0, 50, 0, x\n");
  const std::string short_line = write("short.txt", "0 0 0 0 0 0\n50 0 0 50 0\n");
  const std::string two = write("two.txt", "0 0 0 0 0 0\n50 0 0 50 0 0\n");
  const std::string off =
      write("off.txt", "0 0 0 0 0 0\n50 0 0 50 0 0\n0 40 0 0 40 0\n0 0 30 0 0 33\n");
  const struct {
    std::string args;
    std::vector<std::string> words;
  } cases[] = {
      {"robot --cylinder-radius 30 --hole-radius 30",
       {"hole radius r = 30 mm", "cylinder radius R = 30 mm", "--hole-radius"}},
      {"robot --cylinder-radius 30 --hole-radius 40", {"hole radius r = 40 mm"}},
      {kPaper + " --touch-points " + collinear,
       {"collinear", "0 mm", "less than 1 mm", "touch a point off the line"}},
      {kPaper + " --touch-points " + duplicate, {"touch points 2 and 3", "0.5 mm apart"}},
      {kPaper + " --touch-points " + malformed, {"malformed.txt:3", "'x'"}},
      {kPaper + " --touch-points " + short_line, {"short.txt:2", "5 numbers"}},
      {kPaper + " --touch-points " + two, {"at least 3", "got 2"}},
      {kPaper + " --touch-points " + off, {"touch 4", "--max-touch-residual"}},
      {kPaper + " --touch-points " + (dir_ / "missing.txt").string(), {"missing.txt"}},
      {kPaper + " --depth 2", {"exceeds", "--depth"}},
      {kPaper + " --points 3", {"N = 3"}},
      {kPaper + " --speed 0", {"--speed"}},
      {kPaper + " --speed nan", {"--speed"}},
      {kPaper + " --format csv", {"csv"}},
  };
  for (const auto& c : cases) {
    const fs::path out = dir_ / "out.json";
    const CmdResult r = ncd(c.args + " -o " + out.string());
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    for (const auto& w : c.words) EXPECT_NE(r.err.find(w), std::string::npos) << w << "\n" << r.err;
    EXPECT_FALSE(fs::exists(out)) << c.args;
    EXPECT_EQ(r.out, "");
  }
}

}  // namespace
