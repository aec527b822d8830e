// The one ground clamp (world/ground.h, seed Figure 23) on real, rugged
// terrain: Crater Lake at 31.25 m, 1 km modules, 4 levels.
//  - Its surface at every level and morph matches the surface the built
//    load modules carry (decoded from modules.pack: an independent path
//    from the bytes, not from the grid).
//  - In a rendered frame, the ground straight below the eye is the
//    requested height below it even where a coarse level is drawn there
//    and differs from the finest grid by metres (the eye used to follow
//    the finest grid: it sank into coarse hills and floated over valleys).
#include <cmath>
#include <random>

#include "sandtable/converters/elevation.h"
#include "sandtable/formats/database.h"
#include "sandtable/render/image.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/lod.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/world/ground.h"
#include "sandtable/world/terrain.h"
#include "test_support.h"
#include "sandtable/testing/require.h"

namespace sandtable::test {
namespace {

using world::DrawnLevel;
using world::GroundClamp;

class GroundClampTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    tmp_ = new TempDir("ground-clamp");
    convert::ElevationOptions o;
    o.sources = {data("elevation/geotiff/craterlake-elev-16bit-30m.tif")};
    o.spacing = 31.25;
    o.output = *tmp_ / "crater";
    auto r = convert::buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    auto db = openDatabase(o.output);
    ASSERT_TRUE(db.ok()) << db.error();
    db_ = new Database(std::move(db.value()));
  }
  static void TearDownTestSuite() {
    delete db_;
    delete tmp_;
    db_ = nullptr;
    tmp_ = nullptr;
  }
  void SetUp() override {
    SANDTABLE_REQUIRE_DATA();
    ASSERT_NE(db_, nullptr);
    ASSERT_NE(db_->modules, nullptr);
  }
  static GroundClamp clamp() {
    const auto& h = db_->modules->header();
    return GroundClamp(db_->grid, h.moduleSquares, h.levels);
  }
  static double moduleSize() { return db_->modules->header().moduleSquares * db_->grid->spacing(); }

  /// The drawn surface from the decoded module: level `l`'s vertices, each
  /// moved by m times the gap to level l + 1 under it (as the renderer's
  /// morph does), interpolated on level l's triangle.
  static double moduleSurface(const module::Module& m, std::uint32_t l, double m01, double x, double z) {
    const module::Level& level = m.levels[l];
    const double y = *scene::levelHeightAt(level, x, z);
    if (m01 == 0 || l + 1 >= m.levels.size()) return y;
    // The level-l square holding (x, z) and its corners.
    const double s = level.spacing;
    const std::uint32_t nx = level.squaresX, nz = level.squaresZ;
    const auto c = std::uint32_t(std::clamp(std::floor(x / s), 0.0, double(nx - 1)));
    const auto r = std::uint32_t(std::clamp(std::floor(z / s), 0.0, double(nz - 1)));
    auto post = [&](std::uint32_t a, std::uint32_t b) { return level.vertices[std::size_t(b) * (nx + 1) + a]; };
    const auto nw = post(c, r), ne = post(c + 1, r), sw = post(c, r + 1), se = post(c + 1, r + 1);
    auto moved = [&](const module::Vertex& v) {
      return v.y + m01 * (*scene::levelHeightAt(m.levels[l + 1], v.x, v.z) - v.y);
    };
    const double u = (x - nw.x) / (ne.x - nw.x), v = (z - nw.z) / (sw.z - nw.z);
    if (u + v <= 1.0) return moved(nw) + u * (moved(ne) - moved(nw)) + v * (moved(sw) - moved(nw));
    return moved(se) + (1 - u) * (moved(sw) - moved(se)) + (1 - v) * (moved(ne) - moved(se));
  }

  static inline TempDir* tmp_ = nullptr;
  static inline Database* db_ = nullptr;
};

TEST_F(GroundClampTest, matchesTheBuiltModulesAtEveryLevelAndMorph) {
  const GroundClamp g = clamp();
  const auto& h = db_->modules->header();
  const double size = moduleSize();
  std::mt19937 rng(7);
  double worstGap = 0;  // between level 3 and the finest grid: what the old clamp missed
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto m = db_->modules->read(kx, kz);
      ASSERT_TRUE(m.ok()) << m.error();
      const double w = std::min(size, db_->grid->spacing() * (db_->grid->postsX() - 1) - kx * size);
      const double d = std::min(size, db_->grid->spacing() * (db_->grid->postsZ() - 1) - kz * size);
      std::uniform_real_distribution<double> ux(0, w), uz(0, d);
      for (int k = 0; k < 40; ++k) {
        const double x = ux(rng), z = uz(rng);
        for (std::uint32_t l = 0; l < h.levels; ++l) {
          for (double morph : {0.0, 0.375, 1.0}) {
            const auto got = g.surfaceXZ(kx * size + x, kz * size + z, DrawnLevel{l, float(morph)});
            ASSERT_TRUE(got.has_value());
            const double want = moduleSurface(m.value(), l, morph, x, z);
            ASSERT_NEAR(*got, want, 0.02) << "module " << kx << "," << kz << " level " << l << " morph "
                                          << morph << " at " << x << "," << z;
          }
        }
        worstGap = std::max(worstGap, std::abs(*g.surfaceXZ(kx * size + x, kz * size + z, {3, 0}) -
                                               *g.surfaceXZ(kx * size + x, kz * size + z, {0, 0})));
      }
    }
  }
  // The test means something only where the levels differ by metres.
  EXPECT_GT(worstGap, 10.0);
  // Level 0 is the grid itself.
  const world::Terrain t(db_->grid);
  EXPECT_NEAR(*g.surfaceXZ(1234.5, 2345.25), t.sampleXZ(1234.5, 2345.25)->elevation, 1e-9);
  EXPECT_FALSE(g.surfaceXZ(-1, 10).has_value());
}

TEST_F(GroundClampTest, theEyeStandsOnTheLevelDrawnUnderIt) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  const GroundClamp g = clamp();
  // Where level 3 and the finest grid differ most, over a coarse grid of
  // candidate points away from the edges.
  const auto& hdr = db_->grid->header();
  double bestGap = 0, bx = 0, bz = 0;
  for (double x = 1500; x < 11000; x += 97) {
    for (double z = 1500; z < 7000; z += 89) {
      const double gap = std::abs(*g.surfaceXZ(x, z, {3, 0}) - *g.surfaceXZ(x, z, {0, 0}));
      if (gap > bestGap) bestGap = gap, bx = x, bz = z;
    }
  }
  ASSERT_GT(bestGap, 5.0);
  viewer::FlightOptions o;
  o.motion.easting = hdr.originEasting + bx;
  o.motion.northing = hdr.originNorthing - bz;
  o.motion.heightAgl = 5;
  o.motion.pitchDeg = -89;
  o.motion.speedKmh = 0;
  o.output.frames = 2;
  o.view.width = o.view.height = 65;  // an odd size has a centre pixel
  o.view.viewDistance = 2000;
  o.view.hud = false;
  o.render.mode = viewer::TerrainMode::modules;
  o.render.colour = render::ColourMode::height;
  o.pager.sync = true;
  // A huge allowed error: the coarsest level is drawn even under the eye.
  o.render.lod.mode = scene::LodMode::sse;
  o.render.lod.pixelError = 1e6;
  o.render.lod.morph = false;
  viewer::FlightHooks hooks(o);
  std::optional<double> below;
  hooks.onFrame = [&](std::uint32_t, const render::Image& img) { below = render::heightAt(img, 32, 32); };
  auto r = viewer::fly(*db_, o, &hooks);
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_TRUE(below.has_value());
  const auto& f = r->frames.back();
  ASSERT_EQ(f.levelCounts.size(), 4u);
  EXPECT_EQ(f.levelCounts[0] + f.levelCounts[1] + f.levelCounts[2], 0u) << "only level 3 is drawn";
  EXPECT_NEAR(f.heightAgl, 5.0, 1e-6);
  // The pixel under the eye (5 m x tan 1 deg = 9 cm ahead of it).
  EXPECT_NEAR(*below, f.eyeElevation - 5.0, 0.25);
  const double fine = *g.surfaceXZ(bx, bz, {0, 0});
  EXPECT_GT(std::abs(f.eyeElevation - 5.0 - fine), bestGap - 0.5) << "the eye follows the drawn level, not the grid";
}

}  // namespace
}  // namespace sandtable::test
