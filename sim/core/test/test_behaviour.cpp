// The reactive behaviours (seed VIII.A): zig-zag statistics over many legs
// against Figure 68's distribution, the edge of the world and its placement
// fix, environment limits, fight-or-flight headings (Figure 70).
#include <gtest/gtest.h>

#include <cmath>

#include "sandtable/sim/behaviour.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

TEST(Behaviour, zigzagLegsLastTTo2TAndTurnsAreUniformWithin45Degrees) {
  BehaviourOptions o;
  o.zigzagPeriodS = 10;
  Entity e;
  e.commands.speedMs = 4;
  std::uint64_t counter = 0;
  double now = 0, legSum = 0, turnSum = 0, absSum = 0;
  double minTurn = 1e9, maxTurn = -1e9;
  int left = 0, legs = 20000;
  e.nextTurnS = 0;
  for (int k = 0; k < legs; ++k) {
    now = e.nextTurnS;
    const double before = e.nextTurnS;
    const double turn = zigzag(e, now, 99, counter, o);
    const double leg = e.nextTurnS - now;
    ASSERT_GE(leg, o.zigzagPeriodS);
    ASSERT_LE(leg, 2 * o.zigzagPeriodS);
    ASSERT_GT(e.nextTurnS, before);
    legSum += leg;
    turnSum += turn;
    absSum += std::abs(turn);
    minTurn = std::min(minTurn, turn);
    maxTurn = std::max(maxTurn, turn);
    left += turn < 0;
  }
  // Figure 68 with u uniform: E[leg] = 2T - (T - v)^2 / (2T) = 20 - 36/20.
  EXPECT_NEAR(legSum / legs, 20 - 1.8, 0.1);
  EXPECT_NEAR(turnSum / legs, 0, 0.6);
  EXPECT_NEAR(absSum / legs, 22.5, 0.5);
  EXPECT_GE(minTurn, -45);
  EXPECT_LE(maxTurn, 45);
  EXPECT_LT(minTurn, -44);
  EXPECT_GT(maxTurn, 44);
  EXPECT_NEAR(double(left) / legs, 0.5, 0.02);
}

TEST(Behaviour, zigzagWaitsForTheLegAndForSpeed) {
  BehaviourOptions o;
  Entity e;
  e.commands.speedMs = 10;
  e.nextTurnS = 5;
  std::uint64_t counter = 0;
  EXPECT_EQ(zigzag(e, 4.9, 1, counter, o), 0);
  EXPECT_EQ(counter, 0u);
  e.commands.speedMs = 0.5;  // Figure 68: slower than 1 m/s never zig-zags
  EXPECT_EQ(zigzag(e, 6, 1, counter, o), 0);
  // Faster entities keep longer legs: at v >= T every leg is 2T.
  EXPECT_EQ(zigzagLegS(0.99, 10, o), 20);
  EXPECT_EQ(zigzagLegS(0.0, 0, o), 20);
  EXPECT_EQ(zigzagLegS(0.99, 0, o), 20 - 9.9);
}

TEST(Behaviour, edgeOfTheWorldReversesTheOutwardComponent) {
  auto w = test::makeWorld([](double, double) { return 10.0; });  // 2000 m square
  BehaviourOptions o;
  Entity e;
  e.commands.speedMs = 5;
  e.position = {1000, 10, 100};  // in the north buffer
  e.commands.headingDeg = 0;     // heading out (north)
  EXPECT_TRUE(edgeOfWorld(*w, e, o));
  EXPECT_NEAR(e.commands.headingDeg, 180, 1e-9);
  EXPECT_FALSE(edgeOfWorld(*w, e, o));  // already heading in
  e.position = {1950, 10, 1000};       // east buffer, heading north-east
  e.commands.headingDeg = 45;
  EXPECT_TRUE(edgeOfWorld(*w, e, o));
  EXPECT_NEAR(e.commands.headingDeg, 315, 1e-9);
  e.position = {30, 10, 30};            // north-west corner, heading north-west
  e.commands.headingDeg = 315;
  EXPECT_TRUE(edgeOfWorld(*w, e, o));
  EXPECT_NEAR(e.commands.headingDeg, 135, 1e-9);
  e.position = {1000, 10, 1000};
  EXPECT_FALSE(edgeOfWorld(*w, e, o));
}

TEST(Behaviour, entitiesStartingInTheBufferAreMovedJustOutsideWithTheirMotionKept) {
  auto w = test::makeWorld([](double, double) { return 10.0; });
  BehaviourOptions o;
  Entity e;
  e.position = {10, 10, 1900};
  e.headingDeg = 33;
  e.speedMs = 7;
  ASSERT_TRUE(placeOutsideBuffer(*w, e, o));
  EXPECT_NEAR(e.position.x(), o.edgeBufferM + 1, 1e-9);
  EXPECT_NEAR(e.position.z(), w->depthM() - o.edgeBufferM - 1, 1e-9);
  EXPECT_EQ(e.headingDeg, 33);
  EXPECT_EQ(e.speedMs, 7);
  EXPECT_FALSE(placeOutsideBuffer(*w, e, o));
}

TEST(Behaviour, shipsTurnBackAtLandAndLandEntitiesAtWater) {
  auto w = test::makeWorld([](double x, double) { return x < 1000 ? -5.0 : 20.0; });
  BehaviourOptions o;
  Entity ship;
  ship.domain = Domain::sea;
  ship.position = {975, 0, 1000};
  ship.commands = {10, 90, 0};
  EXPECT_TRUE(environmentLimit(*w, ship, o));
  EXPECT_NEAR(ship.commands.headingDeg, 270, 1e-9);
  EXPECT_FALSE(environmentLimit(*w, ship, o));
  Entity tank;
  tank.position = {1015, 20, 1000};
  tank.commands = {10, 270, 0};
  EXPECT_TRUE(environmentLimit(*w, tank, o));
  EXPECT_NEAR(tank.commands.headingDeg, 90, 1e-9);
}

TEST(Behaviour, fightOrFlightHeadings) {
  BehaviourOptions o;
  const Eigen::Vector3d westward(-300, 0, 0);  // a missile flying west (heading 270): fired from the east
  Entity unarmed;
  unarmed.commands = {3, 0, 0};
  unarmed.vehicle.maxSpeedMs = 18;
  Reaction r = fightOrFlight(unarmed, westward, o);
  EXPECT_TRUE(r.fled);
  EXPECT_NEAR(unarmed.commands.headingDeg, 270, 1e-9);  // along the missile's direction
  EXPECT_EQ(unarmed.commands.speedMs, 18);              // at full speed
  Entity armed;
  armed.armed = true;
  armed.commands = {5, 0, 0};
  r = fightOrFlight(armed, westward, o);  // reverse azimuth 90: 90 away, turn 45
  EXPECT_TRUE(r.turned);
  EXPECT_FALSE(r.fire);
  EXPECT_NEAR(armed.commands.headingDeg, 45, 1e-9);
  r = fightOrFlight(armed, westward, o);  // within one turn: face it and fire
  EXPECT_TRUE(r.fire);
  EXPECT_NEAR(r.fireAzimuthDeg, 90, 1e-9);
  EXPECT_NEAR(armed.commands.headingDeg, 90, 1e-9);
  armed.commands.headingDeg = 300;  // the short way round: 150 to the right
  r = fightOrFlight(armed, westward, o);
  EXPECT_NEAR(armed.commands.headingDeg, 345, 1e-9);
}

TEST(Behaviour, theBoxesAreAxisAlignedAroundTheEntity) {
  Entity e;
  e.position = {100, 50, 100};
  e.height = 3;
  EXPECT_TRUE(inBox(e, {103, 51, 97}, 4));
  EXPECT_FALSE(inBox(e, {105, 51, 100}, 4));
  EXPECT_TRUE(inBox(e, {100, 56.5, 100}, 4));
  EXPECT_FALSE(inBox(e, {100, 45.9, 100}, 4));
}

}  // namespace
}  // namespace sandtable::sim
