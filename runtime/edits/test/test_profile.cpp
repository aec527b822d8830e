// The profiles against independent computations: volumes by numerical
// integration over a fine lattice (not the closed forms), and the shapes
// at hand-picked points.
#include <gtest/gtest.h>

#include <cmath>

#include "sandtable/edits/profile.h"

namespace sandtable::edits {
namespace {

edit::Edit crater(double x, double z, double radius, double depth) {
  edit::Edit e;
  e.kind = edit::Kind::crater;
  e.points = {{x, z}};
  e.radius = radius;
  e.depth = depth;
  return e;
}

TEST(Profile, craterDepthAndRimAtHandPoints) {
  const auto e = crater(10, 20, 3, 1.2);
  EXPECT_DOUBLE_EQ(newHeight(e, 10, 20, 100.0), 100.0 - 1.2);
  EXPECT_DOUBLE_EQ(newHeight(e, 13, 20, 100.0), 100.0 + 0.3);  // rim crest: a quarter of the depth
  EXPECT_DOUBLE_EQ(newHeight(e, 16, 20, 100.0), 100.0);       // the rim's outer foot
  EXPECT_DOUBLE_EQ(newHeight(e, 10, 27, 100.0), 100.0);
  const Box b = support(e);
  EXPECT_DOUBLE_EQ(b.x0, 4);
  EXPECT_DOUBLE_EQ(b.z1, 26);
}

TEST(Profile, craterVolumesMatchNumericalIntegration) {
  for (const CraterSize c : {kCraterSmall, kCraterMedium, kCraterLarge}) {
    const auto e = crater(0, 0, c.radius, c.depth);
    const double h = c.radius / 400.0;  // midpoint rule on a fine lattice
    double removed = 0, added = 0;
    const int n = int(std::ceil(kRimOuter * c.radius / h));
    for (int a = -n; a < n; ++a) {
      for (int b = -n; b < n; ++b) {
        const double d = newHeight(e, (a + 0.5) * h, (b + 0.5) * h, 0.0);
        (d < 0 ? removed : added) += std::abs(d) * h * h;
      }
    }
    EXPECT_NEAR(removed / craterVolumeRemoved(c.radius, c.depth), 1.0, 1e-3) << c.radius;
    EXPECT_NEAR(added / craterVolumeAdded(c.radius, c.depth), 1.0, 1e-3) << c.radius;
  }
}

TEST(Profile, bermAndDitchAreTrapezoids) {
  edit::Edit e;
  e.kind = edit::Kind::berm;
  e.points = {{0, 0}, {100, 0}};
  e.width = 2;
  e.height = 1.5;
  e.sideSlope = 0.5;
  EXPECT_DOUBLE_EQ(newHeight(e, 50, 0.9, 10), 11.5);        // on the crest
  EXPECT_DOUBLE_EQ(newHeight(e, 50, 2.0, 10), 11.0);        // 1 m down the side at 1:2
  EXPECT_DOUBLE_EQ(newHeight(e, 50, 4.0, 10), 10.0);        // the foot: 1 + 1.5 / 0.5
  EXPECT_DOUBLE_EQ(newHeight(e, 103, 0, 10), 10.0 + 0.5);   // round past the end
  e.kind = edit::Kind::ditch;
  EXPECT_DOUBLE_EQ(newHeight(e, 50, -0.5, 10), 8.5);
  EXPECT_DOUBLE_EQ(support(e).z1, 4.0);
}

TEST(Profile, flattenCutsAndFillsToTheSideSlope) {
  edit::Edit e;
  e.kind = edit::Kind::flatten;
  e.points = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  e.height = 50;
  e.sideSlope = 1;
  EXPECT_DOUBLE_EQ(newHeight(e, 5, 5, 40), 50);
  EXPECT_DOUBLE_EQ(newHeight(e, 12, 5, 40), 48);   // filled, 2 m out at 1:1
  EXPECT_DOUBLE_EQ(newHeight(e, 12, 5, 70), 52);   // cut
  EXPECT_DOUBLE_EQ(newHeight(e, 30, 5, 45), 45);   // beyond the slope's reach
  EXPECT_DOUBLE_EQ(flattenReach(e, 20), 20);
}

TEST(Profile, refinementFollowsTheFeatureSize) {
  const auto small = crater(0, 0, 3, 1.2);
  EXPECT_EQ(refineCells(small, 62.5), 128u);  // 0.49 m: "a 6 m crater on a 62.5 m database"
  EXPECT_EQ(refineCells(small, 30), 64u);     // 0.47 m
  EXPECT_EQ(refineCells(crater(0, 0, 40, 4), 30), 4u);  // 7.5 m <= 40 / 4
  EXPECT_EQ(refineCells(crater(0, 0, 60, 4), 30), 0u);  // two posts across: the posts carry it
}

TEST(Edit, checkNamesTheField) {
  auto e = crater(0, 0, -1, 1);
  EXPECT_EQ(edit::checkEdit(e), "edit: crater: Edit::radius must be > 0 (got -1)");
  e.radius = 1;
  EXPECT_EQ(edit::checkEdit(e), "");
  e.points.clear();
  EXPECT_EQ(edit::checkEdit(e), "edit: crater: Edit::points needs at least 1 (got 0)");
}

}  // namespace
}  // namespace sandtable::edits
