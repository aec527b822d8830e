// Path files and the seed's Table 7: which times and leg speeds are given,
// which are computed, and the errors a user sees.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "sandtable/world/path.h"

namespace sandtable::world {
namespace {

/// A stand-in for PROJ: 1 degree = 1 km, and lon > 50 is "outside".
std::string fakeProject(double lon, double lat, double& e, double& n) {
  if (lon > 50) return "is outside the database";
  e = lon * 1000;
  n = lat * 1000;
  return {};
}

PathOptions lonLatOptions() {
  PathOptions o;
  o.toProjected = fakeProject;
  return o;
}

Path parseOk(const std::string& text, const PathOptions& o = lonLatOptions()) {
  auto r = parsePath(text, "test.path", o);
  EXPECT_TRUE(r.ok()) << r.error();
  return r.ok() ? r.value() : Path{};
}

std::string parseError(const std::string& text, const PathOptions& o = lonLatOptions()) {
  auto r = parsePath(text, "test.path", o);
  EXPECT_FALSE(r.ok());
  return r.error();
}

// Table 7 in the seed (speeds in m/s there, km/h here: 10 m/s = 36 km/h).
// Given: A time and speed, B speed, D time and speed. Computed: the times
// at B, C and E, and the speed of C-D.
constexpr const char* kTable7 = R"(# seed Table 7, "Script parameters generated from selected path"
frame projected
0   0  10 speed=36 time=0:00:00   # A
100 20 10 speed=18                # B
110 30 10                         # C
50  35 10 speed=18 time=0:00:45   # D
0   15 10                         # E
)";

TEST(Path, Table7TimesAndSpeedsAreComputed) {
  const Path p = parseOk(kTable7);
  ASSERT_EQ(p.frame, PathFrame::projected);
  ASSERT_EQ(p.waypoints.size(), 5u);
  const auto& w = p.waypoints;
  // The table rounds to tenths of seconds and of m/s.
  EXPECT_NEAR(w[1].timeS, 10.2, 0.05);   // A-B stop time
  EXPECT_NEAR(w[2].timeS, 13.0, 0.05);   // B-C stop time
  EXPECT_NEAR(w[2].legSpeedMs, 1.9, 0.05);  // C-D speed
  EXPECT_DOUBLE_EQ(w[3].timeS, 45);
  EXPECT_NEAR(w[4].timeS, 55.8, 0.05);   // D-E stop time
  EXPECT_DOUBLE_EQ(w[0].legSpeedMs, 10);
  EXPECT_DOUBLE_EQ(w[1].legSpeedMs, 5);
  EXPECT_DOUBLE_EQ(w[3].legSpeedMs, 5);
  // Exact values behind the rounding.
  EXPECT_NEAR(w[1].timeS, std::hypot(100, 20) / 10, 1e-9);
  EXPECT_NEAR(w[2].legSpeedMs, std::hypot(60, 5) / (45 - w[2].timeS), 1e-9);
  // Table 7's underlined (given) values.
  EXPECT_TRUE(w[0].timeGiven && w[0].speedGiven);
  EXPECT_TRUE(w[1].speedGiven && !w[1].timeGiven);
  EXPECT_TRUE(!w[2].speedGiven && !w[2].timeGiven);
  EXPECT_TRUE(w[3].timeGiven);
  EXPECT_EQ(w[3].line, 6);
}

TEST(Path, LegsWithoutSpeedsBetweenTwoTimesShareOneSpeed) {
  const Path p = parseOk("frame projected\n0 0 50 time=0\n300 0 50 speed=3.6\n400 0 50\n400 300 50 time=200\n");
  const auto& w = p.waypoints;
  // The 100 m leg at 1 m/s takes 100 s; the other 600 m share the other 100 s.
  EXPECT_NEAR(w[0].legSpeedMs, 6, 1e-9);
  EXPECT_NEAR(w[1].timeS, 50, 1e-9);
  EXPECT_NEAR(w[2].timeS, 150, 1e-9);
  EXPECT_NEAR(w[2].legSpeedMs, 6, 1e-9);
  EXPECT_DOUBLE_EQ(w[3].timeS, 200);
}

TEST(Path, OldFormatReadsWithTheDefaultSpeed) {
  PathOptions o = lonLatOptions();
  o.defaultSpeedKmh = 36;
  const Path p = parseOk("# up the valley\n1.0 2.0 200\n1.1 2.0 200 72\n1.1 2.1 800\n", o);
  ASSERT_EQ(p.frame, PathFrame::lonLat);
  const auto& w = p.waypoints;
  EXPECT_DOUBLE_EQ(w[0].easting, 1000);
  EXPECT_DOUBLE_EQ(w[0].northing, 2000);
  EXPECT_DOUBLE_EQ(w[0].legSpeedMs, 10);  // --speed
  EXPECT_DOUBLE_EQ(w[1].legSpeedMs, 20);  // the bare 4th field, km/h
  EXPECT_NEAR(w[1].timeS, 10, 1e-9);
  EXPECT_NEAR(w[2].timeS, 15, 1e-9);
  EXPECT_DOUBLE_EQ(w[2].heightAgl, 800);
}

TEST(Path, WithoutADefaultTheSpeedCarriesOn) {
  const Path p = parseOk("frame projected\n0 0 10 speed=36\n100 0 10\n100 100 10\n");
  EXPECT_DOUBLE_EQ(p.waypoints[1].legSpeedMs, 10);
  EXPECT_NEAR(p.waypoints[2].timeS, 20, 1e-9);
}

TEST(Path, RepeatingAWaypointWithALaterTimeWaits) {
  const Path p = parseOk("frame projected\n0 0 10 speed=36\n100 0 10\n100 0 10 time=30\n200 0 10\n");
  const auto& w = p.waypoints;
  EXPECT_NEAR(w[1].timeS, 10, 1e-9);
  EXPECT_DOUBLE_EQ(w[1].legSpeedMs, 0);
  EXPECT_DOUBLE_EQ(w[2].timeS, 30);
  EXPECT_NEAR(w[3].timeS, 40, 1e-9);  // carries the 10 m/s of the first leg on
  const Pose waiting = samplePath(p, 20);
  EXPECT_DOUBLE_EQ(waiting.easting, 100);
  EXPECT_DOUBLE_EQ(waiting.speedKmh, 0);
  EXPECT_DOUBLE_EQ(waiting.headingDeg, 90);  // still facing along the way in
}

TEST(Path, SpeedAndTimeTogetherMustAgree) {
  // 100 m at 36 km/h takes 10 s; 10.02 s is rounding, 20 s is a mistake.
  const Path p = parseOk("frame projected\n0 0 10 speed=36\n100 0 10 time=10.02\n");
  EXPECT_DOUBLE_EQ(p.waypoints[1].timeS, 10.02);
  const std::string e = parseError("frame projected\n0 0 10 speed=36\n100 0 10 time=20\n");
  EXPECT_NE(e.find("test.path"), std::string::npos) << e;
  EXPECT_NE(e.find("take 10 s but time= allows 20 s"), std::string::npos) << e;
  EXPECT_NE(e.find("drop speed="), std::string::npos) << e;
}

TEST(Path, Errors) {
  auto has = [](const std::string& e, const char* what) {
    EXPECT_NE(e.find(what), std::string::npos) << "error: " << e << "\nwanted: " << what;
  };
  has(parseError("frame projected\n0 0 10 time=20\n100 0 10 time=10\n"), "line 3: time=10 is before");
  has(parseError("frame projected\n0 0 10 speed=3.6 time=0\n100 0 10\n200 0 10 time=50\n"),
      "raise a speed or give a later time");
  has(parseError("frame projected\n0 0 10\n100 0 10\n"), "line 2: the leg starting here has no speed=");
  has(parseError("1 2 10 colour=red\n3 4 10\n"), "line 1: unknown key \"colour\"");
  has(parseError("1 2 10 36 48\n3 4 10\n"), "line 1: unexpected field \"48\"");
  has(parseError("1 2 x\n3 4 10\n"), "line 1: expected \"lon lat height_m");
  has(parseError("1 2 10 speed=-3\n3 4 10\n"), "speed must be positive");
  has(parseError("1 2 10 time=1:75\n3 4 10\n"), "H:MM:SS");
  has(parseError("1 2 -5\n3 4 10\n"), "must be >= 0");
  has(parseError("1 2 10\n60 4 10\n"), "test.path @0: line 2: is outside the database");
  has(parseError("1 2 10\nframe projected\n"), "line 2: \"frame\" must come once, before the first waypoint");
  has(parseError("frame utm\n"), "line 1: expected \"frame lonlat\"");
  has(parseError("500000 4000000 10\n500100 4000000 10\n"), "for easting northing put \"frame projected\"");
  has(parseError("1 2 10 speed=36\n"), "at least two waypoints");
  has(parseError("1 2 10 speed=36\n3 4 10\n", PathOptions{}), "need a converter");
}

TEST(Path, AnOutOfRangeHeightNamesTheFileAndLine) {
  // The flight's own --height bound (0 .. 100000 m) is checked while parsing,
  // so the error points at the line, not at --height.
  auto r = parsePath("frame projected\n0 0 10 speed=36\n100 0 100000\n200 0 10\n", "valley.path", lonLatOptions());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(pathProblemText(r.problems().front()),
            "valley.path:3: height_m 100000 is metres above the ground and must be below 100000 (the limit of MotionOptions::heightAgl)");
  EXPECT_TRUE(parsePath("frame projected\n0 0 99999.9 speed=36\n100 0 0\n", "ok.path", lonLatOptions()).ok());
  auto huge = parsePath("frame projected\n0 0 1e300 speed=36\n100 0 0\n", "x.path", lonLatOptions());
  ASSERT_FALSE(huge.ok());
  EXPECT_EQ(pathProblemText(huge.problems().front()).rfind("x.path:2: height_m 1e300", 0), 0u)
      << huge.error();
}

TEST(Path, ProblemTextIsFileColonLine) {
  EXPECT_EQ(pathProblemText({"a.path", 0, "line 12: what"}), "a.path:12: what");
  EXPECT_EQ(pathProblemText({"a.path", 0, "legs line 3 to line 5: what"}), "a.path: legs line 3 to line 5: what");
  EXPECT_EQ(pathProblemText({"a.path", 0, "line x: what"}), "a.path: line x: what");
  EXPECT_EQ(pathProblemText({"a.path", 0, "line 7"}), "a.path: line 7");
}

TEST(Path, TimesReadAsSecondsOrClock) {
  const Path p = parseOk("frame projected\n0 0 10 time=1:02:03.5\n100 0 10 time=3724\n");
  EXPECT_DOUBLE_EQ(p.waypoints[0].timeS, 3723.5);
  EXPECT_DOUBLE_EQ(p.durationS(), 0.5);
}

TEST(Path, SamplePathAlongBeforeAndAfter) {
  const Path p = parseOk("frame projected\n0 0 100 speed=36\n100 0 300 speed=72\n100 -200 300\n");
  Pose a = samplePath(p, 5);  // half way along the first leg
  EXPECT_NEAR(a.easting, 50, 1e-9);
  EXPECT_NEAR(a.northing, 0, 1e-9);
  EXPECT_NEAR(a.heightAgl, 200, 1e-9);
  EXPECT_NEAR(a.headingDeg, 90, 1e-9);
  EXPECT_NEAR(a.speedKmh, 36, 1e-9);
  Pose b = samplePath(p, 15);  // second leg, due south at 20 m/s
  EXPECT_NEAR(b.northing, -100, 1e-9);
  EXPECT_NEAR(b.headingDeg, 180, 1e-9);
  EXPECT_NEAR(b.speedKmh, 72, 1e-9);
  Pose before = samplePath(p, -3);
  EXPECT_DOUBLE_EQ(before.easting, 0);
  EXPECT_DOUBLE_EQ(before.speedKmh, 0);
  EXPECT_NEAR(before.headingDeg, 90, 1e-9);
  Pose after = samplePath(p, 1000);
  EXPECT_DOUBLE_EQ(after.northing, -200);
  EXPECT_DOUBLE_EQ(after.speedKmh, 0);
  EXPECT_NEAR(after.headingDeg, 180, 1e-9);
}

TEST(Path, FrameZeroHasTheFirstLegsSpeed) {
  const Path p = parseOk("frame projected\n0 0 100 speed=36\n100 0 300\n");
  EXPECT_NEAR(samplePath(p, 0).speedKmh, 36, 1e-9);
}

TEST(Path, TheHeadingTurnsSmoothlyAtTheTurnRateRoundEachWaypoint) {
  // East at 10 m/s for 100 s, then south: a 90 degree right turn at 45
  // degrees/s takes 2 s, centred on the waypoint at t = 100.
  const Path p = parseOk("frame projected\n0 0 100 speed=36\n1000 0 100\n1000 -1000 100\n");
  ASSERT_DOUBLE_EQ(p.turnRateDegS, 45);
  EXPECT_NEAR(samplePath(p, 98.9).headingDeg, 90, 1e-9);   // before the turn
  EXPECT_NEAR(samplePath(p, 99.5).headingDeg, 112.5, 1e-9);
  EXPECT_NEAR(samplePath(p, 100).headingDeg, 135, 1e-9);   // half way, on the waypoint
  EXPECT_NEAR(samplePath(p, 100).easting, 1000, 1e-9);     // which the eye still passes
  EXPECT_NEAR(samplePath(p, 101.1).headingDeg, 180, 1e-9);  // after it
  // Frame by frame (30 Hz) the heading never steps more than the rate allows.
  double last = samplePath(p, 0).headingDeg, worst = 0;
  for (int k = 1; k <= 30 * 200; ++k) {
    const double h = samplePath(p, k / 30.0).headingDeg;
    worst = std::max(worst, std::abs(h - last));
    last = h;
  }
  EXPECT_LE(worst, 45.0 / 30 + 1e-9);
  // Left through north: 350 -> 10 degrees turns 20 degrees, not 340.
  const Path q = parseOk("frame projected\n0 0 100 speed=36\n-100 567.1 100\n0 1134.2 100\n");
  const double mid = samplePath(q, q.waypoints[1].timeS).headingDeg;
  EXPECT_TRUE(mid < 1 || mid > 359) << mid;
}

TEST(Path, ResolvePathOnPointsBuiltInCode) {
  std::vector<PathPoint> pts(3);
  pts[1].easting = 30;
  pts[1].northing = 40;  // 50 m
  pts[2].easting = 30;
  pts[2].northing = 90;  // 50 m
  pts[0].timeS = 10;
  pts[2].timeS = 20;
  auto r = resolvePath(pts, {});
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_DOUBLE_EQ(r->waypoints[0].timeS, 10);
  EXPECT_NEAR(r->waypoints[1].timeS, 15, 1e-9);
  EXPECT_NEAR(r->waypoints[0].legSpeedMs, 10, 1e-9);
}

TEST(Path, ReadPathFile) {
  const auto dir = std::filesystem::temp_directory_path();
  const std::string file = (dir / ("sandtable-path-" + std::to_string(::getpid()) + ".path")).string();
  {
    std::ofstream out(file);
    out << kTable7;
  }
  auto r = readPathFile(file, {});
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r->waypoints.size(), 5u);
  std::filesystem::remove(file);
  auto missing = readPathFile(file, {});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().find("cannot open"), std::string::npos);
}

}  // namespace
}  // namespace sandtable::world
