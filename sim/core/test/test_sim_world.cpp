// The collision squares (Figure 56): on random worlds the 3x3 search finds
// exactly what testing every object finds; the soil and water rules.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sandtable/base/hash.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

double rnd(std::uint64_t& s) { return hash::unit(hash::mix(s++)); }

TEST(SimWorld, gridSearchFindsExactlyWhatBruteForceFindsOnRandomWorlds) {
  auto w = test::makeWorld([](double x, double z) { return 50 + 20 * std::sin(x / 300) * std::cos(z / 200); });
  std::uint64_t seed = 7;
  std::size_t found = 0;
  for (int world = 0; world < 5; ++world) {
    std::vector<StaticObject> objects(3000 + 2000 * std::size_t(world));
    for (StaticObject& o : objects) {
      o.x = rnd(seed) * w->widthM();
      o.z = rnd(seed) * w->depthM();
      o.baseY = *w->groundAt(o.x, o.z);
      o.radius = 0.5 + rnd(seed) * (world == 4 ? 40 : 8);  // world 4: big objects widen the squares
      o.height = 2 + rnd(seed) * 20;
      if (rnd(seed) < 0.1) o.state = ObjectState::knockedOver;
    }
    w->setObjects(objects);
    EXPECT_GE(w->squareM(), 125.0);
    std::vector<std::uint32_t> grid, brute;
    for (int q = 0; q < 4000; ++q) {
      const double x = rnd(seed) * w->widthM(), z = rnd(seed) * w->depthM();
      const double r = 0.5 + rnd(seed) * 14;
      const double bottom = *w->groundAt(x, z) + (rnd(seed) < 0.5 ? 0 : rnd(seed) * 30);
      grid.clear();
      brute.clear();
      w->objectsNear(x, z, r, bottom, grid);
      w->objectsNearBruteForce(x, z, r, bottom, brute);
      ASSERT_EQ(grid, brute) << "world " << world << " query " << q;
      found += grid.size();
    }
  }
  EXPECT_GT(found, 500u);  // the worlds are dense enough for the check to mean something
}

TEST(SimWorld, theFirstLevelSkipsSquaresWhoseTallestObjectIsBelowTheEntity) {
  auto w = test::makeWorld([](double, double) { return 0.0; });
  std::vector<StaticObject> objects(1);
  objects[0].x = 500;
  objects[0].z = 500;
  objects[0].radius = 3;
  objects[0].height = 15;
  w->setObjects(objects);
  std::vector<std::uint32_t> out;
  SearchStats stats;
  w->objectsNear(501, 500, 1, 20, out, &stats);  // above the 15 m tree
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(stats.squares, 9u);
  EXPECT_EQ(stats.squaresPassed, 0u);
  EXPECT_EQ(stats.objectsTested, 0u);
  w->objectsNear(501, 500, 1, 10, out, &stats);  // among its branches
  EXPECT_EQ(stats.squaresPassed, 1u);  // the tree's square only
  EXPECT_EQ(stats.objectsTested, 1u);
  EXPECT_EQ(out, std::vector<std::uint32_t>{0});
  out.clear();
  w->objectsNear(504.1, 500, 1, 0, out);  // 4.1 m apart: radii 3 + 1 do not meet
  EXPECT_TRUE(out.empty());
}

TEST(SimWorld, navigableIsWaterOrAtOrBelowSeaLevelWhereTheMaterialIsUnknown) {
  auto w = test::makeWorld([](double x, double) { return x < 1000 ? -3.0 : 12.0; });
  EXPECT_TRUE(w->navigable(500, 500));
  EXPECT_FALSE(w->navigable(1500, 500));
  EXPECT_FALSE(w->navigable(-1, 500));
  EXPECT_FALSE(w->soilAt(500, 500).known);
  EXPECT_EQ(w->soilAt(500, 500).resist, materials::kDefaultResist);
}

TEST(SimWorld, objectKindsFollowIconAndClassNames) {
  EXPECT_EQ(objectKindOf("tree-tall", ""), ObjectKind::tree);
  EXPECT_EQ(objectKindOf("", "forest"), ObjectKind::tree);
  EXPECT_EQ(objectKindOf("garage", ""), ObjectKind::house);
  EXPECT_EQ(objectKindOf("", "building"), ObjectKind::house);
  EXPECT_EQ(objectKindOf("boulder", "rock"), ObjectKind::rock);
}

}  // namespace
}  // namespace sandtable::sim
