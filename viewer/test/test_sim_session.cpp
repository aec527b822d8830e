// The simulation as the viewer shows and drives it (sim_session.h), without
// GL: over a flat 2 km grid with hand-made icons, the frame's instances
// carry each entity's orientation and its turret relative to the hull; a
// missile leaves a trail that ends in a flash where it went off and fades
// out; objects the simulation changed get their look; the map marks, the
// panel, the tethered eye and driving (keys to commands, autopilot, all
// stop) behave as documented.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "sandtable/formats/grid.h"
#include "sandtable/sim/motion.h"
#include "sandtable/sim/scenario_load.h"
#include "sandtable/testing/fixtures.h"
#include "sandtable/viewer/sim_session.h"

namespace sandtable::viewer {
namespace {

constexpr double kGround = 100, kSpacing = 10;
constexpr std::uint32_t kPosts = 201;  // 2 km square
constexpr double kOriginE = 500000, kOriginN = 4000000;

iconpack::Mesh box(float x0, float x1, float y0, float y1, float z0, float z1) {
  iconpack::Mesh m;
  m.positions = {x0, y0, z0, x1, y0, z0, x1, y1, z1, x0, y1, z1};
  m.normals = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
  m.levels = {{0, 1, 2, 0, 2, 3}};
  return m;
}

iconpack::Icon icon(const std::string& name, std::array<float, 6> bounds, bool armed) {
  iconpack::Icon i;
  i.name = name;
  i.armed = armed;
  i.bounds = bounds;
  i.cylinderRadius = std::max(std::abs(bounds[0]), std::abs(bounds[2]));
  i.cylinderHeight = bounds[4];
  i.materials = {{{56, 66, 31, 255}, iconpack::kNoTexture}};
  i.ranges = {5000};
  iconpack::Part hull;
  hull.meshes = {box(bounds[0], bounds[3], bounds[1], bounds[4], bounds[2], bounds[5])};
  i.parts = {hull};
  return i;
}

std::shared_ptr<const grid::GridFile> flatGrid() {
  const std::string path = std::filesystem::temp_directory_path().string() + "/sandtable_simsession_" +
                           std::to_string(::getpid()) + ".grid";
  const Status st = fixtures::writeGrid(
      path, kPosts, kPosts, kSpacing, [](std::uint32_t, std::uint32_t) { return float(kGround); }, kOriginE,
      kOriginN);
  EXPECT_TRUE(st) << st.error();
  auto grid = grid::GridFile::open(path);
  EXPECT_TRUE(grid) << grid.error();
  std::filesystem::remove(path);  // the mapping stays valid
  return grid.value();
}

std::shared_ptr<sim::SimWorld> flatWorld(std::shared_ptr<const grid::GridFile> grid = flatGrid()) {
  auto world = std::make_shared<sim::SimWorld>(std::move(grid), 0, 1);
  iconpack::Pack pack;
  pack.icons = {icon("tank", {-1.75f, 0, -3.5f, 1.75f, 2.5f, 3.5f}, true),
                icon("missile", {-0.1f, -0.1f, -1, 0.1f, 0.1f, 1}, false),
                icon("tree", {-2, 0, -2, 2, 10, 2}, false)};
  world->setIcons(pack);
  return world;
}

sim::Entity tank(const std::string& name, std::uint8_t force, double x, double z, double heading,
                 sim::Mobility mobility = sim::Mobility::tracked) {
  sim::Entity e;
  e.name = name;
  e.icon = 0;
  e.iconName = "tank";
  e.force = force;
  e.mobility = mobility;
  e.position = {x, 0, z};
  e.headingDeg = heading;
  e.vehicle = sim::defaultVehicle(mobility, sim::Domain::land);
  return e;
}

/// Two tanks: blue "b1" at (1000, 1500) heading north, red "r1" 500 m north of it.
std::unique_ptr<sim::Simulation> twoTanks(std::shared_ptr<sim::SimWorld> world = flatWorld()) {
  auto s = std::make_unique<sim::Simulation>(std::move(world));
  EXPECT_TRUE(s->add(tank("b1", 1, 1000, 1500, 0)).ok());
  EXPECT_TRUE(s->add(tank("r1", 2, 1000, 1000, 180, sim::Mobility::simple)).ok());
  return s;
}

SimSessionOptions attachTo(const std::string& name) {
  SimSessionOptions o;
  o.attach = name;
  return o;
}

SimSessionOptions driving() {
  SimSessionOptions o;
  o.drive = true;
  return o;
}

std::unique_ptr<SimSession> session(std::unique_ptr<sim::Simulation> s, SimSessionOptions o = {}) {
  auto r = SimSession::create(std::move(s), std::move(o));
  EXPECT_TRUE(r.ok()) << r.error();
  return r.ok() ? std::move(r.value()) : nullptr;
}

TEST(SimSession, instancesCarryTheOrientationTheTurretRelativeToTheHullAndTheGunsElevation) {
  auto s = session(twoTanks());
  sim::Simulation& sim = s->simulation();
  // A tank that never aimed keeps its turret forward, whatever its heading.
  sim.entity(1).headingDeg = 180;
  scene::DynamicScene d;
  s->fill(d);
  ASSERT_EQ(d.instances.size(), 2u);
  EXPECT_FLOAT_EQ(d.instances[1].turretAzimuthDeg, 0);
  // Aimed at azimuth 150 (a world bearing) on a hull heading 180: -30.
  sim.entity(1).gunAzimuthDeg = 150;
  s->sample();
  s->fill(d);
  EXPECT_NEAR(d.instances[1].turretAzimuthDeg, -30, 1e-4);
  // The gun's elevation is drawn as it is, aimed or not: its 0 is level.
  EXPECT_FLOAT_EQ(d.instances[0].gunElevationDeg, 0);
  sim.entity(0).gunElevationDeg = 12.5;
  sim.entity(1).gunElevationDeg = std::nan("");  // a hostile PDU's float draws level
  s->fill(d);
  EXPECT_FLOAT_EQ(d.instances[0].gunElevationDeg, 12.5f);
  EXPECT_FLOAT_EQ(d.instances[0].turretAzimuthDeg, 0);  // elevating is not aiming
  EXPECT_FLOAT_EQ(d.instances[1].gunElevationDeg, 0);
  // The orientation is the entity's own quaternion, pitch and roll included.
  const Eigen::Quaterniond q = sim::orientationOf(40, 10, -5);
  sim.entity(0).headingDeg = 40;
  sim.entity(0).pitchDeg = 10;
  sim.entity(0).rollDeg = -5;
  s->fill(d);
  const auto& o = d.instances[0].orientation;
  EXPECT_NEAR(std::abs(o[0] * q.x() + o[1] * q.y() + o[2] * q.z() + o[3] * q.w()), 1.0, 1e-6);
  EXPECT_TRUE(d.instances[0].onSurface);
  EXPECT_EQ(d.instances[0].force, 1);
  EXPECT_DOUBLE_EQ(d.instances[0].y, kGround);
  EXPECT_FALSE(d.instances[0].dead);
  sim.kill(0, UINT32_MAX, "test");
  s->fill(d);
  EXPECT_TRUE(d.instances[0].dead);
}

TEST(SimSession, aMissileLeavesAFadingTrailAndFlashesWhereItGoesOff) {
  auto s = session(twoTanks());
  sim::Simulation& sim = s->simulation();
  sim.fire(0, 0, 0, 0, 1);  // the guided missile at r1, 500 m north
  const std::uint16_t missileIcon = *sim.world().iconIndex("missile");
  std::optional<double> wentOff;
  Eigen::Vector3d where = Eigen::Vector3d::Zero();
  bool sawTrail = false, sawMissile = false;
  for (std::uint32_t frame = 1; frame <= 30 * 6; ++frame) {
    const double t = frame / 30.0;
    s->advanceToFlightTime(t);
    EXPECT_EQ(sim.steps(), std::uint64_t(std::llround(t * 60)));  // whole steps of the flight's time
    s->sample();
    scene::DynamicScene d;
    s->fill(d);
    if (!wentOff && sim.counters().detonations > 0) {
      for (const sim::Event& e : sim.events()) {
        if (e.kind == sim::EventKind::detonation) wentOff = e.timeS, where = e.position;
      }
    }
    if (!wentOff) {
      ASSERT_EQ(d.flashes.size(), 0u);
      for (const scene::DynamicInstance& i : d.instances) sawMissile = sawMissile || i.icon == missileIcon;
      if (d.trails.size() == 1) {
        sawTrail = true;
        const scene::Trail& tr = d.trails[0];
        // Oldest first, none older than two seconds, the newest just passed.
        for (std::size_t k = 1; k < tr.points.size(); ++k) EXPECT_LT(tr.points[k].ageS, tr.points[k - 1].ageS);
        EXPECT_LE(tr.points.front().ageS, 2.0f);
        EXPECT_FLOAT_EQ(tr.points.back().ageS, 0.0f);
        EXPECT_FLOAT_EQ(tr.lifeS, 2.0f);
      }
      continue;
    }
    const double since = sim.timeS() - *wentOff;
    if (since < 0.5 - 1e-9) {
      ASSERT_EQ(d.flashes.size(), 1u) << since;
      EXPECT_NEAR(d.flashes[0].ageS, since, 1e-5);
      EXPECT_NEAR(d.flashes[0].x, where.x(), 1e-9);
      EXPECT_NEAR(d.flashes[0].z, where.z(), 1e-9);
      // The trail ends where it went off.
      ASSERT_EQ(d.trails.size(), 1u);
      EXPECT_NEAR(d.trails[0].points.back().z, where.z(), 1e-9);
    } else {
      EXPECT_TRUE(d.flashes.empty()) << since;
    }
    if (since > 2.0 + 1.0 / 30) {
      EXPECT_TRUE(d.trails.empty()) << since;
    }
    // The dead missile is not drawn; the tank it hit is, dead.
    for (const scene::DynamicInstance& i : d.instances) EXPECT_NE(i.icon, missileIcon);
  }
  ASSERT_TRUE(wentOff.has_value());
  EXPECT_TRUE(sawTrail);
  EXPECT_TRUE(sawMissile);
  EXPECT_FALSE(sim.entity(1).alive);
  // The shooter aimed: its turret now points along its fire, relative to the hull.
  scene::DynamicScene d;
  s->fill(d);
  EXPECT_NEAR(d.instances[0].turretAzimuthDeg, sim::turnBetween(sim.entity(0).headingDeg, sim.entity(0).gunAzimuthDeg),
              1e-4);
}

TEST(SimSession, objectsTheSimulationChangedGetTheirLook) {
  auto world = flatWorld();
  sim::StaticObject tree;
  tree.x = 1000;
  tree.z = 1440;  // 60 m north of b1's start
  tree.baseY = kGround;
  tree.radius = 1;
  tree.height = 10;
  tree.icon = 2;
  tree.kind = sim::ObjectKind::tree;
  tree.moduleX = 3;
  tree.moduleZ = 4;
  tree.index = 7;
  sim::StaticObject ruin = tree;
  ruin.x = 1500;
  ruin.moduleX = 5;
  ruin.moduleZ = 6;
  ruin.kind = sim::ObjectKind::house;
  ruin.index = 2;
  ruin.state = sim::ObjectState::ruins;  // before the session: found by its first scan
  world->setObjects({tree, ruin});
  auto sim = twoTanks(world);
  sim->entity(0).mobility = sim::Mobility::simple;
  sim->entity(0).speedMs = sim->entity(0).commands.speedMs = 15;
  auto s = session(std::move(sim));
  scene::DynamicScene d;
  s->fill(d);
  ASSERT_EQ(d.objectOverrides.size(), 1u);
  EXPECT_EQ(d.objectOverrides[0].index, 2u);
  EXPECT_EQ(d.objectOverrides[0].look, scene::ObjectLook::ruins);
  // b1 drives into the tree: the collision's event says which object changed.
  s->advanceToFlightTime(6);
  s->sample();
  const sim::ObjectState state = s->simulation().world().objects()[0].state;
  ASSERT_NE(state, sim::ObjectState::standing) << "the tank should have hit the tree";
  s->fill(d);
  ASSERT_EQ(d.objectOverrides.size(), 2u);
  // Sorted by module (z, then x), then index: the tree's module (3, 4) first.
  const scene::ObjectOverride& o = d.objectOverrides[0];
  EXPECT_EQ(o.moduleX, 3u);
  EXPECT_EQ(o.moduleZ, 4u);
  EXPECT_EQ(o.index, 7u);
  const scene::ObjectLook want = state == sim::ObjectState::knockedOver ? scene::ObjectLook::knockedOver
                          : state == sim::ObjectState::stump     ? scene::ObjectLook::stump
                          : state == sim::ObjectState::ruins     ? scene::ObjectLook::ruins
                                                                 : scene::ObjectLook::destroyed;
  EXPECT_EQ(o.look, want);
  const auto [first, last] = scene::overridesOfModule(d.objectOverrides, 3, 4);
  EXPECT_EQ(last - first, 1);
}

TEST(SimSession, mapMarksAndPanelTellForcesAndTheFocus) {
  auto sim = twoTanks();
  sim->driven = 0;
  auto s = session(std::move(sim));
  s->simulation().fire(0, 0, 0, 0, 1);
  s->sample();
  const auto marks = s->mapMarks();
  ASSERT_EQ(marks.size(), 2u);  // the missile is not on the map
  EXPECT_EQ(marks[1].force, 2);
  EXPECT_DOUBLE_EQ(marks[1].x, 1000);
  EXPECT_DOUBLE_EQ(marks[1].z, 1000);
  EXPECT_TRUE(marks[1].alive);
  EXPECT_FALSE(marks[0].selected);
  const auto lines = s->panelLines();
  ASSERT_GE(lines.size(), 4u);
  EXPECT_EQ(lines[0], "SIM 0.0 S  ENTITIES 2/2 ALIVE  MUNITIONS 1");
  EXPECT_EQ(lines[1], "VIEW STEALTH");
  EXPECT_EQ(lines[2], "B1  TANK  BLUE  ALIVE");  // the scenario's driven entity
  EXPECT_EQ(lines[3], "SPD 0 KM/H  HDG 000\xC2\xB0  FUEL 100%");
  s->simulation().kill(1, UINT32_MAX, "test");
  s->attach(1);
  EXPECT_EQ(s->panelLines()[0], "SIM 0.0 S  ENTITIES 1/2 ALIVE  MUNITIONS 1");
  EXPECT_EQ(s->panelLines()[1], "VIEW ATTACHED TO R1");
  EXPECT_EQ(s->panelLines()[2], "R1  TANK  RED  DEAD");
  EXPECT_TRUE(s->mapMarks()[1].selected);
  EXPECT_FALSE(s->mapMarks()[1].alive);
}

TEST(SimSession, theTetheredEyeFollowsBehindAndAbove) {
  const auto grid = flatGrid();
  auto s = session(twoTanks(flatWorld(grid)), attachTo("b1"));
  ASSERT_EQ(s->mode(), ViewMode::attached);
  sim::Entity& e = s->simulation().entity(0);
  e.headingDeg = 90;  // east
  world::GroundClamp ground(grid);
  const world::Pose p = s->tetherPose(ground);
  const double ex = p.easting - kOriginE, ez = kOriginN - p.northing;
  // Behind (west of) the tank, on its line, above it, looking down at it.
  const double back = e.position.x() - ex;
  EXPECT_GE(back, 18.0);
  EXPECT_LE(back, 250.0);
  EXPECT_NEAR(ez, e.position.z(), 1e-6);
  EXPECT_NEAR(*p.altitude - kGround, 0.4 * back, 1e-6);
  EXPECT_DOUBLE_EQ(p.headingDeg, 90);
  const double down = std::atan2(*p.altitude - (kGround + 0.5 * e.height), back) * 180 / 3.14159265358979;
  EXPECT_NEAR(*p.pitchDeg, -down + 3, 1e-6);
  // The eye's heading eases after the entity's: 0.6 s of simulated time
  // after a turn to 180 it has come 1 - 1/e of the way.
  s->advanceToStep(36);
  e.headingDeg = 180;  // after the steps, which take the heading from the orientation
  const world::Pose q = s->tetherPose(ground);
  EXPECT_NEAR(q.headingDeg, 90 + 90 * (1 - std::exp(-1.0)), 0.5);
}

TEST(SimSession, drivingFeedsTheCommandsAndAllStopStops) {
  auto sim = twoTanks();
  sim->driven = 0;
  auto s = session(std::move(sim), driving());
  ASSERT_EQ(s->mode(), ViewMode::driving);
  sim::Entity& e = s->simulation().entity(0);
  EXPECT_EQ(e.controller, sim::Controller::driven);
  EXPECT_TRUE(e.autopilot);
  EXPECT_TRUE(s->steers(world::Key::up));
  EXPECT_FALSE(s->steers(world::Key::map));
  // Four presses of Up: 10 m/s commanded; one of Left: 5 degrees to port.
  for (int k = 0; k < 4; ++k) {
    s->handle(world::KeyEvent{world::Key::up, true});
    s->handle(world::KeyEvent{world::Key::up, false});
  }
  s->handle(world::KeyEvent{world::Key::left, true});
  s->handle(world::KeyEvent{world::Key::left, false});
  s->step();
  EXPECT_DOUBLE_EQ(e.commands.speedMs, 10);
  EXPECT_DOUBLE_EQ(e.commands.headingDeg, 355);
  // The autopilot turns them into track forces: the tank gets going and turns.
  s->advanceToStep(60 * 15);
  EXPECT_GT(e.speedMs, 5);
  EXPECT_NEAR(sim::turnBetween(e.headingDeg, 355), 0, 2);
  s->handle(ViewerKey::allStop);
  EXPECT_DOUBLE_EQ(e.commands.speedMs, 0);
  EXPECT_DOUBLE_EQ(s->driveCommands()->first, 0);
  s->advanceToStep(60 * 30);
  EXPECT_LT(std::abs(e.speedMs), 0.5);
  // D again stops driving; E goes back to the stealth eye.
  s->handle(ViewerKey::drive);
  EXPECT_EQ(s->mode(), ViewMode::attached);
  s->handle(ViewerKey::stealth);
  EXPECT_EQ(s->mode(), ViewMode::stealth);
  EXPECT_FALSE(s->steers(world::Key::up));
}

TEST(SimSession, tabCyclesThroughTheEntitiesButTheMunitions) {
  auto s = session(twoTanks());
  s->simulation().fire(0, 0, 0, 0, 1);
  s->handle(ViewerKey::nextEntity);
  EXPECT_EQ(s->attached(), 0u);  // from the stealth eye: the first
  s->handle(ViewerKey::nextEntity);
  EXPECT_EQ(s->attached(), 1u);
  s->handle(ViewerKey::nextEntity);
  EXPECT_EQ(s->attached(), 0u);  // the missile (id 2) is skipped
  s->handle(ViewerKey::previousEntity);
  EXPECT_EQ(s->attached(), 1u);
}

TEST(SimSession, attachingToNobodyOrDrivingNobodySaysWhy) {
  auto r = SimSession::create(twoTanks(), attachTo("nobody"));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().find("--attach nobody: no entity of that name in the scenario (it has b1, r1)"),
            std::string::npos)
      << r.error();
  auto d = SimSession::create(twoTanks(), driving());
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().find("marks no entity `driven`"), std::string::npos) << d.error();
  // --sim-start runs the simulation before the first frame.
  SimSessionOptions early;
  early.startS = 2;
  auto started = session(twoTanks(), early);
  EXPECT_EQ(started->simulation().steps(), 120u);
  started->advanceToFlightTime(1);
  EXPECT_EQ(started->simulation().steps(), 180u);
}

TEST(SimSession, aFlightStepsAsManyStepsAsTheStepHostGivesForItsTime) {
  auto s = session(twoTanks());
  // 1.01 s is 60.6 steps: round to 61, as `sandtable sim --duration 1.01`
  // and `bench sim` step (all through sim::StepHost::stepsFor).
  s->advanceToFlightTime(1.01);
  EXPECT_EQ(s->simulation().steps(), 61u);
  EXPECT_EQ(s->stepHost().stepsFor(1.01), 61u);
  // Hooks added to the session's host run for every step it takes.
  std::uint64_t before = 0, after = 0;
  s->stepHost().addBeforeStep([&](sim::Simulation&) { ++before; });
  s->stepHost().addAfterStep([&](sim::Simulation&) { ++after; });
  s->advanceToFlightTime(2.0);
  s->step();
  EXPECT_EQ(s->simulation().steps(), 121u);
  EXPECT_EQ(before, 60u);
  EXPECT_EQ(after, 60u);
}

TEST(SimSession, removingTheDrivenEntityFromAStepHookLeavesTheStealthEye) {
  auto sim = twoTanks();
  sim->driven = 0;
  auto s = session(std::move(sim), driving());
  ASSERT_EQ(s->mode(), ViewMode::driving);
  bool removed = false;
  s->stepHost().addBeforeStep([&](sim::Simulation& at) {
    if (at.steps() == 30) removed = at.remove(0);
  });
  s->advanceToFlightTime(1.0);
  s->sample();
  ASSERT_TRUE(removed);
  EXPECT_EQ(s->mode(), ViewMode::stealth);
  EXPECT_FALSE(s->attached().has_value());
  EXPECT_FALSE(s->simulation().driven.has_value());
  // Everything a frame asks still answers, about what is left.
  ASSERT_EQ(s->mapMarks().size(), 1u);
  EXPECT_EQ(s->panelLines().size(), 2u);
  const auto frame = nlohmann::json::parse(s->frameJson());
  EXPECT_TRUE(frame["attached"].is_null());
  EXPECT_EQ(frame["entities"], 1);
  s->handle(ViewerKey::nextEntity);
  EXPECT_EQ(s->attached(), 1u);  // r1 keeps its id
  s->handle(ViewerKey::drive);
  EXPECT_EQ(s->mode(), ViewMode::driving);
  s->advanceToFlightTime(2.0);
  EXPECT_EQ(s->simulation().steps(), 120u);
}

}  // namespace
}  // namespace sandtable::viewer
