// The simulation on a DIS network (sim_dis): the database frame's anchors
// against PROJ, the publisher's threshold rule against the receiver's dead
// reckoning, smoothing, timeouts, and two simulations joined by gateways.
// Truth is the publishing simulation's own entity state at every step.
#include <gtest/gtest.h>

#include <memory>

#include "sim_dis_support.h"

namespace sandtable::sim_dis {
namespace {

using test::horizontal;
using test::overTheWire;
using test::testFrame;
using test::TwoSims;

TEST(SimDisFrame, anchorsMapNearbyPointsWithinTwoCentimetres) {
  const DisFrame frame = testFrame();
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(1000, 300, 1000), Eigen::Vector3d(90000, 0, 90000)}) {
    auto a = frame.anchorAtFrame(p);
    ASSERT_TRUE(a.ok()) << a.error();
    for (double d : {10.0, 100.0, 500.0}) {
      for (const Eigen::Vector3d& dir : {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.6, 0.1, -0.8)}) {
        const Eigen::Vector3d q = p + d * dir.normalized();
        auto exact = frame.frame().toEcef({q.x(), q.y(), q.z()});
        ASSERT_TRUE(exact.ok());
        const Eigen::Vector3d back = frameOf(a.value(), {exact->x, exact->y, exact->z});
        EXPECT_LT((back - q).norm(), d <= 100 ? 0.001 : 0.025) << d;
        const dis::Vec3d e = ecefOf(a.value(), q);
        EXPECT_LT(std::hypot(e.x - exact->x, e.y - exact->y, e.z - exact->z), d <= 100 ? 0.001 : 0.025) << d;
      }
    }
  }
}

TEST(SimDisFrame, bodyAxesMapAsAProperRotation) {
  // Forward is -Z in the simulator and +x in DIS; right is +X and +y; up is +Y and -z.
  const dis::Vec3d f = disBody({0, 0, -1}), r = disBody({1, 0, 0}), u = disBody({0, 1, 0});
  EXPECT_EQ(f.x, 1);
  EXPECT_EQ(r.y, 1);
  EXPECT_EQ(u.z, -1);
  const Eigen::Vector3d back = simBody(disBody({0.3, -0.2, 0.7}));
  EXPECT_NEAR((back - Eigen::Vector3d(0.3, -0.2, 0.7)).norm(), 0, 1e-15);
}

TEST(SimDisFrame, posesGoToDisAndBack) {
  const DisFrame frame = testFrame();
  auto a = frame.anchorAtFrame({5000, 120, 7000});
  ASSERT_TRUE(a.ok());
  for (double h : {0.0, 45.0, 181.0, 359.0}) {
    const dis::Euler e = disOrientation(a.value(), h, 10, -20);
    const FramePose p = framePose(a.value(), a->ecef, e);
    EXPECT_NEAR(sim::turnBetween(p.headingDeg, h), 0, 1e-4);
    EXPECT_NEAR(p.pitchDeg, 10, 1e-4);
    EXPECT_NEAR(p.rollDeg, -20, 1e-4);
  }
}

/// A land entity on flat ground driving a path: straight, then a turn.
struct Drive {
  sim::Entity e;
  double turnDegS = 0;
  /// Velocity and turn rate from heading and speed.
  void aim() {
    e.velocity = sim::headingVector(e.headingDeg) * e.speedMs;
    e.angularVelocity = {0, -turnDegS * sim::kDegToRad, 0};
  }
  void step(double dt) {
    e.headingDeg = sim::wrapDeg(e.headingDeg + turnDegS * dt);
    e.velocity = sim::headingVector(e.headingDeg) * e.speedMs;
    e.angularVelocity = {0, -turnDegS * sim::kDegToRad, 0};
    e.position += e.velocity * dt;
  }
};

struct Exchange {
  DisFrame frame = testFrame();
  Publisher publisher{frame};
  RemoteOptions remoteOptions;
  std::unique_ptr<RemoteEntities> remote;
  Identity who{{7, 8, 9}, {1, 1, 225, 1, 1, 3, 0}, 2};
  std::uint64_t pdus = 0;
  double worst = 0;

  explicit Exchange(double blendS = 0) {
    remoteOptions.blendLandS = blendS;
    remote = std::make_unique<RemoteEntities>(frame, remoteOptions);
  }
  /// One step: offer the truth, apply what was sent, measure the receiver's error.
  void step(const sim::Entity& truth, double t) {
    if (auto s = publisher.offer(truth, who, t, pdus == 0)) {
      ++pdus;
      remote->update(overTheWire(*s), {0x7f000001, 3000}, t, t);
    }
    RemoteEntity* r = remote->find(who.id);
    ASSERT_NE(r, nullptr);
    auto state = remote->stateAt(*r, t);
    ASSERT_TRUE(state.ok()) << state.error();
    worst = std::max(worst, horizontal(state->pose.position, truth.position));
  }
};

TEST(SimDisPublisher, straightAtConstantSpeedSendsOnlyHeartbeats) {
  Exchange x;
  Drive d;
  d.e.position = {2000, 50, 2000};
  d.e.headingDeg = 60;
  d.e.speedMs = 15;
  d.aim();
  const double dt = 1.0 / 60;
  for (int k = 0; k <= 60 * 30; ++k) {
    x.step(d.e, k * dt);
    d.step(dt);
  }
  // The first PDU at 0 and a heartbeat every 5 s through 30 s.
  EXPECT_EQ(x.pdus, 7u);
  EXPECT_LT(x.worst, 0.05);
}

TEST(SimDisPublisher, turningKeepsEveryReceiverWithinTheThreshold) {
  for (double turn : {3.0, 12.0, 40.0}) {
    Exchange x;
    Drive d;
    d.e.position = {3000, 0, 3000};
    d.e.speedMs = 20;
    d.turnDegS = turn;
    d.aim();
    const double dt = 1.0 / 60;
    for (int k = 0; k <= 60 * 40; ++k) {
      x.step(d.e, k * dt);
      d.step(dt);
    }
    // FPW leaves a turning entity behind its copy: the threshold (1 m) plus
    // one step's growth of the error bounds what a receiver ever shows.
    EXPECT_LE(x.worst, 1.0 + 20 * dt) << turn;
    EXPECT_GT(x.pdus, 8u) << turn;  // more than heartbeats
  }
}

TEST(SimDisPublisher, turningOnTheSpotSendsOnTheAngleThreshold) {
  Exchange x;
  Drive d;
  d.e.position = {3000, 0, 3000};
  d.turnDegS = 30;  // 3 degrees every 0.1 s
  const double dt = 1.0 / 60;
  for (int k = 0; k < 60; ++k) {
    x.step(d.e, k * dt);
    d.step(dt);
  }
  // FPW does not turn the copy: one PDU per 3 degrees of the 30 turned, plus the first.
  EXPECT_GE(x.pdus, 9u);
  EXPECT_LE(x.pdus, 11u);
}

TEST(SimDisRemote, aCorrectionIsSmoothedBackOverTheBlendTime) {
  Exchange x(1.0);
  Drive d;
  d.e.position = {2000, 0, 2000};
  d.e.headingDeg = 90;
  d.e.speedMs = 10;
  d.aim();
  auto first = x.publisher.offer(d.e, x.who, 0, true);
  ASSERT_TRUE(first);
  x.remote->update(overTheWire(*first), {}, 0, 0);
  // At 1 s the entity turns out to be 4 m further south than reckoned.
  d.e.position += Eigen::Vector3d(10, 0, 4);
  auto second = x.publisher.offer(d.e, x.who, 1, true);
  RemoteEntity* r = x.remote->find(x.who.id);
  auto before = x.remote->stateAt(*r, 1);
  x.remote->update(overTheWire(*second), {}, 1, 1);
  auto after = x.remote->stateAt(*r, 1);
  EXPECT_LT((after->pose.position - before->pose.position).norm(), 0.01);  // no jump
  auto half = x.remote->stateAt(*r, 1.5);
  EXPECT_NEAR(half->pose.position.z() - (d.e.position.z() - 2), 0, 0.02);  // half the offset left
  auto done = x.remote->stateAt(*r, 2.5);
  EXPECT_LT(horizontal(done->pose.position, d.e.position + Eigen::Vector3d(15, 0, 0)), 0.02);
  EXPECT_EQ(x.remote->counters().smooths, 1u);
  EXPECT_NEAR(x.remote->counters().lastCorrectionM, 4, 0.02);
}

TEST(SimDisRemote, silenceRemovesAfterTwelveSecondsAndDeactivationAtOnce) {
  Exchange x;
  sim::Entity e;
  e.position = {1000, 0, 1000};
  auto s = x.publisher.offer(e, x.who, 0, true);
  x.remote->update(overTheWire(*s), {1, 3000}, 0, 0);
  EXPECT_TRUE(x.remote->expire(11.9).empty());
  EXPECT_EQ(x.remote->expire(12.0).size(), 1u);
  x.remote->update(overTheWire(*s), {1, 3000}, 13, 13);
  x.remote->update(overTheWire(*s), {2, 3000}, 13.5, 13.5);  // a second sender claims the id
  EXPECT_EQ(x.remote->counters().conflicts, 1u);
  auto retired = x.publisher.retire(e.id, 14);
  ASSERT_TRUE(retired);
  EXPECT_NE(x.remote->update(overTheWire(*retired), {2, 3000}, 14, 14), nullptr);  // not its entity
  EXPECT_EQ(x.remote->counters().conflicts, 2u);
  EXPECT_EQ(x.remote->update(overTheWire(*retired), {1, 3000}, 14, 14), nullptr);
  EXPECT_EQ(x.remote->size(), 0u);
  EXPECT_EQ(x.remote->counters().removed, 1u);
}

TEST(SimDisGateway, aWatcherSeesThePublishersEntitiesWithinTheThreshold) {
  TwoSims t;
  sim::Entity tank;
  tank.name = "T-1";
  tank.position = {600, 0, 900};
  tank.speedMs = 8;
  tank.headingDeg = 30;
  tank.force = 1;
  auto id = t.a.add(tank);
  ASSERT_TRUE(id.ok()) << id.error();
  double worst = 0;
  std::uint32_t seenAs = UINT32_MAX;
  for (int k = 0; k < 60 * 20; ++k) {
    if (k == 300) t.a.entity(id.value()).commands.headingDeg = 120;  // a turn
    t.step();
    if (k == 0) continue;  // the first PDU goes out after A's first step
    const auto& remotes = t.gb->remotes().all();
    ASSERT_EQ(remotes.size(), 1u) << k;
    seenAs = remotes.begin()->second.simId;
    ASSERT_NE(seenAs, UINT32_MAX);
    // B before its step k sees A as it was after A's step k - 1: compare
    // with A's state then, i.e. before A's step k moved it again.
    const sim::Entity& watched = t.b.entity(seenAs);
    const sim::Entity& truth = t.a.entity(id.value());
    worst = std::max(worst, horizontal(watched.position, truth.position - truth.velocity * t.a.options().stepS));
  }
  EXPECT_LE(worst, 1.0 + 8 * t.a.options().stepS);
  const sim::Entity& watched = t.b.entity(seenAs);
  EXPECT_EQ(watched.controller, sim::Controller::remote);
  EXPECT_EQ(watched.name, "T-1");
  EXPECT_EQ(watched.force, 1);
  EXPECT_NEAR(watched.position.y(), 100, 0.01);  // on B's ground
  EXPECT_EQ(t.gb->counters().own, 0u);
  EXPECT_GT(t.ga->counters().sentPdus, 4u);
  EXPECT_LT(t.ga->counters().sentPdus, 60u);
}

TEST(SimDisGateway, aRemovedEntityLeavesTheWatcherAndSilenceRemovesToo) {
  TwoSims t;
  sim::Entity e;
  e.position = {500, 0, 500};
  auto id = t.a.add(e);
  for (int k = 0; k < 10; ++k) t.step();
  EXPECT_EQ(t.gb->remotes().size(), 1u);
  t.a.remove(id.value());
  for (int k = 0; k < 3; ++k) t.step();
  EXPECT_EQ(t.gb->remotes().size(), 0u);
  EXPECT_EQ(t.b.entities().size(), 0u);
  // Silence: A's entity is there but A stops sending.
  auto id2 = t.a.add(e);
  static_cast<void>(id2);
  for (int k = 0; k < 10; ++k) t.step();
  EXPECT_EQ(t.gb->remotes().size(), 1u);
  for (int k = 0; k < 60 * 13; ++k) {
    t.toB.clear();
    t.hb.step();
  }
  EXPECT_EQ(t.gb->remotes().size(), 0u);
  EXPECT_EQ(t.gb->remotes().counters().timedOut, 1u);
}

TEST(SimDisGateway, aDetonationNamingALocalEntityKillsItThere) {
  TwoSims t;
  sim::Entity shooter;
  shooter.name = "shooter";
  shooter.position = {500, 0, 1000};
  shooter.armed = true;
  auto sid = t.a.add(shooter);
  sim::Entity target;
  target.name = "target";
  target.position = {500, 0, 900};  // 100 m north of the shooter
  auto tid = t.b.add(target);
  ASSERT_TRUE(sid.ok() && tid.ok());
  for (int k = 0; k < 5; ++k) t.step();
  const std::uint32_t targetInA = t.ga->simIdOf({2, 1, std::uint16_t(tid.value() + 1)});
  ASSERT_NE(targetInA, UINT32_MAX);
  const sim::Entity& seen = t.a.entity(targetInA);
  const Eigen::Vector3d to = seen.position + Eigen::Vector3d(0, 1, 0) - t.a.entity(sid.value()).position;
  const double elevation = std::atan2(to.y(), Eigen::Vector2d(to.x(), to.z()).norm()) * sim::kRadToDeg;
  t.a.fire(sid.value(), sim::headingOf(to.x(), to.z()), elevation, 0);
  for (int k = 0; k < 120 && t.b.entity(tid.value()).alive; ++k) t.step();
  EXPECT_FALSE(t.b.entity(tid.value()).alive);
  EXPECT_EQ(t.gb->counters().hitsTaken, 1u);
  EXPECT_GE(t.gb->counters().fires, 1u);
  EXPECT_GE(t.gb->counters().detonations, 1u);
  for (int k = 0; k < 3; ++k) t.step();
  EXPECT_FALSE(t.a.entity(targetInA).alive);  // B said so in its next PDU
}

TEST(SimDisGateway, otherExercisesAndMalformedPdusAreCountedNotApplied) {
  TwoSims t;
  sim::Entity e;
  e.position = {500, 0, 500};
  t.a.add(e);
  t.ha.step();
  ASSERT_FALSE(t.toB.empty());
  dis::Datagram other = t.toB.front();
  other.bytes[1] = std::byte{9};  // exercise 9
  dis::Datagram bad = t.toB.front();
  bad.bytes.resize(40);  // truncated
  t.toB.push_back(other);
  t.toB.push_back(bad);
  t.hb.step();
  EXPECT_EQ(t.gb->counters().otherExercise, 1u);
  EXPECT_EQ(t.gb->counters().malformed, 1u);
  EXPECT_NE(t.gb->counters().lastMalformed.find("127.0.0.1:3000"), std::string::npos);
  EXPECT_EQ(t.gb->remotes().size(), 1u);
}

}  // namespace
}  // namespace sandtable::sim_dis
