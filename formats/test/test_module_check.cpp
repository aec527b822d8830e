// Geometric module checks: hand-built sound modules on a 2 x 2-module grid
// pass; each corruption, applied alone, gives its own message.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <tuple>

#include "hand_modules.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/module_check.h"

namespace sandtable::module {
namespace {

namespace fs = std::filesystem;
using namespace handmade;

const std::string kPack = "db/modules.pack";

/// Index of the first group matching, or -1.
int findGroup(const Level& lv, std::uint8_t priority, std::uint32_t square, Half half) {
  for (std::size_t k = 0; k < lv.groups.size(); ++k) {
    const Group& g = lv.groups[k];
    if (g.priority == priority && g.square == square && g.half == half) return int(k);
  }
  return -1;
}

/// Removes triangle `t` of group `gi`, keeping the groups contiguous.
void removeTriangle(Level& lv, int gi, std::uint32_t t) {
  Group& g = lv.groups[std::size_t(gi)];
  const auto at = lv.indices.begin() + g.firstIndex + 3 * t;
  lv.indices.erase(at, at + 3);
  g.indexCount -= 3;
  for (std::size_t k = std::size_t(gi) + 1; k < lv.groups.size(); ++k) lv.groups[k].firstIndex -= 3;
}

std::string joined(const std::vector<Problem>& ps) {
  std::string s;
  for (const auto& p : ps) s += p.str() + "\n";
  return s;
}

bool has(const std::vector<Problem>& ps, const std::string& needle) {
  return std::any_of(ps.begin(), ps.end(), [&](const Problem& p) { return p.message.find(needle) != std::string::npos; });
}

class ModuleCheck : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (fs::temp_directory_path() / ("st-mc." + std::to_string(::getpid()))).string();
    // 8 x 9 posts = 7 x 8 squares: modules of 4 squares, so the east column
    // of modules is 3 squares wide (narrow last squares at levels 1 and 2).
    grid_ = writeGrid(dir_, 8, 9);
    header_.modulesX = 2;
    header_.modulesZ = 2;
    header_.levels = 3;
    header_.moduleSquares = 4;
    header_.moduleSize = 4 * kSpacing;
    table_ = table();
    options_.materials = &table_;
  }
  void TearDown() override {
    grid_.reset();
    fs::remove_all(dir_);
  }
  std::vector<Problem> check(const Module& m, std::uint64_t offset = 4096) const {
    return checkModule(m, *grid_, header_, kPack, offset, options_).problems();
  }

  std::string dir_;
  std::shared_ptr<const grid::GridFile> grid_;
  pack::IndexHeader header_;
  materials::Table table_;
  CheckOptions options_;
};

TEST_F(ModuleCheck, soundModulesPass) {
  for (std::uint32_t kz = 0; kz < 2; ++kz) {
    for (std::uint32_t kx = 0; kx < 2; ++kx) {
      const Module m = buildModule(*grid_, header_, kx, kz);
      EXPECT_EQ(m.levels[2].squaresX, 1u);
      EXPECT_EQ(joined(check(m)), "") << "module " << kx << "," << kz;
    }
  }
  // The east modules are 3 squares wide: level 1 has a narrow last square.
  EXPECT_EQ(buildModule(*grid_, header_, 1, 0).levels[1].squaresX, 2u);
}

TEST_F(ModuleCheck, skirtsOnInteriorNodeLinesAreAccepted) {
  BuildOptions o;
  o.nodeSkirts = true;
  EXPECT_EQ(joined(check(buildModule(*grid_, header_, 0, 0, o))), "");
  EXPECT_EQ(joined(check(buildModule(*grid_, header_, 1, 1, o))), "");
}

TEST_F(ModuleCheck, soundNeighboursPass) {
  const ModuleChecker checker(*grid_, header_, kPack, options_);
  ModuleEdges e[2][2];
  for (std::uint32_t kz = 0; kz < 2; ++kz) {
    for (std::uint32_t kx = 0; kx < 2; ++kx) {
      EXPECT_TRUE(checker.check(buildModule(*grid_, header_, kx, kz), 100 * (kz * 2 + kx), &e[kz][kx]).ok());
    }
  }
  EXPECT_EQ(joined(checker.neighbours(e[0][0], e[0][1]).problems()), "");
  EXPECT_EQ(joined(checker.neighbours(e[1][0], e[1][1]).problems()), "");
  EXPECT_EQ(joined(checker.neighbours(e[0][0], e[1][0]).problems()), "");
  EXPECT_EQ(joined(checker.neighbours(e[0][1], e[1][1]).problems()), "");
  // Level 0 of module (0,0): 5 skin vertices on each edge (4 squares).
  ASSERT_EQ(e[0][0].levels.size(), 3u);
  EXPECT_EQ(e[0][0].levels[0][std::size_t(Side::east)].size(), 5u);
  EXPECT_EQ(e[0][0].levels[2][std::size_t(Side::south)].size(), 2u);
}

TEST_F(ModuleCheck, messageNamesFileOffsetModuleLevelSquareAndWhat) {
  Module m = buildModule(*grid_, header_, 1, 1);
  Level& lv = m.levels[0];
  removeTriangle(lv, findGroup(lv, kPrioritySkin, 5, Half::upper), 0);
  const auto ps = check(m, 123456);
  ASSERT_EQ(ps.size(), 1u) << joined(ps);
  EXPECT_EQ(ps[0].file, kPack);
  EXPECT_EQ(ps[0].offset, 123456u);
  EXPECT_EQ(ps[0].message,
            "module check: module (1,1) level 0 square 5 upper: skin covers 0.5 of the triangle "
            "(area 225 of 450 m^2)");
}

TEST_F(ModuleCheck, eachCorruptionHasItsOwnMessage) {
  struct Case {
    const char* what;
    std::function<void(Module&)> damage;
    std::vector<std::string> expected;  ///< every one must appear, and nothing else
  };
  auto vertexOf = [](Level& lv, int gi, std::uint32_t k) -> Vertex& {
    return lv.vertices[lv.indices[lv.groups[std::size_t(gi)].firstIndex + k]];
  };
  const Case cases[] = {
      {"decal slid off its triangle (kept in the plane)",
       [&](Module& m) {
         Level& lv = m.levels[0];
         Vertex& v = vertexOf(lv, findGroup(lv, kPriorityRoad, 0, Half::upper), 2);
         // along the upper plane, 10 m west: past the module's west edge
         const Vertex nw = lv.vertices[0], ne = lv.vertices[1];
         v.y -= float(10.0 * (double(ne.y) - nw.y) / 30.0);
         v.x -= 10.0f;
       },
       {"level 0 square 0 upper: decal triangle at index", "m outside the grid triangle"}},
      {"decal lifted 1 cm",
       [&](Module& m) {
         Level& lv = m.levels[0];
         vertexOf(lv, findGroup(lv, kPriorityRoad, 0, Half::upper), 0).y += 0.01f;
       },
       {"level 0 square 0 upper: decal triangle at index", "0.010 m off the grid triangle's plane"}},
      {"skin midpoint lifted 2 mm",
       [&](Module& m) {
         Level& lv = m.levels[1];
         vertexOf(lv, findGroup(lv, kPrioritySkin, 0, Half::upper), 2).y += 0.002f;
       },
       {"level 1 square 0 upper: skin triangle at index", "m off the grid triangle's plane"}},
      {"skin triangle flipped",
       [&](Module& m) {
         Level& lv = m.levels[0];
         const Group& g = lv.groups[std::size_t(findGroup(lv, kPrioritySkin, 3, Half::lower))];
         std::swap(lv.indices[g.firstIndex], lv.indices[g.firstIndex + 1]);
       },
       {"level 0 square 3 lower: skin triangle at index", "faces down (clockwise seen from above, area -450 m^2)",
        "level 0 square 3 lower: skin covers -1 of the triangle (area -450 of 450 m^2)"}},
      {"skin triangle missing",
       [&](Module& m) {
         Level& lv = m.levels[2];
         removeTriangle(lv, findGroup(lv, kPrioritySkin, 0, Half::lower), 0);
       },
       {"level 2 square 0 lower: skin covers 0 of the triangle (area 0 of 7200 m^2)",
        "level 2 square 0: maxHeight 120 but the highest vertex is 116.5"}},
      {"skin piece doubled (overlap)",
       [&](Module& m) {
         Level& lv = m.levels[0];
         const int gi = findGroup(lv, kPrioritySkin, 7, Half::lower);
         Group& g = lv.groups[std::size_t(gi)];
         const std::vector<std::uint32_t> tri(lv.indices.begin() + g.firstIndex, lv.indices.begin() + g.firstIndex + 3);
         lv.indices.insert(lv.indices.begin() + g.firstIndex + 3, tri.begin(), tri.end());
         g.indexCount += 3;
         for (std::size_t k = std::size_t(gi) + 1; k < lv.groups.size(); ++k) lv.groups[k].firstIndex += 3;
       },
       {"level 0 square 7 lower: skin covers 2 of the triangle (area 900 of 450 m^2)"}},
      {"lattice vertex one ulp off the grid",
       [&](Module& m) {
         float& y = m.levels[0].vertices[6].y;  // lattice post (1,1)
         y = std::nextafter(y, 1e9f);
       },
       {"level 0 vertex 6 at lattice post (1,1) = grid post (1,1) has y 105.000008; the grid says 105"}},
      {"maxHeight too low",
       [&](Module& m) { m.levels[1].maxHeight[1] -= 0.5f; },
       {"level 1 square 1: maxHeight", "but the highest vertex is"}},
      {"maxHeight too high",
       [&](Module& m) { m.levels[0].maxHeight[2] += 0.01f; },
       {"level 0 square 2: maxHeight"}},
      {"skirt half missing",
       [&](Module& m) {
         Level& lv = m.levels[0];
         removeTriangle(lv, findGroup(lv, kPrioritySkin, 3, Half::skirt), 1);
       },
       {"level 0 ", " edge ", ": skirt covers 0.5 of the band 20.000 m below the edge (area 300 of 600 m^2)"}},
      {"skirt off the lattice line",
       [&](Module& m) {
         Level& lv = m.levels[0];
         vertexOf(lv, findGroup(lv, kPrioritySkin, 0, Half::skirt), 1).z += 0.5f;
       },
       {"level 0 skirt group of square 0: triangle at index", "is not vertical on a lattice line",
        "level 0 north edge x 0.000..30.000: skirt covers 0 of the band"}},
      {"skirt hangs below its depth",
       [&](Module& m) {
         Level& lv = m.levels[0];
         vertexOf(lv, findGroup(lv, kPrioritySkin, 0, Half::skirt), 5).y -= 1.0f;
       },
       {"level 0 skirt triangle at index", "lies 1.000 m outside the band from the edge down 20.000 m",
        "level 0 north edge x 0.000..30.000: skirt covers 0.5 of the band"}},
      {"skirt depth zero",
       [&](Module& m) { m.levels[1].skirtDepth = 0; },
       {"level 1: skirt depth 0 m must be a positive number", "lies 20.000 m outside the band"}},
      {"material not in the table",
       [&](Module& m) { m.levels[0].groups[0].material = 77; },
       {"level 0 group 0 (upper, priority 1) uses material 77, which materials.txt does not define",
        "out of (priority, square, half, material) order"}},
      {"skin drawn with a road class",
       [&](Module& m) {
         Level& lv = m.levels[0];
         lv.groups[std::size_t(findGroup(lv, kPrioritySkin, 15, Half::lower))].material = 2;
       },
       {"level 0 group 58 is skin but uses line class 'road' (2); skin uses area classes"}},
      {"decal at the wrong priority",
       [&](Module& m) {
         Level& lv = m.levels[0];
         lv.groups[std::size_t(findGroup(lv, kPriorityRoad, 0, Half::upper))].priority = 5;
       },
       {"is a decal of priority 5 but uses line class 'road' (2) of priority 10"}},
      {"unknown priority",
       [&](Module& m) { m.levels[0].groups.back().priority = 100; },
       {"priority 100 is none of skin (1), decal (2..98) or object (99)"}},
      {"index past the vertices",
       [&](Module& m) { m.levels[0].indices[0] = 100000; },
       {"level 0 index 0 refers past the", "skin covers 0.5 of the triangle"}},
      {"vertex not finite",
       [&](Module& m) { m.levels[0].vertices[0].s = NAN; },
       {"level 0 vertex 0 (0, 100, 0, s nan, t 0) is not finite", "level 0 square 0 upper: skin covers 0 of",
        "level 0 north edge x 0.000..30.000: skirt covers 0.5 of", "level 0 west edge z 0.000..30.000: skirt covers 0.5 of"}},
      {"wrong square count",
       [&](Module& m) { m.levels[1].squaresX = 3; },
       {"level 1 has 3 x 2 squares; the lattice of posts every 2 has 2 x 2"}},
      {"wrong level spacing",
       [&](Module& m) { m.levels[2].spacing = 100; },
       {"level 2 spacing is 100 m; posts every 4 at 30 m give 120 m"}},
      {"level missing",
       [&](Module& m) { m.levels.pop_back(); },
       {"module (0,0) has 2 levels; the pack index says 3"}},
      {"no levels at all",
       [&](Module& m) { m.levels.clear(); },
       {"module (0,0) has 0 levels; the pack index says 3"}},
      {"skin texture shifted",
       [&](Module& m) { m.levels[0].vertices[6].s += 0.01f; },  // lattice post (1,1): 0.64 m off
       {"skin vertex 6 at x 30.000, z 30.000 has texture s 0.47874999, t 0.46875; its position gives s 0.46875, t "
        "0.46875 (skin repeats every 64.000 m from offsets 0.000, 0.000 m)"}},
      {"decal texture across the line past 1",
       [&](Module& m) {
         Level& lv = m.levels[0];
         vertexOf(lv, findGroup(lv, kPriorityRoad, 0, Half::upper), 1).t = 1.5f;
       },
       {"level 0 square 0 upper: decal vertex", "t 1.5; a line's s (along, in widths) must be >= 0 and its t (across) in [0, 1]"}},
      {"decal texture along the line negative",
       [&](Module& m) {
         Level& lv = m.levels[0];
         vertexOf(lv, findGroup(lv, kPriorityRoad, 0, Half::upper), 0).s = -0.25f;
       },
       {"decal vertex", "has texture s -0.25, t"}},
      {"maxHeight short",
       [&](Module& m) { m.levels[0].maxHeight.pop_back(); },
       {"level 0 maxHeight has 15 entries for 16 squares"}},
  };
  for (const auto& c : cases) {
    Module m = buildModule(*grid_, header_, 0, 0);
    c.damage(m);
    options_.maxPerKind = 0;
    const auto ps = check(m);
    for (const auto& e : c.expected) {
      EXPECT_TRUE(has(ps, e)) << c.what << ": expected \"" << e << "\" in\n" << joined(ps);
    }
    for (const auto& p : ps) {
      const bool expected = std::any_of(c.expected.begin(), c.expected.end(),
                                        [&](const std::string& e) { return p.message.find(e) != std::string::npos; });
      EXPECT_TRUE(expected) << c.what << ": unexpected " << p.str();
      EXPECT_EQ(p.file, kPack);
      EXPECT_EQ(p.offset, 4096u);
    }
  }
}

TEST_F(ModuleCheck, slivers) {
  // A zero-area skin triangle along the diagonal (as rounding to float32
  // leaves behind) is accepted; a flipped one thicker than 1 mm is not.
  Module m = buildModule(*grid_, header_, 0, 0);
  Level& lv = m.levels[0];
  const int gi = findGroup(lv, kPrioritySkin, 5, Half::upper);
  Group& g = lv.groups[std::size_t(gi)];
  const std::uint32_t nw = lv.indices[g.firstIndex], sw = lv.indices[g.firstIndex + 1],
                      md = lv.indices[g.firstIndex + 2];
  const std::uint32_t ne = lv.indices[lv.groups[std::size_t(gi) + 1].firstIndex + 2];
  auto insert = [&](std::initializer_list<std::uint32_t> tri) {
    lv.indices.insert(lv.indices.begin() + g.firstIndex + g.indexCount, tri);
    g.indexCount += 3;
    for (std::size_t k = std::size_t(gi) + 1; k < lv.groups.size(); ++k) lv.groups[k].firstIndex += 3;
  };
  insert({sw, md, ne});  // collinear
  EXPECT_EQ(joined(check(m)), "");
  // A flipped sliver 2 mm thick, with its mirror image so the area still sums.
  const std::uint32_t base = std::uint32_t(lv.vertices.size());
  Vertex a = lv.vertices[sw], b = lv.vertices[md];
  Vertex c = skinTextured(0, 0, (a.x + b.x) / 2 - 0.002f, 0, (a.z + b.z) / 2 - 0.002f);
  const double slope = (double(lv.vertices[ne].y) - lv.vertices[nw].y) / 30.0,
               slopeZ = (double(lv.vertices[sw].y) - lv.vertices[nw].y) / 30.0;
  c.y = float(lv.vertices[nw].y + slope * (c.x - lv.vertices[nw].x) + slopeZ * (c.z - lv.vertices[nw].z));
  lv.vertices.push_back(c);
  insert({sw, md, base});  // clockwise seen from above
  insert({sw, base, md});
  const auto ps = check(m);
  ASSERT_EQ(ps.size(), 1u) << joined(ps);
  EXPECT_NE(ps[0].message.find("level 0 square 5 upper: skin triangle at index"), std::string::npos);
  EXPECT_NE(ps[0].message.find("faces down (clockwise seen from above, area -0.0"), std::string::npos) << ps[0].message;
}

TEST_F(ModuleCheck, shallowSkirtIsReportedWithWhereTheCrackIs) {
  BuildOptions o;
  o.skirtDepth = 0.25f;
  const auto ps = check(buildModule(*grid_, header_, 0, 0, o));
  ASSERT_FALSE(ps.empty());
  EXPECT_TRUE(has(ps, "level 0: skirt depth 0.250 m is less than")) << joined(ps);
  EXPECT_TRUE(has(ps, "how far this level's edge lies above level")) << joined(ps);
  for (const auto& p : ps) EXPECT_NE(p.message.find("skirt depth"), std::string::npos) << p.str();
}

TEST_F(ModuleCheck, neighbourEdgesMustMatch) {
  const ModuleChecker checker(*grid_, header_, kPack, options_);
  BuildOptions split;
  split.splitEastEdge = true;
  ModuleEdges west, east;
  // An extra (sound) skin vertex halfway along each east-edge segment of
  // module (0,0), which module (1,0) does not have.
  EXPECT_EQ(joined(checker.check(buildModule(*grid_, header_, 0, 0, split), 10, &west).problems()), "");
  EXPECT_EQ(joined(checker.check(buildModule(*grid_, header_, 1, 0), 20, &east).problems()), "");
  const auto ps = checker.neighbours(west, east).problems();
  // 4 + 2 + 1 segments over the three levels, 5 listed, then a count.
  ASSERT_EQ(ps.size(), 6u) << joined(ps);
  EXPECT_EQ(ps[0].message,
            "module check: module (0,0) level 0 east edge: skin vertex at z 15.000 y 116.000 has no "
            "twin on the west edge of module (1,0)");
  EXPECT_EQ(ps[0].offset, 10u);
  EXPECT_EQ(ps.back().message, "module check: modules (0,0) and (1,0): 2 more neighbour-edge problems not listed");

  // Heights that disagree, and a vertex only the east module has.
  ModuleEdges a, b;
  a.kx = 0, a.kz = 0, a.offset = 1;
  b.kx = 0, b.kz = 1, b.offset = 2;
  a.levels.resize(1);
  b.levels.resize(1);
  a.levels[0][std::size_t(Side::south)] = {{0, 10}, {30, 11}};
  b.levels[0][std::size_t(Side::north)] = {{0, 10}, {15, 10.5f}, {30.0005f, 11.5}};
  const auto qs = checker.neighbours(a, b).problems();
  ASSERT_EQ(qs.size(), 2u) << joined(qs);
  EXPECT_EQ(qs[0].message,
            "module check: module (0,1) level 0 north edge: skin vertex at x 15.000 y 10.500 has no "
            "twin on the south edge of module (0,0)");
  EXPECT_EQ(qs[0].offset, 2u);
  EXPECT_EQ(qs[1].message,
            "module check: module (0,0) level 0 south edge: skin vertex at x 30.000 has y 11.000 but "
            "11.500 on the north edge of module (0,1)");
}

TEST_F(ModuleCheck, repeatedProblemsAreCappedPerKind) {
  Module m = buildModule(*grid_, header_, 0, 0);
  for (float& h : m.levels[0].maxHeight) h += 1.0f;  // 16 squares
  options_.maxPerKind = 5;
  const auto ps = check(m);
  ASSERT_EQ(ps.size(), 6u) << joined(ps);
  EXPECT_EQ(ps.back().message, "module check: module (0,0): 11 more max-height problems not listed");
}

TEST_F(ModuleCheck, moduleOutsideTheDatabase) {
  Module m = buildModule(*grid_, header_, 1, 1);
  m.kx = 2;
  const auto ps = check(m);
  ASSERT_EQ(ps.size(), 1u) << joined(ps);
  EXPECT_EQ(ps[0].message,
            "module check: module (2,1) lies outside the database (2 x 2 modules of 4 squares over 8 x 9 posts)");
}

TEST_F(ModuleCheck, bigModulePasses) {
  // A sound 256-square module (65,536 level-0 squares over 4 levels, about
  // 280 k triangles) passes. Its check time is bench/microbench.cpp's
  // BM_ModuleCheck, with the complexity fit over module sizes.
  const std::string dir = dir_ + "/big";
  auto g = writeGrid(dir, 257, 257);
  pack::IndexHeader h;
  h.modulesX = h.modulesZ = 1;
  h.levels = 4;
  h.moduleSquares = 256;
  h.moduleSize = 256 * kSpacing;
  const Module m = buildModule(*g, h, 0, 0);
  const ModuleChecker checker(*g, h, kPack, options_);
  ModuleEdges e;
  EXPECT_EQ(joined(checker.check(m, 0, &e).problems()), "");
  ASSERT_EQ(e.levels.size(), 4u);
  EXPECT_EQ(e.levels[0][std::size_t(Side::east)].size(), 257u);
}

}  // namespace
}  // namespace sandtable::module
