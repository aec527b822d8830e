// Scenario files: a full good parse checked field by field, every kind of
// error with its line and column, path resolution and the seeded groups.
#include "sandtable/sim/scenario.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "sandtable/edits/profile.h"
#include "sandtable/sim/scenario_load.h"
#include "sandtable/sim/script.h"

namespace sandtable::sim {
namespace {

const char* const kExample =
    "sandtable-scenario 1\n"
    "frame lonlat            # or: frame projected\n"
    "seed 42\n"
    "# entity NAME key=value ...\n"
    "entity lead  icon=tank  force=blue domain=land mobility=tracked at=13.30,42.29 heading=45 speed=20 "
    "behaviour=zigzag driven\n"
    "entity boat1 icon=boat  force=red  domain=sea  at=13.21,42.20 heading=90 speed=15 behaviour=noise\n"
    "entity jet1  icon=jet   force=blue domain=air  aircraft=aircraft/trainer.txt at=13.3,42.3 altitude=800 "
    "heading=0 speed=300\n"
    "entity s59   icon=tank  force=red  script=demo.script script-entity=59\n"
    "group 40 icon=tank force=red domain=land mobility=wheeled area=13.25,42.25,13.35,42.33 speed=10..30 "
    "behaviour=noise    # many random entities\n";

const ScenarioBehaviour kAll{true, true, true, true};

TEST(Scenario, ExampleParsesFieldByField) {
  const auto r = parseScenario(kExample, "/data/runs/demo.scenario");
  ASSERT_TRUE(r.ok()) << r.error();
  const Scenario& s = r.value();
  EXPECT_EQ(s.frame, ScenarioFrame::lonLat);
  ASSERT_TRUE(s.seed.has_value());
  EXPECT_EQ(*s.seed, 42u);
  EXPECT_EQ(s.source, "/data/runs/demo.scenario");
  ASSERT_EQ(s.entities.size(), 4u);
  ASSERT_TRUE(s.driven.has_value());
  EXPECT_EQ(*s.driven, 0u);

  const EntitySpec& lead = s.entities[0];
  EXPECT_EQ(lead.name, "lead");
  EXPECT_EQ(lead.icon, "tank");
  EXPECT_EQ(lead.force, kScenarioBlue);
  EXPECT_EQ(lead.domain, ScenarioDomain::land);
  EXPECT_EQ(lead.mobility, ScenarioMobility::tracked);
  EXPECT_TRUE(lead.lonLat);
  EXPECT_EQ(lead.a, 13.30);
  EXPECT_EQ(lead.b, 42.29);
  EXPECT_EQ(lead.headingDeg, 45);
  EXPECT_DOUBLE_EQ(lead.speedMs, 20 / 3.6);
  EXPECT_FALSE(lead.altitude.has_value());
  EXPECT_FALSE(lead.agl.has_value());
  EXPECT_EQ(lead.behaviour, (ScenarioBehaviour{true, false, false, false}));
  EXPECT_TRUE(lead.driven);
  EXPECT_EQ(lead.script, "");
  EXPECT_EQ(lead.aircraft, "");
  EXPECT_EQ(lead.fuel, 1.0);
  EXPECT_EQ(lead.line, 5);

  const EntitySpec& boat = s.entities[1];
  EXPECT_EQ(boat.name, "boat1");
  EXPECT_EQ(boat.force, kScenarioRed);
  EXPECT_EQ(boat.domain, ScenarioDomain::sea);
  EXPECT_EQ(boat.mobility, ScenarioMobility::ship);  // the sea's default
  EXPECT_EQ(boat.a, 13.21);
  EXPECT_EQ(boat.b, 42.20);
  EXPECT_EQ(boat.headingDeg, 90);
  EXPECT_DOUBLE_EQ(boat.speedMs, 15 / 3.6);
  EXPECT_EQ(boat.behaviour, kAll);
  EXPECT_FALSE(boat.driven);

  const EntitySpec& jet = s.entities[2];
  EXPECT_EQ(jet.domain, ScenarioDomain::air);
  EXPECT_EQ(jet.mobility, ScenarioMobility::aircraft);
  EXPECT_EQ(jet.aircraft, "/data/runs/aircraft/trainer.txt");
  ASSERT_TRUE(jet.altitude.has_value());
  EXPECT_EQ(*jet.altitude, 800);
  EXPECT_EQ(jet.headingDeg, 0);
  EXPECT_DOUBLE_EQ(jet.speedMs, 300 / 3.6);
  EXPECT_EQ(jet.behaviour, ScenarioBehaviour{});

  const EntitySpec& s59 = s.entities[3];
  EXPECT_EQ(s59.script, "/data/runs/demo.script");
  ASSERT_TRUE(s59.scriptEntity.has_value());
  EXPECT_EQ(*s59.scriptEntity, 59u);
  EXPECT_FALSE(s59.a.has_value());
  EXPECT_FALSE(s59.b.has_value());
  EXPECT_EQ(s59.force, kScenarioRed);

  ASSERT_EQ(s.groups.size(), 1u);
  const GroupSpec& g = s.groups[0];
  EXPECT_EQ(g.name, "group1");
  EXPECT_EQ(g.count, 40);
  EXPECT_EQ(g.icon, "tank");
  EXPECT_EQ(g.force, kScenarioRed);
  EXPECT_EQ(g.mobility, ScenarioMobility::wheeled);
  EXPECT_EQ(g.minA, 13.25);
  EXPECT_EQ(g.minB, 42.25);
  EXPECT_EQ(g.maxA, 13.35);
  EXPECT_EQ(g.maxB, 42.33);
  EXPECT_TRUE(g.lonLat);
  EXPECT_DOUBLE_EQ(g.speedMinMs, 10 / 3.6);
  EXPECT_DOUBLE_EQ(g.speedMaxMs, 30 / 3.6);
  EXPECT_EQ(g.headingMinDeg, 0);
  EXPECT_EQ(g.headingMaxDeg, 360);
  EXPECT_EQ(g.behaviour, kAll);
  EXPECT_EQ(g.line, 9);
}

TEST(Scenario, ProjectedFrameAndTheOtherKeys) {
  const auto r = parseScenario(
      "# comments and blank lines may come first\n\n"
      "sandtable-scenario 1\r\n"
      "frame projected\n"
      "entity a icon=jeep force=7 mobility=simple at=512000.5,4680000 heading=-90 behaviour=edge,fight fuel=0.25\n"
      "entity b icon=heli domain=air agl=150 at=0,0 heading=360\n"
      "entity m icon=shell domain=munition altitude=-20 at=1,2 speed=3600\n"
      "group 3 name=convoy icon=truck area=10,20,30,40 heading=80..100 speed=36 domain=air agl=100..200\n",
      "demo.scenario");
  ASSERT_TRUE(r.ok()) << r.error();
  const Scenario& s = r.value();
  EXPECT_EQ(s.frame, ScenarioFrame::projected);
  EXPECT_FALSE(s.seed.has_value());
  EXPECT_FALSE(s.driven.has_value());
  ASSERT_EQ(s.entities.size(), 3u);
  const EntitySpec& a = s.entities[0];
  EXPECT_FALSE(a.lonLat);
  EXPECT_EQ(a.force, 7);
  EXPECT_EQ(a.domain, ScenarioDomain::land);
  EXPECT_EQ(a.mobility, ScenarioMobility::simple);
  EXPECT_EQ(a.a, 512000.5);
  EXPECT_EQ(a.b, 4680000);
  EXPECT_EQ(a.headingDeg, 270);
  EXPECT_EQ(a.behaviour, (ScenarioBehaviour{false, false, true, true}));
  EXPECT_EQ(a.fuel, 0.25);
  EXPECT_EQ(a.line, 5);
  EXPECT_EQ(s.entities[1].headingDeg, 0);
  ASSERT_TRUE(s.entities[1].agl.has_value());
  EXPECT_EQ(*s.entities[1].agl, 150);
  EXPECT_EQ(s.entities[2].mobility, ScenarioMobility::simple);  // munition's default
  EXPECT_EQ(*s.entities[2].altitude, -20);
  EXPECT_DOUBLE_EQ(s.entities[2].speedMs, 1000);
  ASSERT_EQ(s.groups.size(), 1u);
  const GroupSpec& g = s.groups[0];
  EXPECT_EQ(g.name, "convoy");
  EXPECT_EQ(g.headingMinDeg, 80);
  EXPECT_EQ(g.headingMaxDeg, 100);
  EXPECT_DOUBLE_EQ(g.speedMinMs, 10);
  EXPECT_DOUBLE_EQ(g.speedMaxMs, 10);
  EXPECT_EQ(*g.aglMin, 100);
  EXPECT_EQ(*g.aglMax, 200);
  EXPECT_FALSE(g.lonLat);
}

TEST(Scenario, RelativePathsFollowTheScenarioFile) {
  const char* text =
      "sandtable-scenario 1\n"
      "entity s icon=tank script=scripts/../run.script script-entity=1\n"
      "entity t icon=tank script=/abs/x.script script-entity=2\n";
  auto bare = parseScenario(text, "here.scenario");  // no directory: as written
  ASSERT_TRUE(bare.ok()) << bare.error();
  EXPECT_EQ(bare->entities[0].script, "scripts/../run.script");
  auto nested = parseScenario(text, "runs/a/here.scenario");
  ASSERT_TRUE(nested.ok()) << nested.error();
  EXPECT_EQ(nested->entities[0].script, "runs/a/run.script");
  EXPECT_EQ(nested->entities[1].script, "/abs/x.script");
}

struct Case {
  std::string lines;   // after the header line
  int line;            // expected line number of the first problem
  std::string at;      // the problem's column is where this first occurs in that line
  std::string words;   // part of the message
  int occurrence = 1;  // which occurrence of `at`
};

TEST(Scenario, EveryErrorNamesLineColumnAndFix) {
  const std::string header = "sandtable-scenario 1\n";
  const Case cases[] = {
      {"entity a icon=tank at=1,2 colour=red\n", 2, "colour", "unknown key \"colour\"; the keys are icon"},
      {"entity a at=1,2\n", 2, "entity", "has no icon=; add icon=NAME"},
      {"entity a icon=tank\n", 2, "entity", "has no at=; add at=LON,LAT"},
      {"entity a icon=tank at=1,2\nentity a icon=jeep at=1,2\n", 3, "a icon", "already used at line 2"},
      {"group 2 icon=t area=0,0,1,1\nentity group1 icon=jeep at=1,2\n", 3, "group1", "already used at line 2"},
      {"entity a.b icon=tank at=1,2\n", 2, "a.b", "letters, digits"},
      {"entity a icon=tank at=1,2 driven\nentity b icon=tank at=1,2 driven\n", 3, "driven",
       "only one entity can be driven; entity \"a\" at line 2"},
      {"entity a icon=tank at=1,2 driven driven\n", 2, "driven", "driven is given twice", 2},
      {"entity a icon=tank at=1,2 speed=fast\n", 2, "fast", "speed=fast is not a number from 0 to 15000 km/h"},
      {"entity a icon=tank at=1,2 speed=-5\n", 2, "-5", "out of bounds"},
      {"entity a icon=tank at=1,2 speed=10..20\n", 2, "10..20", "is not a number"},
      {"entity a icon=tank at=1,x\n", 2, "1,x", "must be 2 numbers LON,LAT"},
      {"entity a icon=tank at=1,2,3\n", 2, "1,2,3", "must be 2 numbers"},
      {"entity a icon=tank at=512000,4680000\n", 2, "512000", "frame projected"},
      {"entity a icon=tank at=1,2 heading=400\n", 2, "400", "out of bounds"},
      {"entity a icon=tank at=1,2 heading=nan\n", 2, "nan", "heading=nan is not a number"},
      {"entity a icon=tank at=1,2 force=purple\n", 2, "purple", "blue, red, green, neutral or 0..255"},
      {"entity a icon=tank at=1,2 force=256\n", 2, "256", "0..255"},
      {"entity a icon=tank at=1,2 domain=space\n", 2, "space", "land, sea, air or munition"},
      {"entity a icon=tank at=1,2 domain=sea mobility=tracked\n", 2, "tracked", "needs domain=land, not domain=sea"},
      {"entity a icon=tank at=1,2 mobility=hover\n", 2, "hover", "simple, tracked, wheeled, ship or aircraft"},
      {"entity a icon=tank at=1,2 altitude=100\n", 2, "altitude", "for domain=air or domain=munition"},
      {"entity a icon=jet at=1,2 domain=air altitude=100 agl=50\n", 2, "agl", "not both"},
      {"entity a icon=jet at=1,2 domain=air agl=-1\n", 2, "-1", "out of bounds"},
      {"entity a icon=tank at=1,2 aircraft=f.txt\n", 2, "aircraft", "for mobility=aircraft"},
      {"entity a icon=tank at=1,2 fuel=1.5\n", 2, "1.5", "fraction of a full tank, from 0 to 1"},
      {"entity a icon=tank at=1,2 behaviour=wander\n", 2, "wander", "behaviour \"wander\" is not known"},
      {"entity a icon=tank at=1,2 behaviour=zigzag,fly\n", 2, "fly", "behaviour \"fly\""},
      {"entity a icon=tank at=1,2 behaviour=none,edge\n", 2, "none", "cannot be combined"},
      {"entity a icon=tank script=x.script\n", 2, "script", "needs script-entity=N"},
      {"entity a icon=tank at=1,2 script-entity=3\n", 2, "script-entity", "needs script=FILE"},
      {"entity a icon=tank script=x.script script-entity=-3\n", 2, "-3", "must be an Entity_Number"},
      {"entity a icon=tank script=x.script script-entity=3 driven\n", 2, "driven", "cannot be driven"},
      {"entity a icon=tank script=x.script script-entity=3 speed=10\n", 2, "speed", "does nothing on a scripted"},
      {"entity a icon=tank at=1,2 icon=jeep\n", 2, "icon=jeep", "icon= is given twice"},
      {"entity a icon= at=1,2\n", 2, " at", "has no value"},
      {"entity a icon=tank at=1,2 fast\n", 2, "fast", "unexpected word \"fast\""},
      {"entity\n", 2, "entity", "has no name"},
      {"group 0 icon=t area=0,0,1,1\n", 2, "0", "from 1 to 100000"},
      {"group many icon=t area=0,0,1,1\n", 2, "many", "from 1 to 100000"},
      {"group 5 icon=t\n", 2, "group", "has no area=; add area=MINLON"},
      {"group 5 icon=t area=2,2,1,1\n", 2, "2,2,1,1", "minimum above its maximum"},
      {"group 5 icon=t area=0,0,1,1 speed=30..10\n", 2, "30..10", "the low end 30 is above the high end 10"},
      {"group 5 icon=t area=0,0,1,1 speed=10..x\n", 2, "10..x", "is not a number or a range LOW..HIGH"},
      {"group 5 icon=t area=0,0,1,1 heading=-180..270\n", 2, "-180", "spans more than 360"},
      {"group 5 icon=t area=0,0,1,1 at=1,2\n", 2, "at=", "\"at\" is not for a group"},
      {"group 5 icon=t area=0,0,1,1 driven\n", 2, "driven", "a group cannot be driven"},
      {"group 5 icon=t area=0,0,1,1 name=x.y\n", 2, "x.y", "letters, digits"},
      {"launch a\n", 2, "launch", "unknown directive \"launch\""},
      {"entity a icon=tank at=1,2\nframe projected\n", 3, "frame", "before the first entity"},
      {"frame utm\n", 2, "utm", "expected \"frame lonlat\""},
      {"seed 1\nseed 2\n", 3, "seed", "only once"},
      {"seed -1\n", 2, "-1", "whole number from 0 to 18446744073709551615"},
      {"seed 18446744073709551616\n", 2, "1844", "whole number"},
      {"sandtable-scenario 1\n", 2, "sandtable", "only once"},
      // Terrain edit lines.
      {"crater size=small\n", 2, "crater", "crater has no at=; add at=LON,LAT"},
      {"crater at=1,2\n", 2, "crater", "crater has no size=; add size=small|medium|large, or radius=M depth=M"},
      {"crater at=1,2 size=huge\n", 2, "huge", "size=huge must be small (radius, depth: 1 m, 0.5 m), medium (3 m, 1.2 m)"},
      {"crater at=1,2 size=small depth=3\n", 2, "depth", "give size= or radius= and depth=, not both"},
      {"crater at=1,2 size=small size=large\n", 2, "size", "size= is given twice", 2},
      {"crater at=1,2 radius=3\n", 2, "radius", "radius= needs depth="},
      {"crater at=1,2 depth=3\n", 2, "depth", "depth= needs radius="},
      {"crater at=1,2 radius=0.1 depth=1\n", 2, "0.1", "radius=0.1 is out of bounds; give a value from 0.5 to 500 metres"},
      {"crater at=1,2 radius=3 depth=0\n", 2, "0", "depth=0 is out of bounds; give a value above 0 and at most 100 metres"},
      {"crater at=1,2 radius=3 depth=deep\n", 2, "deep", "depth=deep is not a number above 0 and at most 100 metres"},
      {"crater at=1,2 size=small icon=tank\n", 2, "icon", "unknown key \"icon\"; the keys are at, size, radius, depth"},
      {"crater at=1,2 size=small driven\n", 2, "driven", "unexpected word \"driven\"; write key=value"},
      {"crater at=512000,4680000 size=small\n", 2, "512000", "frame projected"},
      {"crater at=1,2,3 size=small\n", 2, "1,2,3", "must be 2 numbers LON,LAT"},
      {"berm line=1,2 width=3 height=2\n", 2, "1,2", "line= has 1 point; berm needs at least 2: LON,LAT;LON,LAT"},
      {"berm line=1,2;3,x width=3 height=2\n", 2, "3,x", "point 2 \"3,x\" of line= must be two numbers LON,LAT"},
      {"berm line=1,2;3,4; width=3 height=2\n", 2, " width", "point 3 \"\" of line= must be two numbers"},
      {"berm line=1,2;1,2 width=3 height=2\n", 2, "1,2", "line= has no length"},
      {"berm line=1,2;3,4 height=2\n", 2, "berm", "berm has no width=; add width=M (the crest's width"},
      {"berm line=1,2;3,4 width=3\n", 2, "berm", "berm has no height=; add height=M"},
      {"berm width=3 height=2\n", 2, "berm", "berm has no line=; add line=LON,LAT;LON,LAT..."},
      {"berm line=1,2;3,4 width=3 height=2 depth=1\n", 2, "depth",
       "unknown key \"depth\"; the keys are line, width, height, slope"},
      {"berm line=1,2;3,4 width=-1 height=2\n", 2, "-1", "width=-1 is out of bounds; give a value from 0 to 1000 metres"},
      {"berm line=1,2;3,4 width=3 height=101\n", 2, "101", "height=101 is out of bounds"},
      {"berm line=1,2;3,4 width=3 height=2 slope=0\n", 2, "0", "slope=0 is out of bounds; give a value above 0 and "
                                                              "at most 100 (rise over run"},
      {"ditch line=1,2;3,4 width=3 height=2\n", 2, "height",
       "unknown key \"height\"; the keys are line, width, depth, slope"},
      {"ditch line=1,2;3,4 depth=2\n", 2, "ditch", "ditch has no width=; add width=M (the floor's width"},
      {"ditch line=1,2;3,4 width=3\n", 2, "ditch", "ditch has no depth="},
      {"ditch line=1,200;3,4 width=3 depth=2\n", 2, "1,200", "point 1: lon 1 lat 200 is not a position in degrees"},
      {"flatten polygon=1,2;3,4 height=5\n", 2, "1,2", "polygon= has 2 points; flatten needs at least 3"},
      {"flatten polygon=0,0;1,1;2,2 height=5\n", 2, "0,0", "polygon= encloses no area"},
      {"flatten polygon=0,0;1,0;0,1\n", 2, "flatten", "flatten has no height=; add height=M (metres above the datum)"},
      {"flatten polygon=0,0;1,0;0,1 height=10000\n", 2, "10000", "give a value from -500 to 9000 metres above the datum"},
      {"flatten polygon=0,0;1,0;0,1 height=5 width=3\n", 2, "width",
       "unknown key \"width\"; the keys are polygon, height, slope"},
      {"crater at=1,2 size=small\nframe projected\n", 3, "frame", "before the first entity, group or terrain edit"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.lines);
    const std::string text = header + c.lines;
    const auto r = parseScenario(text, "bad.scenario");
    ASSERT_FALSE(r.ok());
    const Problem& p = r.problems().front();
    // Where the expected line starts, and the column of the marker in it.
    std::size_t lineStart = 0;
    for (int k = 1; k < c.line; ++k) lineStart = text.find('\n', lineStart) + 1;
    const std::string line = text.substr(lineStart, text.find('\n', lineStart) - lineStart);
    std::size_t column = line.find(c.at);
    for (int k = 1; k < c.occurrence && column != std::string::npos; ++k) column = line.find(c.at, column + 1);
    ASSERT_NE(column, std::string::npos);
    EXPECT_EQ(p.file, "bad.scenario");
    EXPECT_EQ(p.offset, lineStart + column) << p.message;
    const std::string prefix = "line " + std::to_string(c.line) + ", column " + std::to_string(column + 1) + ": ";
    EXPECT_EQ(p.message.rfind(prefix, 0), 0u) << p.message << " (wanted " << prefix << ")";
    EXPECT_NE(p.message.find(c.words), std::string::npos) << p.message;
  }
}

TEST(Scenario, TerrainEditLinesParseFieldByField) {
  const auto r = parseScenario(
      "sandtable-scenario 1\n"
      "crater at=13.30,42.29 size=medium\n"
      "crater at=13.31,42.28 radius=4.5 depth=2     # a bomb\n"
      "entity lead icon=tank at=13.30,42.29\n"
      "berm line=13.30,42.29;13.31,42.29;13.31,42.30 width=2 height=1.5\n"
      "ditch  line=13.32,42.29;13.33,42.29 depth=3 width=0 slope=1\n"
      "flatten polygon=13.30,42.30;13.31,42.30;13.31,42.31;13.30,42.31 height=-12.5 slope=0.25\n"
      "crater at=13.32,42.30 size=small\n"
      "crater at=13.33,42.30 size=large\n",
      "edits.scenario");
  ASSERT_TRUE(r.ok()) << r.error();
  const auto& t = r->terrainEdits;
  ASSERT_EQ(t.size(), 7u);
  EXPECT_EQ(r->entities.size(), 1u);

  EXPECT_EQ(t[0].kind, edit::Kind::crater);
  EXPECT_EQ(t[0].points, (std::vector<std::array<double, 2>>{{13.30, 42.29}}));
  EXPECT_TRUE(t[0].lonLat);
  EXPECT_EQ(t[0].radius, edits::kCraterMedium.radius);
  EXPECT_EQ(t[0].depth, edits::kCraterMedium.depth);
  EXPECT_EQ(t[0].line, 2);
  EXPECT_EQ(t[1].radius, 4.5);
  EXPECT_EQ(t[1].depth, 2);
  EXPECT_EQ(t[1].line, 3);
  EXPECT_EQ(t[5].radius, edits::kCraterSmall.radius);
  EXPECT_EQ(t[5].depth, edits::kCraterSmall.depth);
  EXPECT_EQ(t[6].radius, edits::kCraterLarge.radius);
  EXPECT_EQ(t[6].depth, edits::kCraterLarge.depth);

  EXPECT_EQ(t[2].kind, edit::Kind::berm);
  EXPECT_EQ(t[2].points, (std::vector<std::array<double, 2>>{{13.30, 42.29}, {13.31, 42.29}, {13.31, 42.30}}));
  EXPECT_EQ(t[2].width, 2);
  EXPECT_EQ(t[2].height, 1.5);
  EXPECT_EQ(t[2].sideSlope, kScenarioDefaultSlope);
  EXPECT_EQ(t[2].line, 5);

  EXPECT_EQ(t[3].kind, edit::Kind::ditch);
  EXPECT_EQ(t[3].points.size(), 2u);
  EXPECT_EQ(t[3].width, 0);
  EXPECT_EQ(t[3].height, 3);  // a ditch's depth= is the edit's height
  EXPECT_EQ(t[3].sideSlope, 1);

  EXPECT_EQ(t[4].kind, edit::Kind::flatten);
  EXPECT_EQ(t[4].points.size(), 4u);
  EXPECT_EQ(t[4].points[2], (std::array<double, 2>{13.31, 42.31}));
  EXPECT_EQ(t[4].height, -12.5);
  EXPECT_EQ(t[4].sideSlope, 0.25);

  // Projected: easting,northing kept as written, beyond lon/lat's range.
  const auto p = parseScenario(
      "sandtable-scenario 1\nframe projected\n"
      "crater at=683500.5,5540000 radius=10 depth=3\n"
      "berm line=683000,5539000;684000,5539500 width=4 height=2 slope=0.3\n",
      "p.scenario");
  ASSERT_TRUE(p.ok()) << p.error();
  EXPECT_FALSE(p->terrainEdits[0].lonLat);
  EXPECT_EQ(p->terrainEdits[0].points[0], (std::array<double, 2>{683500.5, 5540000}));
  EXPECT_EQ(p->terrainEdits[1].points[1], (std::array<double, 2>{684000, 5539500}));
}

TEST(Scenario, TerrainEditCapsAreRefusedAtTheirLine) {
  // 4,096 points in one line= are read; 4,097 are refused, counted before
  // any is stored.
  auto berm = [](std::size_t n) {
    std::string v = "sandtable-scenario 1\nframe projected\nberm width=1 height=1 line=";
    for (std::size_t k = 0; k < n; ++k) {
      // Piece by piece: GCC 12 warns (-Wrestrict, a false positive) on
      // `"..." + std::string` here.
      if (k) v += ';';
      v += std::to_string(k);
      v += ",0";
    }
    return v + "\n";
  };
  const auto atCap = parseScenario(berm(kMaxScenarioEditPoints), "b.scenario");
  ASSERT_TRUE(atCap.ok()) << atCap.error();
  EXPECT_EQ(atCap->terrainEdits[0].points.size(), 4096u);
  EXPECT_EQ(atCap->terrainEdits[0].points.back(), (std::array<double, 2>{4095, 0}));
  const auto over = parseScenario(berm(kMaxScenarioEditPoints + 1), "b.scenario");
  ASSERT_FALSE(over.ok());
  EXPECT_NE(over.error().find("line 3, column 28: line= has 4097 points, more than the 4096 a line may hold"),
            std::string::npos)
      << over.error();
  // A million separators are refused the same way.
  const auto huge = parseScenario("sandtable-scenario 1\nditch width=1 depth=1 line=" + std::string(1000000, ';') + "\n",
                                  "h.scenario");
  ASSERT_FALSE(huge.ok());
  EXPECT_NE(huge.error().find("line= has 1000001 points"), std::string::npos) << huge.error();

  // 100,000 edit lines are read; the 100,001st is refused at its line.
  std::string many = "sandtable-scenario 1\nframe projected\n";
  for (std::size_t k = 0; k < kMaxScenarioEdits; ++k) many += "crater at=0,0 size=small\n";
  const auto full = parseScenario(many, "m.scenario");
  ASSERT_TRUE(full.ok()) << full.error();
  EXPECT_EQ(full->terrainEdits.size(), kMaxScenarioEdits);
  many += "berm line=0,0;1,1 width=1 height=1\n";
  const auto past = parseScenario(many, "m.scenario");
  ASSERT_FALSE(past.ok());
  EXPECT_EQ(past.problems().size(), 1u);
  EXPECT_NE(past.error().find("line 100003, column 1: this line is terrain edit 100001, more than the 100000"),
            std::string::npos)
      << past.error();
}

TEST(Scenario, HeaderErrorsStopTheReading) {
  const auto notScenario = parseScenario("entity a icon=tank at=1,2\n", "x.txt");
  ASSERT_FALSE(notScenario.ok());
  EXPECT_EQ(notScenario.problems().size(), 1u);
  EXPECT_EQ(notScenario.problems()[0].message.rfind("line 1, column 1: this is not a scenario file", 0), 0u);
  const auto v2 = parseScenario("  sandtable-scenario 2\n", "x.scenario");
  ASSERT_FALSE(v2.ok());
  EXPECT_EQ(v2.problems()[0].offset, 21u);
  EXPECT_EQ(v2.problems()[0].message.rfind("line 1, column 22: this reader knows scenario version 1 only", 0), 0u);
  const auto empty = parseScenario("# nothing\n", "x.scenario");
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().find("the file is empty"), std::string::npos);
  // Several bad lines: each is reported.
  const auto many = parseScenario("sandtable-scenario 1\nentity a at=1,2\nentity b icon=t at=1,2 x=1\nbogus\n", "m.scenario");
  ASSERT_FALSE(many.ok());
  EXPECT_EQ(many.problems().size(), 3u);
}

TEST(Scenario, ReadsFilesAndResolvesAgainstTheirDirectory) {
  const auto dir = std::filesystem::temp_directory_path() / "sandtable_test_scenario";
  std::filesystem::create_directories(dir / "sub");
  const auto file = (dir / "sub" / "a.scenario").string();
  {
    std::ofstream out(file, std::ios::binary);
    out << "sandtable-scenario 1\nentity s icon=tank script=../runs/s.script script-entity=4\n";
  }
  const auto r = readScenarioFile(file);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r->entities[0].script, (dir / "runs" / "s.script").string());
  const auto missing = readScenarioFile((dir / "none.scenario").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().find("cannot open the scenario file"), std::string::npos);
  std::filesystem::remove_all(dir);
}

#ifdef SANDTABLE_SOURCE_DIR
TEST(Scenario, ScriptOfTheSampleIsFoundThroughTheScenario) {
  const std::string name = std::string(SANDTABLE_SOURCE_DIR) + "/samples/inline.scenario";
  const auto r = parseScenario("sandtable-scenario 1\nentity s59 icon=tank script=demo.script script-entity=59\n", name);
  ASSERT_TRUE(r.ok()) << r.error();
  const auto script = readScriptFile(r->entities[0].script);
  ASSERT_TRUE(script.ok()) << script.error();
  bool found = false;
  for (const auto& e : scriptEntities(script.value())) found = found || e.entity == *r->entities[0].scriptEntity;
  EXPECT_TRUE(found);
}
#endif

TEST(Scenario, GroupsArePlacedBySeedWithinTheirRanges) {
  const auto r = parseScenario(
      "sandtable-scenario 1\nframe projected\n"
      "group 4000 name=herd icon=tank area=1000,2000,3000,2500 speed=10..30 heading=90..180 behaviour=zigzag\n"
      "group 10 icon=jet domain=air area=0,0,10,10 altitude=500..900\n",
      "g.scenario");
  ASSERT_TRUE(r.ok()) << r.error();
  const GroupSpec& g = r->groups[0];
  const auto members = expandGroup(g, 42);
  ASSERT_EQ(members.size(), 4000u);
  double sumA = 0, sumB = 0, sumH = 0;
  std::set<std::pair<double, double>> places;
  for (const auto& m : members) {
    ASSERT_TRUE(m.a && m.b);
    EXPECT_GE(*m.a, 1000);
    EXPECT_LE(*m.a, 3000);
    EXPECT_GE(*m.b, 2000);
    EXPECT_LE(*m.b, 2500);
    EXPECT_GE(m.speedMs, 10 / 3.6 - 1e-12);
    EXPECT_LE(m.speedMs, 30 / 3.6 + 1e-12);
    EXPECT_GE(m.headingDeg, 90);
    EXPECT_LE(m.headingDeg, 180);
    EXPECT_EQ(m.icon, "tank");
    EXPECT_FALSE(m.lonLat);
    EXPECT_EQ(m.behaviour, (ScenarioBehaviour{true, false, false, false}));
    sumA += *m.a;
    sumB += *m.b;
    sumH += m.headingDeg;
    places.insert({*m.a, *m.b});
  }
  EXPECT_EQ(places.size(), 4000u);  // no two in one place
  // Uniform: means at the centres (standard error of the mean: 577/sqrt(4000) = 9 m).
  EXPECT_NEAR(sumA / 4000, 2000, 40);
  EXPECT_NEAR(sumB / 4000, 2250, 10);
  EXPECT_NEAR(sumH / 4000, 135, 2);
  EXPECT_EQ(members[0].name, "herd.1");
  EXPECT_EQ(members[3999].name, "herd.4000");
  // Deterministic in the seed; another seed places them elsewhere.
  const auto again = expandGroup(g, 42);
  const auto other = expandGroup(g, 43);
  EXPECT_EQ(*again[17].a, *members[17].a);
  EXPECT_EQ(again[17].headingDeg, members[17].headingDeg);
  EXPECT_NE(*other[17].a, *members[17].a);
  EXPECT_EQ(groupMember(g, 18, 42).speedMs, members[17].speedMs);
  // Altitude ranges are drawn too.
  for (const auto& m : expandGroup(r->groups[1], 7)) {
    ASSERT_TRUE(m.altitude.has_value());
    EXPECT_GE(*m.altitude, 500);
    EXPECT_LE(*m.altitude, 900);
    EXPECT_EQ(m.name.rfind("group2.", 0), 0u);
  }
}

TEST(Scenario, EntityCountsPastTheCapAreRefusedAtTheirLine) {
  // 1,000 groups of 100,000 asked for 10^8 entities; the reader stops at the
  // line that passes 100,000 in all, with nothing expanded.
  std::string text = "sandtable-scenario 1\nframe projected\n";
  text += "entity a icon=tank at=0,0\n";
  for (int k = 0; k < 1000; ++k) {
    text += "group 100000 name=g" + std::to_string(k) + " icon=tank area=0,0,10,10\n";
  }
  const auto r = parseScenario(text, "big.scenario");
  ASSERT_FALSE(r.ok());
  // Line 4 is the first group: 1 + 100,000 entities. Line 3 is within the cap.
  EXPECT_NE(r.problems().front().message.find("line 4, column 7"), std::string::npos) << r.error();
  EXPECT_NE(r.problems().front().message.find("100001 entities, more than the 100000"), std::string::npos)
      << r.error();

  // Exactly at the cap is allowed: 99,999 in a group and one entity.
  const auto atCap = parseScenario(
      "sandtable-scenario 1\nframe projected\nentity a icon=tank at=0,0\ngroup 99999 icon=tank area=0,0,10,10\n",
      "cap.scenario");
  ASSERT_TRUE(atCap.ok()) << atCap.error();
  EXPECT_EQ(atCap->groups[0].count, 99999);
}

// makeTerrainEdits (scenario_load.h): the lines become edits in the database
// frame, placed as entities are (X = easting - origin, Z = origin - northing).
TEST(Scenario, TerrainEditsBecomeEditsInTheDatabaseFrame) {
  // 201 x 101 posts 10 m apart: X 0 .. 2000, Z 0 .. 1000.
  const grid::PostLayout layout{201, 101, 10.0, 500000.0, 4000000.0};
  const auto p = parseScenario(
      "sandtable-scenario 1\nframe projected\n"
      "crater at=500100,3999900 size=small\n"
      "berm line=499990,4000000;501000,3999500 width=2 height=1.5\n"  // crosses the west edge: kept
      "ditch line=500200,3999200;500300,3999200 width=1 depth=3 slope=1\n"
      "flatten polygon=500500,3999500;500600,3999500;500600,3999400 height=42\n",
      "p.scenario");
  ASSERT_TRUE(p.ok()) << p.error();
  const auto r = makeTerrainEdits(p.value(), nullptr, layout);
  ASSERT_TRUE(r.ok()) << r.error();
  const auto& e = r.value();
  ASSERT_EQ(e.size(), 4u);
  for (std::size_t k = 0; k < e.size(); ++k) {
    EXPECT_EQ(e[k].id, k + 1);
    EXPECT_EQ(e[k].origin, 0u);
    EXPECT_EQ(e[k].time, 0);
    EXPECT_EQ(edit::checkEdit(e[k]), "");
  }
  EXPECT_EQ(e[0].kind, edit::Kind::crater);
  EXPECT_EQ(e[0].points, (std::vector<std::array<double, 2>>{{100, 100}}));
  EXPECT_EQ(e[0].radius, edits::kCraterSmall.radius);
  EXPECT_EQ(e[0].depth, edits::kCraterSmall.depth);
  EXPECT_EQ(e[1].kind, edit::Kind::berm);
  EXPECT_EQ(e[1].points, (std::vector<std::array<double, 2>>{{-10, 0}, {1000, 500}}));
  EXPECT_EQ(e[1].width, 2);
  EXPECT_EQ(e[1].height, 1.5);
  EXPECT_EQ(e[1].sideSlope, kScenarioDefaultSlope);
  EXPECT_EQ(e[2].kind, edit::Kind::ditch);
  EXPECT_EQ(e[2].points, (std::vector<std::array<double, 2>>{{200, 800}, {300, 800}}));
  EXPECT_EQ(e[2].height, 3);  // the depth
  EXPECT_EQ(e[2].sideSlope, 1);
  EXPECT_EQ(e[3].kind, edit::Kind::flatten);
  EXPECT_EQ(e[3].points, (std::vector<std::array<double, 2>>{{500, 500}, {600, 500}, {600, 600}}));
  EXPECT_EQ(e[3].height, 42);

  // Lon/lat through the caller's transformer, as entities' at= is.
  const auto ll = parseScenario("sandtable-scenario 1\ncrater at=13.001,41.999 radius=4 depth=2\n", "ll.scenario");
  ASSERT_TRUE(ll.ok()) << ll.error();
  const world::ToProjectedFn toy = [](double lon, double lat, double& east, double& north) -> std::string {
    east = 500000 + (lon - 13) * 100000;
    north = 4000000 + (lat - 42) * 100000;
    return {};
  };
  const auto placed = makeTerrainEdits(ll.value(), toy, layout);
  ASSERT_TRUE(placed.ok()) << placed.error();
  EXPECT_NEAR(placed.value()[0].points[0][0], 100, 1e-6);
  EXPECT_NEAR(placed.value()[0].points[0][1], 100, 1e-6);
  EXPECT_EQ(placed.value()[0].radius, 4);

  // Problems name the file, the line and the kind.
  const auto noCrs = makeTerrainEdits(ll.value(), nullptr, layout);
  ASSERT_FALSE(noCrs.ok());
  EXPECT_EQ(noCrs.problems()[0].file, "ll.scenario");
  EXPECT_EQ(noCrs.problems()[0].message, "scenario: line 2: crater: lon/lat positions need the database's CRS");
  const world::ToProjectedFn refuses = [](double, double, double&, double&) -> std::string { return "off the map"; };
  const auto refused = makeTerrainEdits(ll.value(), refuses, layout);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.problems()[0].message, "scenario: line 2: crater: off the map");
  const auto far = parseScenario(
      "sandtable-scenario 1\nframe projected\ncrater at=500100,3999900 size=small\n"
      "ditch line=510000,3999000;511000,3999000 width=1 depth=3\n",
      "far.scenario");
  ASSERT_TRUE(far.ok()) << far.error();
  const auto outside = makeTerrainEdits(far.value(), nullptr, layout);
  ASSERT_FALSE(outside.ok());
  ASSERT_EQ(outside.problems().size(), 1u);
  EXPECT_EQ(outside.problems()[0].message.rfind("scenario: line 4: ditch: lies wholly outside the database: it "
                                                "reaches X 9993.5 .. 11006.5, Z 993.5 .. 1006.5 m",
                                                0),
            0u)
      << outside.problems()[0].message;
}

}  // namespace
}  // namespace sandtable::sim
