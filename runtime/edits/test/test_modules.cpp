// Re-meshed modules (modules.h) on the Bayreuth database with its OSM
// roads: a bump raised across a road passes every module check at every
// level against the edited heights, with the road's decal on the new
// planes; a change at a module corner rebuilds exactly the four modules; a
// crater patch is meshed at level 0 on the fine lattice, covering each
// square once, with no T-junction and its decals clipped onto it; object
// edits; generations per the ModuleSource contract; and the pager swapping
// a rebuilt module in.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "sandtable/edits/heights.h"
#include "sandtable/edits/modules.h"
#include "sandtable/edits/profile.h"
#include "sandtable/formats/module_check.h"
#include "sandtable/formats/terrain_rule.h"
#include "sandtable/paging/pager.h"
#include "test_modules_support.h"

namespace sandtable::edits {
namespace {

using test::TestHeights;

#define REQUIRE_BAYREUTH()                                                          \
  const Database* db = test::bayreuth();                                            \
  if (!db) GTEST_SKIP() << "../shared/data is missing (or the build failed above)"; \
  (void)db

struct Fixture {
  std::shared_ptr<const grid::HeightField> before;
  std::shared_ptr<TestHeights> heights;
  std::shared_ptr<const paging::PackSource> pack;
  std::shared_ptr<EditedModules> modules;
};

Fixture fixture(const Database& db, RemeshOptions o = {}) {
  Fixture f;
  f.before = grid::heightField(db.grid);
  f.heights = std::make_shared<TestHeights>(db.grid);
  f.pack = std::make_shared<paging::PackSource>(db.modules);
  f.modules = std::make_shared<EditedModules>(f.pack, f.before, f.heights, std::move(o));
  return f;
}

module::Module readModule(const paging::ModuleSource& s, std::uint32_t kx, std::uint32_t kz) {
  module::Module m;
  const auto r = s.read(kx, kz, m);
  EXPECT_TRUE(r.ok()) << r.error();
  return m;
}

/// Height tolerance of a level: 1 mm plus half its quantisation step.
double tolerance(const module::Level& l) { return 1e-3 + 0.5 * l.heightStep; }

/// A point on a decal of some interior module's level 0 (the road the
/// tests raise and dig), its world (x, z), x at least `margin` metres from
/// a post column.
struct RoadPoint {
  std::uint32_t kx = 0, kz = 0;
  double x = 0, z = 0;
};

RoadPoint findRoad(const Database& db, double margin) {
  const pack::IndexHeader& h = db.modules->header();
  const double s = db.grid->spacing();
  for (std::uint32_t kz = 1; kz + 1 < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 1; kx + 1 < h.modulesX; ++kx) {
      module::Module m;
      if (!db.modules->readInto(kx, kz, m).ok()) continue;
      const module::Level& l0 = m.levels[0];
      for (const module::Group& g : l0.groups) {
        if (g.priority != module::kPriorityRoad || g.half == module::Half::skirt) continue;
        for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; k += 3) {
          double x = 0, z = 0;
          for (int q = 0; q < 3; ++q) x += l0.vertices[l0.indices[k + q]].x / 3, z += l0.vertices[l0.indices[k + q]].z / 3;
          // Far from the module's edges, and from post columns.
          const double fx = x / s - std::floor(x / s);
          if (x < 3 * s || z < 3 * s || x > h.moduleSize - 3 * s || z > h.moduleSize - 3 * s) continue;
          if (fx * s < margin || (1 - fx) * s < margin) continue;
          return {kx, kz, kx * h.moduleSize + x, kz * h.moduleSize + z};
        }
      }
    }
  }
  ADD_FAILURE() << "no road decal in the database";
  return {};
}

/// Checks every level of every module of `keys` against the heights, and
/// the shared edges of each with its four neighbours.
void expectModulesPass(const Database& db, const grid::HeightField& h, const paging::ModuleSource& src,
                       const std::vector<paging::ModuleKey>& keys) {
  const pack::IndexHeader& hd = src.header();
  module::CheckOptions o;
  o.materials = db.materials ? &*db.materials : nullptr;
  o.maxPerKind = 3;
  const module::ModuleChecker checker(h, hd, "edited");
  for (const paging::ModuleKey& k : keys) {
    const module::Module m = readModule(src, k.kx, k.kz);
    module::ModuleEdges e;
    const Status st = checker.check(m, 0, &e);
    EXPECT_TRUE(st.ok()) << "module (" << k.kx << ", " << k.kz << "): " << st.error() << " (+"
                         << st.problems().size() - 1 << " more)";
    const int around[4][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}};
    for (const auto& d : around) {
      const std::int64_t nx = std::int64_t(k.kx) + d[0], nz = std::int64_t(k.kz) + d[1];
      if (nx < 0 || nz < 0 || nx >= hd.modulesX || nz >= hd.modulesZ) continue;
      const module::Module other = readModule(src, std::uint32_t(nx), std::uint32_t(nz));
      module::ModuleEdges eo;
      checker.check(other, 0, &eo);
      const bool first = d[0] < 0 || d[1] < 0;  // the other is west or north
      const Status ns = first ? checker.neighbours(eo, e) : checker.neighbours(e, eo);
      EXPECT_TRUE(ns.ok()) << ns.error();
    }
  }
}

/// A smooth bump of `height` metres and radius `radius` metres on the
/// posts around (x, z); returns the posts it moved.
grid::PostRect bump(TestHeights& h, double x, double z, double radius, double height) {
  const double s = h.spacing();
  const auto i0 = std::uint32_t(std::floor((x - radius) / s)), i1 = std::uint32_t(std::ceil((x + radius) / s)) + 1;
  const auto j0 = std::uint32_t(std::floor((z - radius) / s)), j1 = std::uint32_t(std::ceil((z + radius) / s)) + 1;
  for (std::uint32_t j = j0; j < j1; ++j) {
    for (std::uint32_t i = i0; i < i1; ++i) {
      const double d2 = (std::pow(i * s - x, 2) + std::pow(j * s - z, 2)) / (radius * radius);
      if (d2 >= 1) continue;
      h.set(i, j, float(h.elevation(i, j) + height * (1 - d2) * (1 - d2)));
    }
  }
  return {i0, j0, i1, j1};
}

/// Height of level `l`'s lattice planes of module (kx, kz) at module-local
/// (x, z) on half `half` of square `square`, from the heights' posts.
double planeAt(const grid::HeightField& h, const pack::IndexHeader& hd, std::uint32_t kx, std::uint32_t kz, std::size_t l,
               std::uint32_t square, module::Half half, double x, double z) {
  const std::uint32_t sq = hd.moduleSquares, step = 1u << l;
  const std::uint32_t i0 = kx * sq, j0 = kz * sq;
  const auto cols = terrain::latticePosts(i0, std::min(i0 + sq, h.postsX() - 1), step);
  const auto rows = terrain::latticePosts(j0, std::min(j0 + sq, h.postsZ() - 1), step);
  const std::size_t a = square % (cols.size() - 1), b = square / (cols.size() - 1);
  const double s = h.spacing();
  const double x0 = (cols[a] - i0) * s, x1 = (cols[a + 1] - i0) * s, z0 = (rows[b] - j0) * s, z1 = (rows[b + 1] - j0) * s;
  return terrain::halfPlane(half, (x - x0) / (x1 - x0), (z - z0) / (z1 - z0), double(h.elevation(cols[a], rows[b])),
                            double(h.elevation(cols[a + 1], rows[b])), double(h.elevation(cols[a], rows[b + 1])),
                            double(h.elevation(cols[a + 1], rows[b + 1])));
}

TEST(EditedModules, aBumpAcrossARoadPassesEveryCheckAtEveryLevelWithTheRoadOnTheNewPlanes) {
  REQUIRE_BAYREUTH();
  Fixture f = fixture(*db);
  const RoadPoint road = findRoad(*db, 0);
  const grid::PostRect moved = bump(*f.heights, road.x, road.z, 75, 4);
  const auto report = f.modules->remesh(moved, {});
  ASSERT_TRUE(report.ok()) << report.error();
  ASSERT_FALSE(report->modules.empty());
  EXPECT_EQ(report->triangles.size(), f.modules->header().levels);
  expectModulesPass(*db, *f.heights, *f.modules, report->modules);
  // The road's vertices on every level lie on the new planes, and moved.
  const pack::IndexHeader& hd = f.modules->header();
  double rose = 0;
  for (const paging::ModuleKey& k : report->modules) {
    const module::Module m = readModule(*f.modules, k.kx, k.kz);
    const module::Module b = readModule(*f.pack, k.kx, k.kz);
    for (std::size_t l = 0; l < m.levels.size(); ++l) {
      const module::Level& lv = m.levels[l];
      double worst = 0;
      for (const module::Group& g : lv.groups) {
        if (g.priority != module::kPriorityRoad || g.half == module::Half::skirt) continue;
        for (std::uint32_t q = g.firstIndex; q < g.firstIndex + g.indexCount; ++q) {
          const module::Vertex& v = lv.vertices[lv.indices[q]];
          worst = std::max(worst, std::fabs(v.y - planeAt(*f.heights, hd, k.kx, k.kz, l, g.square, g.half, v.x, v.z)));
          if (l == 0) {
            rose = std::max(rose, v.y - planeAt(*f.before, hd, k.kx, k.kz, l, g.square, g.half, v.x, v.z));
          }
        }
      }
      EXPECT_LE(worst, tolerance(lv)) << "module (" << k.kx << ", " << k.kz << ") level " << l;
      // Nothing else changed in number: the same groups and triangles.
      EXPECT_EQ(lv.groups.size(), b.levels[l].groups.size());
    }
  }
  EXPECT_GT(rose, 3.0);  // the road climbs the bump
}

TEST(EditedModules, aChangeAtAModuleCornerRebuildsExactlyTheFourModulesAndEveryLevel) {
  REQUIRE_BAYREUTH();
  Fixture f = fixture(*db);
  const pack::IndexHeader& hd = f.modules->header();
  ASSERT_GE(hd.modulesX, 3u);
  ASSERT_GE(hd.modulesZ, 3u);
  const std::uint32_t sq = hd.moduleSquares, ci = sq, cj = sq;  // the corner of modules (0..1, 0..1)
  f.heights->set(ci, cj, f.heights->elevation(ci, cj) + 2.5f);
  const grid::PostRect post{ci, cj, ci + 1, cj + 1};
  const std::vector<paging::ModuleKey> want = {{0, 0}, {1, 0}, {0, 1}, {1, 1}};
  EXPECT_EQ(f.modules->touched(post, {}), want);
  const auto report = f.modules->remesh(post, {});
  ASSERT_TRUE(report.ok()) << report.error();
  EXPECT_EQ(report->modules, want);
  for (std::uint32_t kz = 0; kz < std::min(hd.modulesZ, 3u); ++kz) {
    for (std::uint32_t kx = 0; kx < std::min(hd.modulesX, 3u); ++kx) {
      EXPECT_EQ(f.modules->generation(kx, kz) > 0, kx < 2 && kz < 2) << kx << ", " << kz;
    }
  }
  for (const paging::ModuleKey& k : want) {
    const module::Module m = readModule(*f.modules, k.kx, k.kz);
    const module::Module b = readModule(*f.pack, k.kx, k.kz);
    for (std::size_t l = 0; l < m.levels.size(); ++l) {
      // The corner is a lattice post of every level of the four.
      const module::Level& lv = m.levels[l];
      const std::uint32_t w = lv.squaresX + 1;
      const std::size_t corner = (k.kz == 0 ? std::size_t(lv.squaresZ) * w : 0) + (k.kx == 0 ? lv.squaresX : 0);
      // Onto the new ground exactly: off the base's rounded height by at
      // most half its height step.
      EXPECT_NEAR(lv.vertices[corner].y - b.levels[l].vertices[corner].y, 2.5, 0.5 * b.levels[l].heightStep + 1e-4)
          << k.kx << ", " << k.kz << " level " << l;
    }
  }
  expectModulesPass(*db, *f.heights, *f.modules, want);
}

// ------------------------------------------------------------ refined squares

/// Level-0 skin triangles of square (sa, sb) (module-local squares).
struct Tri {
  std::array<module::Vertex, 3> v;
  std::uint16_t material = 0;
};
std::vector<Tri> squareTriangles(const module::Level& l, std::uint32_t square, bool skin) {
  std::vector<Tri> out;
  for (const module::Group& g : l.groups) {
    if (g.square != square || g.half == module::Half::skirt) continue;
    if (skin != (g.priority == module::kPrioritySkin) || g.priority >= module::kPriorityObject) continue;
    for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; k += 3) {
      out.push_back({{l.vertices[l.indices[k]], l.vertices[l.indices[k + 1]], l.vertices[l.indices[k + 2]]}, g.material});
    }
  }
  return out;
}

double upArea(const module::Vertex& a, const module::Vertex& b, const module::Vertex& c) {
  const double d1x = double(b.x) - a.x, d1z = double(b.z) - a.z, d2x = double(c.x) - a.x, d2z = double(c.z) - a.z;
  return 0.5 * (d1z * d2x - d1x * d2z);
}

/// Smallest barycentric coordinate of (x, z) in t and its height there.
double locate(const Tri& t, double x, double z, double& y) {
  const double area = upArea(t.v[0], t.v[1], t.v[2]);
  const module::Vertex p{float(x), 0, float(z), 0, 0};
  double w[3];
  for (int k = 0; k < 3; ++k) w[k] = upArea(p, t.v[(k + 1) % 3], t.v[(k + 2) % 3]) / area;
  // Doubles, not the float p: recompute with the exact point.
  for (int k = 0; k < 3; ++k) {
    const auto& b = t.v[(k + 1) % 3];
    const auto& c = t.v[(k + 2) % 3];
    const double d1x = double(b.x) - x, d1z = double(b.z) - z, d2x = double(c.x) - x, d2z = double(c.z) - z;
    w[k] = 0.5 * (d1z * d2x - d1x * d2z) / area;
  }
  y = w[0] * t.v[0].y + w[1] * t.v[1].y + w[2] * t.v[2].y;
  return std::min({w[0], w[1], w[2]});
}

/// The level-0 surface of skin triangles `tris` at (x, z): the triangle
/// that holds it best.
double surfaceAt(const std::vector<Tri>& tris, double x, double z, int* holders = nullptr) {
  double best = -1e9, y = NAN;
  int count = 0;
  for (const Tri& t : tris) {
    double ty = 0;
    const double in = locate(t, x, z, ty);
    if (in > 1e-9) ++count;
    if (in > best) best = in, y = ty;
  }
  if (holders) *holders = count;
  return best > -1e-6 ? y : NAN;
}

/// The crater on the road, and the squares it refines.
struct Crater {
  edit::Edit e;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> squares;
};

Crater craterAt(TestHeights& h, double x, double z, std::uint32_t cells) {
  Crater c;
  c.e.kind = edit::Kind::crater;
  c.e.points = {{x, z}};
  c.e.radius = kCraterMedium.radius;
  c.e.depth = kCraterMedium.depth;
  c.squares = test::craterPatches(h, c.e, cells);
  return c;
}

/// Every check of a refined square's level-0 triangles: heights at the fine
/// posts and inside the patch are refinedHeight's, the skin covers the
/// square once, and its sides meet each neighbour without a T-junction.
void expectRefinedSquare(const grid::HeightField& h, const paging::ModuleSource& src, std::uint32_t i, std::uint32_t j) {
  const pack::IndexHeader& hd = src.header();
  const std::uint32_t sq = hd.moduleSquares, kx = std::min(i / sq, hd.modulesX - 1), kz = std::min(j / sq, hd.modulesZ - 1);
  const module::Module m = readModule(src, kx, kz);
  const module::Level& l0 = m.levels[0];
  const std::uint32_t sa = i - kx * sq, sb = j - kz * sq, square = sb * l0.squaresX + sa;
  const std::vector<Tri> skin = squareTriangles(l0, square, true);
  const auto r = h.refined(i, j);
  ASSERT_TRUE(r);
  const double s = h.spacing(), x0 = sa * s, z0 = sb * s, tol = tolerance(l0);
  SCOPED_TRACE("square (" + std::to_string(i) + ", " + std::to_string(j) + ")");
  // Heights at every fine post of the patch and at random points in it.
  double worst = 0;
  for (std::uint32_t b = r->b0; b <= r->b1; ++b) {
    for (std::uint32_t a = r->a0; a <= r->a1; ++a) {
      bool inside = false;
      const double want = grid::refinedHeight(*r, double(a) / r->cells, double(b) / r->cells, inside);
      const double got = surfaceAt(skin, x0 + a * s / r->cells, z0 + b * s / r->cells);
      worst = std::max(worst, std::fabs(got - want));
    }
  }
  EXPECT_LE(worst, tol) << "at the fine posts";
  std::mt19937_64 rng(i * 7919 + j);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double worstInside = 0;
  int twice = 0, never = 0;
  for (int k = 0; k < 400; ++k) {
    const double fx = (r->a0 + unit(rng) * (r->a1 - r->a0)) / r->cells, fz = (r->b0 + unit(rng) * (r->b1 - r->b0)) / r->cells;
    bool inside = false;
    const double want = grid::refinedHeight(*r, fx, fz, inside);
    int holders = 0;
    const double got = surfaceAt(skin, x0 + fx * s, z0 + fz * s, &holders);
    worstInside = std::max(worstInside, std::fabs(got - want));
    // Anywhere in the square: exactly one skin triangle holds the point.
    int h2 = 0;
    surfaceAt(skin, x0 + unit(rng) * s, z0 + unit(rng) * s, &h2);
    twice += holders > 1 || h2 > 1;
    never += holders == 0 || h2 == 0;
  }
  EXPECT_LE(worstInside, tol) << "inside the patch";
  EXPECT_EQ(twice, 0) << "points under two skin triangles";
  EXPECT_EQ(never, 0) << "points under no skin triangle";
  double area = 0;
  for (const Tri& t : skin) {
    const double a = upArea(t.v[0], t.v[1], t.v[2]);
    EXPECT_GT(a, 0) << "a skin triangle faces down";
    area += a;
  }
  EXPECT_NEAR(area / (s * s), 1.0, 1e-6);
  // The sides: beside an unrefined square, one triangle edge from post to
  // post; beside a refined one, the same vertices on both sides.
  struct Side {
    int di, dj;
    bool vertical;
    double at;  // module-local x (vertical) or z of the side
  };
  for (const Side side : {Side{-1, 0, true, x0}, Side{1, 0, true, x0 + s}, Side{0, -1, false, z0}, Side{0, 1, false, z0 + s}}) {
    const std::int64_t ni = std::int64_t(i) + side.di, nj = std::int64_t(j) + side.dj;
    if (ni < 0 || nj < 0 || ni + 1 >= h.postsX() || nj + 1 >= h.postsZ()) continue;
    auto onSide = [&](const std::vector<Tri>& tris, double at, std::vector<std::pair<float, float>>& pts, int& edges) {
      edges = 0;
      for (const Tri& t : tris) {
        int on = 0;
        for (const module::Vertex& v : t.v) {
          const float c = side.vertical ? v.x : v.z;
          if (std::fabs(c - at) < 1e-4) {
            pts.push_back({side.vertical ? v.z : v.x, v.y});
            ++on;
          }
        }
        edges += on == 2;
      }
      std::sort(pts.begin(), pts.end());
      pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
    };
    std::vector<std::pair<float, float>> mine;
    int myEdges = 0;
    onSide(skin, side.at, mine, myEdges);
    if (!h.refined(std::uint32_t(ni), std::uint32_t(nj))) {
      EXPECT_EQ(myEdges, 1) << "side " << side.di << "," << side.dj << ": one edge beside an unrefined square";
      EXPECT_EQ(mine.size(), 2u) << "side " << side.di << "," << side.dj << ": only the posts";
      continue;
    }
    // The neighbour, in this module or the next.
    const auto ui = std::uint32_t(ni), uj = std::uint32_t(nj);
    const std::uint32_t nkx = std::min(ui / sq, hd.modulesX - 1), nkz = std::min(uj / sq, hd.modulesZ - 1);
    const module::Module nm = nkx == kx && nkz == kz ? m : readModule(src, nkx, nkz);
    const module::Level& n0 = nm.levels[0];
    const std::uint32_t na = ui - nkx * sq, nb = uj - nkz * sq;
    const std::vector<Tri> theirs = squareTriangles(n0, nb * n0.squaresX + na, true);
    // The side in the neighbour's module frame.
    const double shift = side.vertical ? (double(kx) - nkx) * hd.moduleSize : (double(kz) - nkz) * hd.moduleSize;
    std::vector<std::pair<float, float>> other;
    int otherEdges = 0;
    onSide(theirs, side.at + shift, other, otherEdges);
    EXPECT_EQ(mine, other) << "side " << side.di << "," << side.dj << " of a refined neighbour";
    EXPECT_GT(mine.size(), 2u);
  }
}

TEST(EditedModules, aCraterOnARoadIsMeshedOnTheFineLatticeAtLevelZero) {
  REQUIRE_BAYREUTH();
  RemeshOptions o;
  o.craterMaterial = 4242;
  Fixture f = fixture(*db, o);
  // A crater on a road, its support clear of every post (x at least 7 m
  // from a post column), 64 fine cells on the 30 m posts (0.47 m).
  const RoadPoint road = findRoad(*db, 7);
  const Crater c = craterAt(*f.heights, road.x, road.z, 64);
  ASSERT_FALSE(c.squares.empty());
  const auto report = f.modules->remesh({}, c.squares);
  ASSERT_TRUE(report.ok()) << report.error();
  EXPECT_EQ(report->refinedSquares, c.squares.size());
  for (const auto& [i, j] : c.squares) expectRefinedSquare(*f.heights, *f.modules, i, j);
  // The road's decal: clipped onto the fine surface, its area kept.
  const pack::IndexHeader& hd = f.modules->header();
  bool floor = false;
  for (const auto& [i, j] : c.squares) {
    const std::uint32_t sq = hd.moduleSquares, kx = i / sq, kz = j / sq;
    const module::Module m = readModule(*f.modules, kx, kz);
    const module::Module b = readModule(*f.pack, kx, kz);
    const std::uint32_t square = (j - kz * sq) * m.levels[0].squaresX + (i - kx * sq);
    const auto decal = squareTriangles(m.levels[0], square, false);
    const auto was = squareTriangles(b.levels[0], square, false);
    double area = 0, areaWas = 0, worst = 0;
    const auto r = f.heights->refined(i, j);
    const double s = f.heights->spacing();
    for (const Tri& t : decal) {
      area += upArea(t.v[0], t.v[1], t.v[2]);
      for (const module::Vertex& v : t.v) {
        const double fx = v.x / s - (i - kx * sq), fz = v.z / s - (j - kz * sq);
        bool inside = false;
        const double want = grid::refinedHeight(*r, fx, fz, inside);
        if (inside) worst = std::max(worst, std::fabs(v.y - want));
      }
    }
    for (const Tri& t : was) areaWas += upArea(t.v[0], t.v[1], t.v[2]);
    EXPECT_NEAR(area, areaWas, 1e-6 * s * s) << "decal area in square " << i << ", " << j;
    EXPECT_LE(worst, tolerance(m.levels[0])) << "decal off the fine surface in square " << i << ", " << j;
    for (const Tri& t : squareTriangles(m.levels[0], square, true)) floor = floor || t.material == 4242;
  }
  EXPECT_TRUE(floor) << "the crater's floor takes RemeshOptions::craterMaterial";
  // Coarser levels are re-draped and pass every check; level 0's refined
  // squares are what module_check cannot judge (its planes), so it is
  // checked above.
}

TEST(EditedModules, aCraterOnAModuleEdgeMeetsAcrossItWithSkirtsThroughTheFineEdge) {
  REQUIRE_BAYREUTH();
  Fixture f = fixture(*db);
  const pack::IndexHeader& hd = f.modules->header();
  const double s = f.heights->spacing();
  const std::uint32_t i = hd.moduleSquares, j = hd.moduleSquares / 2;  // modules (0, 0) and (1, 0)
  const Crater c = craterAt(*f.heights, i * s, (j + 0.5) * s, 64);
  ASSERT_EQ(c.squares.size(), 2u);
  const auto report = f.modules->remesh({}, c.squares);
  ASSERT_TRUE(report.ok()) << report.error();
  for (const auto& [a, b] : c.squares) expectRefinedSquare(*f.heights, *f.modules, a, b);
  // Module (0, 0)'s east skirt passes through the fine edge vertices.
  const module::Module m = readModule(*f.modules, 0, 0);
  const module::Level& l0 = m.levels[0];
  std::set<float> skirtTops, edge;
  for (const module::Group& g : l0.groups) {
    for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; ++k) {
      const module::Vertex& v = l0.vertices[l0.indices[k]];
      if (v.x != float(hd.moduleSize) || v.z <= j * s || v.z >= (j + 1) * s) continue;
      if (g.half == module::Half::skirt) {
        skirtTops.insert(v.z);
      } else if (g.priority == module::kPrioritySkin) {
        edge.insert(v.z);
      }
    }
  }
  EXPECT_GT(edge.size(), 10u);
  for (const float z : edge) EXPECT_TRUE(skirtTops.count(z)) << "no skirt through the edge vertex at z " << z;
  // Every skirt hangs below the crater's floor on the edge.
  const double floorY = f.heights->refined(i, j)->at(0, 32);
  for (const module::Level& l : m.levels) {
    EXPECT_LE(f.heights->elevation(i, j) - l.skirtDepth, floorY - 0.5) << "skirt depth " << l.skirtDepth;
  }
}

TEST(EditedModules, neighbourPatchesOfOtherCellsAndPatchesOnAnUnrefinedEdgeLeaveNoTJunction) {
  REQUIRE_BAYREUTH();
  Fixture f = fixture(*db);
  const pack::IndexHeader& hd = f.modules->header();
  const double s = f.heights->spacing();
  // Across a post column inside module (1, 1): the west square at 64 fine
  // cells, the east at 128, whose posts on the shared edge take the west
  // patch's line there (the overlay resamples so; refinedHeight is the rule).
  const std::uint32_t i = hd.moduleSquares + 10, j = hd.moduleSquares + 10;
  Crater c = craterAt(*f.heights, i * s, (j + 0.5) * s, 64);
  ASSERT_EQ(c.squares.size(), 2u);
  {
    grid::RefinedSquare east = *f.heights->refined(i, j);
    east.cells = 128;
    east.a0 *= 2, east.a1 *= 2, east.b0 *= 2, east.b1 *= 2;
    east.heights.clear();
    const auto west = f.heights->refined(i - 1, j);
    for (std::uint32_t b = east.b0; b <= east.b1; ++b) {
      for (std::uint32_t a = east.a0; a <= east.a1; ++a) {
        bool inside = false;
        const double y = a == 0 ? grid::refinedHeight(*west, 1.0, b / 128.0, inside)
                                : newHeight(c.e, (i + a / 128.0) * s, (j + b / 128.0) * s,
                                            terrain::planeHeight(a / 128.0, b / 128.0, double(f.heights->elevation(i, j)),
                                                                 double(f.heights->elevation(i + 1, j)),
                                                                 double(f.heights->elevation(i, j + 1)),
                                                                 double(f.heights->elevation(i + 1, j + 1))));
        east.heights.push_back(float(y));
      }
    }
    f.heights->refine(std::move(east));
  }
  // A patch grown to its square's west edge beside an unrefined square (its
  // posts there on the edge's line, as RefinedSquare says).
  const std::uint32_t pi = hd.moduleSquares + 20, pj = hd.moduleSquares + 4;
  const Crater alone = craterAt(*f.heights, (pi + 0.5) * s, (pj + 0.5) * s, 64);
  ASSERT_EQ(alone.squares.size(), 1u);
  {
    grid::RefinedSquare r = *f.heights->refined(pi, pj);
    grid::RefinedSquare g = r;
    g.a0 = 0;
    g.heights.clear();
    for (std::uint32_t b = g.b0; b <= g.b1; ++b) {
      for (std::uint32_t a = 0; a <= g.a1; ++a) {
        bool inside = false;
        const double y = grid::refinedHeight(r, a / 64.0, b / 64.0, inside);
        g.heights.push_back(inside ? float(y)
                                   : float(terrain::planeHeight(a / 64.0, b / 64.0, double(f.heights->elevation(pi, pj)),
                                                                double(f.heights->elevation(pi + 1, pj)),
                                                                double(f.heights->elevation(pi, pj + 1)),
                                                                double(f.heights->elevation(pi + 1, pj + 1)))));
      }
    }
    f.heights->refine(std::move(g));
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> squares = c.squares;
  squares.push_back({pi, pj});
  const auto report = f.modules->remesh({}, squares);
  ASSERT_TRUE(report.ok()) << report.error();
  EXPECT_EQ(report->refinedSquares, 3u);
  for (const auto& [a, b] : squares) expectRefinedSquare(*f.heights, *f.modules, a, b);
}

TEST(EditedModules, aCraterOnAPostMeshesItsDetailFineAndTheRestOfTheFourSquaresAsTheGroundBefore) {
  REQUIRE_BAYREUTH();
  // The overlay itself (heights.h): a crater on a post moves the post, so
  // the four squares round it are refined whole (their planes moved, the
  // ground away from the crater did not), and only the crater's box is
  // detail.
  auto heights = std::make_shared<EditedHeights>(grid::heightField(db->grid));
  auto pack = std::make_shared<paging::PackSource>(db->modules);
  EditedModules modules(pack, grid::heightField(db->grid), heights);
  const pack::IndexHeader& hd = modules.header();
  const double s = heights->spacing();
  const std::uint32_t pi = hd.moduleSquares + 10, pj = hd.moduleSquares + 11;  // inside module (1, 1)
  edit::Edit e;
  e.kind = edit::Kind::crater;
  e.points = {{pi * s, pj * s}};
  e.radius = kCraterMedium.radius;
  e.depth = kCraterMedium.depth;
  e.id = 1;
  const float before = heights->elevation(pi, pj);
  const auto change = heights->apply(e);
  ASSERT_TRUE(change.ok()) << change.error();
  EXPECT_NEAR(heights->elevation(pi, pj), before - e.depth, 1e-3);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> squares;
  for (const SquareIndex& q : change->squares) squares.emplace_back(q.i, q.j);
  ASSERT_EQ(squares.size(), 4u);
  const auto report = modules.remesh(change->posts, squares);
  ASSERT_TRUE(report.ok()) << report.error();
  EXPECT_EQ(report->modules, (std::vector<paging::ModuleKey>{{1, 1}}));
  const module::Module m = readModule(modules, 1, 1);
  std::size_t fineSquares = 0;
  for (const auto& [i, j] : squares) {
    const auto r = heights->refined(i, j);
    ASSERT_TRUE(r);
    EXPECT_EQ(std::tie(r->a0, r->b0, r->a1, r->b1), std::make_tuple(0u, 0u, r->cells, r->cells)) << "refined whole";
    const auto d = r->detail();
    EXPECT_LT((d[2] - d[0]) * (d[3] - d[1]), r->cells * r->cells / 4) << "the detail is the crater's box";
    fineSquares += std::size_t(d[2] - d[0]) * (d[3] - d[1]);
    // The drawn skin equals the overlay's surface at every fine post and
    // anywhere in the square; each side meets its neighbour.
    expectRefinedSquare(*heights, modules, i, j);
  }
  // The four squares' skin: the detail's fine triangles and a few dozen
  // rest triangles, not the whole squares' fine lattices.
  std::size_t tris = 0;
  for (const auto& [i, j] : squares) {
    const module::Level& l0 = m.levels[0];
    tris += squareTriangles(l0, (j - hd.moduleSquares) * l0.squaresX + (i - hd.moduleSquares), true).size();
  }
  EXPECT_LE(tris, 2 * fineSquares + 200);

  // A second crater on the next post east (two squares now hold two
  // craters' detail, one at each of their corners), then a large one the
  // posts carry (the patches ride on their planes' change): still exact.
  edit::Edit e2 = e;
  e2.id = 2;
  e2.points = {{(pi + 1) * s, pj * s}};
  edit::Edit e3 = e;
  e3.id = 3;
  e3.points = {{(pi + 2.5) * s, (pj + 0.5) * s}};
  e3.radius = 70;
  e3.depth = 3;
  std::set<std::pair<std::uint32_t, std::uint32_t>> all(squares.begin(), squares.end());
  for (const edit::Edit& next : {e2, e3}) {
    const auto c = heights->apply(next);
    ASSERT_TRUE(c.ok()) << c.error();
    std::vector<std::pair<std::uint32_t, std::uint32_t>> sq;
    for (const SquareIndex& q : c->squares) sq.emplace_back(q.i, q.j), all.insert({q.i, q.j});
    ASSERT_TRUE(modules.remesh(c->posts, sq).ok());
  }
  EXPECT_EQ(all.size(), 6u);
  for (const auto& [i, j] : all) expectRefinedSquare(*heights, modules, i, j);
}

TEST(EditedModules, coarserLevelsTakeACraterWhereItDepartsMoreThanTheirOwnError) {
  REQUIRE_BAYREUTH();
  RemeshOptions o;
  o.craterMaterial = 4242;
  Fixture f = fixture(*db, o);
  const pack::IndexHeader& hd = f.modules->header();
  const double s = f.heights->spacing();
  // The flattest 4 x 4 block of grid squares (a level-2 lattice square)
  // inside a module: its planes' error against the posts under it.
  auto error = [&](std::uint32_t gi, std::uint32_t gj, std::uint32_t span) {
    double e = 0;
    for (std::uint32_t z = 0; z <= span; ++z) {
      for (std::uint32_t x = 0; x <= span; ++x) {
        const double plane = terrain::planeHeight(double(x) / span, double(z) / span, double(f.heights->elevation(gi, gj)),
                                                  double(f.heights->elevation(gi + span, gj)),
                                                  double(f.heights->elevation(gi, gj + span)),
                                                  double(f.heights->elevation(gi + span, gj + span)));
        e = std::max(e, std::fabs(f.heights->elevation(gi + x, gj + z) - plane));
      }
    }
    return e;
  };
  std::uint32_t bi = 0, bj = 0;
  double best = 1e9;
  for (std::uint32_t gj = hd.moduleSquares; gj + 4 < 2 * hd.moduleSquares; gj += 4) {
    for (std::uint32_t gi = hd.moduleSquares; gi + 4 < 2 * hd.moduleSquares; gi += 4) {
      const double e = error(gi, gj, 4);
      if (e < best) best = e, bi = gi, bj = gj;
    }
  }
  ASSERT_LT(best, 1.0) << "no flat 120 m square in module (1, 1)";
  // A large crater (7.5 m, 2.5 m deep) in the block's second grid square,
  // its support (30 m) clear of the posts.
  edit::Edit e;
  e.kind = edit::Kind::crater;
  e.points = {{(bi + 1.5) * s, (bj + 1.5) * s}};
  e.radius = 6.0;
  e.depth = 2.0;
  const auto squares = test::craterPatches(*f.heights, e, 64);
  ASSERT_EQ(squares.size(), 1u);
  const auto report = f.modules->remesh({}, squares);
  ASSERT_TRUE(report.ok()) << report.error();
  const module::Module m = readModule(*f.modules, 1, 1);
  const auto r = f.heights->refined(bi + 1, bj + 1);
  // The patch's detail: its largest departure from its grid square's planes.
  double detail = 0;
  for (std::uint32_t b = r->b0; b <= r->b1; ++b) {
    for (std::uint32_t a = r->a0; a <= r->a1; ++a) {
      const double plane = terrain::planeHeight(double(a) / r->cells, double(b) / r->cells, double(f.heights->elevation(bi + 1, bj + 1)),
                                                double(f.heights->elevation(bi + 2, bj + 1)),
                                                double(f.heights->elevation(bi + 1, bj + 2)),
                                                double(f.heights->elevation(bi + 2, bj + 2)));
      detail = std::max(detail, std::fabs(double(r->at(a, b)) - plane));
    }
  }
  EXPECT_EQ(report->patchSquares[0], 1u);
  for (std::size_t l = 1; l < m.levels.size(); ++l) {
    const std::uint32_t span = 1u << l, gi = (bi + 1) / span * span, gj = (bj + 1) / span * span;
    EXPECT_EQ(report->patchSquares[l], error(gi, gj, span) < detail ? 1u : 0u) << "level " << l;
  }
  ASSERT_GE(report->patchSquares[2], 1u);
  for (std::size_t l = 1; l < m.levels.size(); ++l) {
    if (report->patchSquares[l] == 0) continue;
    SCOPED_TRACE("level " + std::to_string(l));
    const module::Level& lv = m.levels[l];
    const std::uint32_t span = 1u << l, gi = (bi + 1) / span * span, gj = (bj + 1) / span * span;
    const std::uint32_t sa = (gi - hd.moduleSquares) / span, sb = (gj - hd.moduleSquares) / span;
    const std::vector<Tri> skin = squareTriangles(lv, sb * lv.squaresX + sa, true);
    EXPECT_GT(skin.size(), 100u);
    const double x0 = sa * span * s, z0 = sb * span * s, side = span * s;
    // The level's planes plus the patch's detail, at every fine post of
    // the level's own lattice (the patch's, 2^level times coarser).
    auto planeQ = [&](double fx, double fz) {
      return terrain::planeHeight(fx, fz, double(f.heights->elevation(gi, gj)), double(f.heights->elevation(gi + span, gj)),
                                  double(f.heights->elevation(gi, gj + span)),
                                  double(f.heights->elevation(gi + span, gj + span)));
    };
    const double gx0 = (bi + 1) * s - hd.moduleSize, gz0 = (bj + 1) * s - hd.moduleSize;  // the grid square, module-local
    double worst = 0, deepest = 0;
    for (std::uint32_t b = r->b0; b <= r->b1; ++b) {
      for (std::uint32_t a = r->a0; a <= r->a1; ++a) {
        if (a % span != 0 || b % span != 0) continue;
        const double fx = double(a) / r->cells, fz = double(b) / r->cells;
        const double grid0 = terrain::planeHeight(fx, fz, double(f.heights->elevation(bi + 1, bj + 1)),
                                                  double(f.heights->elevation(bi + 2, bj + 1)),
                                                  double(f.heights->elevation(bi + 1, bj + 2)),
                                                  double(f.heights->elevation(bi + 2, bj + 2)));
        const double x = gx0 + fx * s, z = gz0 + fz * s;
        const double want = planeQ((x - x0) / side, (z - z0) / side) + (double(r->at(a, b)) - grid0);
        worst = std::max(worst, std::fabs(surfaceAt(skin, x, z) - want));
        deepest = std::min(deepest, double(r->at(a, b)) - grid0);
      }
    }
    EXPECT_LE(worst, tolerance(lv));
    EXPECT_LT(deepest, -1.5);
    // Each point of the square under exactly one triangle, the area whole,
    // and each side one edge from corner to corner (nothing beside it moved).
    double area = 0;
    for (const Tri& t : skin) area += upArea(t.v[0], t.v[1], t.v[2]);
    EXPECT_NEAR(area / (side * side), 1.0, 1e-6);
    std::mt19937_64 rng(l);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    int bad = 0;
    for (int k = 0; k < 400; ++k) {
      int holders = 0;
      surfaceAt(skin, x0 + unit(rng) * side, z0 + unit(rng) * side, &holders);
      bad += holders != 1;
    }
    EXPECT_EQ(bad, 0);
    for (const Tri& t : skin) {
      for (const module::Vertex& v : t.v) {
        const bool onSide = std::fabs(v.x - x0) < 1e-3 || std::fabs(v.x - (x0 + side)) < 1e-3 ||
                            std::fabs(v.z - z0) < 1e-3 || std::fabs(v.z - (z0 + side)) < 1e-3;
        const bool corner = (std::fabs(v.x - x0) < 1e-3 || std::fabs(v.x - (x0 + side)) < 1e-3) &&
                            (std::fabs(v.z - z0) < 1e-3 || std::fabs(v.z - (z0 + side)) < 1e-3);
        EXPECT_TRUE(!onSide || corner) << "a vertex on a side at " << v.x << ", " << v.z;
      }
    }
  }
  // The crater's floor takes its class on the coarse levels too, and an
  // object in it stands on every level's surface.
  edit::Edit add;
  add.kind = edit::Kind::addObject;
  add.points = e.points;
  add.icon = 0;
  ASSERT_TRUE(f.modules->editObject(add).ok());
  const module::Module withObject = readModule(*f.modules, 1, 1);
  const auto it = std::find_if(withObject.objects.begin(), withObject.objects.end(),
                               [](const module::Object& x) { return !module::isScattered(x.id) && x.icon == 0; });
  ASSERT_NE(it, withObject.objects.end());
  const std::size_t k = std::size_t(it - withObject.objects.begin());
  for (std::size_t l = 0; l < withObject.levels.size(); ++l) {
    const module::Level& lv = withObject.levels[l];
    const std::uint32_t span = 1u << l;
    const std::uint32_t sa = ((bi + 1) / span * span - hd.moduleSquares) / span, sb = ((bj + 1) / span * span - hd.moduleSquares) / span;
    const double ground = surfaceAt(squareTriangles(lv, sb * lv.squaresX + sa, true), it->x, it->z);
    EXPECT_NEAR(lv.objectY[k], ground, tolerance(lv)) << "level " << l;
  }
}

TEST(EditedModules, coarseSquaresTakingACraterAcrossAModuleEdgeCarryTheSameEdgeOnBothSides) {
  REQUIRE_BAYREUTH();
  Fixture f = fixture(*db);
  const pack::IndexHeader& hd = f.modules->header();
  const double s = f.heights->spacing();
  const std::uint32_t i = 2 * hd.moduleSquares;  // the edge between modules (1, 1) and (2, 1)
  auto error = [&](std::uint32_t gi, std::uint32_t gj, std::uint32_t span) {
    double e = 0;
    for (std::uint32_t z = 0; z <= span; ++z) {
      for (std::uint32_t x = 0; x <= span; ++x) {
        const double plane = terrain::planeHeight(double(x) / span, double(z) / span, double(f.heights->elevation(gi, gj)),
                                                  double(f.heights->elevation(gi + span, gj)),
                                                  double(f.heights->elevation(gi, gj + span)),
                                                  double(f.heights->elevation(gi + span, gj + span)));
        e = std::max(e, std::fabs(f.heights->elevation(gi + x, gj + z) - plane));
      }
    }
    return e;
  };
  // The flattest pair of level-1 squares either side of the edge.
  std::uint32_t bj = 0;
  double best = 1e9;
  for (std::uint32_t gj = hd.moduleSquares; gj + 2 < 2 * hd.moduleSquares; gj += 2) {
    const double e = std::max(error(i - 2, gj, 2), error(i, gj, 2));
    if (e < best) best = e, bj = gj;
  }
  edit::Edit e;
  e.kind = edit::Kind::crater;
  e.points = {{i * s, (bj + 0.5) * s}};
  e.radius = 6.0;
  e.depth = 2.0;
  const auto squares = test::craterPatches(*f.heights, e, 64);
  ASSERT_EQ(squares.size(), 2u);
  const auto report = f.modules->remesh({}, squares);
  ASSERT_TRUE(report.ok()) << report.error();
  if (best > 1.5) GTEST_SKIP() << "no flat pair of squares on the edge (error " << best << " m)";
  ASSERT_GE(report->patchSquares[1], 2u);
  const module::Module west = readModule(*f.modules, 1, 1), east = readModule(*f.modules, 2, 1);
  for (std::size_t l = 0; l < west.levels.size(); ++l) {
    const std::uint32_t span = 1u << l;
    const std::uint32_t sb = (bj / span * span - hd.moduleSquares) / span;
    // The shared side's skin vertices (z, y) on each module's side of it.
    auto side = [&](const module::Level& lv, std::uint32_t sa, float x) {
      std::set<std::pair<float, float>> out;
      for (const Tri& t : squareTriangles(lv, sb * lv.squaresX + sa, true)) {
        for (const module::Vertex& v : t.v) {
          if (v.x == x) out.insert({v.z, v.y});
        }
      }
      return out;
    };
    const auto a = side(west.levels[l], west.levels[l].squaresX - 1, float(hd.moduleSize));
    const auto b = side(east.levels[l], 0, 0.0f);
    EXPECT_EQ(a, b) << "level " << l;
    if (l <= 1) {
      EXPECT_GT(a.size(), 10u) << "level " << l << ": the fine edge";
    }
  }
}

// ------------------------------------------------------------ object edits

TEST(EditedModules, objectEditsArePublishedAndKeptThroughRemeshing) {
  REQUIRE_BAYREUTH();
  RemeshOptions o;
  o.iconCylinders = {{1.0f, 10.0f}, {2.0f, 5.0f}};
  Fixture f = fixture(*db, o);
  const pack::IndexHeader& hd = f.modules->header();
  edit::Edit add;
  add.kind = edit::Kind::addObject;
  add.points = {{1.5 * hd.moduleSize + 11, 1.5 * hd.moduleSize + 7}};
  add.icon = 1;
  add.heading = 1.0;
  add.scale = 2;
  ASSERT_TRUE(f.modules->editObject(add).ok());
  EXPECT_GT(f.modules->generation(1, 1), 0u);
  module::Module m = readModule(*f.modules, 1, 1);
  const auto it = std::find_if(m.objects.begin(), m.objects.end(), [](const module::Object& x) {
    return !module::isScattered(x.id) && x.icon == 1 && x.scale == 2.0f;
  });
  ASSERT_NE(it, m.objects.end());
  EXPECT_FLOAT_EQ(it->radius, 4.0f);
  EXPECT_FLOAT_EQ(it->x, float(0.5 * hd.moduleSize + 11));
  const std::uint64_t id = it->id;
  const module::ModuleChecker checker(*f.heights, hd, "edited");
  EXPECT_TRUE(checker.check(m, 0).ok()) << checker.check(m, 0).error();  // objectY on every level
  // Scale and switch it, then raise the ground under it: it rides up.
  edit::Edit scale;
  scale.kind = edit::Kind::scaleObject;
  scale.moduleX = scale.moduleZ = 1;
  scale.object = id;
  scale.scale = 1.5;
  ASSERT_TRUE(f.modules->editObject(scale).ok());
  edit::Edit sw = scale;
  sw.kind = edit::Kind::switchObject;
  sw.icon = 0;
  ASSERT_TRUE(f.modules->editObject(sw).ok());
  m = readModule(*f.modules, 1, 1);
  std::vector<float> baseY;
  for (const module::Level& l : m.levels) {
    baseY.push_back(l.objectY[std::size_t(std::find_if(m.objects.begin(), m.objects.end(),
                                                       [&](const module::Object& x) { return x.id == id; }) -
                                          m.objects.begin())]);
  }
  const grid::PostRect moved = bump(*f.heights, add.points[0][0], add.points[0][1], 90, 3);
  ASSERT_TRUE(f.modules->remesh(moved, {}).ok());
  m = readModule(*f.modules, 1, 1);
  const auto o2 = std::find_if(m.objects.begin(), m.objects.end(), [&](const module::Object& x) { return x.id == id; });
  ASSERT_NE(o2, m.objects.end());
  EXPECT_EQ(o2->icon, 0);
  EXPECT_FLOAT_EQ(o2->scale, 3.0f);
  EXPECT_FLOAT_EQ(o2->radius, 3.0f);   // icon 0's cylinder at scale 3
  EXPECT_FLOAT_EQ(o2->height, 30.0f);
  EXPECT_TRUE(checker.check(m, 0).ok()) << checker.check(m, 0).error();
  const std::size_t k = std::size_t(o2 - m.objects.begin());
  for (std::size_t l = 0; l < m.levels.size(); ++l) {
    EXPECT_GT(m.levels[l].objectY[k], baseY[l] + 1.0f) << "level " << l << ": the object rides up the bump";
  }
  // Remove it; an unknown object is refused.
  edit::Edit rm = scale;
  rm.kind = edit::Kind::removeObject;
  ASSERT_TRUE(f.modules->editObject(rm).ok());
  m = readModule(*f.modules, 1, 1);
  EXPECT_TRUE(std::none_of(m.objects.begin(), m.objects.end(), [&](const module::Object& x) { return x.id == id; }));
  EXPECT_FALSE(f.modules->editObject(rm).ok());
  edit::Edit crater;
  crater.kind = edit::Kind::crater;
  crater.points = {{10, 10}};
  crater.radius = 1;
  crater.depth = 1;
  EXPECT_FALSE(f.modules->editObject(crater).ok());
}

// ------------------------------------------------------------ generations

TEST(EditedModules, generationsAndChangesFollowTheModuleSourceContract) {
  REQUIRE_BAYREUTH();
  Fixture f = fixture(*db);
  const pack::IndexHeader& hd = f.modules->header();
  EXPECT_EQ(f.modules->changes(), 0u);
  const std::uint32_t ci = hd.moduleSquares + 5, cj = hd.moduleSquares + 5;  // inside module (1, 1)
  f.heights->set(ci, cj, f.heights->elevation(ci, cj) + 1);
  ASSERT_TRUE(f.modules->remesh({ci, cj, ci + 1, cj + 1}, {}).ok());
  EXPECT_EQ(f.modules->changes(), 1u);
  std::vector<paging::ModuleKey> changed;
  EXPECT_EQ(f.modules->changedSince(0, changed), 1u);
  ASSERT_EQ(changed.size(), 1u);
  EXPECT_EQ(changed[0], (paging::ModuleKey{1, 1}));
  const std::uint64_t g1 = f.modules->generation(1, 1);
  EXPECT_GT(g1, 0u);
  EXPECT_EQ(f.modules->generation(0, 1), 0u);
  module::Module m;
  EXPECT_EQ(f.modules->read(1, 1, m).value(), g1);
  EXPECT_EQ(f.modules->read(0, 1, m).value(), 0u);
  // Again: the generation grows, the log lists the module again.
  f.heights->set(ci, cj, f.heights->elevation(ci, cj) + 1);
  ASSERT_TRUE(f.modules->remesh({ci, cj, ci + 1, cj + 1}, {}).ok());
  EXPECT_GT(f.modules->generation(1, 1), g1);
  changed.clear();
  EXPECT_EQ(f.modules->changedSince(1, changed), 2u);
  EXPECT_EQ(changed, (std::vector<paging::ModuleKey>{{1, 1}}));
  // Coarse and fine reads together are the published module.
  module::Module split;
  const auto gc = f.modules->readCoarse(1, 1, split);
  ASSERT_TRUE(gc.ok());
  EXPECT_EQ(gc.value(), f.modules->generation(1, 1));
  ASSERT_TRUE(f.modules->readFine(1, 1, split).ok());
  const module::Module whole = readModule(*f.modules, 1, 1);
  ASSERT_EQ(split.levels.size(), whole.levels.size());
  for (std::size_t l = 0; l < whole.levels.size(); ++l) {
    EXPECT_EQ(split.levels[l].vertices.size(), whole.levels[l].vertices.size());
    EXPECT_EQ(split.levels[l].indices, whole.levels[l].indices);
  }
  EXPECT_FALSE(f.modules->missing(1, 1));
}

TEST(EditedModules, thePagerSwapsARebuiltModuleIn) {
  REQUIRE_BAYREUTH();
  Fixture f = fixture(*db);
  const pack::IndexHeader& hd = f.modules->header();
  paging::PagerOptions o;
  o.viewDistance = 2000;
  o.lookAheadScale = 0;
  o.log = [](const std::string&) {};
  auto opened = paging::Pager::open(db->grid, std::shared_ptr<const paging::ModuleSource>(f.modules), o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  paging::Pager& p = *opened.value();
  const double x = 1.5 * hd.moduleSize, z = 1.5 * hd.moduleSize;
  p.update(x, z, 0, 0, 0);
  ASSERT_TRUE(p.waitIdle(60));
  float before = 0;
  {
    const paging::ResidentRef r = p.resident(1, 1);
    ASSERT_TRUE(r);
    EXPECT_EQ(r.module().generation, 0u);
    before = r.level(0).vertices[0].y;
  }
  const std::uint32_t ci = hd.moduleSquares, cj = hd.moduleSquares;  // module (1, 1)'s north-west post
  f.heights->set(ci, cj, f.heights->elevation(ci, cj) + 3);
  ASSERT_TRUE(f.modules->remesh({ci, cj, ci + 1, cj + 1}, {}).ok());
  p.update(x, z, 0, 0, 1);
  ASSERT_TRUE(p.waitIdle(60));
  const paging::ResidentRef r = p.resident(1, 1);
  ASSERT_TRUE(r);
  EXPECT_EQ(r.module().generation, f.modules->generation(1, 1));
  // Onto the new post exactly: the base's rounding (the fixture's default
  // height step) goes.
  EXPECT_NEAR(r.level(0).vertices[0].y - before, 3.0, 0.5 * module::kDefaultHeightStep + 1e-4);
  EXPECT_GE(p.metrics().reloaded, 1u);
  EXPECT_EQ(p.metrics().holesInWindow, 0u);
}

}  // namespace
}  // namespace sandtable::edits
