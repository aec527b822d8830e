// Land and sea motion against closed forms: the projected-point attitude on
// tilted planes, a = F/m - g sin(theta) - resist g cos(theta) integrated as
// v0 + a t, the stick angle, and Figure 54's turning radius.
#include <gtest/gtest.h>

#include <cmath>

#include "sandtable/sim/motion.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

constexpr double kDt = 1.0 / 60.0;

/// A plane y = 100 + gx x + gz z (x east, z south).
std::shared_ptr<SimWorld> plane(double gx, double gz) {
  return test::makeWorld([=](double x, double z) { return 100 + gx * x + gz * z; });
}

Entity tank(double x, double z, double heading) {
  Entity e;
  e.mobility = Mobility::tracked;
  e.position = {x, 0, z};
  e.headingDeg = heading;
  e.halfLength = 3.5;
  e.halfWidth = 1.7;
  e.vehicle.powerW = 1e15;  // the force stays constant at every speed
  return e;
}

/// Puts the entity on the ground with its projected-point attitude.
void place(const SimWorld& w, Entity& e) {
  auto a = projectedPointAttitude(w, e.position.x(), e.position.z(), e.headingDeg, e.halfLength, e.halfWidth);
  ASSERT_TRUE(a);
  e.position.y() = a->groundY;
  e.pitchDeg = a->pitchDeg;
  e.rollDeg = a->rollDeg;
}

TEST(Motion, projectedPointPitchAndRollAreTheSlopesOfATiltedPlane) {
  const double gx = 0.12, gz = -0.05;
  auto w = plane(gx, gz);
  for (double h : {0.0, 30.0, 90.0, 135.0, 200.0, 290.0}) {
    const double hr = h * kDegToRad;
    // Independent: the plane's gradient along the forward (sin h, -cos h)
    // and right (cos h, sin h) horizontal directions.
    const double along = gx * std::sin(hr) - gz * std::cos(hr);
    const double across = gx * std::cos(hr) + gz * std::sin(hr);
    auto a = projectedPointAttitude(*w, 1000, 1000, h, 3.5, 1.7);
    ASSERT_TRUE(a);
    EXPECT_NEAR(a->pitchDeg, std::atan(along) * kRadToDeg, 1e-4) << h;
    EXPECT_NEAR(a->rollDeg, -std::atan(across) * kRadToDeg, 1e-4) << h;
    EXPECT_NEAR(a->groundY, 100 + gx * 1000 + gz * 1000, 1e-3);
  }
}

TEST(Motion, underAConstantForceTheSpeedFollowsVPlusATUphillDownhillAndLevel) {
  const double slope = 0.1;  // rising to the north: y = 100 - 0.1 z
  auto w = plane(0, -slope);
  const double theta = std::atan(slope);
  for (double heading : {0.0, 180.0, 90.0}) {  // uphill, downhill, level
    Entity e = tank(1000, 1500, heading);
    place(*w, e);
    // The force that holds speed on level firm ground: resist * m * g.
    const double hold = materials::kDefaultResist * e.vehicle.massKg * kGravity;
    e.controls.leftTrack = e.controls.rightTrack = hold / e.vehicle.maxForceN;
    e.speedMs = 10;
    const double pitch = heading == 0 ? theta : heading == 180 ? -theta : 0.0;
    const double a = hold / e.vehicle.massKg - kGravity * std::sin(pitch) -
                     materials::kDefaultResist * kGravity * std::cos(pitch);
    const int steps = 120;
    for (int k = 0; k < steps; ++k) ASSERT_TRUE(stepSurface(*w, e, kDt));
    EXPECT_NEAR(e.speedMs, 10 + a * steps * kDt, 1e-6) << heading;
    if (heading == 0) {
      EXPECT_LT(e.speedMs, 10 - 1.0);  // slows going uphill
    } else if (heading == 180) {
      EXPECT_GT(e.speedMs, 10 + 1.0);  // speeds up going downhill
    } else {
      EXPECT_NEAR(e.speedMs, 10, 1e-9);  // holds it on the level
    }
    EXPECT_NEAR(e.headingDeg, heading, 1e-9);
  }
}

TEST(Motion, withNoForceFrictionStopsTheEntityAndNeverReversesIt) {
  auto w = plane(0, 0);
  Entity e = tank(1000, 1000, 45);
  place(*w, e);
  e.speedMs = 5;
  const double stopS = 5 / (materials::kDefaultResist * kGravity);
  for (int k = 0; k < int(stopS / kDt) - 2; ++k) stepSurface(*w, e, kDt);
  EXPECT_GT(e.speedMs, 0);
  for (int k = 0; k < 120; ++k) stepSurface(*w, e, kDt);
  EXPECT_EQ(e.speedMs, 0);
}

TEST(Motion, atRestAnEntitySlidesOnlyOnSlopesSteeperThanTheStickAngle) {
  for (double deg : {20.0, 29.0, 31.0, 40.0}) {
    auto w = plane(0, -std::tan(deg * kDegToRad));
    Entity e = tank(1000, 1000, 0);  // facing uphill
    e.halfLength = 1;  // keeps the projected points on the plane
    place(*w, e);
    for (int k = 0; k < 60; ++k) stepSurface(*w, e, kDt);
    if (deg < materials::kDefaultStickDeg) {
      EXPECT_EQ(e.speedMs, 0) << deg;
    } else {
      // Sliding backwards, downhill, at g sin - resist g cos.
      const double a = kGravity * std::sin(deg * kDegToRad) -
                       materials::kDefaultResist * kGravity * std::cos(deg * kDegToRad);
      EXPECT_NEAR(e.speedMs, -a * 60 * kDt, 1e-4) << deg;  // float posts
    }
  }
}

TEST(Motion, wheeledTurningRadiusIsFigure54s) {
  // By hand: d = 2, alpha = 30: 2d / tan(alpha) = 6.9282; sqrt(48 + 4) = 7.2111.
  EXPECT_NEAR(turningRadius(2, 30), std::sqrt(52.0), 1e-9);
  EXPECT_TRUE(std::isinf(turningRadius(2, 0)));
  auto w = plane(0, 0);
  for (double steer : {0.5, 1.0, -0.7}) {
    Entity e = tank(1000, 1000, 0);
    e.mobility = Mobility::wheeled;
    e.halfLength = 2.5;
    place(*w, e);
    e.speedMs = 6;
    e.controls.throttle = materials::kDefaultResist * e.vehicle.massKg * kGravity / e.vehicle.maxForceN;
    e.controls.steer = steer;
    const double alpha = steer * e.vehicle.steerLimitDeg;
    const double rho = std::sqrt(std::pow(2 * 2.5 / std::tan(std::abs(alpha) * kDegToRad), 2) + 2.5 * 2.5);
    // One full circle: the centre is the mean of points evenly spaced on it.
    const int steps = int(std::round(2 * M_PI * rho / 6 / kDt));
    Eigen::Vector2d sum(0, 0);
    std::vector<Eigen::Vector2d> pts;
    for (int k = 0; k < steps; ++k) {
      stepSurface(*w, e, kDt);
      pts.emplace_back(e.position.x(), e.position.z());
      sum += pts.back();
    }
    const Eigen::Vector2d centre = sum / double(steps);
    double r = 0;
    for (const auto& p : pts) r += (p - centre).norm();
    r /= double(steps);
    EXPECT_NEAR(r, rho, 0.01 * rho) << steer;
    // Turning right (positive steer) puts the centre to the east of the start.
    EXPECT_EQ(centre.x() > 1000, steer > 0) << steer;
  }
}

TEST(Motion, trackedEqualTracksGoStraightUnequalTurnToTheWeakerSide) {
  auto w = plane(0, 0);
  Entity e = tank(1000, 1000, 0);
  place(*w, e);
  e.controls.leftTrack = e.controls.rightTrack = 0.2;
  for (int k = 0; k < 120; ++k) stepSurface(*w, e, kDt);
  EXPECT_NEAR(e.headingDeg, 0, 1e-9);
  EXPECT_NEAR(e.position.x(), 1000, 1e-6);
  e.controls.rightTrack = 0.05;  // weaker right track: turns right
  for (int k = 0; k < 60; ++k) stepSurface(*w, e, kDt);
  EXPECT_GT(e.headingDeg, 1);
  EXPECT_LT(e.headingDeg, 90);
  // Pivot: equal and opposite tracks turn in place at the turn-rate limit.
  Entity p = tank(1000, 1000, 0);
  place(*w, p);
  p.controls.leftTrack = 1;
  p.controls.rightTrack = -1;
  for (int k = 0; k < 600; ++k) stepSurface(*w, p, kDt);
  EXPECT_NEAR(p.position.x(), 1000, 1e-6);
  EXPECT_NEAR(-p.angularVelocity.y() * kRadToDeg, p.vehicle.turnRateDegS, 0.01 * p.vehicle.turnRateDegS);
}

TEST(Motion, simpleControlIsFirstOrderInSpeedAndTurnsAtTheTurnRate) {
  auto w = plane(0.05, 0);
  Entity e = tank(1000, 1000, 0);
  e.mobility = Mobility::simple;
  place(*w, e);
  e.commands.speedMs = 8;
  e.commands.headingDeg = 90;
  stepSurface(*w, e, kDt);
  EXPECT_EQ(e.speedMs, 8);  // Table 5: the speed is the input
  EXPECT_NEAR(e.headingDeg, e.vehicle.turnRateDegS * kDt, 1e-9);
  for (int k = 0; k < 600; ++k) stepSurface(*w, e, kDt);
  EXPECT_NEAR(e.headingDeg, 90, 1e-9);
  const auto g = w->groundAt(e.position.x(), e.position.z());
  EXPECT_NEAR(e.position.y(), *g, 1e-9);  // on the drawn surface
}

TEST(Motion, shipsStopWhereTheBowWouldReachLand) {
  // Sea (elevation -5) west of x = 1000, land (+20) east of it.
  auto w = test::makeWorld([](double x, double) { return x < 1000 ? -5.0 : 20.0; });
  Entity s;
  s.domain = Domain::sea;
  s.mobility = Mobility::ship;
  s.position = {500, 0, 1000};
  s.headingDeg = s.commands.headingDeg = 90;
  s.commands.speedMs = 10;
  s.halfLength = 12;
  for (int k = 0; k < 60 * 120; ++k) stepSurface(*w, s, kDt);
  EXPECT_TRUE(w->navigable(s.position.x(), s.position.z()));
  EXPECT_LT(s.position.x() + s.halfLength, 1000);
  EXPECT_EQ(s.speedMs, 0);
  EXPECT_EQ(s.pitchDeg, 0);
  EXPECT_EQ(s.rollDeg, 0);
}

}  // namespace
}  // namespace sandtable::sim

namespace sandtable::sim {
namespace {

TEST(Motion, secondOrderControlIntegratesAccelerationAndAngularAcceleration) {
  auto w = test::makeWorld([](double, double) { return 5.0; });
  Entity e;
  e.position = {1000, 0, 1000};
  e.commands.order = 2;
  e.commands.accelerationMs2 = 1.5;
  e.commands.turnAccelerationDegS2 = 2;
  const double dt = 1.0 / 60;
  for (int k = 0; k < 120; ++k) ASSERT_TRUE(stepSurface(*w, e, dt));
  EXPECT_NEAR(e.speedMs, 1.5 * 2, 1e-9);
  EXPECT_NEAR(-e.angularVelocity.y() * kRadToDeg, 2 * 2, 1e-9);
  // Heading: the sum of rates k * a * dt over the steps, times dt.
  EXPECT_NEAR(e.headingDeg, 2 * dt * dt * 120 * 121 / 2, 1e-9);
  e.commands.turnAccelerationDegS2 = 100;  // the rate stops at the vehicle's limit
  for (int k = 0; k < 120; ++k) stepSurface(*w, e, dt);
  EXPECT_NEAR(-e.angularVelocity.y() * kRadToDeg, e.vehicle.turnRateDegS, 1e-9);
}

}  // namespace
}  // namespace sandtable::sim

namespace sandtable::sim {
namespace {

TEST(Motion, theAutopilotHoldsItsSpeedDownASteepSlopeBecauseBrakesAreNotPowerLimited) {
  EXPECT_EQ(propulsiveForce(VehicleParams{}, -1, 20), -VehicleParams{}.maxForceN);  // braking
  EXPECT_NEAR(propulsiveForce(VehicleParams{}, 1, 20), VehicleParams{}.powerW / 20, 1e-9);
  auto w = test::makeWorld([](double, double z) { return 500 + 0.47 * z; });  // 25 degrees down to the north
  Entity e;
  e.mobility = Mobility::tracked;
  e.position = {1000, 0, 1500};
  e.halfLength = 3.5;
  e.halfWidth = 1.7;
  e.commands = {15, 0, 0};  // at 15 m/s the engine's power gives 73 kN, too little to hold a tank on 25 degrees
  e.speedMs = 15;
  const double dt = 1.0 / 60;
  for (int k = 0; k < 60 * 30; ++k) {
    landAutopilot(e);
    ASSERT_TRUE(stepSurface(*w, e, dt));
  }
  EXPECT_NEAR(e.speedMs, 15, 1.0);
}

}  // namespace
}  // namespace sandtable::sim
