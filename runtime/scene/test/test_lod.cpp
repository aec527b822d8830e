// Level-of-detail rules of the stealth viewer (lod.h): Table 8 bins,
// screen-space levels and morph factors that are continuous where the level
// switches, level sampling on the lattice, and the quadtree's Morton ranges.
#include <gtest/gtest.h>

#include <cmath>

#include "sandtable/scene/lod.h"

namespace sandtable::scene {
namespace {

TEST(Lod, RingsFollowTable8) {
  LodOptions o;  // no rings: Table 8's four equal bins scaled to the view distance
  EXPECT_EQ(ringLevel(o, 0, 6000, 4), 0u);
  EXPECT_EQ(ringLevel(o, 1500, 6000, 4), 0u);
  EXPECT_EQ(ringLevel(o, 1501, 6000, 4), 1u);
  EXPECT_EQ(ringLevel(o, 4500, 6000, 4), 2u);
  EXPECT_EQ(ringLevel(o, 5999, 6000, 4), 3u);
  o.rings = {3000, 6000};  // two bins: high, then medium-high
  EXPECT_EQ(ringLevel(o, 2999, 6000, 4), 0u);
  EXPECT_EQ(ringLevel(o, 3001, 6000, 4), 1u);
  EXPECT_EQ(ringLevel(o, 7000, 6000, 4), 2u);  // beyond the last bin: the next level
  o.rings = {6000};
  EXPECT_EQ(ringLevel(o, 5999, 6000, 4), 0u);
  EXPECT_EQ(ringLevel(o, 100, 6000, 1), 0u);
}

TEST(Lod, RingMorphReachesOneAtTheBinEdge) {
  LodOptions o;
  o.rings = {1000, 2000};
  EXPECT_EQ(ringMorph(o, 0, 500, 6000, 4), 0.0);
  EXPECT_NEAR(ringMorph(o, 0, 875, 6000, 4), 0.5, 1e-9);
  EXPECT_EQ(ringMorph(o, 0, 1000, 6000, 4), 1.0);
  EXPECT_EQ(ringMorph(o, 3, 5000, 6000, 4), 0.0);  // the coarsest level has nothing to morph to
}

TEST(Lod, ScreenSpaceLevelAndMorphAreContinuous) {
  const std::vector<double> errors = {0, 2, 6, 20};
  const double ppr = pixelsPerRadian(60, 720);
  const double px = 2;
  double previousLevel = 0;
  for (double d = 10; d < 50000; d *= 1.01) {
    const std::uint32_t l = sseLevel(errors, d, ppr, px, 0);
    EXPECT_GE(l, previousLevel);
    previousLevel = l;
    const double m = sseMorph(errors, l, d, ppr, px);
    const double e1 = l + 1 < errors.size() ? errors[l + 1] : errors[l];
    // The morphed surface's error bound stays within the budget.
    EXPECT_LE(projectedError((1 - m) * errors[l] + m * e1, d, ppr), px * (1 + 1e-9)) << d;
    // Just before a switch the morph is complete, so the switch cannot pop.
    if (l + 1 < errors.size() && sseLevel(errors, d * 1.01, ppr, px, 0) > l) {
      EXPECT_EQ(sseMorph(errors, l, d * 1.01, ppr, px), 1.0);
      EXPECT_GT(m, 0.9) << d;
    }
  }
  EXPECT_EQ(previousLevel, 3);
  EXPECT_EQ(sseLevel(errors, 1, ppr, px, 0), 0u);
}

module::Level latticeLevel(std::uint32_t n, double spacing, double (*height)(double, double)) {
  module::Level l;
  l.spacing = spacing;
  l.squaresX = l.squaresZ = n;
  for (std::uint32_t r = 0; r <= n; ++r) {
    for (std::uint32_t c = 0; c <= n; ++c) {
      const float x = float(c * spacing), z = float(r * spacing);
      l.vertices.push_back({x, float(height(x, z)), z, 0, 0});
    }
  }
  return l;
}

TEST(Lod, LevelHeightFollowsTheGridTriangles) {
  const auto plane = [](double x, double z) { return 10 + 0.5 * x - 0.25 * z; };
  const module::Level l = latticeLevel(4, 100, plane);
  for (double x : {0.0, 33.0, 150.0, 399.0}) {
    for (double z : {0.0, 71.0, 250.0, 400.0}) EXPECT_NEAR(*levelHeightAt(l, x, z), plane(x, z), 1e-4);
  }
  // A bump at one post: the SW-NE diagonal decides which corners count.
  module::Level b = latticeLevel(2, 100, [](double, double) { return 0.0; });
  b.vertices[0].y = 30;  // NW post of square (0, 0)
  EXPECT_NEAR(*levelHeightAt(b, 0, 0), 30, 1e-6);
  EXPECT_NEAR(*levelHeightAt(b, 25, 25), 15, 1e-6);  // upper triangle: 30 * (1 - u - v)
  EXPECT_NEAR(*levelHeightAt(b, 75, 75), 0, 1e-6);   // lower triangle: NW not a corner
  EXPECT_FALSE(levelHeightAt(module::Level{}, 0, 0));
}

TEST(Lod, LevelErrorsAreMeasuredAtTheFinestPosts) {
  const auto bumpy = [](double x, double z) { return std::fmod(x + z, 200.0) == 100.0 ? 8.0 : 0.0; };
  std::vector<module::Level> levels = {latticeLevel(4, 50, bumpy), latticeLevel(2, 100, bumpy),
                                       latticeLevel(1, 200, bumpy)};
  const auto e = levelErrors(levels, 0);
  ASSERT_EQ(e.size(), 3u);
  EXPECT_EQ(e[0], 0);
  EXPECT_GT(e[1], 0);
  EXPECT_GE(e[2], e[1]);
}

TEST(Lod, MortonRangesNestLikeTheQuadtree) {
  EXPECT_EQ(mortonIndex(0, 0), 0u);
  EXPECT_EQ(mortonIndex(1, 0), 1u);
  EXPECT_EQ(mortonIndex(0, 1), 2u);
  EXPECT_EQ(mortonIndex(1, 1), 3u);
  // Child c of node n is 4 n + c.
  for (std::uint32_t a = 0; a < 4; ++a) {
    for (std::uint32_t b = 0; b < 4; ++b) {
      for (std::uint32_t c = 0; c < 4; ++c) {
        EXPECT_EQ(mortonIndex(2 * a + (c & 1), 2 * b + (c >> 1)), 4 * mortonIndex(a, b) + c);
      }
    }
  }
  EXPECT_EQ(nodesPerSide(0, 4), 8u);
  EXPECT_EQ(nodesPerSide(3, 4), 1u);
}

TEST(Lod, NodeTrianglesCoverTheLevel) {
  module::Level l = latticeLevel(8, 10, [](double, double) { return 0.0; });
  // One group of two triangles per square, as a plain lattice has.
  for (std::uint32_t q = 0; q < 64; ++q) {
    const std::uint32_t c = q % 8, r = q / 8, nw = r * 9 + c;
    module::Group g;
    g.square = q;
    g.firstIndex = std::uint32_t(l.indices.size());
    g.indexCount = 6;
    l.indices.insert(l.indices.end(), {nw, nw + 9, nw + 1, nw + 1, nw + 9, nw + 10});
    l.groups.push_back(g);
  }
  EXPECT_FALSE(needsUnderlay(l));
  const auto prefix = nodeTrianglePrefix(l, 4, 2);  // 2 x 2 nodes of 4 x 4 squares
  ASSERT_EQ(prefix.size(), 5u);
  for (std::size_t n = 0; n < 4; ++n) EXPECT_EQ(prefix[n + 1] - prefix[n], 32u);
  EXPECT_EQ(nodeOfSquare(l, 0, 4, 2), 0u);
  EXPECT_EQ(nodeOfSquare(l, 7, 4, 2), 1u);   // east half, north
  EXPECT_EQ(nodeOfSquare(l, 56, 4, 2), 2u);  // west half, south
}

TEST(Lod, OptionsAreChecked) {
  LodOptions o;
  EXPECT_EQ(checkLodOptions(o), "");
  o.rings = {3000, 1000};
  EXPECT_NE(checkLodOptions(o), "");
  o.rings = {-1};
  EXPECT_NE(checkLodOptions(o), "");
  o.rings = {};
  o.pixelError = 0;
  EXPECT_NE(checkLodOptions(o), "");
}

}  // namespace
}  // namespace sandtable::scene
