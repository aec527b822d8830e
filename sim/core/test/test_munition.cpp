// Munitions: the binary-search terrain impact (Figure 27) against the
// analytic intersection with a plane, the swept volumes (Figure 59) against
// hand-worked segments, ballistic flight against the parabola.
#include <gtest/gtest.h>

#include <cmath>

#include "sandtable/sim/munition.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

TEST(Munition, terrainImpactIsTheSegmentsCrossingOfTheSurfaceWithinOneCentimetre) {
  const double gx = 0.2, gz = -0.1;
  auto w = test::makeWorld([=](double x, double z) { return 100 + gx * x + gz * z; });
  const Eigen::Vector3d a(500, 400, 700), b(530, 100, 690);
  // Independent: solve a.y + t (b.y - a.y) = 100 + gx x(t) + gz z(t).
  auto f = [&](double t) {
    const Eigen::Vector3d p = a + (b - a) * t;
    return p.y() - (100 + gx * p.x() + gz * p.z());
  };
  const double t = f(0) / (f(0) - f(1));  // f is linear in t on a plane
  const Eigen::Vector3d want = a + (b - a) * t;
  auto hit = terrainImpact(*w, a, b);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->x(), want.x(), 0.01);
  EXPECT_NEAR(hit->z(), want.z(), 0.01);
  EXPECT_NEAR(hit->y(), want.y(), 0.01);
  EXPECT_FALSE(terrainImpact(*w, a, a + Eigen::Vector3d(10, 0, 0)));  // stays above
}

TEST(Munition, sweptVolumesCatchWhatAPointTestAtEachEndWouldMiss) {
  // A 20 m step straight through a 1 m tree trunk: both ends are outside it.
  const Eigen::Vector3d a(90, 5, 100), b(110, 5, 100);
  auto t = sweptHitsCylinder(a, b, 0.2, 100, 100, 1, 0, 15);
  ASSERT_TRUE(t);
  EXPECT_NEAR(*t, (10 - 1.2) / 20, 1e-9);
  EXPECT_FALSE(sweptHitsCylinder(a + Eigen::Vector3d(0, 20, 0), b + Eigen::Vector3d(0, 20, 0), 0.2, 100, 100, 1, 0,
                                 15));  // passes over the top
  EXPECT_FALSE(sweptHitsCylinder(a, b, 0.2, 100, 102, 1, 0, 15));  // passes beside it
  // Diving in through the top: enters the vertical range at y = 15.2.
  auto top = sweptHitsCylinder({100, 25, 100}, {100, 5, 100}, 0.2, 100, 100, 1, 0, 15);
  ASSERT_TRUE(top);
  EXPECT_NEAR(*top, (25 - 15.2) / 20, 1e-9);
  auto s = sweptHitsSphere(a, b, 2, {100, 5, 101});
  ASSERT_TRUE(s);
  EXPECT_NEAR(*s, (10 - std::sqrt(3.0)) / 20, 1e-9);
  EXPECT_FALSE(sweptHitsSphere(a, b, 2, {100, 5, 103}));
}

TEST(Munition, ballisticFlightFollowsTheParabola) {
  Entity m;
  m.position = {0, 0, 0};
  m.velocity = {100, 100, 0};
  const MunitionType& round = builtinMunitions()[1];
  ASSERT_FALSE(round.guided);
  const double dt = 1.0 / 60;
  for (int k = 0; k < 600; ++k) stepMunition(m, round, std::nullopt, dt);
  const double t = 10;
  // Semi-implicit Euler: y = v0 t - g t^2 / 2 - g t dt / 2.
  EXPECT_NEAR(m.position.x(), 1000, 1e-9);
  EXPECT_NEAR(m.position.y(), 100 * t - kGravity * t * t / 2 - kGravity * t * dt / 2, 1e-6);
}

TEST(Munition, guidedMissilesTurnAtTheirLimitAndReachTheTarget) {
  Entity m;
  m.position = {0, 100, 0};
  const MunitionType& missile = builtinMunitions()[0];
  ASSERT_TRUE(missile.guided);
  m.velocity = {0, 0, -missile.speedMs};  // north
  const Eigen::Vector3d target(2000, 100, 0);  // due east
  const double dt = 1.0 / 60;
  Eigen::Vector3d before = m.velocity;
  stepMunition(m, missile, target, dt);
  const double turned = std::acos(before.normalized().dot(m.velocity.normalized())) * kRadToDeg;
  EXPECT_NEAR(turned, missile.turnRateDegS * dt, 1e-6);
  double closest = 1e9;
  for (int k = 0; k < 60 * 20; ++k) {
    stepMunition(m, missile, target, dt);
    closest = std::min(closest, (m.position - target).norm());
  }
  EXPECT_LT(closest, 5.0);
}

}  // namespace
}  // namespace sandtable::sim
