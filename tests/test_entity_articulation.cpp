// Articulated entities drawn (docs/VIEWER.md "Entities", docs/ICONS.md §3):
// the sample tank (samples/icons.txt: hull, turret, gun on the turret at
// its trunnion), seen side-on from 14 m east through the renderer on
// headless EGL. Raised 20 degrees, its barrel's top edge rises where the
// hand-worked geometry puts it, and nothing but the gun changes: the hull
// and turret pixels are those of the gun held level. Level, the tank is
// the one-piece `builtin:tank` (the geometry from before the gun was a
// part of its own) outside the gun. The gun pitches in the turret's frame
// before the turret turns: a hull facing east with its turret turned back
// north shows the raised barrel where the hull facing north does.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>

#include "sandtable/icons/builtin_models.h"
#include "sandtable/icons/definitions.h"
#include "sandtable/icons/icon_build.h"
#include "sandtable/render/image.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/camera_math.h"
#include "sandtable/testing/require.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

using render::Image;
using render::Rgb;

constexpr std::uint32_t kW = 480, kH = 270;
constexpr double kPi = 3.14159265358979323846;

/// The sample file's icons and a one-piece tank beside them.
std::shared_ptr<const iconpack::Pack> samplePack() {
  const std::string dir = std::string(SANDTABLE_SOURCE_DIR) + "/samples";
  std::string text = slurpFile(dir + "/icons.txt");
  text += "\nicon tank-one-piece\n  model builtin:tank\n  lod 1\n";
  auto defs = icons::parseDefinitions(std::as_bytes(std::span(text.data(), text.size())), "icons.txt", dir);
  EXPECT_TRUE(defs) << defs.error();
  if (!defs) return nullptr;
  auto pack = icons::buildPack(defs.value());
  EXPECT_TRUE(pack) << pack.error();
  if (!pack) return nullptr;
  return std::make_shared<const iconpack::Pack>(std::move(pack.value()));
}

std::uint16_t iconOf(const iconpack::Pack& p, const std::string& name) {
  for (std::size_t k = 0; k < p.icons.size(); ++k) {
    if (p.icons[k].name == name) return std::uint16_t(k);
  }
  ADD_FAILURE() << "no icon " << name;
  return 0;
}

/// From 14 m east of the tank's origin, 1 m up, looking west: north (the
/// gun) is to the right, and the barrel (2 m up) stands against the sky.
scene::Camera sideCamera() {
  scene::Camera c;
  c.x = 14;
  c.y = 1;
  c.z = -1.5;
  c.headingDeg = 270;
  c.hfovDeg = 50;
  c.aspect = double(kW) / double(kH);
  c.viewDistance = 3000;
  return c;
}

/// Image (column, row) of a world point.
Eigen::Vector2d project(const Eigen::Vector3d& p) {
  const Eigen::Vector4d c = scene::viewProjection(sideCamera(), 0, 0) * p.homogeneous();
  return {(c.x() / c.w() + 1) / 2 * kW, (1 - c.y() / c.w()) / 2 * kH};
}

class EntityArticulation : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
    pack_ = samplePack();
    ASSERT_TRUE(pack_);
    render::RenderSettings s;
    s.width = kW;
    s.height = kH;
    s.fog = false;
    s.sky = false;  // one background colour: what is not it is drawn
    s.icons = pack_;
    s.staticObjects = false;
    auto r = render::Renderer::create(s);
    ASSERT_TRUE(r) << r.error();
    renderer_ = std::move(r.value());
  }

  /// One frame of flat ground and, unless `icon` is empty, that icon at
  /// the origin with a hull heading, turret angle and gun elevation.
  Image shoot(const std::string& icon, double headingDeg = 0, float turretDeg = 0, float gunDeg = 0,
              const std::string& keep = "") {
    scene::DisplayBuffer b;
    b.camera = sideCamera();
    b.vertices = {{-1000, 0, -1000, 0, 1, 0, 0}, {-1000, 0, 1000, 0, 1, 0, 0}, {1000, 0, -1000, 0, 1, 0, 0},
                  {1000, 0, 1000, 0, 1, 0, 0}};
    b.firsts = {0};
    b.counts = {4};
    if (!icon.empty()) {
      scene::DynamicInstance d;
      d.icon = iconOf(*pack_, icon);
      const Eigen::Quaterniond q(Eigen::AngleAxisd(-headingDeg * kPi / 180, Eigen::Vector3d::UnitY()));
      d.orientation = {float(q.x()), float(q.y()), float(q.z()), float(q.w())};
      d.turretAzimuthDeg = turretDeg;
      d.gunElevationDeg = gunDeg;
      b.dynamic.instances.push_back(d);
    }
    Image img;
    EXPECT_TRUE(renderer_->draw(b).ok());
    EXPECT_TRUE(renderer_->readFrame(img).ok());
    // SANDTABLE_KEEP_TEST_OUTPUT=DIR keeps the frames for a look.
    if (const char* dir = std::getenv("SANDTABLE_KEEP_TEST_OUTPUT"); dir && !keep.empty()) {
      EXPECT_TRUE(render::writePng(std::string(dir) + "/articulation " + keep + ".png", img).ok());
    }
    return img;
  }

  std::shared_ptr<const iconpack::Pack> pack_;
  std::unique_ptr<render::Renderer> renderer_;
};

bool same(Rgb a, Rgb b) { return a.r == b.r && a.g == b.g && a.b == b.b; }

/// The topmost row of column x where `img` is not `bare`, or kH.
std::uint32_t topDrawn(const Image& img, const Image& bare, std::uint32_t x) {
  for (std::uint32_t y = 0; y < kH; ++y) {
    if (!same(img.at(x, y), bare.at(x, y))) return y;
  }
  return kH;
}

/// The pixel box (x0, y0, x1, y1) over the tank's gun (builtin:tank-gun's
/// bounds about its trunnion) at each elevation given, grown 3 pixels.
std::array<double, 4> gunBox(std::initializer_list<double> elevationsDeg) {
  const Eigen::Vector3d trunnion(icons::kTankGunTrunnion[0], icons::kTankTurretRingHeight + icons::kTankGunTrunnion[1],
                                 icons::kTankGunTrunnion[2]);
  std::array<double, 4> box{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (const double e : elevationsDeg) {
    const Eigen::AngleAxisd pitch(e * kPi / 180, Eigen::Vector3d::UnitX());
    for (const double x : {-0.35, 0.35}) {
      for (const double y : {-0.25, 0.25}) {
        for (const double z : {-4.1, 0.05}) {
          const Eigen::Vector2d p = project(trunnion + pitch * Eigen::Vector3d(x, y, z));
          box = {std::min(box[0], p.x()), std::min(box[1], p.y()), std::max(box[2], p.x()), std::max(box[3], p.y())};
        }
      }
    }
  }
  return {box[0] - 3, box[1] - 3, box[2] + 3, box[3] + 3};
}

/// Pixels where a and b differ: inside `box`, and outside it.
std::array<std::size_t, 2> differences(const Image& a, const Image& b, const std::array<double, 4>& box) {
  std::array<std::size_t, 2> n{0, 0};
  for (std::uint32_t y = 0; y < kH; ++y) {
    for (std::uint32_t x = 0; x < kW; ++x) {
      if (same(a.at(x, y), b.at(x, y))) continue;
      const bool inside = x >= box[0] && x <= box[2] && y >= box[1] && y <= box[3];
      ++n[inside ? 0 : 1];
    }
  }
  return n;
}

TEST_F(EntityArticulation, theRaisedGunRisesAndNothingElseMoves) {
  const Image bare = shoot("");
  const Image level = shoot("tank", 0, 0, 0, "level");
  const Image raised = shoot("tank", 0, 0, 20, "raised 20");
  const Image onePiece = shoot("tank-one-piece", 0, 0, 0, "one piece");
  // The barrel's top edge over world z = -5 (3.1 m ahead of the trunnion):
  // level, its axis 2.0 m up plus its 0.12 m radius; raised 20 degrees,
  // 3.1 tan 20 higher and the radius over cos 20.
  const double e = 20 * kPi / 180;
  const double levelTop = 2.0 + 0.12, raisedTop = 2.0 + 3.1 * std::tan(e) + 0.12 / std::cos(e);
  const auto column = std::uint32_t(std::lround(project({0, 2, -5}).x()));
  const std::uint32_t levelRow = topDrawn(level, bare, column), raisedRow = topDrawn(raised, bare, column);
  EXPECT_NEAR(double(levelRow), project({0.12, levelTop, -5}).y(), 3.0);
  EXPECT_NEAR(double(raisedRow), project({0.12, raisedTop, -5}).y(), 3.0);
  EXPECT_LT(raisedRow + 30, levelRow) << "about 1.1 m higher at 14 m: some 40 pixels";
  // Raising it changes the gun's pixels only: the hull and the turret are
  // the very pixels they were.
  const auto box = gunBox({0, 20});
  const auto moved = differences(level, raised, box);
  EXPECT_GT(moved[0], 500u);
  EXPECT_EQ(moved[1], 0u);
  // Level, outside the gun it is the one-piece tank to the pixel (the hull
  // and turret as before); the gun itself within a few edge pixels, as its
  // vertices add the trunnion back in floating point (llvmpipe: none).
  const auto asBefore = differences(level, onePiece, gunBox({0}));
  EXPECT_EQ(asBefore[1], 0u);
  EXPECT_LE(asBefore[0], 10u);
}

TEST_F(EntityArticulation, theGunPitchesInTheTurretsFrameBeforeTheTurretTurns) {
  const Image bare = shoot("");
  // Hull north, turret forward; hull east, turret turned back north (-90):
  // the turret and gun stand the same in the world.
  const Image north = shoot("tank", 0, 0, 20);
  const Image east = shoot("tank", 90, -90, 20, "east turret north raised 20");
  const auto from = std::uint32_t(std::lround(project({0, 2, -4.0}).x()));
  const auto to = std::uint32_t(std::lround(project({0, 2, -5.5}).x()));
  ASSERT_LT(from + 20, to);
  for (std::uint32_t x = from; x <= to; ++x) {
    const std::uint32_t a = topDrawn(north, bare, x), b = topDrawn(east, bare, x);
    ASSERT_LT(a, kH) << "column " << x << ": the barrel is drawn";
    EXPECT_LE(std::abs(int(a) - int(b)), 1) << "column " << x;
  }
}

}  // namespace
}  // namespace sandtable::test
