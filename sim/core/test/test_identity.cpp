// Stable entity ids: an entity removed in the middle leaves the others
// their ids and, compared with a run where it stays, their motion bit for
// bit; what named it (a homing missile, a script, the driven entity, the
// recorder, a pending launch) lets go; ids are never reused; the event
// log names entities by id, removed ones too.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include "sandtable/sim/scenario_load.h"
#include "sandtable/sim/report.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

Entity tank(const char* name, double x, double z, double heading, double speed, Mobility m = Mobility::simple) {
  Entity e;
  e.name = name;
  e.mobility = m;
  e.position = {x, 0, z};
  e.headingDeg = heading;
  e.speedMs = speed;
  e.vehicle = defaultVehicle(m, Domain::land);
  e.autopilot = true;
  e.radius = 2;
  e.sphereRadius = 3;
  e.height = 2.5;
  e.halfLength = 3;
  e.halfWidth = 1.5;
  return e;
}

/// Five entities far apart (no two meet in the run): simple, tracked,
/// wheeled and a simple air entity, the middle one (id 2) the one removed.
std::unique_ptr<Simulation> five() {
  auto w = test::makeWorld([](double x, double z) { return 40 + 15 * std::sin(x / 150.0) * std::cos(z / 190.0); });
  auto s = std::make_unique<Simulation>(w);
  EXPECT_EQ(s->add(tank("zero", 200, 1800, 10, 6)).value(), 0u);
  EXPECT_EQ(s->add(tank("one", 600, 1800, 350, 0, Mobility::tracked)).value(), 1u);
  EXPECT_EQ(s->add(tank("two", 1000, 1000, 90, 5, Mobility::wheeled)).value(), 2u);
  EXPECT_EQ(s->add(tank("three", 1400, 1800, 0, 0, Mobility::wheeled)).value(), 3u);
  Entity air = tank("four", 1800, 1800, 0, 60);
  air.domain = Domain::air;
  air.position.y() = 400;
  EXPECT_EQ(s->add(air).value(), 4u);
  // The tracked and wheeled ones drive on their autopilots.
  s->entity(1).commands.speedMs = 8;
  s->entity(3).commands.speedMs = 8;
  s->entity(3).commands.headingDeg = 20;
  return s;
}

TEST(Identity, removingAnEntityInTheMiddleLeavesTheOthersTheirIdsAndTheirMotion) {
  auto kept = five();
  auto removed = five();
  std::vector<Eigen::Vector3d> start;
  for (const Entity& e : kept->entities()) start.push_back(e.position);
  kept->runFor(3);
  removed->runFor(3);
  ASSERT_TRUE(removed->remove(2));
  EXPECT_EQ(removed->find(2), nullptr);
  EXPECT_FALSE(removed->remove(2));  // once
  EXPECT_EQ(removed->entities().size(), 4u);
  kept->runFor(20);
  removed->runFor(20);
  for (std::uint32_t id : {0u, 1u, 3u, 4u}) {
    const Entity* a = kept->find(id);
    const Entity* b = removed->find(id);
    ASSERT_NE(b, nullptr) << id;
    EXPECT_EQ(b->id, id);
    EXPECT_EQ(b->name, a->name);
    // Bit for bit: removal touched nothing of theirs.
    EXPECT_EQ(b->position, a->position) << id;
    EXPECT_EQ(b->velocity, a->velocity) << id;
    EXPECT_EQ(b->headingDeg, a->headingDeg) << id;
    // They moved (the comparison is not between statues).
    EXPECT_GT((b->position - start[id]).norm(), 50) << id;
  }
  // Iteration is id order without the gap.
  std::vector<std::uint32_t> ids;
  for (const Entity& e : removed->entities()) ids.push_back(e.id);
  EXPECT_EQ(ids, (std::vector<std::uint32_t>{0, 1, 3, 4}));
}

TEST(Identity, anIdIsNeverReusedInARun) {
  auto s = five();
  std::set<std::uint32_t> given = {0, 1, 2, 3, 4};
  ASSERT_TRUE(s->remove(4));  // the last one: its id must not come back either
  ASSERT_TRUE(s->remove(0));
  const std::uint32_t missile = s->fire(1, 0, 2, 0);
  EXPECT_EQ(missile, 5u);
  given.insert(missile);
  for (int k = 0; k < 3; ++k) {
    const std::uint32_t id = s->add(tank("late", 1000, 400 + 100.0 * k, 0, 0)).value();
    EXPECT_FALSE(given.count(id)) << id;
    given.insert(id);
    s->runFor(0.5);
    ASSERT_TRUE(s->remove(id));
  }
  EXPECT_EQ(s->nextId(), 9u);
  // A failed add uses up no id.
  EXPECT_FALSE(s->add(tank("off", -500, 100, 0, 0)).ok());
  EXPECT_EQ(s->add(tank("ok", 900, 900, 0, 0)).value(), 9u);
  // Firing from an entity that is gone launches nothing.
  EXPECT_EQ(s->fire(0, 0, 2, 0), UINT32_MAX);
  EXPECT_EQ(s->nextId(), 10u);
}

TEST(Identity, whatNamedARemovedEntityLetsGo) {
  auto w = test::makeWorld([](double, double) { return 20.0; });
  Simulation s(w);
  Entity shooter = tank("shooter", 200, 1000, 90, 0);
  shooter.armed = true;
  shooter.force = 1;
  ASSERT_EQ(s.add(shooter).value(), 0u);
  Entity target = tank("target", 1800, 1000, 0, 0);
  target.force = 2;
  ASSERT_EQ(s.add(target).value(), 1u);
  ASSERT_EQ(s.add(tank("scripted", 1000, 1600, 0, 0)).value(), 2u);
  // A script line for script entity 7 every second, mapped to id 2.
  std::vector<ScriptLine> lines;
  for (int k = 0; k < 20; ++k) {
    ScriptLine l;
    l.setTime(k);
    l.entity = 7;
    l.x = 1000 + 5.0 * k;
    l.z = 1600;
    l.directionDeg = 90;
    l.speed = 5;
    lines.push_back(l);
  }
  s.addScript(lines, {{7, 2}});
  s.driven = 1;
  s.record(1, 2, 0);
  // A guided missile homing on the target; it turns towards it at first.
  const std::uint32_t missile = s.fire(0, 80, 2, 0, 1);
  ASSERT_EQ(missile, 3u);
  s.runFor(1);
  const double headingBefore = s.entity(missile).headingDeg;
  EXPECT_GT(headingBefore, 80.5);  // turned south, towards the target at 90
  ASSERT_TRUE(s.remove(1));
  ASSERT_TRUE(s.remove(2));
  EXPECT_FALSE(s.driven.has_value());
  const std::size_t recorded = s.recorder()->lines().size();
  s.runFor(1);
  // Straight on (no target to turn to), and nothing read the removed ones.
  const Entity& m = s.entity(missile);
  EXPECT_TRUE(m.alive);
  EXPECT_NEAR(m.headingDeg, headingBefore, 1e-9);
  EXPECT_EQ(s.recorder()->lines().size(), recorded);
  s.runFor(20);  // the script runs out for id 2 without touching anyone
  EXPECT_EQ(s.entities().size(), 2u);
}

TEST(Identity, theEventLogNamesEntitiesByIdRemovedOnesToo) {
  auto w = test::makeWorld([](double, double) { return 20.0; });
  Simulation s(w);
  ASSERT_EQ(s.add(tank("alpha", 500, 1000, 90, 0)).value(), 0u);
  ASSERT_EQ(s.add(tank("bravo", 900, 1000, 90, 0)).value(), 1u);
  ASSERT_EQ(s.add(tank("charlie", 1300, 1000, 90, 0)).value(), 2u);
  const std::uint32_t round = s.fire(1, 0, 1, 1);  // bravo fires a round north
  s.runFor(0.5);
  ASSERT_TRUE(s.remove(1));
  const std::uint32_t late = s.fire(2, 180, 1, 1);  // charlie fires after bravo is gone
  s.runFor(0.5);
  const nlohmann::json log = eventsJson(s);
  auto find = [&](const std::string& kind, std::uint32_t entity) -> const nlohmann::json* {
    for (const auto& ev : log) {
      if (ev["kind"] == kind && ev["entity"] == entity) return &ev;
    }
    return nullptr;
  };
  const nlohmann::json* fired = find("fire", round);
  ASSERT_NE(fired, nullptr);
  EXPECT_EQ((*fired)["other"], 1u);
  EXPECT_EQ((*fired)["other_name"], "bravo");  // removed since, still named
  const nlohmann::json* gone = find("removed", 1);
  ASSERT_NE(gone, nullptr);
  EXPECT_EQ((*gone)["name"], "bravo");
  EXPECT_DOUBLE_EQ((*gone)["t"].get<double>(), 0.5);
  const nlohmann::json* after = find("fire", late);
  ASSERT_NE(after, nullptr);
  EXPECT_EQ(late, 4u);
  EXPECT_EQ((*after)["other"], 2u);
  EXPECT_EQ((*after)["other_name"], "charlie");
}

}  // namespace
}  // namespace sandtable::sim
