// The icon definition file: every directive parsed into its field, and
// every bad line refused with its byte offset and what to write instead.
#include <gtest/gtest.h>

#include <string>

#include "sandtable/icons/definitions.h"

using namespace sandtable;
using namespace sandtable::icons;

namespace {

Result<Definitions> parse(const std::string& text) {
  return parseDefinitions(std::as_bytes(std::span(text.data(), text.size())), "defs.txt", "/models");
}

const char* kFull =
    "sandtable-icons 1\n"
    "# a tank with a turret and a gun\n"
    "icon m1-tank\n"
    "  model hull.glb\n"
    "  dead hull-burnt.glb\n"
    "  component turret turret.glb offset=0,1.5,-0.25\n"
    "  component gun gun.glb offset=0,0.3,1.2 parent=turret\n"
    "  component turret turret-burnt.glb offset=0,1.4,0 state=dead\n"
    "  up z\n"
    "  unit 0.01\n"
    "  scale 1.5\n"
    "  max-triangles 20000\n"
    "  capabilities armed resupply\n"
    "  bounds -2 0 -4 2 2.5 4\n"
    "  cylinder 4.5 2.5\n"
    "  lod 1 150\n"
    "  lod 0.4\n"
    "  lod 0.1 2000\n"
    "  dis 1.1.225.1.1.3.0\n"
    "  dis 1.1.*.1   # any country's tank\n"
    "  dis 1.2.225.*.*.*.*\n"
    "icon rock   # a second icon, all defaults\n"
    "  model fels.3ds\n";

TEST(Definitions, everyDirectiveLandsInItsField) {
  auto r = parse(kFull);
  ASSERT_TRUE(r) << r.error();
  ASSERT_EQ(r->icons.size(), 2u);
  EXPECT_EQ(r->baseDir, "/models");
  const IconDef& t = r->icons[0];
  EXPECT_EQ(t.name, "m1-tank");
  EXPECT_EQ(t.line, std::string(kFull).find("icon m1-tank"));
  EXPECT_EQ(t.alive, "hull.glb");
  EXPECT_EQ(t.dead, "hull-burnt.glb");
  ASSERT_EQ(t.components.size(), 3u);
  EXPECT_EQ(t.components[0].name, "turret");
  EXPECT_EQ(t.components[0].offset, (std::array<float, 3>{0, 1.5f, -0.25f}));
  EXPECT_EQ(t.components[1].parent, "turret");
  EXPECT_EQ(t.components[2].state, iconpack::State::dead);
  EXPECT_EQ(t.import.up, UpAxis::kZ);
  EXPECT_FLOAT_EQ(float(t.import.unitMetres), 0.01f);
  EXPECT_FLOAT_EQ(float(t.import.scale), 1.5f);
  EXPECT_EQ(t.import.maxTriangles, 20000u);
  EXPECT_TRUE(t.armed && t.resupply);
  ASSERT_TRUE(t.bounds && t.cylinder);
  EXPECT_EQ(*t.bounds, (std::array<float, 6>{-2, 0, -4, 2, 2.5f, 4}));
  EXPECT_EQ(*t.cylinder, (std::array<float, 2>{4.5f, 2.5f}));
  ASSERT_EQ(t.levels.size(), 3u);
  EXPECT_EQ(t.levels[1].ratio, 0.4f);
  EXPECT_EQ(t.levels[1].range, 0.0f);
  EXPECT_EQ(t.levels[2].range, 2000.0f);
  // Several dis lines; `*` and left-off trailing fields are wildcards
  // (bit k of the mask for field k, kind first), stored as 0.
  ASSERT_EQ(t.dis.size(), 3u);
  EXPECT_EQ(t.dis[0], (iconpack::DisPattern{{1, 1, 225, 1, 1, 3, 0}, 0}));
  EXPECT_EQ(t.dis[1], (iconpack::DisPattern{{1, 1, 0, 1, 0, 0, 0}, 0x04 | 0x10 | 0x20 | 0x40}));
  EXPECT_EQ(t.dis[2], (iconpack::DisPattern{{1, 2, 225, 0, 0, 0, 0}, 0x78}));
  const IconDef& rock = r->icons[1];
  EXPECT_EQ(rock.alive, "fels.3ds");
  EXPECT_FALSE(rock.armed || rock.resupply || rock.bounds || rock.cylinder || !rock.dis.empty());
  EXPECT_TRUE(rock.levels.empty());
  EXPECT_EQ(rock.import.up, UpAxis::kFromFile);
}

struct Bad {
  std::string body;      ///< lines after "sandtable-icons 1\nicon a\n  model a.glb\n"
  std::string message;   ///< a part of the message
};

TEST(Definitions, badLinesNameTheirOffsetAndTheFix) {
  const std::string head = "sandtable-icons 1\nicon a\n  model a.glb\n";
  const Bad cases[] = {
      {"  model b.glb\n", "'model' twice"},
      {"  wheels 4\n", "unknown directive 'wheels'"},
      {"  lod 0.5\n", "the first lod must have ratio 1"},
      {"  lod 1\n  lod 1\n", "lod ratios must decrease"},
      {"  lod 1 100\n  lod 0.5 50\n", "lod ranges must increase"},
      {"  lod 1.5\n", "lod ratio must be in (0, 1]"},
      {"  lod 1 -3\n", "lod range must be metres >= 0"},
      {"  bounds 1 0 0 0 1 1\n", "each minimum must not exceed its maximum"},
      {"  bounds 1 2 3\n", "'bounds' takes MINX"},
      {"  cylinder 0 2\n", "radius and height must be positive"},
      {"  cylinder 1 nan\n", "'nan' is not a finite number"},
      {"  capabilities flying\n", "capability 'flying' is not armed"},
      {"  dis 1.1.70000.1.1.1.0\n",
       "dis '1.1.70000.1.1.1.0': field 3 (country) '70000' is not a number from 0 to 65535 or * (write e.g. "},
      {"  dis 256\n", "field 1 (kind) '256' is not a number from 0 to 255 or *"},
      {"  dis 1.x\n", "field 2 (domain) 'x' is not a number"},
      {"  dis 1..2\n", "field 2 (domain) '' is not a number"},
      {"  dis 1.2.\n", "field 3 (country) '' is not a number"},
      {"  dis -1\n", "field 1 (kind) '-1' is not a number"},
      {"  dis 1.1.225.1.1.3.0.0\n", "has more than 7 fields"},
      {"  dis 1.1 1.2\n", "'dis' takes one pattern KIND.DOMAIN"},
      {"  dis\n", "'dis' takes one pattern"},
      {"  dis 1.1\n  dis 1.1.*.*\n", "dis 1.1 is already given for icon 'a'; a pattern names one icon"},
      {"  dis 1.1\nicon b\n  model b.glb\n  dis 1.1.*\n", "dis 1.1 is already given for icon 'a'"},
      {"  up x\n", "up must be auto, y or z"},
      {"  scale -1\n", "scale must be a positive number"},
      {"  max-triangles 0\n", "max-triangles must be a positive integer"},
      {"  component t t.glb\n", "'component' takes NAME FILE offset=X,Y,Z"},
      {"  component t t.glb state=alive\n", "needs offset=X,Y,Z"},
      {"  component t t.glb offset=1,2\n", "is not offset=X,Y,Z"},
      {"  component g g.glb offset=0,0,0 parent=t\n", "parent 't' is not an earlier component"},
      {"  component t t.glb offset=0,0,0\n  component t u.glb offset=0,0,0\n", "component 't' twice"},
      {"icon a\n", "icon 'a' is defined twice"},
      {"icon b@\n", "icon name 'b@' must be"},
  };
  for (const Bad& c : cases) {
    const std::string text = head + c.body;
    auto r = parse(text);
    ASSERT_FALSE(r) << c.body;
    const Problem& p = r.problems().front();
    EXPECT_EQ(p.file, "defs.txt");
    EXPECT_NE(p.message.find(c.message), std::string::npos) << c.body << " gave " << p.message;
    // The offset is the start of the last line, the one at fault.
    const std::size_t last = text.rfind('\n', text.size() - 2) + 1;
    EXPECT_EQ(p.offset, last) << c.body << " gave " << p.message;
  }
}

TEST(Definitions, anIconTakesAtMost64DisLines) {
  std::string text = "sandtable-icons 1\nicon a\n  model a.glb\n";
  for (int k = 0; k < 64; ++k) text += "  dis 1.1.225." + std::to_string(k) + "\n";
  auto ok = parse(text);
  ASSERT_TRUE(ok) << ok.error();
  EXPECT_EQ(ok->icons[0].dis.size(), 64u);
  const std::size_t last = text.size();
  text += "  dis 1.1.225.64\n";
  auto r = parse(text);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.problems().front().offset, last);
  EXPECT_NE(r.error().find("at most 64 dis lines per icon"), std::string::npos) << r.error();
}

TEST(Definitions, theHeaderAndTheModelAreRequired) {
  auto noHeader = parse("icon a\n  model a.glb\n");
  ASSERT_FALSE(noHeader);
  EXPECT_NE(noHeader.error().find("the first line must be 'sandtable-icons 1'"), std::string::npos);
  auto noModel = parse("sandtable-icons 1\nicon a\n  scale 2\nicon b\n  model b.glb\n");
  ASSERT_FALSE(noModel);
  EXPECT_EQ(noModel.problems().front().offset, std::string("sandtable-icons 1\n").size());
  EXPECT_NE(noModel.error().find("icon 'a' has no 'model FILE' line"), std::string::npos);
  auto orphan = parse("sandtable-icons 1\n  model a.glb\n");
  ASSERT_FALSE(orphan);
  EXPECT_NE(orphan.error().find("before the first 'icon NAME' line"), std::string::npos);
}

TEST(Definitions, everyProblemIsReportedNotJustTheFirst) {
  auto r = parse("sandtable-icons 1\nicon a\n  model a.glb\n  scale 0\n  up w\n");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.problems().size(), 2u);
}

TEST(Definitions, readDefinitionsResolvesModelsNextToTheFile) {
  auto r = readDefinitions(std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt");
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->baseDir, std::string(SANDTABLE_SOURCE_DIR) + "/samples");
  EXPECT_FALSE(r->icons.empty());
  auto missing = readDefinitions("/nonexistent/icons.txt");
  EXPECT_FALSE(missing);
}

}  // namespace
