// Lattices, per-square heights, skirts and module assembly, each against a
// computation of its own here: heights read straight from the grid posts,
// surfaces interpolated by hand, skirt depths worked out on paper.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <set>

#include "sandtable/formats/bytes.h"
#include "sandtable/meshing/assemble.h"
#include "sandtable/meshing/heights.h"
#include "sandtable/meshing/lattice.h"
#include "sandtable/meshing/skirts.h"
#include "sandtable/testing/fixtures.h"

namespace sandtable::meshing {
namespace {

namespace fs = std::filesystem;
using Elevation = std::function<float(std::uint32_t, std::uint32_t)>;

constexpr double kSpacing = 10.0;

/// A px x pz grid of `f` in a temporary directory.
std::shared_ptr<const grid::GridFile> makeGrid(const std::string& name, std::uint32_t px, std::uint32_t pz,
                                               const Elevation& f) {
  const fs::path dir = fs::temp_directory_path() / ("sandtable-meshing-" + name + "." + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / "grid.stg").string();
  const Status written = fixtures::writeGrid(path, px, pz, kSpacing, f);
  EXPECT_TRUE(written.ok()) << written.error();
  auto g = grid::GridFile::open(path);
  EXPECT_TRUE(g.ok()) << g.error();
  fs::remove_all(dir);  // the mapping stays valid
  return g.value();
}

float slope(std::uint32_t i, std::uint32_t j) { return float(100.0 + 0.25 * i + 0.5 * j + ((i * 7 + j * 3) % 5)); }

/// The posts a level of [first, last] uses, written out: every 2^l, last kept.
std::vector<std::uint32_t> postsByHand(std::uint32_t first, std::uint32_t last, int l) {
  std::vector<std::uint32_t> p;
  for (std::uint32_t v = first; v <= last; v += 1u << l) p.push_back(v);
  if (p.back() != last) p.push_back(last);
  return p;
}

/// Height of level l's SW-NE triangles at level-0 post (i, j), straight
/// from the grid posts.
double surfaceByHand(const grid::GridFile& g, std::uint32_t i0, std::uint32_t i1, std::uint32_t j0,
                     std::uint32_t j1, int l, std::uint32_t i, std::uint32_t j) {
  const auto cols = postsByHand(i0, i1, l), rows = postsByHand(j0, j1, l);
  std::size_t a = 0, b = 0;
  while (a + 2 < cols.size() && cols[a + 1] <= i) ++a;
  while (b + 2 < rows.size() && rows[b + 1] <= j) ++b;
  const double u = double(i - cols[a]) / double(cols[a + 1] - cols[a]);
  const double v = double(j - rows[b]) / double(rows[b + 1] - rows[b]);
  const double nw = g.elevation(cols[a], rows[b]), ne = g.elevation(cols[a + 1], rows[b]);
  const double sw = g.elevation(cols[a], rows[b + 1]), se = g.elevation(cols[a + 1], rows[b + 1]);
  // Upper triangle (NW, NE, SW) where u + v <= 1, else lower (NE, SE, SW).
  if (u + v <= 1) return nw * (1 - u - v) + ne * u + sw * v;
  return se * (u + v - 1) + ne * (1 - v) + sw * (1 - u);
}

TEST(Meshing, moduleSquaresRoundToWholeNodes) {
  EXPECT_EQ(moduleSquares(1000, 31.25, 4), 32u);
  EXPECT_EQ(moduleSquares(700, 25, 3), 28u);  // 28 is a multiple of 4
  EXPECT_EQ(moduleSquares(10, 31.25, 4), 8u);  // never below 2^(levels-1)
  EXPECT_EQ(nodeSquares(32, 4), 4u);
}

TEST(Meshing, latticesReadTheGridPostsAndClampAtTheEastAndSouthEdges) {
  // 30 x 21 posts: module (1, 1) of 16 squares covers posts 16..29 x 16..20.
  const auto g = makeGrid("lattice", 30, 21, slope);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 1, 1);
  EXPECT_EQ(w.i0, 16u);
  EXPECT_EQ(w.i1, 29u);
  EXPECT_EQ(w.j0, 16u);
  EXPECT_EQ(w.j1, 20u);
  for (int l = 0; l < 3; ++l) {
    EXPECT_EQ(w.cols[std::size_t(l)], postsByHand(16, 29, l));
    EXPECT_EQ(w.rows[std::size_t(l)], postsByHand(16, 20, l));
    const LevelLattice lat = levelLattice(grid::GridHeightField(*g), w, l);
    EXPECT_EQ(lat.spacing, kSpacing * (1 << l));
    EXPECT_EQ(lat.moduleX, 160.0);
    EXPECT_EQ(lat.moduleZ, 160.0);
    const auto cols = postsByHand(16, 29, l), rows = postsByHand(16, 20, l);
    ASSERT_EQ(lat.xs.size(), cols.size());
    ASSERT_EQ(lat.heights.size(), cols.size() * rows.size());
    EXPECT_EQ(lat.xs.back(), 130.0);  // the narrower last square ends on the edge post
    for (std::size_t b = 0; b < rows.size(); ++b) {
      EXPECT_EQ(lat.zs[b], double(rows[b] - 16) * kSpacing);
      for (std::size_t a = 0; a < cols.size(); ++a) {
        EXPECT_EQ(lat.heights[b * cols.size() + a], slope(cols[a], rows[b])) << l << " " << a << " " << b;
      }
    }
  }
}

TEST(Meshing, nonFinitePostsReadAsZeroOnlyWhenAsked) {
  const auto g = makeGrid("nan", 9, 9, [](std::uint32_t i, std::uint32_t j) {
    return i == 4 && j == 4 ? std::numeric_limits<float>::quiet_NaN() : 7.0f;
  });
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 8, 1, 0, 0);
  EXPECT_TRUE(std::isnan(levelLattice(grid::GridHeightField(*g), w, 0).heights[4 * 9 + 4]));
  EXPECT_EQ(levelLattice(grid::GridHeightField(*g), w, 0, NonFinite::zero).heights[4 * 9 + 4], 0.0f);
}

TEST(Meshing, surfacesFollowTheSwNeTriangles) {
  const auto g = makeGrid("surface", 30, 21, slope);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 1, 1);
  for (int l = 0; l < 3; ++l) {
    const LevelLattice lat = levelLattice(grid::GridHeightField(*g), w, l);
    for (std::uint32_t j = w.j0; j <= w.j1; ++j) {
      for (std::uint32_t i = w.i0; i <= w.i1; ++i) {
        EXPECT_NEAR(surfaceAt(lat, w, l, i, j), surfaceByHand(*g, w.i0, w.i1, w.j0, w.j1, l, i, j), 1e-9)
            << l << " " << i << " " << j;
      }
    }
  }
}

TEST(Meshing, skirtDepthsOnPaper) {
  // Flat at 0 but for post (1, 0) at -10, on the module's north edge. Four
  // squares, two levels, nodes of 2 squares. Level 1 (posts 0, 2, 4) skips
  // the dip: its surface there is 0, 10 m above level 0's, and the post is
  // on its node edge, so it hangs 10 + 1 m. Level 0 is the lowest surface
  // everywhere: 1 m.
  const auto g = makeGrid("dip", 5, 5, [](std::uint32_t i, std::uint32_t j) { return i == 1 && j == 0 ? -10.0f : 0.0f; });
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 4, 2, 0, 0);
  const std::vector<LevelLattice> lats = {levelLattice(grid::GridHeightField(*g), w, 0), levelLattice(grid::GridHeightField(*g), w, 1)};
  EXPECT_EQ(skirtDepths(lats, w, 2), (std::vector<float>{1.0f, 11.0f}));
  // A bump instead: level 0 lies 10 m above level 1 at (1, 0); level 0 hangs 11 m.
  const auto g2 = makeGrid("bump", 5, 5, [](std::uint32_t i, std::uint32_t j) { return i == 1 && j == 0 ? 10.0f : 0.0f; });
  const std::vector<LevelLattice> lats2 = {levelLattice(grid::GridHeightField(*g2), w, 0), levelLattice(grid::GridHeightField(*g2), w, 1)};
  EXPECT_EQ(skirtDepths(lats2, w, 2), (std::vector<float>{11.0f, 1.0f}));
}

TEST(Meshing, skirtDepthsAgreeWithTheSurfacesByHand) {
  const auto g = makeGrid("depths", 30, 21, slope);
  const std::uint32_t node = nodeSquares(16, 3);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 1, 1);
  std::vector<LevelLattice> lats;
  for (int l = 0; l < 3; ++l) lats.push_back(levelLattice(grid::GridHeightField(*g), w, l));
  const std::vector<float> depths = skirtDepths(lats, w, node);
  for (int l = 0; l < 3; ++l) {
    double worst = 0;
    for (std::uint32_t j = w.j0; j <= w.j1; ++j) {
      for (std::uint32_t i = w.i0; i <= w.i1; ++i) {
        const std::uint32_t edge = node << l;
        const bool line = (i - w.i0) % edge == 0 || (j - w.j0) % edge == 0 || i == w.i1 || j == w.j1;
        if (!line) continue;
        double lowest = INFINITY;
        for (int k = 0; k < 3; ++k) lowest = std::min(lowest, surfaceByHand(*g, w.i0, w.i1, w.j0, w.j1, k, i, j));
        worst = std::max(worst, surfaceByHand(*g, w.i0, w.i1, w.j0, w.j1, l, i, j) - lowest);
      }
    }
    EXPECT_NEAR(depths[std::size_t(l)], worst + kSkirtMargin, 1e-4) << l;
  }
}

TEST(Meshing, blockRangeDepthIsTheElevationRangeUnderTheWindow) {
  // Two blocks across (posts 0..63 and 64..99); module 0 of 32 squares
  // lies in the first only, module 2 (posts 64..96) in the second only.
  const auto g = makeGrid("blocks", 100, 40, [](std::uint32_t i, std::uint32_t j) {
    return i < 64 ? float(j) : float(200 + i);
  });
  EXPECT_EQ(blockRangeDepth(*g, moduleWindow(grid::GridHeightField(*g), 32, 1, 0, 0), 5.0f), 39.0f);   // 0 .. 39
  EXPECT_EQ(blockRangeDepth(*g, moduleWindow(grid::GridHeightField(*g), 32, 1, 2, 0), 264.0f), 35.0f);  // 264 .. 299
  EXPECT_EQ(blockRangeDepth(*g, moduleWindow(grid::GridHeightField(*g), 32, 1, 2, 0), 0.0f), 299.0f);   // the seed widens it
  const auto flat = makeGrid("flat", 9, 9, [](std::uint32_t, std::uint32_t) { return 3.0f; });
  EXPECT_EQ(blockRangeDepth(*flat, moduleWindow(grid::GridHeightField(*flat), 8, 1, 0, 0), 3.0f), 1.0f);  // at least 1 m
}

TEST(Meshing, plainSkinIsTwoTrianglesPerSquareOnTheLatticePosts) {
  const auto g = makeGrid("skin", 30, 21, slope);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 1, 1);
  const LevelLattice lat = levelLattice(grid::GridHeightField(*g), w, 1);
  module::Level lv;
  plainSkin(lat, 7, lv);
  const std::uint32_t nx = lv.squaresX, nz = lv.squaresZ;
  EXPECT_EQ(nx, 7u);  // posts 16, 18, .., 28, 29
  EXPECT_EQ(nz, 2u);  // posts 16, 18, 20
  ASSERT_EQ(lv.vertices.size(), std::size_t(nx + 1) * (nz + 1));
  ASSERT_EQ(lv.groups.size(), std::size_t(2) * nx * nz);
  for (std::size_t k = 0; k < lv.groups.size(); ++k) {
    const module::Group& gr = lv.groups[k];
    EXPECT_EQ(gr.square, k / 2);
    EXPECT_EQ(gr.half, k % 2 ? module::Half::lower : module::Half::upper);
    EXPECT_EQ(gr.material, 7);
    EXPECT_EQ(gr.firstIndex, 3 * k);
    // Counter-clockwise seen from above: seen from +y, east is right and
    // north (-z) is up, so the signed area in (x, -z) is positive.
    const module::Vertex& a = lv.vertices[lv.indices[3 * k]];
    const module::Vertex& b = lv.vertices[lv.indices[3 * k + 1]];
    const module::Vertex& c = lv.vertices[lv.indices[3 * k + 2]];
    const double area = (b.x - a.x) * (-(c.z - a.z)) - (-(b.z - a.z)) * (c.x - a.x);
    EXPECT_GT(area, 0) << k;
  }
  for (const module::Vertex& v : lv.vertices) {
    const auto i = std::uint32_t(16 + std::lround(v.x / kSpacing)), j = std::uint32_t(16 + std::lround(v.z / kSpacing));
    EXPECT_EQ(v.y, slope(i, j));
  }
}

TEST(Meshing, maxHeightIsTheHighestCornerOfEachSquare) {
  const auto g = makeGrid("maxh", 30, 21, slope);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 1, 1);
  const LevelLattice lat = levelLattice(grid::GridHeightField(*g), w, 2);
  module::Level lv;
  plainSkin(lat, 0, lv);
  computeMaxHeights(lv);
  const auto cols = postsByHand(16, 29, 2), rows = postsByHand(16, 20, 2);
  ASSERT_EQ(lv.maxHeight.size(), (cols.size() - 1) * (rows.size() - 1));
  for (std::size_t b = 0; b + 1 < rows.size(); ++b) {
    for (std::size_t a = 0; a + 1 < cols.size(); ++a) {
      const float top = std::max({slope(cols[a], rows[b]), slope(cols[a + 1], rows[b]), slope(cols[a], rows[b + 1]),
                                  slope(cols[a + 1], rows[b + 1])});
      EXPECT_EQ(lv.maxHeight[b * (cols.size() - 1) + a], top) << a << " " << b;
    }
  }
}

TEST(Meshing, skirtsHangAlongEveryNodeEdgeAndShareTheSkinsPosts) {
  const auto g = makeGrid("skirts", 17, 17, slope);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 0, 0);
  const LevelLattice lat = levelLattice(grid::GridHeightField(*g), w, 0);  // 16 x 16 squares, nodes of 4
  module::Level lv;
  plainSkin(lat, 1, lv);
  const std::size_t posts = lv.vertices.size();
  const std::uint64_t tris = addSkirts(lv, lat, 4, 2.5f, 9);
  // 16 nodes, 4 sides of 4 squares, 2 triangles a square.
  EXPECT_EQ(tris, 16u * 4 * 4 * 2);
  EXPECT_EQ(lv.vertices.size(), posts + 16 * 4 * 5);  // only bottom vertices are new
  std::set<std::uint32_t> skirtSquares;
  std::uint32_t next = 0;
  for (std::size_t k = 0; k < lv.groups.size(); ++k) {
    const module::Group& gr = lv.groups[k];
    EXPECT_EQ(gr.firstIndex, next);  // contiguous in group order
    next += gr.indexCount;
    if (k > 0) {
      const module::Group& p = lv.groups[k - 1];
      EXPECT_TRUE(p.square < gr.square || (p.square == gr.square && p.half < gr.half)) << k;
    }
    if (gr.half != module::Half::skirt) continue;
    EXPECT_EQ(gr.material, 9);
    skirtSquares.insert(gr.square);
    for (std::uint32_t q = gr.firstIndex; q < gr.firstIndex + gr.indexCount; ++q) {
      const std::uint32_t v = lv.indices[q];
      if (v < posts) continue;  // a top: a skin post
      // A bottom vertex: 2.5 m below the post at its position.
      const module::Vertex& b = lv.vertices[v];
      const auto i = std::uint32_t(std::lround(b.x / kSpacing)), j = std::uint32_t(std::lround(b.z / kSpacing));
      EXPECT_TRUE(i % 4 == 0 || j % 4 == 0);
      EXPECT_EQ(b.y, slope(i, j) - 2.5f);
    }
  }
  EXPECT_EQ(next, lv.indices.size());
  std::set<std::uint32_t> nodeCorners;
  for (std::uint32_t nz = 0; nz < 16; nz += 4) {
    for (std::uint32_t nx = 0; nx < 16; nx += 4) nodeCorners.insert(nz * 16 + nx);
  }
  EXPECT_EQ(skirtSquares, nodeCorners);
}

TEST(Meshing, skirtsPassThroughTheSurfacesVerticesBetweenPostsOnANodeLine) {
  const auto g = makeGrid("skirt-lines", 17, 17, slope);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 0, 0);
  const LevelLattice lat = levelLattice(grid::GridHeightField(*g), w, 0);
  module::Level plain, fine;
  plainSkin(lat, 1, plain);
  plainSkin(lat, 1, fine);
  // Two vertices on node line x = 40 (column 4) between rows 1 and 2 (a
  // refined square's fine edge, out of order), one on no line.
  const auto on = std::uint32_t(fine.vertices.size());
  fine.vertices.push_back({40.0f, 90.0f, 17.5f, 0, 0});
  fine.vertices.push_back({40.0f, 91.0f, 12.5f, 0, 0});
  fine.vertices.push_back({41.0f, 92.0f, 12.5f, 0, 0});
  const std::uint32_t extra[] = {on, on + 1, on + 2};
  const std::uint64_t plainTris = addSkirts(plain, lat, 4, 2.5f, 9);
  const std::uint64_t tris = addSkirts(fine, lat, 4, 2.5f, 9, extra);
  // Both nodes beside the line (its west and east sides) gain a quad per
  // vertex on it; the vertex off the lines gains nothing.
  EXPECT_EQ(tris, plainTris + 2 * 2 * 2);
  std::set<std::pair<float, float>> tops;  // (z, y) of skirt vertices on x = 40 between z 10 and 20
  for (const module::Group& gr : fine.groups) {
    if (gr.half != module::Half::skirt) continue;
    for (std::uint32_t q = gr.firstIndex; q < gr.firstIndex + gr.indexCount; ++q) {
      const module::Vertex& v = fine.vertices[fine.indices[q]];
      if (v.x == 40.0f && v.z > 10.0f && v.z < 20.0f) tops.insert({v.z, v.y});
    }
  }
  const std::set<std::pair<float, float>> want = {{12.5f, 91.0f}, {12.5f, 88.5f}, {17.5f, 90.0f}, {17.5f, 87.5f}};
  EXPECT_EQ(tops, want);
  // No extra vertices: the builder's skirts, bit for bit.
  module::Level again;
  plainSkin(lat, 1, again);
  addSkirts(again, lat, 4, 2.5f, 9, {});
  EXPECT_EQ(again.indices, plain.indices);
}

TEST(Meshing, assembledModulesHaveEveryLevelWithHeightsAndSkirts) {
  const auto g = makeGrid("assemble", 30, 21, slope);
  int calls = 0;
  const module::Module m = assembleModule(grid::GridHeightField(*g), 16, 3, 1, 1, 5, [&](int l, const LevelLattice& lat, module::Level& out) {
    EXPECT_EQ(l, calls++);
    plainSkin(lat, 2, out);
    for (module::Vertex& v : out.vertices) {  // the skin texture rule (module.h), offsets 0
      v.s = float(double(v.x) / module::kSkinTextureRepeat);
      v.t = float(double(v.z) / module::kSkinTextureRepeat);
    }
    return true;
  });
  ASSERT_EQ(m.levels.size(), 3u);
  EXPECT_EQ(m.kx, 1u);
  EXPECT_EQ(m.kz, 1u);
  const ModuleWindow w = moduleWindow(grid::GridHeightField(*g), 16, 3, 1, 1);
  std::vector<LevelLattice> lats;
  for (int l = 0; l < 3; ++l) lats.push_back(levelLattice(grid::GridHeightField(*g), w, l));
  const std::vector<float> depths = skirtDepths(lats, w, 4);
  for (int l = 0; l < 3; ++l) {
    const module::Level& lv = m.levels[std::size_t(l)];
    EXPECT_EQ(lv.spacing, kSpacing * (1 << l));
    EXPECT_EQ(lv.squaresX, postsByHand(16, 29, l).size() - 1);
    EXPECT_EQ(lv.skirtDepth, depths[std::size_t(l)]);
    EXPECT_EQ(lv.maxHeight.size(), std::size_t(lv.squaresX) * lv.squaresZ);
    EXPECT_TRUE(module::checkEncodable(m).ok()) << module::checkEncodable(m).error();
    EXPECT_TRUE(std::any_of(lv.groups.begin(), lv.groups.end(),
                            [](const module::Group& gr) { return gr.half == module::Half::skirt; }));
  }
  // The module survives the format round trip.
  const auto bytes = module::encode(m);
  auto back = module::decode(bytes, "assembled");
  ASSERT_TRUE(back.ok()) << back.error();
  // Version 3 stores none of the skirts and rebuilds them bit for bit,
  // narrow last squares (this window reaches the grid's east edge) included.
  const auto v3 = module::encode(m, {.heightStep = 0});
  auto exact = module::decode(v3, "assembled v3");
  ASSERT_TRUE(exact.ok()) << exact.error();
  for (std::size_t l = 0; l < m.levels.size(); ++l) {
    const module::Level& x = m.levels[l];
    const module::Level& y = exact->levels[l];
    EXPECT_EQ(x.indices, y.indices) << l;
    ASSERT_EQ(x.vertices.size(), y.vertices.size()) << l;
    for (std::size_t k = 0; k < x.vertices.size(); ++k) {
      EXPECT_EQ(std::memcmp(&x.vertices[k], &y.vertices[k], sizeof(module::Vertex)), 0) << l << " " << k;
    }
    ASSERT_EQ(x.groups.size(), y.groups.size());
    for (std::size_t k = 0; k < x.groups.size(); ++k) {
      EXPECT_TRUE(x.groups[k].square == y.groups[k].square && x.groups[k].half == y.groups[k].half &&
                  x.groups[k].material == y.groups[k].material && x.groups[k].firstIndex == y.groups[k].firstIndex)
          << l << " " << k;
    }
  }
  EXPECT_NE(loadLE<std::uint32_t>(v3.data() + module::kHeaderBytes + module::levelField2::flags) &
                module::kLevel3ImplicitSkirts,
            0u);
  EXPECT_LT(v3.size(), module::encode(m, {.version = 2, .heightStep = 0}).size());
  // A skin that stops leaves the later levels empty.
  const module::Module stopped = assembleModule(grid::GridHeightField(*g), 16, 3, 0, 0, 5, [&](int l, const LevelLattice& lat, module::Level& out) {
    if (l == 1) return false;
    plainSkin(lat, 2, out);
    return true;
  });
  EXPECT_FALSE(stopped.levels[0].groups.empty());
  EXPECT_TRUE(stopped.levels[1].groups.empty());
  EXPECT_TRUE(stopped.levels[2].groups.empty());
}

}  // namespace
}  // namespace sandtable::meshing
