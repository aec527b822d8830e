// The module-mode flight loop without real data or converters: a pack of
// small planar modules written with PackWriter, flown through the pager by
// the main and render threads. Also what tools/tsan_pager.sh-style
// ThreadSanitizer runs of the viewer exercise (filter ViewerModules.*).
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <filesystem>

#include "sandtable/formats/database.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/pack.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/renderer.h"
#include "sandtable/testing/fixtures.h"

namespace sandtable::runtime {
namespace {

namespace fs = std::filesystem;

constexpr double kSpacing = 30;
constexpr std::uint32_t kSquares = 16, kLevels = 3, kModules = 6;
constexpr double kOriginE = 400000, kOriginN = 5000000;

/// One plane under every level, so every level is exact and nothing cracks.
float planeY(double x, double z) { return float(200.0 + 0.04 * x - 0.03 * z); }

module::Module planarModule(std::uint32_t kx, std::uint32_t kz) {
  module::Module m;
  m.kx = kx;
  m.kz = kz;
  const double ox = kx * kSquares * kSpacing, oz = kz * kSquares * kSpacing;
  for (std::uint32_t l = 0; l < kLevels; ++l) {
    const std::uint32_t n = kSquares >> l;
    module::Level lv;
    lv.spacing = kSpacing * (1u << l);
    lv.squaresX = lv.squaresZ = n;
    lv.skirtDepth = 5;
    for (std::uint32_t b = 0; b <= n; ++b) {
      for (std::uint32_t a = 0; a <= n; ++a) {
        const float x = float(a * lv.spacing), z = float(b * lv.spacing);
        lv.vertices.push_back({x, planeY(ox + x, oz + z), z, 0, 0});
      }
    }
    fixtures::addLatticeSkin(lv, n);
    m.levels.push_back(std::move(lv));
  }
  return m;
}

Database planarDatabase(const std::string& dir) {
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::uint32_t posts = kModules * kSquares + 1;
  const Status written = fixtures::writeGrid(dir + "/grid.stg", posts, posts, kSpacing,
      [](std::uint32_t i, std::uint32_t j) { return planeY(i * kSpacing, j * kSpacing); }, kOriginE, kOriginN);
  EXPECT_TRUE(written.ok()) << written.error();
  pack::IndexHeader h;
  h.modulesX = h.modulesZ = kModules;
  h.levels = kLevels;
  h.moduleSquares = kSquares;
  h.moduleSize = kSquares * kSpacing;
  auto pw = pack::PackWriter::create(dir, h, 1);
  EXPECT_TRUE(pw.ok()) << pw.error();
  for (std::uint32_t kz = 0; kz < kModules; ++kz) {
    for (std::uint32_t kx = 0; kx < kModules; ++kx) EXPECT_EQ(pw.value()->add(planarModule(kx, kz)).message(), "");
  }
  EXPECT_EQ(pw.value()->finish().message(), "");
  Database db;
  db.directory = dir;
  auto g = grid::GridFile::open(dir + "/grid.stg");
  EXPECT_TRUE(g.ok()) << g.error();
  db.grid = g.value();
  auto pr = pack::PackReader::open(dir);
  EXPECT_TRUE(pr.ok()) << pr.error();
  db.modules = pr.value();
  materials::Table t;
  materials::Class c;
  c.id = 0;
  c.name = "grass";
  c.upperRgb = 0x40A040;
  c.lowerRgb = 0x309030;
  t.classes.push_back(c);
  db.materials = t;
  return db;
}

class ViewerModules : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    if (!headlessGlAvailable(why)) GTEST_SKIP() << "no headless GL: " << why;
    dir_ = (fs::temp_directory_path() / ("sandtable-viewer-" + std::to_string(::getpid()))).string();
    db_ = planarDatabase(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string dir_;
  Database db_;
};

TEST_F(ViewerModules, FliesThroughThePagerOnTwoThreads) {
  for (const LodMode mode : {LodMode::rings, LodMode::sse, LodMode::full}) {
    FlightOptions o;
    o.view.width = 160;
    o.view.height = 90;
    o.output.frames = 40;
    o.motion.easting = kOriginE + 300;
    o.motion.northing = kOriginN - 1400;
    o.motion.headingDeg = 90;
    o.motion.heightAgl = 120;
    o.motion.pitchDeg = -12;
    o.motion.speedKmh = 3600;  // 33 m a frame: across modules, so the pager pages
    o.view.viewDistance = 1500;
    o.render.lod.mode = mode;
    o.render.lod.rings = {300, 700};
    o.view.hud = true;
    std::uint32_t images = 0;
    FlightHooks hooks(o);
    hooks.onFrame = [&](std::uint32_t, const Image& img) { images += img.width == 160; };
    auto r = fly(db_, o, &hooks);
    ASSERT_TRUE(r.ok()) << r.error();
    EXPECT_EQ(r->summary.mode, "modules");
    ASSERT_EQ(r->frames.size(), 40u);
    EXPECT_EQ(images, 40u);
    for (const auto& f : r->frames) {
      EXPECT_GT(f.nodesDrawn, 0u) << lodModeName(mode) << " frame " << f.frame;
      EXPECT_GT(f.triangles, 0u);
      EXPECT_LE(f.cachedLevels, f.windowModules * kLevels);
    }
    const auto& last = r->frames.back();
    if (mode == LodMode::full) {
      EXPECT_EQ(last.levelCounts[1] + last.levelCounts[2], 0u);
    } else if (mode == LodMode::rings) {
      EXPECT_GT(last.levelCounts[2], 0u);  // beyond 700 m: the coarsest level
    } else {
      // A plane is exact at every level: the screen-space mode takes the coarsest.
      EXPECT_LT(last.maxErrorPx, 0.01);  // float rounding only
      EXPECT_EQ(last.levelCounts[0] + last.levelCounts[1], 0u);
    }
  }
}

TEST_F(ViewerModules, ControllerViewDistanceGrowsThePagersWindowUpToItsMostAndItsClockIsReported) {
  FlightOptions o;
  o.view.width = 160;
  o.view.height = 90;
  o.output.frames = 3;
  o.motion.easting = kOriginE + 300;
  o.motion.northing = kOriginN - 1400;
  o.view.viewDistance = 1500;  // the pager's window at open; it may grow to 3 x, 4500 m
  o.pager.sync = true;     // every load done before each frame
  FlightHooks hooks(o);
  hooks.onPose = [&](std::uint32_t frame, double, GroundClamp&) -> std::optional<Pose> {
    Pose p;
    p.easting = o.motion.easting;
    p.northing = o.motion.northing;
    p.heightAgl = 120;
    p.viewDistance = frame == 0 ? 1000.0 : 5000.0;  // a "+" key beyond the most
    p.clockS = 10.0 + frame;                        // e.g. a window's wall clock
    return p;
  };
  auto r = fly(db_, o, &hooks);
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r->frames.size(), 3u);
  EXPECT_EQ(r->frames[0].viewDistance, 1000.0);
  EXPECT_EQ(r->frames[1].viewDistance, 4500.0) << "the window grew to maxViewDistance";
  EXPECT_EQ(r->frames[2].timeS, 12.0);
  EXPECT_FALSE(r->frames[2].freeFlight);
}

}  // namespace
}  // namespace sandtable::runtime
