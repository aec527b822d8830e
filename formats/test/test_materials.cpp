// Material table text: the default sample, round trip, a table of malformed
// lines with their exact messages and offsets, and classification.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "sandtable/formats/materials.h"

namespace sandtable::materials {
namespace {

namespace fs = std::filesystem;

std::span<const std::byte> asBytes(const std::string& s) { return std::as_bytes(std::span(s.data(), s.size())); }

Result<Table> parseText(const std::string& s) { return parse(asBytes(s), "t.txt"); }

const std::string kSample = std::string(SANDTABLE_SOURCE_DIR) + "/samples/materials.txt";

/// Attributes of a test feature.
using Attrs = std::map<std::string, std::string>;
std::optional<std::string> attrOf(const void* f, const std::string& key) {
  const auto& m = *static_cast<const Attrs*>(f);
  const auto it = m.find(key);
  if (it == m.end()) return std::nullopt;
  return it->second;
}

std::string nameOf(const Table& t, const Match& m) {
  if (m.classId == kNoClass) return "-";
  const Class* c = t.find(m.classId);
  return c ? c->name : "?";
}

TEST(Materials, sampleParsesAndCoversTheSeedClasses) {
  auto t = readFile(kSample);
  ASSERT_TRUE(t) << t.error();
  const Table& m = t.value();
  for (const char* name : {"grass", "soil", "farmland", "meadow", "scrub", "wetland", "sand", "rock", "residential",
                           "industrial", "forest", "water", "motorway", "trunk", "primary", "secondary", "tertiary",
                           "street", "service", "track", "path", "river", "stream", "canal", "ditch", "railway"}) {
    EXPECT_NE(m.findByName(name), nullptr) << name;
  }
  EXPECT_EQ(m.find(m.defaultArea)->name, "grass");
  EXPECT_EQ(m.defaultLine, kNoClass);
  for (const Class& c : m.classes) {
    EXPECT_LT(c.id, 256) << c.name;
    if (c.kind == Kind::area) {
      EXPECT_EQ(c.priority, 1) << c.name;
    }
  }
  EXPECT_GT(m.findByName("water")->rank, m.findByName("forest")->rank);  // lakes win over forest
  EXPECT_EQ(m.findByName("motorway")->width, 25.0);
  EXPECT_EQ(m.findByName("motorway")->priority, 10);
  EXPECT_LT(m.findByName("river")->priority, m.findByName("street")->priority);  // bridges show the road
  EXPECT_LT(m.findByName("path")->width, m.findByName("track")->width);
  // Soil (seed VII.B.2.b): sand and wetland hold a vehicle back more than a road does.
  EXPECT_GT(m.findByName("sand")->resist, m.findByName("primary")->resist);
  EXPECT_LT(m.findByName("wetland")->stickDeg, m.findByName("rock")->stickDeg);
  for (const char* wet : {"water", "river", "canal", "stream", "ditch"}) EXPECT_TRUE(m.findByName(wet)->water) << wet;
  EXPECT_FALSE(m.findByName("grass")->water);
}

TEST(Materials, soilFieldsDefaultParseAndRefuseBadValues) {
  const std::string head = "sandtable-materials 1\n";
  const std::string cls = "class 0 g kind=area priority=1 upper=000000 lower=000000 material=0 texture=0";
  auto plain = parseText(head + cls + "\ndefault-area g\ndefault-line none\n");
  ASSERT_TRUE(plain) << plain.error();
  EXPECT_EQ(plain->classes[0].stickDeg, kDefaultStickDeg);
  EXPECT_EQ(plain->classes[0].resist, kDefaultResist);
  EXPECT_FALSE(plain->classes[0].water);
  auto soil = parseText(head + cls + " stick=12.5 resist=0.3 water=yes\ndefault-area g\ndefault-line none\n");
  ASSERT_TRUE(soil) << soil.error();
  EXPECT_EQ(soil->classes[0].stickDeg, 12.5);
  EXPECT_EQ(soil->classes[0].resist, 0.3);
  EXPECT_TRUE(soil->classes[0].water);
  auto again = parseText(format(soil.value()));
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(again.value(), soil.value());
  for (const char* bad : {" stick=91", " stick=x", " resist=-1", " resist=nan", " water=maybe"}) {
    auto r = parseText(head + cls + bad + "\ndefault-area g\ndefault-line none\n");
    ASSERT_FALSE(r) << bad;
    EXPECT_EQ(r.problems().front().offset, head.size()) << bad;
  }
}

TEST(Materials, formatRoundTripsTheSample) {
  auto t = readFile(kSample);
  ASSERT_TRUE(t) << t.error();
  const std::string text = format(t.value());
  auto again = parseText(text);
  ASSERT_TRUE(again) << again.error() << "\n" << text;
  EXPECT_EQ(again.value(), t.value());
  EXPECT_EQ(format(again.value()), text);
  EXPECT_NE(text.find("class 12 water kind=area priority=1 rank=90 upper=3A6EA5 lower=33639A material=14 texture=43 stick=0 resist=1 "
                      "water=yes\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("class 49 track kind=line priority=10 upper=9E8460 lower=9E8460 material=9 texture=102 width=3.5 stick=26 "
                      "resist=0.07\n"),
            std::string::npos);
  EXPECT_NE(text.find("rule highway=motorway motorway width-field=width\n"), std::string::npos);
  EXPECT_NE(text.find("default-line none\n"), std::string::npos);
}

TEST(Materials, acceptsCommentsBlankLinesAndCrLf) {
  const std::string text =
      "# c\r\n\r\n  sandtable-materials 1   # header\r\n"
      "class 3 a kind=area priority=1 upper=010203 lower=0a0B0c material=1 texture=2 # trailing\r\n"
      "class 4 b kind=line priority=7 upper=FFFFFF lower=000000 material=1 texture=2 width=2.25\r\n"
      "\trule\thighway=*\tb\r\n"
      "default-area a\r\ndefault-line b";
  auto t = parseText(text);
  ASSERT_TRUE(t) << t.error();
  ASSERT_EQ(t->classes.size(), 2u);
  EXPECT_EQ(t->classes[0].lowerRgb, 0x0A0B0Cu);
  EXPECT_EQ(t->classes[0].rank, 0);
  EXPECT_EQ(t->classes[1].width, 2.25);
  EXPECT_EQ(t->rules.size(), 1u);
  EXPECT_EQ(t->defaultArea, 3);
  EXPECT_EQ(t->defaultLine, 4);
}

struct Bad {
  std::string line;     ///< inserted as line 4
  std::string message;  ///< expected first problem
};

TEST(Materials, malformedLinesNameTheirOffsetAndTheFix) {
  const std::string head =
      "sandtable-materials 1\n"
      "class 0 grass kind=area priority=1 upper=000000 lower=000000 material=0 texture=0\n"
      "class 1 road kind=line priority=10 upper=000000 lower=000000 material=0 texture=0 width=5\n";
  const std::string tail = "default-area grass\ndefault-line road\n";
  const std::string c = "class 2 x kind=area priority=1 upper=000000 lower=000000 material=0 texture=0";
  const std::vector<Bad> cases = {
      {"class 0 dirt kind=area priority=1 upper=000000 lower=000000 material=0 texture=0",
       "class id 0 is already used by \"grass\" (line 2); give every class its own id"},
      {"class 2 grass kind=area priority=1 upper=000000 lower=000000 material=0 texture=0",
       "class name \"grass\" is already used (line 2); give every class its own name"},
      {"class 2 x kind=area priority=1 upper=12345 lower=000000 material=0 texture=0",
       "upper must be a colour of 6 hex digits RRGGBB, not \"12345\""},
      {"class 2 x kind=area priority=1 upper=000000 lower=00GG00 material=0 texture=0",
       "lower must be a colour of 6 hex digits RRGGBB, not \"00GG00\""},
      {"class 2 x kind=area priority=0 upper=000000 lower=000000 material=0 texture=0",
       "priority must be 1..99 (1 skin, 2-10 decals, roads 10, 99 objects), not \"0\""},
      {"class 2 x kind=area priority=100 upper=000000 lower=000000 material=0 texture=0",
       "priority must be 1..99 (1 skin, 2-10 decals, roads 10, 99 objects), not \"100\""},
      {"class 2 x kind=area priority=5 upper=000000 lower=000000 material=0 texture=0",
       "area class \"x\" must have priority=1: area classes are the skin; decals are line classes"},
      {"class 2 x kind=line priority=1 upper=000000 lower=000000 material=0 texture=0 width=3",
       "line class \"x\" is a decal: its priority must be 2..98, not 1"},
      {"class 2 x kind=line priority=10 upper=000000 lower=000000 material=0 texture=0",
       "line class \"x\" needs width=W (metres)"},
      {"class 2 x kind=line priority=10 upper=000000 lower=000000 material=0 texture=0 width=-2",
       "width must be metres in (0, 1000], not \"-2\""},
      {c + " width=3", "width= applies only to line classes"},
      {"class 2 x kind=line priority=10 rank=3 upper=000000 lower=000000 material=0 texture=0 width=3",
       "rank= applies only to area classes"},
      {c + " colour=red", "unknown class field \"colour\" (known: kind, priority, rank, upper, lower, material, texture, width, extrude, storey, stick, resist, water)"},
      {c + " kind=area", "class field \"kind\" is given twice"},
      {c + " width", "\"width\" is not KEY=VALUE"},
      {"class 2 x kind=area priority=1 upper=000000 lower=000000 texture=0", "class \"x\" is missing material="},
      {"class 2 x kind=lake priority=1 upper=000000 lower=000000 material=0 texture=0",
       "kind must be area or line, not \"lake\""},
      {"class 70000 x kind=area priority=1 upper=000000 lower=000000 material=0 texture=0",
       "class id \"70000\" is not a whole number 0..65534"},
      {"class 2 x kind=area priority=1 upper=000000 lower=000000 material=65536 texture=0",
       "material must be 0..65535, not \"65536\""},
      {"class 2 a/b kind=area priority=1 upper=000000 lower=000000 material=0 texture=0",
       "class name \"a/b\" may hold only letters, digits, '_', '-' and '.' (and may not be \"-\" or \"none\")"},
      {"class 2", "class needs an id and a name: class ID NAME kind=area|line priority=P [rank=R] "
                  "upper=RRGGBB lower=RRGGBB material=M texture=T [width=W]"},
      {"rule highway=motorway motorway", "rule names class \"motorway\", which no class line defines"},
      {"rule highway motorway", "\"highway\" is not KEY=VALUE (VALUE * matches any non-empty value)"},
      {"rule highway= road", "\"highway=\" is not KEY=VALUE (VALUE * matches any non-empty value)"},
      {"rule highway=primary", "rule needs KEY=VALUE and a class name: rule KEY=VALUE CLASS [width-field=FIELD]"},
      {"rule highway=primary road width=w", "unknown rule option \"width=w\" (known: width-field=FIELD)"},
      {"rule landuse=grass grass width-field=width",
       "width-field= applies only to line classes; \"grass\" is an area class"},
      {"colour grass 00FF00", "unknown directive \"colour\" (known: class, rule, default-area, default-line, scatter, place)"},
      {"sandtable-materials 1", "the header \"sandtable-materials 1\" may appear only once"},
      {"default-area road road", "default-area needs exactly one class name"},
      {"default-area grass", "default-area is given twice (first on line 4)"},
      {std::string("class 2 x\x01 kind=area"), "control character 0x01 at column 10; the table is plain text"},
  };
  for (const Bad& b : cases) {
    const std::string text = head + b.line + "\n" + tail;
    auto t = parseText(text);
    ASSERT_FALSE(t) << b.line;
    const Problem& p = t.problems().front();
    EXPECT_EQ(p.file, "t.txt");
    // "default-area given twice" points at the second one (line 5).
    const bool second = b.message.find("given twice (first on line 4)") != std::string::npos;
    EXPECT_EQ(p.offset, second ? head.size() + b.line.size() + 1 : head.size()) << b.line;
    EXPECT_EQ(p.message, "materials: line " + std::string(second ? "5" : "4") + ": " + b.message) << b.line;
  }
}

TEST(Materials, malformedTablesAsAWhole) {
  struct Whole {
    std::string text;
    std::uint64_t offset;
    std::string message;
  };
  const std::string grass = "class 0 grass kind=area priority=1 upper=000000 lower=000000 material=0 texture=0\n";
  const std::string road = "class 1 road kind=line priority=10 upper=000000 lower=000000 material=0 texture=0 width=5\n";
  const std::vector<Whole> cases = {
      {"", 0, "materials: the table is empty; its first line that is not a comment must be \"sandtable-materials 1\""},
      {"# nothing\n\n", 11,
       "materials: the table is empty; its first line that is not a comment must be \"sandtable-materials 1\""},
      {"# c\n" + grass, 4,
       "materials: line 2: missing header; the first line that is not a comment must be \"sandtable-materials 1\""},
      {"sandtable-materials 2\n" + grass, 0,
       "materials: line 1: version 2 is newer than this reader knows (1); use a newer sandtable"},
      {"sandtable-materials 1\n" + grass + road + "default-line road\n", 22 + grass.size() + road.size() + 18,
       "materials: default-area is missing; add \"default-area NAME\" naming an area class"},
      {"sandtable-materials 1\n" + grass + "default-area grass\n", 22 + grass.size() + 19,
       "materials: default-line is missing; add \"default-line NAME\" naming a line class, or \"default-line none\""},
      {"sandtable-materials 1\n" + grass + road + "default-area road\ndefault-line none\n", 22 + grass.size() + road.size(),
       "materials: line 4: default-area must name an area class; \"road\" is a line class"},
      {"sandtable-materials 1\n" + grass + road + "default-area grass\ndefault-line grass\n",
       22 + grass.size() + road.size() + 19,
       "materials: line 5: default-line must name a line class (or none); \"grass\" is an area class"},
      {"sandtable-materials 1\n" + grass + "default-area sand\ndefault-line none\n", 22 + grass.size(),
       "materials: line 3: default-area names class \"sand\", which no class line defines"},
  };
  for (const Whole& w : cases) {
    auto t = parseText(w.text);
    ASSERT_FALSE(t) << w.text;
    EXPECT_EQ(t.problems().front().offset, w.offset) << w.text;
    EXPECT_EQ(t.problems().front().message, w.message) << w.text;
  }
  // Every problem is reported, not only the first.
  auto t = parseText("sandtable-materials 1\n" + grass + "class 0 x kind=area\nrule a=b nothing\ndefault-area grass\n");
  ASSERT_FALSE(t);
  EXPECT_EQ(t.problems().size(), 3u);  // duplicate id, unknown class in the rule, no default-line
}

TEST(Materials, everyTruncatedPrefixOfTheSampleFailsCleanlyOrParses) {
  auto t = readFile(kSample);
  ASSERT_TRUE(t);
  const std::string text = format(t.value());
  for (std::size_t n = 0; n < text.size(); n += 7) {
    auto r = parseText(text.substr(0, n));
    if (!r) {
      EXPECT_EQ(r.problems().front().message.rfind("materials: ", 0), 0u);
    }
  }
}

TEST(Materials, readFileRefusesMissingAndHugeFiles) {
  auto missing = readFile("/nonexistent/materials.txt");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.problems().front().file, "/nonexistent/materials.txt");
  EXPECT_EQ(missing.problems().front().message.rfind("materials: cannot open", 0), 0u);
  const fs::path big = fs::temp_directory_path() / ("sandtable_materials_big_" + std::to_string(::getpid()));
  {
    std::ofstream out(big);
    out << "sandtable-materials 1\n" << std::string(kMaxFileBytes, '#');
  }
  auto huge = readFile(big.string());
  fs::remove(big);
  ASSERT_FALSE(huge);
  EXPECT_NE(huge.problems().front().message.find("more than the 4194304 allowed"), std::string::npos);
}

TEST(Materials, classifiesOsmAttributes) {
  auto t = readFile(kSample);
  ASSERT_TRUE(t);
  const Table& m = t.value();
  struct Case {
    std::string layer;
    Attrs attrs;
    bool line;
    std::string cls;
    double width;
    bool matched;
  };
  const std::vector<Case> cases = {
      {"lines", {{"highway", "motorway"}}, true, "motorway", 25, true},
      {"lines", {{"highway", "motorway"}, {"width", "31.5"}}, true, "motorway", 31.5, true},
      {"lines", {{"highway", "primary"}, {"width", "7 m"}}, true, "primary", 7, true},
      {"lines", {{"highway", "primary"}, {"width", "wide"}}, true, "primary", 9, true},
      {"lines", {{"highway", "Residential"}}, true, "street", 6, true},  // values ignore case
      {"lines", {{"highway", "track"}}, true, "track", 3.5, true},
      {"lines", {{"highway", "footway"}}, true, "path", 2, true},
      {"lines", {{"highway", "primary"}, {"tunnel", "yes"}}, true, "-", 0, true},
      {"lines", {{"waterway", "river"}}, true, "river", 20, true},
      {"lines", {{"waterway", "stream"}, {"tunnel", "culvert"}}, true, "-", 0, true},
      {"lines", {{"waterway", "ditch"}}, true, "ditch", 2, true},
      {"lines", {{"railway", "rail"}}, true, "railway", 5, true},
      {"lines", {{"power", "line"}}, true, "-", 0, false},  // default-line none
      {"multipolygons", {{"natural", "water"}}, false, "water", 0, true},
      {"multipolygons", {{"landuse", "forest"}}, false, "forest", 0, true},
      {"multipolygons", {{"natural", "wood"}, {"leisure", "park"}}, false, "forest", 0, true},
      {"multipolygons", {{"building", "yes"}, {"landuse", "residential"}}, false, "building", 0, true},
      {"multipolygons", {{"landuse", "farmland"}}, false, "farmland", 0, true},
      {"multipolygons", {{"natural", "beach"}}, false, "sand", 0, true},
      {"multipolygons", {{"highway", "pedestrian"}}, false, "grass", 0, false},  // line rules skip polygons
      {"multipolygons", {{"amenity", "parking"}}, false, "grass", 0, false},
      {"roads", {{"type", "motorway"}, {"width", "25"}}, true, "motorway", 25, true},  // sandtable synth
      {"roads", {{"type", "secondary"}, {"width", "7.7"}}, true, "secondary", 7.7, true},
      {"rivers", {{"name", "R1"}, {"width", "14.2"}}, true, "river", 14.2, true},
      {"lakes", {{"level", "120"}}, false, "water", 0, true},
      {"forest", {}, false, "forest", 0, true},
      {"BayArea", {{"Height", "12.5"}}, false, "building", 0, true},
      {"x", {{"TYPE", "WOOD"}}, false, "forest", 0, true},  // a shapefile's TYPE (lookup is the caller's: here exact)
  };
  for (const Case& c : cases) {
    // Shapefile-style keys: the callback sees the rule's key; emulate a
    // case-insensitive field lookup for "TYPE".
    Attrs a = c.attrs;
    if (a.count("TYPE")) a["type"] = a["TYPE"];
    if (a.count("Height")) a["height"] = a["Height"];
    const Match r = classify(m, c.layer, &a, &attrOf, c.line);
    EXPECT_EQ(nameOf(m, r), c.cls) << c.layer;
    EXPECT_EQ(r.matched, c.matched) << c.layer << " " << c.cls;
    EXPECT_DOUBLE_EQ(r.width, c.width) << c.layer << " " << c.cls;
  }
}

TEST(Materials, unknownFeaturesFallBackToTheDefaults) {
  auto t = parseText(
      "sandtable-materials 1\n"
      "class 0 grass kind=area priority=1 upper=000000 lower=000000 material=0 texture=0\n"
      "class 5 road kind=line priority=10 upper=000000 lower=000000 material=0 texture=0 width=5\n"
      "rule layer=roads road width-field=w\n"
      "default-area grass\ndefault-line road\n");
  ASSERT_TRUE(t) << t.error();
  Attrs none;
  Match m = classify(t.value(), "other", &none, &attrOf, true);
  EXPECT_EQ(m.classId, 5);
  EXPECT_FALSE(m.matched);
  EXPECT_EQ(m.width, 5);
  m = classify(t.value(), "other", &none, &attrOf, false);
  EXPECT_EQ(m.classId, 0);
  EXPECT_FALSE(m.matched);
  Attrs w{{"w", "12"}};
  m = classify(t.value(), "roads", &w, &attrOf, true);
  EXPECT_TRUE(m.matched);
  EXPECT_EQ(m.width, 12);
  // The layer rule is for lines: a polygon in layer "roads" is unknown.
  m = classify(t.value(), "roads", &w, &attrOf, false);
  EXPECT_FALSE(m.matched);
  EXPECT_EQ(m.classId, 0);
}

}  // namespace
}  // namespace sandtable::materials
