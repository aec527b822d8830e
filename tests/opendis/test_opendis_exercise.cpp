// Sandtable tracks an exercise Open-DIS for JavaScript sends (docs/DIS.md
// §10): `sandtable sim DB --scenario EMPTY --dis 127.255.255.255:PORT
// --site 2 --json` watches while exercise.js sends four entities (three in
// DIS 7, one in DIS 6; land and air; relative and absolute timestamps;
// one standing still) every 0.2 s for 3 s, a Fire and a Detonation. Every
// entity is tracked with its marking, nothing is malformed, where the
// watcher shows each at its end is where the sender's own constant
// velocity has it then (converted with Open-DIS's own WGS-84 code), and
// its heading is the sender's, turned to grid north.
//
// The position tolerance: the dead-reckoning threshold, 1 m, plus
// speed x (one step + 0.1 s). The sender's PDUs reckon exactly (FPW at the
// constant velocity they carry), so what is left is timing. The gateway
// places remote entities at the pre-step hook, at the simulation time of
// the step's start; under real-time pacing that hook runs when the step is
// due, and the report's wall clock (unix_time_s) is read just after the
// last one. So:
// - absolute timestamps: the PDU's age is taken against the wall clock at
//   the hook, and the watcher shows the entity where it was at the hook:
//   off only by how late the hooks ran;
// - relative timestamps: a PDU counts from the hook that applies it, up to
//   one step (1/60 s) after it arrived, so the watcher shows the entity up
//   to one step (and a late hook) behind; the smooth-back of each such
//   correction (1 s, land) stays within the same bound;
// 0.1 s covers late hooks and a late report on a busy two-core machine.
// Land entities are put on the watcher's ground, so only their horizontal
// position is compared; the aircraft is compared in 3-D.
//
// Thread safety: one test; the watcher runs on a second thread, node in
// this one.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include "opendis_support.h"

namespace sandtable::opendis_test {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kStepS = 1.0 / 60.0;       // the simulator's step (SimOptions::stepS)
constexpr double kSchedulingS = 0.1;        // a late paced step, a late report
constexpr double kThresholdM = 1.0;         // the dead-reckoning threshold
constexpr double kHeadingDeg = 0.02;        // the convergence formula below is good to 0.005 deg here

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// `sandtable ARGS`, stdout and stderr to files in `dir` named `tag`; the exit status.
int cli(const std::string& args, const fs::path& dir, const std::string& tag) {
  std::string command = shellQuoted(SANDTABLE_CLI);
  command += ' ';
  command += args;
  command += " >";
  command += shellQuoted(dir / (tag + ".out"));
  command += " 2>";
  command += shellQuoted(dir / (tag + ".err"));
  command += " </dev/null";
  const int rc = std::system(command.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

/// Metres between two WGS-84 points of nearly the same place: north and
/// east through the ellipsoid's radii of curvature, and the height.
struct Offset {
  double horizontal = 0, vertical = 0;
};
Offset offsetBetween(const json& a, const json& b) {
  constexpr double kA = 6378137.0, kE2 = 6.69437999014e-3;
  const double lat = double(a["lat"]) * kPi / 180;
  const double w = std::sqrt(1 - kE2 * std::sin(lat) * std::sin(lat));
  const double meridian = kA * (1 - kE2) / (w * w * w), normal = kA / w;
  const double north = (double(b["lat"]) - double(a["lat"])) * kPi / 180 * meridian;
  const double east = (double(b["lon"]) - double(a["lon"])) * kPi / 180 * normal * std::cos(lat);
  return {std::hypot(north, east), double(b["height"]) - double(a["height"])};
}

/// The meridian convergence of a UTM zone's grid at (lon, lat), degrees:
/// grid heading = true heading - convergence. The spherical formula
/// atan(tan(lon - lon0) sin lat); the ellipsoid changes it by a fraction
/// e'^2 cos^2 lat of itself (under 0.005 deg a degree and a half from the
/// central meridian).
double convergenceDeg(int zone, double lon, double lat) {
  const double lon0 = zone * 6.0 - 183.0;
  return std::atan(std::tan((lon - lon0) * kPi / 180) * std::sin(lat * kPi / 180)) * 180 / kPi;
}

/// The UTM zone the database's CRS names ("UTM zone 33N"), or 0.
int utmZone(const std::string& manifest) {
  const auto at = manifest.find("UTM zone ");
  return at == std::string::npos ? 0 : std::atoi(manifest.c_str() + at + 9);
}

/// The spec exercise.js sends: four entities around (lon, lat), each
/// within a kilometre of it.
json exerciseSpec(double lon, double lat) {
  const auto at = [&](double east, double north) {
    return std::pair{lon + east / (111320 * std::cos(lat * kPi / 180)), lat + north / 111132};
  };
  const auto entity = [&](int n, int version, const char* marking, json type, double east, double north,
                          double height, double heading, double speed, double climb, const char* timestamp) {
    const auto [lo, la] = at(east, north);
    return json{{"entity", n}, {"version", version}, {"marking", marking}, {"type", type}, {"force", n == 3 ? 2 : 1},
                {"lon", lo}, {"lat", la}, {"height", height}, {"heading_deg", heading}, {"speed_ms", speed},
                {"climb_ms", climb}, {"timestamp", timestamp}};
  };
  return {{"exercise", 1}, {"site", 7}, {"application", 9}, {"seconds", 3}, {"interval_s", 0.2},
          {"entities",
           {entity(1, 7, "ODIS7 TANK", {1, 1, 225, 1, 1, 1, 0}, -300, -200, 300, 60, 8, 0, "relative"),
            entity(2, 7, "ODIS7 HELO", {1, 2, 225, 20, 1, 0, 0}, 200, 300, 3500, 200, 15, 2, "absolute"),
            entity(3, 6, "ODIS6 T72", {1, 1, 222, 1, 2, 1, 0}, 400, -300, 300, 300, 5, 0, "relative"),
            entity(4, 7, "ODIS7 HQ", {1, 1, 225, 3, 1, 0, 0}, -500, 400, 300, 0, 0, 0, "absolute")}},
          {"fire", {{"at_s", 1.0}, {"firing", 1}, {"target", 3}, {"version", 7}}},
          {"detonation", {{"at_s", 1.4}}}};
}

TEST(OpenDisExercise, sandtableTracksOpenDisEntitiesWhereTheSenderHasThem) {
  ASSERT_TRUE(haveOpenDis());
  const fs::path dir = scratchDir("exercise");
  // A 4 km synthetic square at 125 m posts: a second to make.
  ASSERT_EQ(cli("synth -o " + shellQuoted(dir / "in") + " --size-km 4 --force", dir, "synth"), 0)
      << slurp(dir / "synth.err");
  const json synth = json::parse(slurp(dir / "in/synth.json"));
  const json& b = synth["bounds"];
  char extent[200];
  std::snprintf(extent, sizeof extent, "%.12f %.12f %.12f %.12f", double(b["west"]), double(b["south"]),
                double(b["east"]), double(b["north"]));
  ASSERT_EQ(cli("build --elevation " + shellQuoted(dir / "in/dted2") + " --extent " + extent +
                    " --spacing 125 --icons " + shellQuoted(fs::path(SANDTABLE_SOURCE_DIR) / "samples/icons.txt") +
                    " -o " + shellQuoted(dir / "db"),
                dir, "build"),
            0)
      << slurp(dir / "build.err");
  std::ofstream(dir / "empty.scenario") << "sandtable-scenario 1\n";
  const int zone = utmZone(slurp(dir / "db/manifest.json"));
  ASSERT_GT(zone, 0) << "the build's default CRS is UTM";
  const json spec = exerciseSpec((double(b["west"]) + double(b["east"])) / 2,
                                 (double(b["south"]) + double(b["north"])) / 2);
  std::ofstream(dir / "spec.json") << spec.dump(1);

  // The watcher: 6 s, listening before the sender starts; the sender's
  // 3.3 s end well inside it.
  const std::string port = std::to_string(20000 + (::getpid() + 13) % 20000);
  int watcherExit = -1;
  std::thread watcher([&] {
    watcherExit = cli("sim " + shellQuoted(dir / "db") + " --scenario " + shellQuoted(dir / "empty.scenario") +
                          " --dis 127.255.255.255:" + port + " --site 2 --duration 6 --json",
                      dir, "watcher");
  });
  bool listening = false;
  for (int k = 0; k < 300 && !listening; ++k) {  // at most 15 s
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    listening = slurp(dir / "watcher.err").find("sandtable sim: DIS") != std::string::npos;
  }
  std::optional<json> sent;
  if (listening) sent = node("exercise.js", "send 127.255.255.255 " + port + " " + shellQuoted(dir / "spec.json"));
  watcher.join();
  ASSERT_TRUE(listening) << slurp(dir / "watcher.err");
  ASSERT_TRUE(sent);
  ASSERT_EQ(watcherExit, 0) << slurp(dir / "watcher.err");
  const json seen = json::parse(slurp(dir / "watcher.out"))["dis"];

  // What went out: 16 Entity State PDUs an entity (0 to 3 s every 0.2 s), a Fire, a Detonation.
  EXPECT_EQ((*sent)["entity_states"], 64);
  EXPECT_EQ((*sent)["fires"], 1);
  EXPECT_EQ((*sent)["detonations"], 1);
  EXPECT_LT(double(seen["unix_time_s"]), double((*sent)["last_send_unix_s"]) + 6) << "the watcher outlived the sender";
  EXPECT_GT(double(seen["unix_time_s"]), double((*sent)["last_send_unix_s"])) << "the watcher ended before the sender";

  // What came in: all of it, none refused.
  EXPECT_EQ(seen["entity_states"], (*sent)["entity_states"]);
  EXPECT_GE(seen["fires"], 1);
  EXPECT_GE(seen["detonations"], 1);
  EXPECT_EQ(seen["malformed"], 0) << seen["last_malformed"];
  EXPECT_EQ(seen["other_exercise"], 0);
  EXPECT_EQ(seen["unknown_type"], 0);
  EXPECT_EQ(seen["conflicts"], 0);
  EXPECT_EQ(seen["stale"], 0);
  EXPECT_EQ(seen["non_finite"], 0);

  // Where the sender has each entity at the watcher's last step.
  const double elapsed = double(seen["unix_time_s"]) - double((*sent)["t0_unix_s"]);
  const auto truth = node("exercise.js", "where " + shellQuoted(dir / "spec.json") + " " + std::to_string(elapsed));
  ASSERT_TRUE(truth);
  std::map<std::string, json> tracked;
  for (const json& e : seen["remote_entities"]) tracked[e["id"]] = e;
  for (const json& e : seen["departed"]) tracked.try_emplace(e["id"], e);
  ASSERT_EQ((*truth)["entities"].size(), (*sent)["entities"].size());
  for (std::size_t k = 0; k < (*truth)["entities"].size(); ++k) {
    const json& want = (*truth)["entities"][k];
    const json& spec1 = (*sent)["entities"][k];
    SCOPED_TRACE(want["marking"].get<std::string>());
    const auto it = tracked.find(want["id"]);
    ASSERT_NE(it, tracked.end()) << want["id"] << " is not tracked: " << seen["remote_entities"].dump();
    const json& got = it->second;
    EXPECT_EQ(got["marking"], want["marking"]);
    ASSERT_TRUE(got.contains("lat")) << got.dump();
    const Offset d = offsetBetween(want, got);
    const bool air = want["domain"] == 2;
    const double error = air ? std::hypot(d.horizontal, d.vertical) : d.horizontal;
    const double tolerance = kThresholdM + double(spec1["speed_ms"]) * (kStepS + kSchedulingS);
    EXPECT_LT(error, tolerance) << (air ? "3-D" : "horizontal") << " error; got " << got.dump() << ", want "
                                << want.dump();
    // The sender's heading (its psi, theta, phi from the local heading) as
    // the watcher's grid heading.
    const json& in = spec["entities"][k];
    const double grid = double(in["heading_deg"]) - convergenceDeg(zone, double(got["lon"]), double(got["lat"]));
    const double turn = std::remainder(double(got["heading_deg"]) - grid, 360.0);
    EXPECT_LT(std::abs(turn), kHeadingDeg) << "heading " << got["heading_deg"] << ", want " << grid;
    std::printf("opendis exercise: %-11s DIS %d %-4s %5.1f m/s, %s timestamps: %s error %.4f m (tolerance %.2f m), "
                "heading error %.4f deg\n",
                want["marking"].get<std::string>().c_str(), int(spec1["version"]), air ? "air" : "land",
                double(spec1["speed_ms"]), spec1["timestamp"].get<std::string>().c_str(), air ? "3-D" : "horizontal",
                error, tolerance, turn);
  }
  std::printf("opendis exercise: watcher ended %.3f s after t0, %.3f s after the last PDU\n", elapsed,
              double(seen["unix_time_s"]) - double((*sent)["last_send_unix_s"]));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::opendis_test
