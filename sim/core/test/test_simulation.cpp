// The simulation as a whole on synthetic worlds: Table 6 and Figure 64
// through the step, munitions and fight or flight, script record and
// playback within 1 cm, the grid against brute force, determinism.
#include <gtest/gtest.h>

#include <cmath>

#include "sandtable/base/hash.h"
#include "sandtable/sim/motion.h"
#include "sandtable/sim/report.h"
#include "sandtable/sim/simulation.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

double hills(double x, double z) { return 60 + 25 * std::sin(x / 170.0) * std::cos(z / 230.0) + 0.01 * x; }

Entity vehicle(double x, double z, double heading, double speed, Mobility m = Mobility::simple) {
  Entity e;
  e.name.push_back('v');  // (not = "v": GCC 12 warns -Wrestrict falsely)
  e.mobility = m;
  e.position = {x, 0, z};
  e.headingDeg = heading;
  e.speedMs = speed;
  e.radius = 2;
  e.sphereRadius = 3;
  e.height = 2.5;
  e.halfLength = 3;
  e.halfWidth = 1.5;
  e.autopilot = true;
  return e;
}

StaticObject tree(const SimWorld& w, double x, double z) {
  StaticObject o;
  o.x = x;
  o.z = z;
  o.baseY = *w.groundAt(x, z);
  o.radius = 2.5;
  o.height = 8;
  o.kind = ObjectKind::tree;
  return o;
}

TEST(Simulation, aTankMeetingATreeGetsTable6sResultForItsSpeed) {
  // Tank row of Table 6 against a tree: slow stop/none, medium
  // destroyed/knocked-over, fast destroyed/stump (bins 10 and 40 km/h).
  struct Case {
    double kmh;
    bool alive;
    ObjectState tree;
  };
  for (const Case c : {Case{5, true, ObjectState::standing}, Case{25, false, ObjectState::knockedOver},
                       Case{60, false, ObjectState::stump}}) {
    auto w = test::makeWorld([](double, double) { return 20.0; });
    w->setObjects({tree(*w, 1000, 970)});
    Simulation sim(w);
    ASSERT_TRUE(sim.add(vehicle(1000, 1000, 0, c.kmh / 3.6)));
    sim.runFor(30);
    const Entity& t = sim.entity(0);
    EXPECT_EQ(t.alive, c.alive) << c.kmh;
    EXPECT_EQ(w->objects()[0].state, c.tree) << c.kmh;
    EXPECT_EQ(sim.counters().collisions.objects, 1u) << c.kmh;
    // It never got into the trunk: centre distance stays above the radii.
    EXPECT_GE(std::hypot(t.position.x() - 1000, t.position.z() - 970), 4.5 - c.kmh / 3.6 / 60) << c.kmh;
  }
}

TEST(Simulation, headOnAboveTheKillSpeedKillsBothBelowItStopsBoth) {
  for (double speed : {1.0, 10.0}) {
    auto w = test::makeWorld([](double, double) { return 20.0; });
    Simulation sim(w);
    ASSERT_TRUE(sim.add(vehicle(1000, 1050, 0, speed)));   // north
    ASSERT_TRUE(sim.add(vehicle(1000, 950, 180, speed)));  // south, towards it
    sim.runFor(60);
    const bool kill = 2 * speed > sim.options().killSpeedMs;
    EXPECT_EQ(sim.entity(0).alive, !kill) << speed;
    EXPECT_EQ(sim.entity(1).alive, !kill) << speed;
    EXPECT_EQ(sim.counters().collisions.entities, 1u) << speed;
    if (!kill) {
      EXPECT_EQ(sim.entity(0).speedMs, 0);
      EXPECT_EQ(sim.entity(1).speedMs, 0);
    }
    const double gap = (sim.entity(0).position - sim.entity(1).position).norm();
    EXPECT_LE(gap, 6.0 + 1e-9);  // they met: the spheres (3 + 3) touched
  }
}

TEST(Simulation, aGlancingContactBouncesBothWithLessSpeed) {
  auto w = test::makeWorld([](double, double) { return 20.0; });
  Simulation sim(w);
  ASSERT_TRUE(sim.add(vehicle(1000, 1000, 0, 8)));
  ASSERT_TRUE(sim.add(vehicle(1003, 960, 200, 8)));  // passes 3 m to the east: a glancing touch
  for (int k = 0; k < 60 * 10 && sim.counters().collisions.entities == 0; ++k) sim.step();
  ASSERT_EQ(sim.counters().collisions.entities, 1u);
  const Entity& a = sim.entity(0);
  const Entity& b = sim.entity(1);
  EXPECT_TRUE(a.alive);
  EXPECT_TRUE(b.alive);
  EXPECT_LT(a.speedMs, 8);
  EXPECT_LT(b.speedMs, 8);
  EXPECT_NE(a.headingDeg, 0);
  EXPECT_NE(b.headingDeg, 200);
  sim.runFor(5);
  EXPECT_EQ(sim.counters().collisions.entities, 1u);  // they part, and do not touch again
}

TEST(Simulation, aGuidedMissileKillsItsTargetAndArmedEntitiesFireBack) {
  auto w = test::makeWorld([](double, double) { return 20.0; });
  Simulation sim(w);
  Entity blue = vehicle(600, 1000, 90, 0);
  blue.force = 1;
  blue.armed = true;
  Entity red = vehicle(1400, 1000, 300, 0);  // within one 45-degree turn of the reverse azimuth, 270
  red.force = 2;
  red.armed = true;
  red.behaviours.fight = true;
  red.controller = Controller::behaviour;
  Entity bystander = vehicle(1400, 1030, 0, 0);  // 30 m from the target: in the near-miss box
  bystander.behaviours.fight = true;
  bystander.controller = Controller::behaviour;
  bystander.vehicle.maxSpeedMs = 12;
  ASSERT_TRUE(sim.add(blue));
  ASSERT_TRUE(sim.add(red));
  ASSERT_TRUE(sim.add(bystander));
  const auto missile = sim.fire(0, 90, 2, 0, 1);
  sim.runFor(15);
  EXPECT_FALSE(sim.entity(missile).alive);
  EXPECT_FALSE(sim.entity(1).alive);
  bool killedByBlue = false, redFired = false;
  for (const Event& ev : sim.events()) {
    if (ev.kind == EventKind::kill && ev.entity == 1 && ev.other == 0) killedByBlue = true;
    if (ev.kind == EventKind::fire && ev.other == 1) redFired = true;
  }
  EXPECT_TRUE(killedByBlue);
  // Red sensed the missile before it hit and, within one turn of the
  // reverse azimuth, fired back; the unarmed bystander fled east.
  EXPECT_TRUE(redFired);
  EXPECT_NEAR(sim.entity(2).headingDeg, 90, 1.0);
  EXPECT_GT(sim.entity(2).speedMs, 11);
}

TEST(Simulation, aMunitionFoundUnderTheSurfaceDetonatesWhereItsSegmentCrossedIt) {
  auto w = test::makeWorld(hills);
  Simulation sim(w);
  ASSERT_TRUE(sim.add(vehicle(1000, 1000, 0, 0)));
  sim.fire(0, 0, -5, 1);  // a round fired down the slope
  sim.runFor(5);
  ASSERT_EQ(sim.counters().detonations, 1u);
  const Event* det = nullptr;
  for (const Event& ev : sim.events()) {
    if (ev.kind == EventKind::detonation) det = &ev;
  }
  ASSERT_NE(det, nullptr);
  EXPECT_EQ(det->detail, "terrain");
  EXPECT_NEAR(det->position.y(), *w->groundAt(det->position.x(), det->position.z()), 0.02);
}

TEST(Simulation, aRoundThatHitsTheGroundLeavesItsCraterAtTheImpactAndFellsTheTreesInIt) {
  auto w = test::makeWorld(hills);
  Simulation sim(w);
  ASSERT_TRUE(sim.add(vehicle(1000, 1000, 0, 0)));
  sim.fire(0, 0, -5, 1);  // the ballistic round: a small crater (munition.cpp's table)
  sim.runFor(5);
  const Event* det = nullptr;
  const Event* edit = nullptr;
  for (const Event& ev : sim.events()) {
    if (ev.kind == EventKind::detonation) det = &ev;
    if (ev.kind == EventKind::terrainEdit) edit = &ev;
  }
  ASSERT_NE(det, nullptr);
  ASSERT_NE(edit, nullptr);
  EXPECT_EQ(edit->detail, "crater small");
  const auto edits = sim.takeTerrainEdits();
  ASSERT_EQ(edits.size(), 1u);
  EXPECT_TRUE(sim.takeTerrainEdits().empty());
  const edit::Edit& c = edits[0];
  EXPECT_EQ(c.kind, edit::Kind::crater);
  // Figure 27: at the true impact point the binary search found.
  EXPECT_EQ(c.points[0][0], det->position.x());
  EXPECT_EQ(c.points[0][1], det->position.z());
  EXPECT_EQ(c.radius, 1.0);
  EXPECT_EQ(c.depth, 0.5);
  EXPECT_EQ(edit::checkEdit(c), "");

  // Trees: one inside the radius falls, one outside it stands.
  const double x = c.points[0][0], z = c.points[0][1];
  w->setObjects({tree(*w, x + 0.5, z), tree(*w, x + 3, z)});
  EXPECT_EQ(sim.objectsInCrater(c), 1u);
  EXPECT_EQ(w->objects()[0].state, ObjectState::knockedOver);
  EXPECT_EQ(w->objects()[1].state, ObjectState::standing);
  EXPECT_EQ(sim.objectsInCrater(c), 0u);  // already down
}

TEST(Simulation, cratersCanBeTurnedOff) {
  auto w = test::makeWorld(hills);
  SimOptions o;
  o.craters = false;
  Simulation sim(w, o);
  ASSERT_TRUE(sim.add(vehicle(1000, 1000, 0, 0)));
  sim.fire(0, 0, -5, 1);
  sim.runFor(5);
  EXPECT_EQ(sim.counters().detonations, 1u);
  EXPECT_TRUE(sim.takeTerrainEdits().empty());
}

/// A sim of `n` zig-zagging entities among 4,000 trees, with some missiles.
std::string run(std::uint64_t seed, bool brute, int n = 150) {
  auto w = test::makeWorld(hills);
  std::vector<StaticObject> trees;
  for (std::uint64_t k = 0; k < 4000; ++k) {
    trees.push_back(tree(*w, 300 + hash::unit(hash::mix(2 * k)) * 1400, 300 + hash::unit(hash::mix(2 * k + 1)) * 1400));
  }
  w->setObjects(trees);
  SimOptions o;
  o.seed = seed;
  o.bruteForce = brute;
  Simulation sim(w, o);
  for (int k = 0; k < n; ++k) {
    Entity e = vehicle(300 + 1400 * hash::unit(hash::mix(9000 + k)), 300 + 1400 * hash::unit(hash::mix(7000 + k)),
                       360 * hash::unit(hash::mix(5000 + k)), 3 + 12 * hash::unit(hash::mix(3000 + k)),
                       k % 3 == 0 ? Mobility::tracked : Mobility::simple);
    e.force = std::uint8_t(1 + k % 2);
    e.armed = k % 4 == 0;
    e.behaviours = {true, true, true, true};
    e.controller = Controller::behaviour;
    e.autopilot = false;
    EXPECT_TRUE(sim.add(e));
  }
  for (int k = 0; k < 20; ++k) sim.fire(std::uint32_t(k), 360.0 * k / 20, 1, 0);
  sim.runFor(40);
  return eventsJson(sim).dump() + summaryJson(sim).dump();
}

TEST(Simulation, twoRunsWithTheSameSeedGiveByteIdenticalEventLogs) {
  const std::string a = run(5, false), b = run(5, false), c = run(6, false);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  EXPECT_GT(a.size(), 2000u);  // things happened
}

TEST(Simulation, theGridAndTheBoxFindExactlyTheCollisionsBruteForceFinds) {
  EXPECT_EQ(run(11, false), run(11, true));
}

TEST(Simulation, recordingAndPlayingBackReproducesThePathWithinOneCentimetre) {
  auto w = test::makeWorld(hills);
  std::vector<Eigen::Vector3d> path;
  std::vector<ScriptLine> lines;
  {
    Simulation sim(w);
    Entity t = vehicle(700, 1200, 30, 0, Mobility::tracked);
    t.autopilot = false;
    ASSERT_TRUE(sim.add(t));
    sim.driven = 0;
    sim.record(0, 7, 2);
    for (int k = 0; k < 60 * 90; ++k) {
      Entity& d = sim.entity(0);
      const double s = sim.timeS();
      d.controls.leftTrack = 0.35 + 0.2 * std::sin(s / 7);
      d.controls.rightTrack = 0.35 + 0.2 * std::cos(s / 5);
      sim.step();
      path.push_back(d.position);
    }
    sim.finishRecording();
    lines = sim.recorder()->lines();
    auto reread = parseScript(formatScript(lines), "recorded");  // through the text
    ASSERT_TRUE(reread) << reread.error();
    lines = reread.value();
  }
  ASSERT_GT(lines.size(), 10u);
  ASSERT_LT(lines.size(), path.size() / 5);  // it records changes, not every step
  Simulation play(w);
  Entity p = vehicle(lines[0].x, lines[0].z, lines[0].directionDeg, 0);
  ASSERT_TRUE(play.add(p));
  play.addScript(lines, {{7, 0}});
  double worst = 0;
  for (std::size_t k = 0; k < path.size(); ++k) {
    play.step();
    worst = std::max(worst, (play.entity(0).position - path[k]).norm());
  }
  EXPECT_LT(worst, 0.01);
}

TEST(Simulation, landEntitiesStayOnTheDrawnSurfaceAndTheirAttitudeNeverJumps) {
  auto w = test::makeWorld(hills, 201, 10);
  Simulation sim(w);
  Entity t = vehicle(500, 500, 60, 0, Mobility::tracked);
  t.autopilot = false;
  ASSERT_TRUE(sim.add(t));
  double worstGround = 0, worstPitchStep = 0, worstRollStep = 0;
  double pitch = sim.entity(0).pitchDeg, roll = sim.entity(0).rollDeg;
  for (int k = 0; k < 60 * 120; ++k) {
    Entity& e = sim.entity(0);
    e.controls.leftTrack = 0.5;
    e.controls.rightTrack = 0.45;
    sim.step();
    worstGround = std::max(worstGround, std::abs(e.position.y() - *w->groundAt(e.position.x(), e.position.z())));
    worstPitchStep = std::max(worstPitchStep, std::abs(e.pitchDeg - pitch));
    worstRollStep = std::max(worstRollStep, std::abs(e.rollDeg - roll));
    pitch = e.pitchDeg;
    roll = e.rollDeg;
  }
  EXPECT_LT(worstGround, 0.01);
  EXPECT_LT(worstPitchStep, 0.5);
  EXPECT_LT(worstRollStep, 0.5);
}

TEST(Simulation, anAircraftFlownIntoTheGroundCrashes) {
  auto w = test::makeWorld(hills);
  Simulation sim(w);
  Entity jet = vehicle(200, 1000, 90, 20);
  jet.domain = Domain::air;
  jet.position.y() = 300;
  ASSERT_TRUE(sim.add(jet));
  sim.entity(0).commands.altitudeM = -100;  // dive
  sim.runFor(60);
  EXPECT_FALSE(sim.entity(0).alive);
  ASSERT_FALSE(sim.events().empty());
  EXPECT_EQ(sim.events()[0].kind, EventKind::crash);
}

}  // namespace
}  // namespace sandtable::sim

namespace sandtable::sim {
namespace {

TEST(Simulation, computerGeneratedForcesSteerAroundObjectsInTheirPath) {
  auto w = test::makeWorld([](double, double) { return 20.0; });
  w->setObjects({tree(*w, 1000, 940)});
  Simulation sim(w);
  Entity e = vehicle(1000, 1000, 0, 25 / 3.6, Mobility::tracked);
  e.controller = Controller::behaviour;
  e.autopilot = false;
  e.behaviours.environment = true;
  ASSERT_TRUE(sim.add(e));
  sim.runFor(30);
  EXPECT_EQ(sim.counters().collisions.objects, 0u);
  EXPECT_TRUE(sim.entity(0).alive);
  EXPECT_LT(sim.entity(0).position.z(), 900);  // it went past the tree
  EXPECT_GT(sim.entity(0).speedMs, 5);          // and back up to speed
}

}  // namespace
}  // namespace sandtable::sim
