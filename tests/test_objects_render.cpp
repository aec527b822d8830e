// Objects on multi-resolution terrain, rendered (issue 12): over the
// rugged SRTM terrain behind Monaco, tall magenta columns stand on a grid
// of points; for each level-of-detail configuration the same pose is drawn
// twice, once with the objects and once as a height frame of the terrain
// alone. In each column's image column the height frame says, pixel by
// pixel, which ground point the eye sees (the ray through the pixel meets
// the ground at the height the frame encodes), so the row where the ground
// at the object's own (x, z) shows is measured, not computed from the
// object code. A column standing on the drawn ground starts at that row
// and ends where a point 30 m above that ground projects: floating moves
// its foot up, burying moves its top down, and drawing it on another level
// of detail than the ground under it does one or the other.
#include <Eigen/Dense>

#include <cmath>
#include <fstream>

#include "sandtable/formats/database.h"
#include "sandtable/render/image.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/camera_math.h"
#include "sandtable/viewer/flight.h"
#include "test_support.h"
#include "viewer_support.h"
#include "sandtable/testing/require.h"

namespace sandtable::test {
namespace {

using viewer::FlightOptions;
using render::Image;
using scene::LodMode;

constexpr double kColumnHeight = 30, kColumnHalfWidth = 1.5;
/// From over the sea south of Monaco, a narrow view up the slopes: the
/// columns 2 to 4.5 km away are 20 to 40 pixels tall.
constexpr double kEyeLon = 7.4215, kEyeLat = 43.712, kFovDeg = 24, kPitchDeg = -4, kEyeAgl = 500;
constexpr std::uint32_t kWidth = 1280, kHeight = 720;

/// A magenta box, 3 m square and 30 m tall, standing on y = 0.
void writeColumnIcon(const std::string& dir) {
  std::ofstream(dir + "/column.obj") << "mtllib column.mtl\nusemtl magenta\n"
                                        "v -1.5 0 -1.5\nv 1.5 0 -1.5\nv 1.5 0 1.5\nv -1.5 0 1.5\n"
                                        "v -1.5 30 -1.5\nv 1.5 30 -1.5\nv 1.5 30 1.5\nv -1.5 30 1.5\n"
                                        "f 1 2 3\nf 1 3 4\nf 5 7 6\nf 5 8 7\nf 1 5 6\nf 1 6 2\nf 2 6 7\n"
                                        "f 2 7 3\nf 3 7 8\nf 3 8 4\nf 4 8 5\nf 4 5 1\n";
  std::ofstream(dir + "/column.mtl") << "newmtl magenta\nKd 1 0 1\n";
  std::ofstream(dir + "/icons.txt") << "sandtable-icons 1\nicon column\n  model column.obj\n  base-below 0\n"
                                       "  lod 1 20000\n";
}

/// Columns on a grid of 11 x 9 points over the slopes north of Monaco.
void writePoints(const std::string& path) {
  std::ofstream f(path);
  f << "lon,lat,icon\n";
  for (int i = 0; i < 11; ++i) {
    for (int j = 0; j < 9; ++j) f << 7.405 + 0.003 * i << "," << 43.736 + 0.002 * j << ",column\n";
  }
}

bool magenta(const Image& img, int x, int y) {
  const auto c = img.at(std::uint32_t(x), std::uint32_t(y));
  return c.r > 60 && c.b > 60 && c.g * 3 < std::min(c.r, c.b);
}

/// Rays through pixels of the frame's camera, from its own projection.
struct Rays {
  Eigen::Vector3d eye;
  Eigen::Matrix4d inverse, viewProjection;
  Eigen::Vector3d direction(double px, double py) const {
    const double nx = (px + 0.5) / kWidth * 2 - 1, ny = 1 - (py + 0.5) / kHeight * 2;
    // Any depth on the pixel's line of sight: the ray runs from the eye through it.
    const Eigen::Vector4d a = inverse * Eigen::Vector4d(nx, ny, 0.5, 1);
    return (a.head<3>() / a.w() - eye).normalized();
  }
  /// Image (column, row) of a world point.
  Eigen::Vector2d project(const Eigen::Vector3d& p) const {
    const Eigen::Vector4d c = viewProjection * Eigen::Vector4d(p.x(), p.y(), p.z(), 1);
    return {(c.x() / c.w() + 1) / 2 * kWidth, (1 - c.y() / c.w()) / 2 * kHeight};
  }
};

struct Shots {
  Image objects, heights;
  Rays rays;
};

/// The pose, drawn with the objects and as a height frame.
Shots shoot(const Database& db, LodMode lod, double easting, double northing) {
  Shots s;
  for (const bool height : {false, true}) {
    FlightOptions o;
    o.view.width = kWidth;
    o.view.height = kHeight;
    o.view.fog = false;
    o.view.clearColour = {0x80, 0xB0, 0xE0};  // not magenta: the columns are
    o.view.hud = false;
    o.view.viewDistance = 6000;
    o.view.hfovDeg = kFovDeg;
    o.output.frames = 2;
    o.pager.sync = true;
    o.motion.speedKmh = 0;
    o.render.mode = viewer::TerrainMode::modules;
    o.render.lod.mode = lod;
    if (lod == LodMode::rings) o.render.lod.rings = {1200, 2400, 3600};
    o.render.colour = height ? render::ColourMode::height : render::ColourMode::natural;
    viewer::FlightHooks hooks(o);
    hooks.onPose = [&](std::uint32_t, double, world::GroundClamp&) -> std::optional<world::Pose> {
      world::Pose p;
      p.easting = easting;
      p.northing = northing;
      p.heightAgl = kEyeAgl;
      p.headingDeg = 0;
      p.pitchDeg = kPitchDeg;
      return p;
    };
    hooks.onFrame = [&](std::uint32_t, const Image& img) { (height ? s.heights : s.objects) = img; };
    auto r = viewer::fly(db, o, &hooks);
    EXPECT_TRUE(r.ok()) << r.error();
    if (!r.ok() || r->frames.empty()) return s;
    const auto& f = r->frames.back();
    scene::Camera cam;
    cam.x = f.easting - db.manifest.originEasting;
    cam.z = db.manifest.originNorthing - f.northing;
    cam.y = f.eyeElevation;
    cam.headingDeg = f.headingDeg;
    cam.pitchDeg = kPitchDeg;
    cam.hfovDeg = f.hfovDeg;
    cam.aspect = double(kWidth) / kHeight;
    cam.viewDistance = f.viewDistance;
    s.rays.viewProjection = scene::viewProjection(cam, 0, 0);
    s.rays.inverse = s.rays.viewProjection.inverse();
    s.rays.eye = {cam.x, cam.y, cam.z};
  }
  return s;
}

/// What one column measured: its foot and top rows against the ground's.
struct Measure {
  bool seen = false;
  double footRow = 0, groundRow = 0, topRow = 0, expectedTopRow = 0, ground = 0;
};

Measure measure(const Shots& s, double x, double z, double guessY) {
  Measure m;
  const Eigen::Vector2d at = s.rays.project({x, guessY, z});
  const int u = int(std::floor(at.x()));
  if (u < 2 || u >= int(kWidth) - 2 || at.y() < 0 || at.y() >= kHeight) return m;
  // The row whose ground point lies nearest the column's (x, z).
  double best = INFINITY;
  int row = -1;
  for (int v = 0; v < int(kHeight); ++v) {
    const auto h = render::heightAt(s.heights, std::uint32_t(u), std::uint32_t(v));
    if (!h) continue;
    const Eigen::Vector3d d = s.rays.direction(u, v);
    if (d.y() >= 0) continue;
    const Eigen::Vector3d p = s.rays.eye + d * ((*h - s.rays.eye.y()) / d.y());
    const double off = std::hypot(p.x() - x, p.z() - z);
    if (off < best) best = off, row = v, m.ground = *h;
  }
  if (row < 1) return m;
  const auto groundAt = [&](int v) -> std::optional<Eigen::Vector3d> {
    const auto h = render::heightAt(s.heights, std::uint32_t(u), std::uint32_t(v));
    const Eigen::Vector3d d = s.rays.direction(u, v);
    if (!h || d.y() >= 0) return std::nullopt;
    return s.rays.eye + d * ((*h - s.rays.eye.y()) / d.y());
  };
  // Hidden behind nearer ground, or a column the pixel grid misses: not
  // measured; nor where one row spans more than 8 m of ground (grazing).
  const auto above = groundAt(row - 1), here = groundAt(row);
  if (!above || !here) return m;
  const double span = (*above - *here).norm();
  if (span > 8 || best > std::max(2 * kColumnHalfWidth, 0.6 * span)) return m;
  // The magenta run that holds the ground row or starts just above it.
  int foot = -1;
  for (int v = std::min(row + 3, int(kHeight) - 1); v >= std::max(row - 40, 0); --v) {
    if (magenta(s.objects, u, v)) {
      foot = v;
      break;
    }
  }
  if (foot < 0) return m;
  int top = foot;
  while (top > 0 && magenta(s.objects, u, top - 1)) --top;
  m.seen = true;
  m.groundRow = row;
  m.footRow = foot;
  m.topRow = top;
  m.expectedTopRow = s.rays.project({x, m.ground + kColumnHeight, z}).y();
  return m;
}

TEST(ObjectsRender, columnsOnRuggedTerrainNeitherFloatNorSinkAtAnyLevelOfDetail) {
  SANDTABLE_REQUIRE_DATA();
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  TempDir t("objrender");
  writeColumnIcon(t.path());
  writePoints(t / "columns.csv");
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--extent", "7.38", "43.70",
                         "7.47", "43.78", "--spacing", "30", "--icons", t / "icons.txt", "--objects",
                         t / "columns.csv", "-o", t / "db"});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  FlightOptions start;
  auto db = openAt(t / "db", kEyeLon, kEyeLat, start);
  ASSERT_TRUE(db);
  // The columns in world metres, with their level-0 base to find their image column.
  std::vector<Eigen::Vector3d> columns;
  const auto& h = db->modules->header();
  const double edge = double(h.moduleSquares) * db->grid->spacing();
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto m = db->modules->read(kx, kz);
      ASSERT_TRUE(m.ok());
      for (std::size_t k = 0; k < m->objects.size(); ++k) {
        columns.push_back({kx * edge + m->objects[k].x, m->levels[0].objectY[k], kz * edge + m->objects[k].z});
      }
    }
  }
  ASSERT_EQ(columns.size(), 99u);
  for (const LodMode lod : {LodMode::full, LodMode::rings, LodMode::sse}) {
    SCOPED_TRACE(scene::lodModeName(lod));
    const Shots s = shoot(db.value(), lod, start.motion.easting, start.motion.northing);
    ASSERT_EQ(s.objects.width, kWidth);
    std::size_t seen = 0;
    for (const auto& c : columns) {
      // Another column in front of or behind this one in the image would
      // join its magenta run: such pairs are not measured.
      const Eigen::Vector2d at = s.rays.project(c);
      bool alone = true;
      for (const auto& other : columns) {
        const Eigen::Vector2d o = s.rays.project(other);
        alone = alone && (&other == &c || std::abs(o.x() - at.x()) > 6 || std::abs(o.y() - at.y()) > 80);
      }
      const Measure m = alone ? measure(s, c.x(), c.z(), c.y()) : Measure{};
      if (!m.seen) continue;
      ++seen;
      // Floating shows ground below the foot; a foot a row or two under the
      // ground row is the column's near face, nearer than its centre.
      EXPECT_LE(m.footRow, m.groundRow + 2.5) << "column at " << c.transpose() << " sinks below the drawn ground";
      EXPECT_GE(m.footRow, m.groundRow - 1.5) << "column at " << c.transpose() << " floats over the drawn ground "
                                              << m.ground << " m";
      EXPECT_NEAR(m.topRow, m.expectedTopRow, 2.5)
          << "column at " << c.transpose() << ": its top is not 30 m over the drawn ground " << m.ground << " m";
    }
    EXPECT_GE(seen, 30u) << "too few columns measured to say";
  }
}

}  // namespace
}  // namespace sandtable::test

namespace sandtable::test {
namespace {

/// Objects drawn, sprites and thinned in the last of two frames over the
/// Bayreuth forest.
viewer::FrameStats forestFrame(const Database& db, double thinPixels, double easting, double northing) {
  FlightOptions o;
  o.view.width = 640;
  o.view.height = 360;
  o.view.viewDistance = 6000;
  o.output.frames = 2;
  o.pager.sync = true;
  o.motion.speedKmh = 0;
  o.motion.easting = easting;
  o.motion.northing = northing;
  o.motion.heightAgl = 60;
  o.motion.pitchDeg = -6;
  o.render.objectThinPixels = thinPixels;
  auto r = viewer::fly(db, o);
  EXPECT_TRUE(r.ok()) << r.error();
  return r.ok() && !r->frames.empty() ? r->frames.back() : viewer::FrameStats{};
}

TEST(ObjectsRender, farSpritesAreThinnedTheSameWayEveryFrameAndNoneWithoutThinning) {
  SANDTABLE_REQUIRE_DATA();
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  TempDir t("objthin");
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.55", "49.94",
                         "11.62", "49.99", "--spacing", "30", "--culture",
                         data("culture/osm/north-bayreuth.osm.gz"), "-o", t / "db"});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  FlightOptions start;
  auto db = openAt(t / "db", 11.585, 49.945, start);
  ASSERT_TRUE(db);
  const auto all = forestFrame(db.value(), 0, start.motion.easting, start.motion.northing);
  const auto thinned = forestFrame(db.value(), 6, start.motion.easting, start.motion.northing);
  const auto again = forestFrame(db.value(), 6, start.motion.easting, start.motion.northing);
  ASSERT_GT(all.objectsDrawn, 1000u);
  EXPECT_EQ(all.objectsThinned, 0u);
  // Every object in range and view is either drawn or thinned, and only sprites are thinned.
  EXPECT_GT(thinned.objectsThinned, 0u);
  EXPECT_EQ(thinned.objectsDrawn + thinned.objectsThinned, all.objectsDrawn);
  EXPECT_EQ(thinned.objectInstances, all.objectInstances);
  EXPECT_EQ(thinned.objectSprites + thinned.objectsThinned, all.objectSprites);
  // The same ones every time: the choice hangs on the object, not the frame.
  EXPECT_EQ(again.objectsDrawn, thinned.objectsDrawn);
  EXPECT_EQ(again.objectsThinned, thinned.objectsThinned);
}

}  // namespace
}  // namespace sandtable::test
