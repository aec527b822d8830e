// Every run-time reader of the terrain reads the HeightField (issue 34 item
// 3): a second implementation that raises one patch of posts by 50 m is
// seen by the ground clamp, by `sample`'s query (Terrain), by the renderer's
// CPU side (mesh mode's display buffer), by the map and by the simulator
// (an entity standing on it), and nothing outside the patch moves: every
// value away from it equals the grid file's own.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/render/map_view.h"
#include "sandtable/scene/display_buffer.h"
#include "sandtable/sim/motion.h"
#include "sandtable/sim/scenario_load.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/sim_world.h"
#include "sandtable/testing/fixtures.h"
#include "sandtable/world/ground.h"
#include "sandtable/world/terrain.h"

namespace sandtable::viewer {
namespace {

constexpr std::uint32_t kPosts = 101;
constexpr double kSpacing = 10, kOriginE = 500000, kOriginN = 4000000;
constexpr float kRaise = 50;
/// Posts i 40..44, j 50..53: a 4 x 3 square patch, well inside the grid
/// and below its highest post once raised.
constexpr grid::PostRect kPatch{40, 50, 45, 54};

float baseElevation(std::uint32_t i, std::uint32_t j) { return 100.0f + 2.0f * float(i) + float(j); }

std::shared_ptr<const grid::GridFile> baseGrid() {
  const std::string path = std::filesystem::temp_directory_path().string() + "/sandtable_hf_readers_" +
                           std::to_string(::getpid()) + ".grid";
  const Status st = fixtures::writeGrid(path, kPosts, kPosts, kSpacing, baseElevation, kOriginE, kOriginN);
  EXPECT_TRUE(st) << st.error();
  auto g = grid::GridFile::open(path);
  EXPECT_TRUE(g) << g.error();
  std::filesystem::remove(path);  // the mapping stays valid
  return g.value();
}

/// The grid's posts with kPatch raised by raise(): a second HeightField,
/// changing once (as dynamic terrain will).
class RaisedPatch final : public grid::HeightField {
 public:
  explicit RaisedPatch(std::shared_ptr<const grid::HeightField> base) : base_(std::move(base)) {}
  const grid::PostLayout& layout() const override { return base_->layout(); }
  float elevation(std::uint32_t i, std::uint32_t j) const override {
    return base_->elevation(i, j) + (kPatch.contains(i, j) ? dz_.load(std::memory_order_acquire) : 0.0f);
  }
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const override { return base_->normal(i, j); }
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const override { return base_->material(i, j); }
  std::pair<float, float> elevationBounds() const override {
    const auto b = base_->elevationBounds();
    return {b.first, b.second + kRaise};
  }
  std::uint64_t generation() const override { return generation_.load(std::memory_order_acquire); }
  std::uint64_t regionGeneration(const grid::PostRect& r) const override {
    return r.intersects(kPatch) ? generation() : 0;
  }
  void raise() {
    dz_.store(kRaise, std::memory_order_release);
    generation_.store(1, std::memory_order_release);
    notifyChanged({kPatch, 1});
  }

 private:
  std::shared_ptr<const grid::HeightField> base_;
  std::atomic<float> dz_{0};
  std::atomic<std::uint64_t> generation_{0};
};

struct Fields {
  std::shared_ptr<const grid::GridFile> file = baseGrid();
  std::shared_ptr<const grid::HeightField> base = grid::heightField(file);
  std::shared_ptr<RaisedPatch> raised = std::make_shared<RaisedPatch>(base);
  Fields() { raised->raise(); }
};

bool inPatch(std::uint32_t i, std::uint32_t j) { return kPatch.contains(i, j); }
/// Square (i, j) (posts i..i+1, j..j+1) touches no raised post.
bool squareOutside(std::uint32_t i, std::uint32_t j) {
  return !inPatch(i, j) && !inPatch(i + 1, j) && !inPatch(i, j + 1) && !inPatch(i + 1, j + 1);
}
bool squareInside(std::uint32_t i, std::uint32_t j) {
  return inPatch(i, j) && inPatch(i + 1, j) && inPatch(i, j + 1) && inPatch(i + 1, j + 1);
}

/// Points inside square (i, j): both triangles, and a post.
std::array<std::pair<double, double>, 3> pointsIn(std::uint32_t i, std::uint32_t j) {
  return {{{(i + 0.3) * kSpacing, (j + 0.2) * kSpacing},
           {(i + 0.8) * kSpacing, (j + 0.7) * kSpacing},
           {i * kSpacing, j * kSpacing}}};
}

TEST(HeightFieldReaders, theGroundClampAndSamplesSeeThePatchAndNothingElse) {
  const Fields f;
  // The clamp as the flight and the simulator build it (module mode: 16
  // squares a module, 3 levels) and level 0 as `sample` reads it.
  const world::GroundClamp rawClamp(f.raised, 16, 3), baseClamp(f.base, 16, 3);
  const world::Terrain raw(f.raised), base(f.file);
  int inside = 0, outside = 0;
  for (std::uint32_t j = 0; j + 1 < kPosts; ++j) {
    for (std::uint32_t i = 0; i + 1 < kPosts; ++i) {
      const bool out = squareOutside(i, j), in = squareInside(i, j);
      for (const auto& [x, z] : pointsIn(i, j)) {
        const double dClamp = *rawClamp.surfaceXZ(x, z) - *baseClamp.surfaceXZ(x, z);
        const auto a = raw.sampleXZ(x, z), b = base.sampleXZ(x, z);
        const double dSample = a->elevation - b->elevation;
        EXPECT_EQ(a->material, b->material);
        if (out) {
          ASSERT_EQ(dClamp, 0.0) << i << "," << j;
          ASSERT_EQ(dSample, 0.0) << i << "," << j;
          ++outside;
        } else if (in) {
          ASSERT_NEAR(dClamp, kRaise, 1e-9) << i << "," << j;
          ASSERT_NEAR(dSample, kRaise, 1e-9) << i << "," << j;
          ++inside;
        } else {  // the patch's edge squares slope up to it
          ASSERT_GE(dSample, -1e-9);
          ASSERT_LE(dSample, kRaise + 1e-9);
        }
      }
    }
  }
  EXPECT_EQ(inside, 4 * 3 * 3);  // 4 x 3 squares wholly inside, 3 points each
  EXPECT_GT(outside, 29000);
  // The query `sample` makes, in projected coordinates, at a raised post
  // and at one beside the patch.
  const double e = kOriginE + 42 * kSpacing, n = kOriginN - 51 * kSpacing;
  EXPECT_DOUBLE_EQ(raw.sampleEN(e, n)->elevation, baseElevation(42, 51) + kRaise);
  EXPECT_DOUBLE_EQ(raw.sampleEN(e + 3 * kSpacing, n)->elevation, baseElevation(45, 51));
  // Coarser levels see it too where their lattice has a raised post: level
  // 1 keeps every other post, and (42, 52) is one.
  EXPECT_NEAR(*rawClamp.surfaceXZ(42 * kSpacing, 52 * kSpacing, {1, 0}), baseElevation(42, 52) + kRaise, 1e-9);
  EXPECT_EQ(*rawClamp.surfaceXZ(10 * kSpacing, 10 * kSpacing, {1, 0}), *baseClamp.surfaceXZ(10 * kSpacing, 10 * kSpacing, {1, 0}));
}

TEST(HeightFieldReaders, meshModeDrawsThePatchAndNothingElse) {
  const Fields f;
  scene::Camera cam;
  cam.x = 420;
  cam.z = 900;
  cam.y = 400;
  cam.headingDeg = 0;  // looking north over the patch
  cam.viewDistance = 800;
  scene::DisplayBuffer raised, base;
  fillDisplayBuffer(*f.raised, cam, 1, raised);
  fillDisplayBuffer(*f.base, cam, 1, base);
  ASSERT_EQ(raised.vertices.size(), base.vertices.size());
  int moved = 0;
  for (std::size_t k = 0; k < raised.vertices.size(); ++k) {
    const scene::TerrainVertex& a = raised.vertices[k];
    const scene::TerrainVertex& b = base.vertices[k];
    const auto i = std::uint32_t(std::lround((a.x + raised.originX) / kSpacing));
    const auto j = std::uint32_t(std::lround((a.z + raised.originZ) / kSpacing));
    ASSERT_EQ(a.x, b.x);
    ASSERT_EQ(a.z, b.z);
    ASSERT_EQ(b.y, baseElevation(i, j));
    ASSERT_EQ(a.y, baseElevation(i, j) + (inPatch(i, j) ? kRaise : 0.0f)) << i << "," << j;
    moved += inPatch(i, j);
  }
  EXPECT_GT(moved, 0);  // the patch is in view
}

TEST(HeightFieldReaders, theMapRedrawsThePatchWhenTheFieldChangesAndNothingElse) {
  const Fields f;
  const auto field = std::make_shared<RaisedPatch>(f.base);  // not yet raised
  render::MapView map(field);
  render::MapView reference(f.base);
  map.setVisible(true);
  render::Image frame;
  frame.width = frame.height = 400;
  frame.rgba.assign(400 * 400 * 4, 0);
  map.compose(frame, 500, 500, 0);
  EXPECT_EQ(map.overview().rgba, reference.overview().rgba);
  field->raise();
  map.compose(frame, 500, 500, 0);  // sees the new generation
  const render::Image& a = map.overview();
  const render::Image& b = reference.overview();
  ASSERT_EQ(a.width, kPosts);  // one pixel per post
  int changed = 0;
  for (std::uint32_t y = 0; y < a.height; ++y) {
    for (std::uint32_t x = 0; x < a.width; ++x) {
      const std::size_t p = (std::size_t(y) * a.width + x) * 4;
      const bool same = std::equal(a.rgba.begin() + std::ptrdiff_t(p), a.rgba.begin() + std::ptrdiff_t(p + 4),
                                   b.rgba.begin() + std::ptrdiff_t(p));
      ASSERT_EQ(same, !inPatch(x, y)) << x << "," << y;
      changed += !same;
    }
  }
  EXPECT_EQ(changed, 5 * 4);
}

sim::Entity tankAt(const std::string& name, double x, double z) {
  sim::Entity e;
  e.name = name;
  e.mobility = sim::Mobility::tracked;
  e.position = {x, 0, z};
  e.vehicle = sim::defaultVehicle(e.mobility, sim::Domain::land);
  e.radius = 1.5;
  e.halfLength = 3;
  e.halfWidth = 1.5;
  return e;
}

TEST(HeightFieldReaders, anEntityStandsOnThePatchAndOneBesideItOnTheGrid) {
  const Fields f;
  auto world = std::make_shared<sim::SimWorld>(f.raised, 0, 1);
  sim::Simulation s(world);
  // At the patch's middle post, and 100 m east of it.
  const auto on = s.add(tankAt("on", 42 * kSpacing, 52 * kSpacing));
  const auto off = s.add(tankAt("off", 52 * kSpacing, 52 * kSpacing));
  ASSERT_TRUE(on.ok() && off.ok());
  for (int k = 0; k < 3; ++k) s.step();
  EXPECT_NEAR(s.entity(on.value()).position.y(), baseElevation(42, 52) + kRaise, 1e-6);
  EXPECT_NEAR(s.entity(off.value()).position.y(), baseElevation(52, 52), 1e-6);
  EXPECT_NEAR(*world->groundAt(41.5 * kSpacing, 51.5 * kSpacing), baseElevation(41, 51) + 0.5 * 3 + kRaise, 1e-9);
}

}  // namespace
}  // namespace sandtable::viewer
