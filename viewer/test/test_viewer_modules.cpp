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
#include "sandtable/formats/icon_pack.h"
#include "sandtable/scene/camera_math.h"
#include "sandtable/formats/pack.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/renderer.h"
#include "sandtable/testing/fixtures.h"
#include "sandtable/testing/require.h"

namespace sandtable::viewer {
namespace {

namespace fs = std::filesystem;

constexpr double kSpacing = 30;
constexpr std::uint32_t kSquares = 16, kLevels = 3, kModules = 6;
constexpr double kOriginE = 400000, kOriginN = 5000000;

/// One plane under every level, so every level is exact and nothing cracks.
float planeY(double x, double z) { return float(200.0 + 0.04 * x - 0.03 * z); }

/// The one static object (ViewerModules.Objects*): a red column in module
/// (2, 2) whose stored base on level l is the plane plus l * kObjectLift,
/// so an image tells which level's elevation the viewer used.
constexpr std::uint32_t kObjectModule = 2;
constexpr float kObjectLocal = 240;
constexpr double kObjectLift = 4;
double objectWorld() { return kObjectModule * kSquares * kSpacing + kObjectLocal; }

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
    if (kx == kObjectModule && kz == kObjectModule) {
      lv.objectY = {float(planeY(objectWorld(), objectWorld()) + l * kObjectLift)};
    }
    m.levels.push_back(std::move(lv));
  }
  if (kx == kObjectModule && kz == kObjectModule) {
    module::Object o;
    o.icon = 0;
    o.x = o.z = kObjectLocal;
    o.radius = 1.5f;
    o.height = 20;
    m.objects = {o};
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
  // Module version 5 stores each level's object base as given, so the
  // column's lift per level survives; version 6 computes the bases from the
  // level's own triangles, which would hide which level the viewer used.
  pack::PackLayout layout;
  layout.encode.version = 5;
  auto pw = pack::PackWriter::create(dir, h, 1, layout);
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

/// A 2 x 20 x 2 m red box standing on y = 0, one level of detail to 2 km.
iconpack::Pack columnIcons() {
  iconpack::Mesh mesh;
  const float x0 = -1, x1 = 1, y0 = 0, y1 = 20, z0 = -1, z1 = 1;
  const auto face = [&](std::array<float, 12> q, std::array<float, 3> n) {
    const auto base = std::uint32_t(mesh.vertexCount());
    for (int k = 0; k < 4; ++k) {
      mesh.positions.insert(mesh.positions.end(), {q[3 * k], q[3 * k + 1], q[3 * k + 2]});
      mesh.normals.insert(mesh.normals.end(), n.begin(), n.end());
    }
    if (mesh.levels.empty()) mesh.levels.emplace_back();
    mesh.levels[0].insert(mesh.levels[0].end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  };
  face({x0, y0, z1, x1, y0, z1, x1, y1, z1, x0, y1, z1}, {0, 0, 1});
  face({x1, y0, z0, x0, y0, z0, x0, y1, z0, x1, y1, z0}, {0, 0, -1});
  face({x0, y0, z0, x0, y0, z1, x0, y1, z1, x0, y1, z0}, {-1, 0, 0});
  face({x1, y0, z1, x1, y0, z0, x1, y1, z0, x1, y1, z1}, {1, 0, 0});
  face({x0, y1, z1, x1, y1, z1, x1, y1, z0, x0, y1, z0}, {0, 1, 0});
  iconpack::Icon icon;
  icon.name = "column";
  icon.bounds = {x0, y0, z0, x1, y1, z1};
  icon.cylinderRadius = 1.5f;
  icon.cylinderHeight = y1;
  icon.materials = {iconpack::Material{{230, 20, 20, 255}, iconpack::kNoTexture}};
  icon.ranges = {2000};
  iconpack::Part hull;
  hull.meshes = {mesh};
  icon.parts = {hull};
  iconpack::Pack pack;
  pack.icons = {icon};
  return pack;
}

class ViewerModules : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
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
  for (const scene::LodMode mode : {scene::LodMode::rings, scene::LodMode::sse, scene::LodMode::full}) {
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
    hooks.onFrame = [&](std::uint32_t, const render::Image& img) { images += img.width == 160; };
    auto r = fly(db_, o, &hooks);
    ASSERT_TRUE(r.ok()) << r.error();
    EXPECT_EQ(r->summary.mode, "modules");
    ASSERT_EQ(r->frames.size(), 40u);
    EXPECT_EQ(images, 40u);
    for (const auto& f : r->frames) {
      EXPECT_GT(f.nodesDrawn, 0u) << scene::lodModeName(mode) << " frame " << f.frame;
      EXPECT_GT(f.triangles, 0u);
      EXPECT_LE(f.cachedLevels, f.windowModules * kLevels);
    }
    const auto& last = r->frames.back();
    if (mode == scene::LodMode::full) {
      EXPECT_EQ(last.levelCounts[1] + last.levelCounts[2], 0u);
    } else if (mode == scene::LodMode::rings) {
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
  hooks.onPose = [&](std::uint32_t frame, double, world::GroundClamp&) -> std::optional<world::Pose> {
    world::Pose p;
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

/// The lowest image row (top row 0) of column x where the red column shows; -1: none.
int lowestRed(const render::Image& img, std::uint32_t x) {
  for (int y = int(img.height) - 1; y >= 0; --y) {
    const std::uint8_t* p = img.rgba.data() + (std::size_t(y) * img.width + x) * 4;
    if (p[0] > 60 && p[0] > 2 * p[1] && p[0] > 2 * p[2]) return y;
  }
  return -1;
}

struct ObjectView {
  FrameStats stats;
  render::Image image;
};

/// One frame looking north at the column from 500 m south (from the next
/// module, so rings draw the column's whole module at the coarsest
/// level), eye 30 m up, no fog.
ObjectView viewColumn(const Database& db, scene::LodMode mode, bool objects,
                      double impostorPixels = render::kDefaultImpostorPixels) {
  FlightOptions o;
  o.view.width = 640;
  o.view.height = 360;
  o.view.fog = false;
  o.view.hud = false;
  o.view.viewDistance = 1500;
  o.output.frames = 1;
  o.pager.sync = true;
  o.render.lod.mode = mode;
  o.render.lod.rings = {1, 2};  // rings: the coarsest level everywhere
  o.render.lod.morph = false;
  o.render.objects = objects;
  o.render.impostorPixels = impostorPixels;
  o.motion.easting = kOriginE + objectWorld();
  o.motion.northing = kOriginN - (objectWorld() + 500);
  ObjectView v;
  FlightHooks hooks(o);
  hooks.onPose = [&](std::uint32_t, double, world::GroundClamp&) -> std::optional<world::Pose> {
    world::Pose p;
    p.easting = o.motion.easting;
    p.northing = o.motion.northing;
    p.heightAgl = 30;
    p.pitchDeg = 0;
    return p;
  };
  hooks.onFrame = [&](std::uint32_t, const render::Image& img) { v.image = img; };
  auto r = fly(db, o, &hooks);
  EXPECT_TRUE(r.ok()) << r.error();
  if (r.ok() && !r->frames.empty()) v.stats = r->frames.back();
  return v;
}

/// Image row of a world point (x, y, z) seen by the frame's camera,
/// from the camera's own projection (independent of the object code).
double projectedRow(const FrameStats& s, const render::Image& img, double x, double y, double z) {
  scene::Camera cam;
  cam.x = s.easting - kOriginE;
  cam.z = kOriginN - s.northing;
  cam.y = s.eyeElevation;
  cam.headingDeg = s.headingDeg;
  cam.pitchDeg = 0;
  cam.hfovDeg = s.hfovDeg;
  cam.aspect = double(img.width) / img.height;
  cam.viewDistance = s.viewDistance;
  const Eigen::Vector4d c = scene::viewProjection(cam, 0, 0) * Eigen::Vector4d(x, y, z, 1);
  return (1.0 - c.y() / c.w()) / 2.0 * img.height;
}

TEST_F(ViewerModules, ObjectsStandOnTheElevationOfTheLevelDrawnUnderThem) {
  db_.icons = columnIcons();
  const double x = objectWorld(), ground = planeY(x, x);
  const std::uint32_t column = 320;  // straight ahead
  for (const auto& [mode, level] : {std::pair{scene::LodMode::full, 0}, std::pair{scene::LodMode::rings, int(kLevels) - 1}}) {
    const ObjectView v = viewColumn(db_, mode, true);
    ASSERT_EQ(v.image.width, 640u);
    EXPECT_EQ(v.stats.objectsDrawn, 1u);
    EXPECT_EQ(v.stats.objectInstances, 1u);
    EXPECT_EQ(v.stats.objectDraws, 1u);
    EXPECT_EQ(v.stats.objectTriangles, 10u);
    const double expected = projectedRow(v.stats, v.image, x, ground + level * kObjectLift, x);
    const int row = lowestRed(v.image, column);
    ASSERT_GE(row, 0) << scene::lodModeName(mode) << ": the column is not drawn";
    EXPECT_NEAR(row + 0.5, expected, 1.5) << scene::lodModeName(mode) << ": level " << level << "'s base";
    // The top, 20 m up, too: the scale and the projection.
    const double top = projectedRow(v.stats, v.image, x, ground + level * kObjectLift + 20, x - 1);
    int highest = row;
    while (highest > 0 && lowestRed(v.image, column) >= 0) {
      const std::uint8_t* p = v.image.rgba.data() + (std::size_t(highest - 1) * v.image.width + column) * 4;
      if (!(p[0] > 60 && p[0] > 2 * p[1])) break;
      --highest;
    }
    EXPECT_NEAR(highest, top, 2.0) << scene::lodModeName(mode);
  }
  const ObjectView off = viewColumn(db_, scene::LodMode::full, false);
  EXPECT_EQ(off.stats.objectsDrawn, 0u);
  EXPECT_EQ(lowestRed(off.image, column), -1) << "--no-objects still drew the column";
}

/// The red rows of image column x: first (top) and last; {-1, -1}: none.
std::pair<int, int> redSpan(const render::Image& img, std::uint32_t x) {
  std::pair<int, int> span{-1, -1};
  for (int y = 0; y < int(img.height); ++y) {
    const std::uint8_t* p = img.rgba.data() + (std::size_t(y) * img.width + x) * 4;
    if (!(p[0] > 60 && p[0] > 2 * p[1] && p[0] > 2 * p[2])) continue;
    if (span.first < 0) span.first = y;
    span.second = y;
  }
  return span;
}

TEST_F(ViewerModules, AnObjectUnderTheImpostorSizeIsOneSpriteCoveringWhereItsMeshWould) {
  db_.icons = columnIcons();
  const double x = objectWorld(), ground = planeY(x, x);
  const std::uint32_t column = 320;
  // 20 m at 500 m projects to about 22 px: a mesh under 16 px, a sprite under 64.
  const ObjectView mesh = viewColumn(db_, scene::LodMode::full, true, 16);
  const ObjectView sprite = viewColumn(db_, scene::LodMode::full, true, 64);
  EXPECT_EQ(mesh.stats.objectSprites, 0u);
  EXPECT_EQ(mesh.stats.objectInstances, 1u);
  EXPECT_EQ(sprite.stats.objectsDrawn, 1u);
  EXPECT_EQ(sprite.stats.objectSprites, 1u);
  EXPECT_EQ(sprite.stats.objectInstances, 0u);
  EXPECT_EQ(sprite.stats.objectTriangles, 0u);
  // Base and top from the camera's own projection; the sprite's square
  // spans the column's height, so both land where the mesh's do.
  const double base = projectedRow(sprite.stats, sprite.image, x, ground, x);
  const double top = projectedRow(sprite.stats, sprite.image, x, ground + 20, x);
  const auto s = redSpan(sprite.image, column), m = redSpan(mesh.image, column);
  ASSERT_GE(s.first, 0) << "the sprite is not drawn";
  ASSERT_GE(m.first, 0);
  EXPECT_NEAR(s.second + 0.5, base, 2.5);
  EXPECT_NEAR(s.first, top, 2.5);
  EXPECT_NEAR(s.second, m.second, 2);
  EXPECT_NEAR(s.first, m.first, 2);
  // About as wide: 2 m at 500 m is about 2 px, both ways.
  int wide = 0;
  for (std::uint32_t c = column - 10; c <= column + 10; ++c) wide += redSpan(sprite.image, c).first >= 0;
  EXPECT_GE(wide, 1);
  EXPECT_LE(wide, 5);
  const ObjectView noSprites = viewColumn(db_, scene::LodMode::full, true, 0);
  EXPECT_EQ(noSprites.stats.objectSprites, 0u);
}

}  // namespace
}  // namespace sandtable::viewer
