// Scripts (seed VIII.B): Figure 71 read and written back byte for byte,
// reader errors with line and column, Figure 73 playback, the recorder's
// dead-reckoning rule, the play-and-record merge and Table 7 as a script.
#include "sandtable/sim/script.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>

#include "sandtable/world/path.h"

namespace sandtable::sim {
namespace {

// Figure 71 of the seed, verbatim.
const char* const kFigure71[9] = {
    "00 00 11 59 2 8161.926270 0.0 8174.560547 135.989869 0.000000 0.000000 0.000000 12.496254 0 1",
    "00 00 13 56 2 9659.545898 0.0 5527.709961 178.391381 156.804391 0.000000 0.000000 2.778167 0 1",
    "00 00 13 107 61 8621.704102 0.0 8938.416016 170.537046 10.795384 0.000000 0.000000 0.000000 0 1",
    "00 00 13 58 2 7601.989746 0.0 8732.117187 201.021437 118.372680 0.000000 0.000000 0.000000 0 1",
    "00 00 13 58 2 7601.989746 0.0 8732.117187 0.000000 180.000014 0.000000 0.785398 0.000000 0 0",
    "00 00 14 124 1 9361.876953 0.0 9833.312500 203.685402 0.000000 0.000000 0.000000 8.330992 0 1",
    "00 00 15 59 2 8125.976562 0.0 8209.289062 135.989869 168.226653 0.000000 0.000000 0.000000 0 1",
    "00 00 15 57 2 7855.773926 0.0 8645.324219 162.891606 0.000000 0.000000 0.000000 12.500731 0 0",
    "00 00 15 60 2 9689.331055 0.0 5599.487305 175.381522 160.417411 0.000000 0.000000 12.507100 1 1",
};

std::string figure71Text() {
  std::string t;
  for (const char* l : kFigure71) {
    t += l;
    t += '\n';
  }
  return t;
}

std::vector<ScriptLine> figure71() {
  auto r = parseScript(figure71Text(), "fig71.script");
  EXPECT_TRUE(r.ok()) << r.error();
  return r.ok() ? r.value() : std::vector<ScriptLine>{};
}

struct Expected {
  int s;
  std::uint32_t entity, type;
  double x, z, dir, view, gun, agl, speed;
  bool fire, alive;
};

TEST(Script, Figure71ParsesToTheSeedsValues) {
  // Every field of every line, typed from the figure.
  const Expected e[9] = {
      {11, 59, 2, 8161.926270, 8174.560547, 135.989869, 0, 0, 0, 12.496254, false, true},
      {13, 56, 2, 9659.545898, 5527.709961, 178.391381, 156.804391, 0, 0, 2.778167, false, true},
      {13, 107, 61, 8621.704102, 8938.416016, 170.537046, 10.795384, 0, 0, 0, false, true},
      {13, 58, 2, 7601.989746, 8732.117187, 201.021437, 118.372680, 0, 0, 0, false, true},
      {13, 58, 2, 7601.989746, 8732.117187, 0, 180.000014, 0, 0.785398, 0, false, false},
      {14, 124, 1, 9361.876953, 9833.312500, 203.685402, 0, 0, 0, 8.330992, false, true},
      {15, 59, 2, 8125.976562, 8209.289062, 135.989869, 168.226653, 0, 0, 0, false, true},
      {15, 57, 2, 7855.773926, 8645.324219, 162.891606, 0, 0, 0, 12.500731, false, false},
      {15, 60, 2, 9689.331055, 5599.487305, 175.381522, 160.417411, 0, 0, 12.507100, true, true},
  };
  const auto lines = figure71();
  ASSERT_EQ(lines.size(), 9u);
  for (int k = 0; k < 9; ++k) {
    SCOPED_TRACE(k + 1);
    const ScriptLine& l = lines[static_cast<std::size_t>(k)];
    EXPECT_EQ(l.hours, 0);
    EXPECT_EQ(l.minutes, 0);
    EXPECT_EQ(l.seconds, e[k].s);
    EXPECT_EQ(l.timeS, e[k].s);
    EXPECT_EQ(l.entity, e[k].entity);
    EXPECT_EQ(l.type, e[k].type);
    EXPECT_EQ(l.x, e[k].x);
    EXPECT_EQ(l.y, 0.0);
    EXPECT_EQ(l.z, e[k].z);
    EXPECT_EQ(l.directionDeg, e[k].dir);
    EXPECT_EQ(l.viewDirectionDeg, e[k].view);
    EXPECT_EQ(l.gunElevation, e[k].gun);
    EXPECT_EQ(l.aboveGroundLevel, e[k].agl);
    EXPECT_EQ(l.speed, e[k].speed);
    EXPECT_EQ(l.fire, e[k].fire);
    EXPECT_EQ(l.alive, e[k].alive);
    EXPECT_EQ(l.line, k + 1);
  }
}

TEST(Script, Figure71WritesBackByteForByte) {
  // %f reproduces every float of the figure; its Y "0.0" is the writer's
  // ground marker, so every line comes back exactly.
  const auto lines = figure71();
  ASSERT_EQ(lines.size(), 9u);
  for (std::size_t k = 0; k < 9; ++k) EXPECT_EQ(formatScriptLine(lines[k]), kFigure71[k]) << "line " << k + 1;
  EXPECT_EQ(formatScript(lines), figure71Text());
}

TEST(Script, WriterLayout) {
  ScriptLine s;
  s.setTime(3723.25);  // 1 h 2 min 3.25 s
  EXPECT_EQ(s.hours, 1);
  EXPECT_EQ(s.minutes, 2);
  EXPECT_DOUBLE_EQ(s.seconds, 3.25);
  s.entity = 7;
  s.type = 3;
  s.x = 1.5;
  s.y = 120.25;  // an aircraft: not the ground marker
  s.z = -2;
  s.directionDeg = 90;
  s.speed = 300;
  s.fire = true;
  s.alive = false;
  EXPECT_EQ(formatScriptLine(s),
            "01 02 03.250000 7 3 1.500000 120.250000 -2.000000 90.000000 0.000000 0.000000 0.000000 300.000000 1 0");
  s.setTime(5.5);
  EXPECT_EQ(formatScriptLine(s).substr(0, 15), "00 00 05.500000");
  s.setTime(11);
  EXPECT_EQ(formatScriptLine(s).substr(0, 9), "00 00 11 ");
  // 60 Hz: a fraction rounded to the microsecond, read back to it.
  s.setTime(661.0 / 60.0);
  EXPECT_EQ(formatScriptLine(s).substr(0, 15), "00 00 11.016667");
  s.setTime(59.9999999);  // rounds up into the next minute
  EXPECT_EQ(formatScriptLine(s).substr(0, 9), "00 01 00 ");
  EXPECT_EQ(s.minutes, 1);
  EXPECT_EQ(s.seconds, 0.0);
}

TEST(Script, FractionalSecondsCommentsBlankLinesAndCrlfRead) {
  const auto r = parseScript(
      "# a comment line\n\n00 00 05.500000 1 2 0 0.0 0 0 0 0 0 0 0 1  # trailing comment\r\n"
      "01 02 03.25 1 2 0 0.0 0 0 0 0 0 0 0 1\n",
      "x.script");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r->size(), 2u);
  EXPECT_EQ(r.value()[0].timeS, 5.5);
  EXPECT_EQ(r.value()[0].line, 3);
  EXPECT_EQ(r.value()[1].timeS, 3723.25);
  EXPECT_EQ(r.value()[1].hours, 1);
  EXPECT_EQ(r.value()[1].minutes, 2);
  EXPECT_EQ(r.value()[1].seconds, 3.25);
}

/// The first problem of a text that must fail.
Problem firstProblem(const std::string& text) {
  const auto r = parseScript(text, "bad.script");
  EXPECT_FALSE(r.ok());
  if (r.ok()) return {};
  return r.problems().front();
}

TEST(Script, ErrorsNameLineAndColumn) {
  const std::string good = "00 00 11 59 2 1 0.0 2 3 4 5 6 7 0 1\n";  // 35 bytes and newline
  struct Case {
    std::string line;
    std::uint64_t column;  // 1-based
    std::string words;
  };
  const Case cases[] = {
      {"00 00 13 59 2 1 0.0 2 3 4 5 6 7 0", 34, "found 14; Alive_Flag"},
      {"00 00 13 59 2 1 0.0 2 3 4 5 6 7 0 1 9", 37, "unexpected 16th field \"9\""},
      {"00 00 13 59 2 1 0.0 2 3 4 5 6 7 2 1", 33, "Fire_Flag \"2\" must be 0 or 1"},
      {"00 00 13 59 2 1 0.0 2 3 4 5 6 7 0 yes", 35, "Alive_Flag \"yes\" must be 0 or 1"},
      {"00 00 13 59 2 nan 0.0 2 3 4 5 6 7 0 1", 15, "X_Position \"nan\" is not a finite number"},
      {"00 00 13 59 2 1 0.0 2 3 4 5 6 1e999 0 1", 31, "Speed \"1e999\""},
      {"00 60 13 59 2 1 0.0 2 3 4 5 6 7 0 1", 4, "Minutes \"60\""},
      {"00 00 60 59 2 1 0.0 2 3 4 5 6 7 0 1", 7, "Seconds \"60\""},
      {"00 00 -1 59 2 1 0.0 2 3 4 5 6 7 0 1", 7, "Seconds \"-1\""},
      {"0.5 00 13 59 2 1 0.0 2 3 4 5 6 7 0 1", 1, "Hours \"0.5\""},
      {"00 00 13 -59 2 1 0.0 2 3 4 5 6 7 0 1", 10, "Entity_Number \"-59\""},
      {"00 00 13 59 4294967296 1 0.0 2 3 4 5 6 7 0 1", 13, "Entity_Type \"4294967296\""},
      {"00 00 10 59 2 1 0.0 2 3 4 5 6 7 0 1", 1, "before the 11 s of line 1"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.line);
    const Problem p = firstProblem(good + c.line + "\n");
    EXPECT_EQ(p.file, "bad.script");
    EXPECT_EQ(p.offset, good.size() + c.column - 1);
    EXPECT_EQ(p.message.rfind("line 2, column " + std::to_string(c.column) + ": ", 0), 0u) << p.message;
    EXPECT_NE(p.message.find(c.words), std::string::npos) << p.message;
  }
  // Every bad line is reported, not only the first.
  const auto r = parseScript("1\n2\n", "two.script");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.problems().size(), 2u);
}

TEST(Script, ReadsFilesAndReportsMissingOnes) {
  const auto dir = std::filesystem::temp_directory_path() / "sandtable_test_script";
  std::filesystem::create_directories(dir);
  const auto file = (dir / "fig71.script").string();
  {
    std::ofstream out(file, std::ios::binary);
    out << figure71Text();
  }
  const auto r = readScriptFile(file);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r->size(), 9u);
  const auto missing = readScriptFile((dir / "none.script").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().find("cannot open the script file"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(Script, PlaybackAppliesDueLinesAndIgnoresTheDead) {
  // Figure 71 plus a later line that would reincarnate entity 58 (its
  // line 5 kills it) and one for entity 59.
  auto lines = figure71();
  auto extra = parseScript(
      "00 00 16 58 2 7601.989746 0.0 8732.117187 0 0 0 0 5 0 1\n"
      "00 00 16 59 2 8125.976562 0.0 8209.289062 90 0 0 0 3 0 1\n",
      "more.script");
  ASSERT_TRUE(extra.ok()) << extra.error();
  lines.insert(lines.end(), extra->begin(), extra->end());
  ScriptPlayer player(lines);
  const auto ents = player.entities();
  ASSERT_EQ(ents.size(), 7u);
  const std::uint32_t ids[7] = {59, 56, 107, 58, 124, 57, 60};
  const std::uint32_t types[7] = {2, 2, 61, 2, 1, 2, 2};
  for (std::size_t k = 0; k < 7; ++k) {
    EXPECT_EQ(ents[k].entity, ids[k]);
    EXPECT_EQ(ents[k].type, types[k]);
  }
  EXPECT_EQ(ents[0].firstTimeS, 11);

  std::map<std::uint32_t, bool> alive;
  std::vector<int> applied;  // source lines, in order
  auto isAlive = [&](std::uint32_t e) { return !alive.count(e) || alive[e]; };
  auto apply = [&](const ScriptLine& l) {
    alive[l.entity] = l.alive;
    applied.push_back(l.line);
  };
  EXPECT_EQ(player.advance(10.9, isAlive, apply), 0u);
  EXPECT_EQ(player.nextTimeS(), 11);
  EXPECT_EQ(player.advance(11, isAlive, apply), 1u);  // a line is due at its own time
  EXPECT_EQ(player.advance(13.5, isAlive, apply), 4u);
  EXPECT_FALSE(alive[58]);
  EXPECT_EQ(player.advance(15, isAlive, apply), 4u);
  EXPECT_FALSE(player.finished());
  // At 16: entity 58's line is consumed but not applied; 59's is applied.
  EXPECT_EQ(player.advance(100, isAlive, apply), 1u);
  EXPECT_TRUE(player.finished());
  EXPECT_EQ(applied, (std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8, 9, 2}));
  EXPECT_FALSE(alive[58]);
  // Without isAlive every line applies; rewind replays from the start.
  player.rewind();
  EXPECT_EQ(player.advance(100, {}, {}), 11u);
}

TEST(Script, PlayerSortsLinesBuiltInCodeStably) {
  std::vector<ScriptLine> lines(3);
  lines[0].timeS = 2;
  lines[0].entity = 1;
  lines[1].timeS = 1;
  lines[1].entity = 2;
  lines[2].timeS = 2;
  lines[2].entity = 3;
  ScriptPlayer player(lines);
  std::vector<std::uint32_t> order;
  player.advance(5, {}, [&](const ScriptLine& l) { order.push_back(l.entity); });
  EXPECT_EQ(order, (std::vector<std::uint32_t>{2, 1, 3}));
}

TEST(Script, DeadReckoningIsClockwiseFromNorthWithNorthUpZ) {
  ScriptLine l;
  l.setTime(10);
  l.x = 100;
  l.z = 200;
  l.speed = 10;
  l.directionDeg = 0;  // north: -z
  EXPECT_NEAR(deadReckon(l, 12).x(), 100, 1e-12);
  EXPECT_NEAR(deadReckon(l, 12).y(), 180, 1e-12);
  l.directionDeg = 90;  // east: +x
  EXPECT_NEAR(deadReckon(l, 12).x(), 120, 1e-12);
  EXPECT_NEAR(deadReckon(l, 12).y(), 200, 1e-12);
  l.directionDeg = 225;  // south-west: -x, +z
  EXPECT_NEAR(deadReckon(l, 12).x(), 100 - 20 / std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(deadReckon(l, 12).y(), 200 + 20 / std::sqrt(2.0), 1e-9);
  // Before the line's time the entity waits at the line's position.
  EXPECT_EQ(deadReckon(l, 9).x(), 100);
  EXPECT_EQ(deadReckon(l, 9).y(), 200);
}

/// The truth a recorder is offered, at 60 Hz: 10 s straight east at
/// 10 m/s; 10 s clockwise round a circle of 50 m radius at 10 m/s; 10 s
/// braking straight on at 1 m/s^2; 5 s stopped, turning the turret at
/// 20 deg/s and firing once at 32 s.
constexpr int kTruthSteps = 60 * 35;

ScriptLine truth(int step) {
  const double t = step / 60.0;
  ScriptLine s;
  s.timeS = t;
  s.entity = 59;
  s.type = 2;
  const double r = 50, v = 10, deg = 180 / std::numbers::pi;
  if (t <= 10) {
    s.x = v * t;
    s.directionDeg = 90;
    s.speed = v;
    return s;
  }
  // Heading grows (clockwise seen from above, north up); the centre is south (+z).
  const double a = v * (std::min(t, 20.0) - 10) / r;  // radians turned
  s.x = 100 + r * std::sin(a);
  s.z = r - r * std::cos(a);
  s.directionDeg = std::fmod(90 + a * deg, 360.0);
  s.speed = v;
  if (t <= 20) return s;
  const double tau = std::min(t, 30.0) - 20;
  const double along = v * tau - tau * tau / 2;  // braking at 1 m/s^2
  s.x += std::sin(s.directionDeg / deg) * along;
  s.z -= std::cos(s.directionDeg / deg) * along;
  s.speed = v - tau;
  if (t <= 30) return s;
  s.viewDirectionDeg = 20 * (t - 30);
  s.fire = step == 60 * 32;
  return s;
}

/// Records the truth with `options`, writes and reads the text, plays it
/// back step by step and returns the largest horizontal miss.
double worstPlaybackMiss(const RecorderOptions& options, std::size_t& lineCount, int& fires) {
  ScriptRecorder rec(options);
  for (int k = 0; k <= kTruthSteps; ++k) rec.record(truth(k));
  rec.finish();
  const auto parsed = parseScript(rec.text(), "rec.script");  // as a file would carry it
  EXPECT_TRUE(parsed.ok()) << parsed.error();
  if (!parsed.ok()) return 1e9;
  lineCount = parsed->size();
  EXPECT_EQ(parsed->back().speed, 0);
  ScriptPlayer player(parsed.value());
  const ScriptLine* current = nullptr;
  double worst = 0;
  fires = 0;
  for (int k = 0; k <= kTruthSteps; ++k) {
    const ScriptLine want = truth(k);
    player.advance(want.timeS, {}, [&](const ScriptLine& l) {
      current = &l;
      fires += l.fire;
    });
    if (!current) return 1e9;
    const Eigen::Vector2d p = deadReckon(*current, want.timeS);
    worst = std::max(worst, std::hypot(p.x() - want.x, p.y() - want.z));
    EXPECT_LE(std::abs(current->viewDirectionDeg - want.viewDirectionDeg), options.angleToleranceDeg + 1e-6)
        << want.timeS;
  }
  return worst;
}

TEST(Script, RecordThenPlayBackStaysWithinOneCentimetre) {
  std::size_t lines = 0;
  int fires = 0;
  EXPECT_LE(worstPlaybackMiss({}, lines, fires), 0.0051);
  EXPECT_EQ(fires, 1);
  EXPECT_GT(lines, 35u);
  EXPECT_LT(lines, std::size_t(kTruthSteps / 2));  // it does compress
  // The dead-reckoning rule alone (no heartbeat, no direction or speed
  // rule) still holds the track; without it the braking leg drifts metres.
  RecorderOptions drOnly;
  drOnly.maxIntervalS = 0;
  drOnly.angleToleranceDeg = 1000;
  drOnly.speedToleranceMs = 1000;
  EXPECT_LE(worstPlaybackMiss(drOnly, lines, fires), 0.0051);
  RecorderOptions none = drOnly;
  none.toleranceM = 1e9;
  EXPECT_GT(worstPlaybackMiss(none, lines, fires), 1.0);
}

TEST(Script, RecorderEmitsOnHeartbeatAndChanges) {
  // Straight and steady for 10 s at 60 Hz: only the first state and one
  // heartbeat a second (t = 1 .. 10): 11 lines.
  ScriptRecorder rec;
  for (int k = 0; k <= 600; ++k) rec.record(truth(k));
  rec.finish();
  ASSERT_EQ(rec.lines().size(), 11u);
  for (std::size_t k = 0; k < 11; ++k) EXPECT_NEAR(rec.lines()[k].timeS, double(k), 1e-9);
  // No heartbeat: the first state, then the last on finish().
  RecorderOptions quiet;
  quiet.maxIntervalS = 0;
  ScriptRecorder still(quiet);
  for (int k = 0; k <= 600; ++k) EXPECT_EQ(still.record(truth(k)), k == 0);
  EXPECT_EQ(still.lines().size(), 1u);
  still.finish();
  ASSERT_EQ(still.lines().size(), 2u);
  EXPECT_EQ(still.lines()[1].timeS, 10);
  EXPECT_EQ(still.lines()[1].x, 100);
  // A speed change, a fire flag, death: each one line. Earlier states are ignored.
  ScriptLine s = truth(0);
  ScriptRecorder events(quiet);
  EXPECT_TRUE(events.record(s));
  s.timeS = 0.1;
  s.x = 1;  // on the dead-reckoned track
  EXPECT_FALSE(events.record(s));
  s.timeS = 0.2;
  s.x = 2;
  s.speed = 10.2;
  EXPECT_TRUE(events.record(s));
  s.timeS = 0.3;
  s.x = 3.02;
  s.fire = true;
  EXPECT_TRUE(events.record(s));
  s.timeS = 0.4;
  s.x = 4.04;
  s.fire = false;
  EXPECT_TRUE(events.record(s));
  s.timeS = 0.5;
  s.x = 5.06;
  s.alive = false;
  EXPECT_TRUE(events.record(s));
  s.timeS = 0.45;
  EXPECT_FALSE(events.record(s));
  EXPECT_EQ(events.lines().size(), 5u);
  EXPECT_EQ(events.lines()[3].fire, false);
  EXPECT_EQ(events.lines()[4].alive, false);
}

TEST(Script, MergeKeepsEveryLineInTimeOrderPlayedFirst) {
  auto make = [](double t, std::uint32_t e) {
    ScriptLine l;
    l.setTime(t);
    l.entity = e;
    return l;
  };
  const std::vector<ScriptLine> played = {make(0, 1), make(1, 1), make(2, 1)};
  const std::vector<ScriptLine> recorded = {make(0.5, 9), make(1, 9), make(3, 9)};
  const std::string text = mergeScripts(played, recorded);
  const std::string expected =
      "00 00 00 1 0 0.000000 0.0 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0 1\n"
      "00 00 00.500000 9 0 0.000000 0.0 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0 1\n"
      "00 00 01 1 0 0.000000 0.0 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0 1\n"
      "00 00 01 9 0 0.000000 0.0 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0 1\n"
      "00 00 02 1 0 0.000000 0.0 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0 1\n"
      "00 00 03 9 0 0.000000 0.0 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0 1\n";
  EXPECT_EQ(text, expected);
  // Figure 71 merged with itself: 18 lines, each pair equal.
  const auto fig = figure71();
  const auto both = mergeScriptLines(fig, fig);
  ASSERT_EQ(both.size(), 18u);
  // Equal times: all of the played lines of a time, then the recorded ones.
  const int from[18] = {0, 0, 1, 2, 3, 4, 1, 2, 3, 4, 5, 5, 6, 7, 8, 6, 7, 8};
  for (std::size_t k = 0; k < 18; ++k) EXPECT_EQ(formatScriptLine(both[k]), kFigure71[from[k]]) << k;
}

TEST(Script, Table7PathBecomesAScript) {
  // Table 7's underlined values only (docs/PATH.md): speeds 10 and 5 m/s
  // are 36 and 18 km/h.
  const char* text =
      "frame projected\n"
      "0   0  10 speed=36 time=0:00:00   # A\n"
      "100 20 10 speed=18                # B\n"
      "110 30 10                         # C\n"
      "50  35 10 speed=18 time=0:00:45   # D\n"
      "0   15 10                         # E\n";
  const auto path = world::parsePath(text, "table7.path", {});
  ASSERT_TRUE(path.ok()) << path.error();
  const double oE = -1000, oN = 500;  // the grid's north-west corner
  const auto r = scriptFromPath(path.value(), 7, 1, oE, oN);
  ASSERT_TRUE(r.ok()) << r.error();
  const auto& s = r.value();
  ASSERT_EQ(s.size(), 5u);
  // Times: closed form, then the table's rounding.
  const double tB = std::hypot(100.0, 20.0) / 10, tC = tB + std::hypot(10.0, 10.0) / 5;
  const double tE = 45 + std::hypot(50.0, 20.0) / 5;
  EXPECT_EQ(s[0].timeS, 0);
  EXPECT_NEAR(s[1].timeS, tB, 1e-9);
  EXPECT_NEAR(s[2].timeS, tC, 1e-9);
  EXPECT_EQ(s[3].timeS, 45);
  EXPECT_NEAR(s[4].timeS, tE, 1e-9);
  EXPECT_NEAR(s[1].timeS, 10.2, 0.05);
  EXPECT_NEAR(s[2].timeS, 13, 0.05);
  EXPECT_NEAR(s[4].timeS, 55.8, 0.05);
  // Speeds: A-B 10, B-C 5, C-D computed 1.9, D-E 5, then stopped.
  EXPECT_NEAR(s[0].speed, 10, 1e-9);
  EXPECT_NEAR(s[1].speed, 5, 1e-9);
  EXPECT_NEAR(s[2].speed, std::hypot(60.0, 5.0) / (45 - tC), 1e-9);
  EXPECT_NEAR(s[2].speed, 1.9, 0.05);
  EXPECT_NEAR(s[3].speed, 5, 1e-9);
  EXPECT_EQ(s[4].speed, 0);
  // Bearings clockwise from north.
  const double deg = 180 / std::numbers::pi;
  EXPECT_NEAR(s[0].directionDeg, std::atan2(100.0, 20.0) * deg, 1e-9);  // 78.69
  EXPECT_NEAR(s[1].directionDeg, 45, 1e-9);
  EXPECT_NEAR(s[2].directionDeg, 360 - std::atan2(60.0, 5.0) * deg, 1e-9);  // 274.76
  EXPECT_NEAR(s[3].directionDeg, 180 + std::atan2(50.0, 20.0) * deg, 1e-9);  // 248.20
  EXPECT_NEAR(s[4].directionDeg, s[3].directionDeg, 1e-12);
  // Positions in database x/z.
  const double wp[5][2] = {{0, 0}, {100, 20}, {110, 30}, {50, 35}, {0, 15}};
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_EQ(s[k].x, wp[k][0] - oE);
    EXPECT_EQ(s[k].z, oN - wp[k][1]);
    EXPECT_EQ(s[k].y, 0);
    EXPECT_EQ(s[k].entity, 7u);
    EXPECT_EQ(s[k].type, 1u);
    EXPECT_TRUE(s[k].alive);
    EXPECT_FALSE(s[k].fire);
  }
  // Dead reckoning each line to the next line's time lands on the next waypoint.
  for (std::size_t k = 0; k + 1 < 5; ++k) {
    const Eigen::Vector2d p = deadReckon(s[k], s[k + 1].timeS);
    EXPECT_LT(std::hypot(p.x() - s[k + 1].x, p.y() - s[k + 1].z), 0.01) << k;
  }
  // And so does the written text, read back.
  const auto again = parseScript(formatScript(s), "table7.script");
  ASSERT_TRUE(again.ok()) << again.error();
  EXPECT_EQ(formatScriptLine(again.value()[0]),
            "00 00 00 7 1 1000.000000 0.0 500.000000 78.690068 0.000000 0.000000 0.000000 10.000000 0 1");
  for (std::size_t k = 0; k + 1 < 5; ++k) {
    const Eigen::Vector2d p = deadReckon(again.value()[k], again.value()[k + 1].timeS);
    EXPECT_LT(std::hypot(p.x() - s[k + 1].x, p.y() - s[k + 1].z), 0.01) << k;
  }
}

TEST(Script, PathWithAWaitAndTooShortPathsConvert) {
  // A wait: the repeated waypoint's leg has speed 0 and keeps the bearing.
  const auto path = world::parsePath("frame projected\n0 0 0 time=0\n0 100 0 time=20\n0 100 0 time=30\n",
                                       "wait.path", {});
  ASSERT_TRUE(path.ok()) << path.error();
  const auto r = scriptFromPath(path.value(), 1, 1, 0, 0);
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r->size(), 3u);
  EXPECT_NEAR(r.value()[0].speed, 5, 1e-12);  // 100 m in 20 s
  EXPECT_EQ(r.value()[1].speed, 0);
  EXPECT_EQ(r.value()[1].directionDeg, 0);
  EXPECT_EQ(r.value()[1].z, -100);
  world::Path one;
  one.waypoints.resize(1);
  EXPECT_FALSE(scriptFromPath(one, 1, 1, 0, 0).ok());
}

#ifdef SANDTABLE_SOURCE_DIR
TEST(Script, SampleScriptReads) {
  const auto r = readScriptFile(std::string(SANDTABLE_SOURCE_DIR) + "/samples/demo.script");
  ASSERT_TRUE(r.ok()) << r.error();
  bool has59 = false;
  for (const auto& e : scriptEntities(r.value())) has59 = has59 || e.entity == 59;
  EXPECT_TRUE(has59);
}
#endif

}  // namespace
}  // namespace sandtable::sim
