// The view triangle and the grid squares it selects (seed Figures 76-78),
// bounded below and above by a brute-force overlap test of every square.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <set>
#include <utility>

#include "sandtable/paging/view_triangle.h"

namespace sandtable::paging {
namespace {

constexpr double kTol = 1e-9;

ViewTriangleParams params(double x, double z, double heading, double half, double dist,
                          double pullback = 0) {
  ViewTriangleParams p;
  p.eyeX = x;
  p.eyeZ = z;
  p.headingDeg = heading;
  p.halfAngleDeg = half;
  p.viewDistance = dist;
  p.pullback = pullback;
  return p;
}

double cross(GroundPoint o, GroundPoint a, GroundPoint b) {
  return (a.x - o.x) * (b.z - o.z) - (a.z - o.z) * (b.x - o.x);
}

bool inside(const ViewTriangle& t, GroundPoint p) {
  const double d1 = cross(t.apex, t.left, p), d2 = cross(t.left, t.right, p),
               d3 = cross(t.right, t.apex, p);
  const bool neg = d1 < 0 || d2 < 0 || d3 < 0, pos = d1 > 0 || d2 > 0 || d3 > 0;
  return !(neg && pos);
}

std::set<std::pair<std::uint32_t, std::uint32_t>> asSet(const std::vector<RowSpan>& spans) {
  std::set<std::pair<std::uint32_t, std::uint32_t>> s;
  for (const auto& r : spans) {
    for (std::uint32_t i = r.firstI; i <= r.lastI; ++i) s.insert({i, r.j});
  }
  return s;
}

TEST(ViewTriangle, HeadingZeroLooksNorth) {
  const auto t = makeViewTriangle(params(1000, 1000, 0, 30, 100));
  const double side = 100 / std::cos(30 * 3.14159265358979323846 / 180);
  EXPECT_NEAR(t.apex.x, 1000, kTol);
  EXPECT_NEAR(t.apex.z, 1000, kTol);
  EXPECT_NEAR(t.left.x, 1000 - side * 0.5, 1e-6);  // west of the eye
  EXPECT_NEAR(t.left.z, 900, 1e-6);                // north is -Z
  EXPECT_NEAR(t.right.x, 1000 + side * 0.5, 1e-6);
  EXPECT_NEAR(t.right.z, 900, 1e-6);
}

TEST(ViewTriangle, HeadingNinetyLooksEast) {
  const auto t = makeViewTriangle(params(0, 0, 90, 45, 100));
  EXPECT_NEAR(t.left.x, 100, 1e-6);
  EXPECT_NEAR(t.left.z, -100, 1e-6);  // left of east is north
  EXPECT_NEAR(t.right.x, 100, 1e-6);
  EXPECT_NEAR(t.right.z, 100, 1e-6);
}

TEST(ViewTriangle, HeadingOneEightyAndTwoSeventy) {
  const auto s = makeViewTriangle(params(0, 0, 180, 30, 100));
  EXPECT_NEAR(s.left.z, 100, 1e-6);
  EXPECT_GT(s.left.x, 0);  // facing south, left is east
  const auto w = makeViewTriangle(params(0, 0, 270, 30, 100));
  EXPECT_NEAR(w.left.x, -100, 1e-6);
  EXPECT_GT(w.left.z, 0);  // facing west, left is south
}

TEST(ViewTriangle, ApexIsPulledBackOneSpacing) {
  const auto t = makeViewTriangle(params(500, 500, 90, 30, 1000, 30));
  EXPECT_NEAR(t.apex.x, 470, kTol);
  EXPECT_NEAR(t.apex.z, 500, kTol);
  // The triangle from the pulled-back apex still reaches the full distance
  // ahead of the eye.
  EXPECT_NEAR(t.left.x, 1500, 1e-6);
}

TEST(ViewTriangle, CoversTheFullViewDistanceSector) {
  const auto t = makeViewTriangle(params(0, 0, 37, 35, 1000, 10));
  for (double a = -35; a <= 35; a += 0.5) {
    const GroundPoint d = headingVector(37 + a);
    EXPECT_TRUE(inside(t, {d.x * 999.9, d.z * 999.9})) << a;
  }
}

TEST(ViewTriangle, FieldOfViewAngles) {
  EXPECT_NEAR(verticalFovDeg(90, 1.0), 90, 1e-9);
  EXPECT_NEAR(verticalFovDeg(60, 16.0 / 9.0), 36.0, 0.1);
  EXPECT_NEAR(groundHalfAngleDeg(60, 36, 0), 30, 1e-9);
  // Pitching down fans the bottom corners out on the ground.
  EXPECT_GT(groundHalfAngleDeg(60, 36, -10), 30.5);
  EXPECT_LE(groundHalfAngleDeg(90, 90, -80), 80.0);
}

TEST(ViewTriangle, BoundingBoxInSquares) {
  const auto t = makeViewTriangle(params(300, 300, 0, 30, 100));
  const auto b = boundingSquares(t, 10, 100, 100);
  EXPECT_EQ(b.minJ, 20);
  EXPECT_EQ(b.maxJ, 30);
  EXPECT_EQ(b.minI, 24);
  EXPECT_EQ(b.maxI, 35);
}

TEST(ViewTriangle, SelectsEverySquareWhoseCentreIsInside) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-200, 1200), head(0, 360), half(5, 60), dist(50, 900);
  const std::uint32_t nx = 90, nz = 70;
  const double s = 10;
  for (int trial = 0; trial < 200; ++trial) {
    const auto t = makeViewTriangle(params(pos(rng), pos(rng), head(rng), half(rng), dist(rng), s));
    for (const std::uint32_t grow : {0u, 1u}) {
      const auto chosen = asSet(selectSquares(t, s, nx, nz, grow));
      for (std::uint32_t j = 0; j < nz; ++j) {
        for (std::uint32_t i = 0; i < nx; ++i) {
          if (inside(t, {(i + 0.5) * s, (j + 0.5) * s})) {
            ASSERT_TRUE(chosen.count({i, j})) << "trial " << trial << " square " << i << "," << j;
          }
        }
      }
    }
  }
}

TEST(ViewTriangle, SelectsEverySquareTheTriangleTouches) {
  // Points spread over the triangle, edges included: the square under each
  // must be selected even without growing.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pos(0, 600), head(0, 360), u01(0, 1);
  const double s = 7;
  for (int trial = 0; trial < 100; ++trial) {
    const auto t = makeViewTriangle(params(pos(rng), pos(rng), head(rng), 20, 150));
    const auto chosen = asSet(selectSquares(t, s, 100, 100, 0));
    for (int k = 0; k < 400; ++k) {
      double a = u01(rng), b = u01(rng);
      if (k % 4 == 0) b = 0;  // on an edge
      if (a + b > 1) {
        a = 1 - a;
        b = 1 - b;
      }
      const double x = t.apex.x + a * (t.left.x - t.apex.x) + b * (t.right.x - t.apex.x);
      const double z = t.apex.z + a * (t.left.z - t.apex.z) + b * (t.right.z - t.apex.z);
      if (x < 0 || z < 0 || x >= 700 || z >= 700) continue;
      const auto i = std::uint32_t(x / s), j = std::uint32_t(z / s);
      ASSERT_TRUE(chosen.count({i, j})) << trial << " " << x << "," << z;
    }
  }
}

/// Brute force, independent of selectSquares' row scan: whether the closed
/// square (i, j) of side s and the closed triangle overlap, by the
/// separating axis theorem (the square's two axes and the triangle's three
/// edge normals suffice for two convex polygons). `slack` metres widen
/// (> 0) or narrow (< 0) the overlap test.
bool touches(const ViewTriangle& t, double s, std::int64_t i, std::int64_t j, double slack) {
  const GroundPoint tri[3] = {t.apex, t.left, t.right};
  const GroundPoint box[4] = {{double(i) * s, double(j) * s},
                              {double(i + 1) * s, double(j) * s},
                              {double(i) * s, double(j + 1) * s},
                              {double(i + 1) * s, double(j + 1) * s}};
  auto separated = [&](double ax, double az) {
    const double len = std::hypot(ax, az);
    if (len == 0) return false;
    ax /= len, az /= len;
    double tMin = INFINITY, tMax = -INFINITY, bMin = INFINITY, bMax = -INFINITY;
    for (const auto& p : tri) tMin = std::min(tMin, p.x * ax + p.z * az), tMax = std::max(tMax, p.x * ax + p.z * az);
    for (const auto& p : box) bMin = std::min(bMin, p.x * ax + p.z * az), bMax = std::max(bMax, p.x * ax + p.z * az);
    return tMax + slack < bMin || bMax + slack < tMin;
  };
  if (separated(1, 0) || separated(0, 1)) return false;
  for (int e = 0; e < 3; ++e) {
    const GroundPoint a = tri[e], b = tri[(e + 1) % 3];
    if (separated(-(b.z - a.z), b.x - a.x)) return false;
  }
  return true;
}

/// The squares of an nx x nz grid within `grow` squares (each way, corners
/// included) of a square the triangle touches; touching squares off the
/// grid count too, as their grown neighbours may be on it.
std::set<std::pair<std::uint32_t, std::uint32_t>> bruteForce(const ViewTriangle& t, double s, std::uint32_t nx,
                                                             std::uint32_t nz, std::uint32_t grow, double slack) {
  const std::int64_t g = grow;
  std::set<std::pair<std::uint32_t, std::uint32_t>> out;
  for (std::int64_t j = -g; j < std::int64_t(nz) + g; ++j) {
    for (std::int64_t i = -g; i < std::int64_t(nx) + g; ++i) {
      if (!touches(t, s, i, j, slack)) continue;
      for (std::int64_t dj = -g; dj <= g; ++dj) {
        for (std::int64_t di = -g; di <= g; ++di) {
          const std::int64_t a = i + di, b = j + dj;
          if (a >= 0 && b >= 0 && a < std::int64_t(nx) && b < std::int64_t(nz)) out.insert({a, b});
        }
      }
    }
  }
  return out;
}

TEST(ViewTriangle, SelectsNoSquareBeyondThoseTheGrownTriangleTouches) {
  // The upper bound (selecting every square passes the lower-bound tests
  // above): each selected square is within `grow` squares of one the
  // triangle touches, counted by brute force. The allowed margin is 1 µm of
  // slack in the touch test, for the rounding of the vertices divided by
  // the spacing; the lower bound is checked with the slack the other way,
  // so the selection is the touched set, grown, to within that margin.
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> pos(-200, 1100), head(0, 360), half(5, 60), dist(20, 700);
  const std::uint32_t nx = 90, nz = 70;
  const double s = 10, margin = 1e-6;
  std::size_t selected = 0, grid = 0;
  for (int trial = 0; trial < 150; ++trial) {
    const auto t = makeViewTriangle(params(pos(rng), pos(rng), head(rng), half(rng), dist(rng), s));
    for (const std::uint32_t grow : {0u, 1u, 2u}) {
      const auto chosen = asSet(selectSquares(t, s, nx, nz, grow));
      const auto upper = bruteForce(t, s, nx, nz, grow, margin);
      const auto lower = bruteForce(t, s, nx, nz, grow, -margin);
      for (const auto& sq : chosen) {
        ASSERT_TRUE(upper.count(sq)) << "trial " << trial << " grow " << grow << ": square " << sq.first << ","
                                     << sq.second << " is selected but the triangle does not come near it";
      }
      for (const auto& sq : lower) {
        ASSERT_TRUE(chosen.count(sq)) << "trial " << trial << " grow " << grow << ": square " << sq.first << ","
                                      << sq.second << " is touched but not selected";
      }
      selected += chosen.size();
      grid += std::size_t(nx) * nz;
    }
  }
  // The trials are not all whole-grid views, or the bound would prove little.
  EXPECT_LT(selected, grid / 2);
}

TEST(ViewTriangle, GrowingAddsOneSquareEachWay) {
  const auto t = makeViewTriangle(params(500, 500, 20, 25, 300, 10));
  const auto tight = asSet(selectSquares(t, 10, 100, 100, 0));
  const auto grown = asSet(selectSquares(t, 10, 100, 100, 1));
  for (const auto& [i, j] : tight) {
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        EXPECT_TRUE(grown.count({i + di, j + dj})) << i + di << "," << j + dj;
      }
    }
  }
  EXPECT_GT(grown.size(), tight.size());
}

TEST(ViewTriangle, SpansAreOnePerRowWithinTheGrid) {
  const auto t = makeViewTriangle(params(200, 200, 45, 30, 5000, 10));
  const auto spans = selectSquares(t, 10, 64, 48);
  ASSERT_FALSE(spans.empty());
  for (std::size_t k = 0; k < spans.size(); ++k) {
    EXPECT_LE(spans[k].firstI, spans[k].lastI);
    EXPECT_LT(spans[k].lastI, 64u);
    EXPECT_LT(spans[k].j, 48u);
    if (k > 0) {
      EXPECT_GT(spans[k].j, spans[k - 1].j);
    }
  }
}

TEST(ViewTriangle, PartlyOutsideIsClipped) {
  // Eye near the west edge looking west: most of the triangle is off the
  // grid; only the wedge near the apex remains.
  const auto t = makeViewTriangle(params(25, 500, 270, 30, 2000, 10));
  const auto spans = selectSquares(t, 10, 100, 100);
  ASSERT_FALSE(spans.empty());
  for (const auto& r : spans) {
    EXPECT_LE(r.lastI, 4u);  // only the squares west of the apex, grown by one
    EXPECT_LT(r.j, 100u);
  }
  EXPECT_LE(spans.front().j, 50u);
  EXPECT_GE(spans.back().j, 50u);
}

TEST(ViewTriangle, RunningOffTheNorthEdgeIsClipped) {
  const auto t = makeViewTriangle(params(500, 100, 0, 30, 2000, 10));
  const auto spans = selectSquares(t, 10, 100, 100);
  ASSERT_FALSE(spans.empty());
  EXPECT_EQ(spans.front().j, 0u);  // cut by the north edge
  EXPECT_EQ(spans.back().j, 12u);  // apex at z = 110 touches row 11; grown by one
  EXPECT_GT(spans.front().squares(), spans.back().squares());
  for (const auto& r : spans) EXPECT_LT(r.lastI, 100u);
}

TEST(ViewTriangle, EntirelyOutsideSelectsNothing) {
  const auto t = makeViewTriangle(params(-500, -500, 315, 30, 300, 10));
  EXPECT_TRUE(selectSquares(t, 10, 100, 100).empty());
  EXPECT_TRUE(boundingSquares(t, 10, 100, 100).empty());
}

TEST(ViewTriangle, CountsSquares) {
  const std::vector<RowSpan> spans = {{0, 2, 4}, {1, 0, 0}};
  EXPECT_EQ(countSquares(spans), 4u);
}

}  // namespace
}  // namespace sandtable::paging
