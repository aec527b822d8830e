// TerrainEditing (terrain_edits.h) on a synthetic world whose posts the
// editor overlays: a round that hits the ground leaves, after the step it
// detonated in (not before), a crater centred on the detonation point; the ground the
// simulation reads is then that much lower there (checked against a world
// over the same grid with no edits, minus the crater's depth), and a tree
// standing in the crater falls.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>

#include "sandtable/edits/editor.h"
#include "sandtable/edits/profile.h"
#include "sandtable/paging/world.h"
#include "sandtable/sim/step_host.h"
#include "sandtable/sim/terrain_edits.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

double slope(double x, double z) { return 80 + 0.05 * x - 0.03 * z + 4 * std::sin(x / 90.0); }

/// A grid with the slope, as the editor's base World (no modules).
std::shared_ptr<const paging::World> baseWorld() {
  const std::string path = std::filesystem::temp_directory_path().string() + "/sandtable_terrain_edits_" +
                           std::to_string(::getpid()) + ".grid";
  const double spacing = 10;
  const Status st = fixtures::writeGrid(path, 201, 201, spacing, [&](std::uint32_t i, std::uint32_t j) {
    return static_cast<float>(slope(i * spacing, j * spacing));
  });
  EXPECT_TRUE(st) << st.error();
  auto grid = grid::GridFile::open(path);
  EXPECT_TRUE(grid) << grid.error();
  std::filesystem::remove(path);  // the mapping stays valid
  Database db;
  db.grid = grid.value();
  return std::make_shared<const paging::World>(std::move(db));
}

Entity shooter() {
  Entity e;
  e.name.push_back('s');
  e.position = {1000, 0, 1000};
  e.radius = 2;
  e.sphereRadius = 3;
  e.height = 2.5;
  e.halfLength = 3;
  e.halfWidth = 1.5;
  return e;
}

/// One run: a ballistic round fired north, 5 degrees down, stepped one
/// step at a time until it detonates (at most 10 s).
struct Battle {
  std::shared_ptr<const paging::World> base = baseWorld();
  std::unique_ptr<edits::Editor> editor;
  std::shared_ptr<SimWorld> world;
  std::unique_ptr<Simulation> sim;
  std::unique_ptr<TerrainEditing> editing;
  std::unique_ptr<StepHost> host;

  Battle() {
    auto ed = edits::Editor::open(base);
    EXPECT_TRUE(ed) << ed.error();
    editor = std::move(ed.value());
    world = std::make_shared<SimWorld>(editor->world()->heights(), 0, 1);
    sim = std::make_unique<Simulation>(world);
    editing = std::make_unique<TerrainEditing>(*sim, *editor);
    host = std::make_unique<StepHost>(*sim);
    editing->attach(*host);
    EXPECT_TRUE(sim->add(shooter()));
  }
  /// The detonation, or null when none came.
  const Event* fireAndStepToDetonation() {
    sim->fire(0, 0, -5, 1);  // the ballistic round: a small crater
    for (int k = 0; k < 600 && sim->counters().detonations == 0; ++k) {
      EXPECT_TRUE(editor->edits().empty());  // nothing before the step that hit
      host->step();
    }
    for (const Event& ev : sim->events()) {
      if (ev.kind == EventKind::detonation) return &ev;
    }
    return nullptr;
  }
};

TEST(TerrainEditing, aRoundThatHitsTheGroundDigsItsCraterAtTheImpactAfterTheStep) {
  Battle run;
  const Event* det = run.fireAndStepToDetonation();
  ASSERT_NE(det, nullptr);
  ASSERT_EQ(det->detail, "terrain");
  // The step that detonated is the one whose after-step hook applied it.
  ASSERT_EQ(run.editor->edits().size(), 1u);
  const edit::Edit& c = run.editor->edits()[0];
  EXPECT_EQ(c.kind, edit::Kind::crater);
  EXPECT_EQ(c.points[0][0], det->position.x());
  EXPECT_EQ(c.points[0][1], det->position.z());
  EXPECT_EQ(c.time, det->timeS);  // stamped as the detonation was
  EXPECT_EQ(c.radius, edits::kCraterSmall.radius);
  EXPECT_EQ(c.depth, edits::kCraterSmall.depth);
  EXPECT_EQ(run.editing->counters().local, 1u);
  EXPECT_EQ(run.editing->counters().applied, 1u);
  EXPECT_EQ(run.editing->counters().failed, 0u) << run.editing->counters().lastError;

  // The same grid with no edits: the ground before the crater.
  SimWorld unedited(run.base->heights(), 0, 1);
  const double x = c.points[0][0], z = c.points[0][1];
  const double before = *unedited.groundAt(x, z);
  // The detonation was found on the ground as it was (Figure 27, 1 cm).
  EXPECT_NEAR(det->position.y(), before, 0.02);
  // The clamp now reads the crater: depth d below the old ground at the
  // centre, less what the fine lattice (10 m posts / 32 cells) can hold of
  // the bowl between its posts: at most (d + rim) h^2 / (2 R^2) = 0.031 m.
  const double d = c.depth, rim = d / 4, h = 10.0 / 32;
  const double lattice = (d + rim) * h * h / (2 * c.radius * c.radius);
  const double after = *run.world->groundAt(x, z);
  EXPECT_LE(after, before - d + lattice);
  EXPECT_GE(after, before - d - 1e-4);
  EXPECT_NEAR(after, before - d, lattice);
  // The rim crest stands above the old ground, at most d / 4 (the fine
  // lattice cuts the crest's kink between its posts); beyond twice the
  // radius nothing changed.
  const double crest = *run.world->groundAt(x + c.radius, z) - *unedited.groundAt(x + c.radius, z);
  EXPECT_GT(crest, 0);
  EXPECT_LE(crest, rim + 1e-4);
  EXPECT_EQ(*run.world->groundAt(x + 2.5 * c.radius, z), *unedited.groundAt(x + 2.5 * c.radius, z));
  // A land entity put down at the centre stands in the crater.
  Entity v = shooter();
  v.position = {x, 0, z};
  const auto id = run.sim->add(v);
  ASSERT_TRUE(id);
  EXPECT_NEAR(run.sim->entity(id.value()).position.y(), after, run.sim->options().groundToleranceM);
}

TEST(TerrainEditing, aTreeInTheCraterFalls) {
  // Where the round lands (the run is deterministic)...
  double x = 0, z = 0;
  {
    Battle first;
    const Event* det = first.fireAndStepToDetonation();
    ASSERT_NE(det, nullptr);
    x = det->position.x(), z = det->position.z();
  }
  // ...a small tree beside it, inside the crater's radius, and one outside.
  Battle run;
  auto tree = [&](double tx, double tz) {
    StaticObject o;
    o.x = tx, o.z = tz;
    o.baseY = *run.world->groundAt(tx, tz);
    o.radius = 0.05;
    o.height = 0.1;
    o.kind = ObjectKind::tree;
    return o;
  };
  run.world->setObjects({tree(x + 0.7, z), tree(x + 1.6, z)});
  const Event* det = run.fireAndStepToDetonation();
  ASSERT_NE(det, nullptr);
  ASSERT_EQ(det->detail, "terrain");  // it hit the ground, not the tree
  EXPECT_EQ(det->position.x(), x);
  EXPECT_EQ(run.editing->counters().objectsFelled, 1u);
  EXPECT_EQ(run.world->objects()[0].state, ObjectState::knockedOver);
  EXPECT_EQ(run.world->objects()[1].state, ObjectState::standing);
}

}  // namespace
}  // namespace sandtable::sim
