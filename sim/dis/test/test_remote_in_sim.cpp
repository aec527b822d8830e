// Remote entities take part in the local simulation (issue 36): local
// entities collide with them (and only the local side answers), and fight
// or flight reacts to a remote simulation's rounds flying by.
#include <gtest/gtest.h>

#include "sim_dis_support.h"

namespace sandtable::sim_dis {
namespace {

using test::TwoSims;

TEST(SimDisInSim, aLocalEntityCollidesWithARemoteOneAndOnlyTheLocalSideAnswers) {
  TwoSims t;
  sim::Entity parked;  // A's, standing still
  parked.name = "parked";
  parked.position = {1000, 0, 1000};
  auto pid = t.a.add(parked);
  sim::Entity driver;  // B's, driving north into it
  driver.name = "driver";
  driver.position = {1000, 0, 1060};
  driver.speedMs = 10;
  driver.headingDeg = 0;
  auto did = t.b.add(driver);
  ASSERT_TRUE(pid.ok() && did.ok());
  bool collided = false;
  for (int k = 0; k < 60 * 10 && !collided; ++k) {
    t.step();
    for (const sim::Event& ev : t.b.events()) {
      collided = collided || (ev.kind == sim::EventKind::entityCollision &&
                              (ev.entity == did.value() || ev.other == did.value()));
    }
  }
  ASSERT_TRUE(collided);
  const std::uint32_t parkedInB = t.gb->simIdOf({1, 1, std::uint16_t(pid.value() + 1)});
  ASSERT_NE(parkedInB, UINT32_MAX);
  // B's driver was stopped or bounced; A's parked entity, as B shows it, did not move:
  // B never moves a remote entity, and A's simulation knows nothing of the crash.
  EXPECT_LT(std::abs(t.b.entity(did.value()).speedMs), 10.0);
  EXPECT_LT((t.b.entity(parkedInB).position - t.a.entity(pid.value()).position).norm(), 0.01);
  EXPECT_TRUE(t.b.entity(parkedInB).alive);
  EXPECT_LT((t.a.entity(pid.value()).position - Eigen::Vector3d(1000, 100, 1000)).norm(), 0.01);
}

TEST(SimDisInSim, fightOrFlightSeesARemoteRoundGoBy) {
  TwoSims t;
  sim::Entity shooter;  // A's
  shooter.name = "shooter";
  shooter.position = {1000, 0, 1150};  // 150 m south: the round drops little on the way
  shooter.armed = true;
  shooter.force = 2;
  auto sid = t.a.add(shooter);
  sim::Entity target;  // B's, with fight or flight; unarmed, so it flees
  target.name = "target";
  target.position = {1000, 0, 1000};
  target.behaviours.fight = true;
  target.controller = sim::Controller::behaviour;
  target.force = 1;
  auto tid = t.b.add(target);
  ASSERT_TRUE(sid.ok() && tid.ok());
  for (int k = 0; k < 5; ++k) t.step();
  // Aim 10 m to the side of the target: a near miss, not a hit.
  const Eigen::Vector3d aim = t.b.entity(tid.value()).position + Eigen::Vector3d(10, 2, 0) -
                              t.a.entity(sid.value()).position;
  const double elevation = std::atan2(aim.y(), Eigen::Vector2d(aim.x(), aim.z()).norm()) * sim::kRadToDeg;
  t.a.fire(sid.value(), sim::headingOf(aim.x(), aim.z()), elevation, 0);
  bool sensed = false;
  for (int k = 0; k < 120 && !sensed; ++k) {
    t.step();
    sensed = t.b.entity(tid.value()).lastSensed != UINT32_MAX;
  }
  EXPECT_TRUE(sensed);
  EXPECT_TRUE(t.b.entity(tid.value()).alive);
  EXPECT_GE(t.gb->counters().fires, 1u);
}

}  // namespace
}  // namespace sandtable::sim_dis
