// Entities take their icon's levels of detail by distance (docs/VIEWER.md,
// "Entities"), through headless EGL: a far tank draws fewer triangles than
// a near one, none past its far range, and with RenderSettings::objectLod
// false the far one draws at full detail as before. Skips without a
// headless GL context.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "sandtable/formats/icon_pack.h"
#include "sandtable/render/renderer.h"
#include "sandtable/testing/require.h"

namespace sandtable::render {
namespace {

constexpr std::uint32_t kW = 320, kH = 200;

/// A box of 12 triangles over [-s, s]^2 x [0, 2s]; level 1 keeps the top
/// and bottom faces (4 triangles).
iconpack::Mesh box(float s) {
  iconpack::Mesh m;
  m.positions = {-s, 0, -s, s, 0, -s, s, 0, s, -s, 0, s, -s, 2 * s, -s, s, 2 * s, -s, s, 2 * s, s, -s, 2 * s, s};
  m.normals.assign(24, 0.0f);
  for (std::size_t v = 0; v < 8; ++v) m.normals[3 * v + 1] = v < 4 ? -1.0f : 1.0f;
  const std::vector<std::uint32_t> full = {0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6, 0, 4, 5, 0, 5, 1,
                                           1, 5, 6, 1, 6, 2, 2, 6, 7, 2, 7, 3, 3, 7, 4, 3, 4, 0};
  m.levels = {full, std::vector<std::uint32_t>(full.begin(), full.begin() + 12)};
  return m;
}

/// "tank": a hull box and a turret box (a part named "turret"), level 0 to
/// 200 m, level 1 to 2 km.
std::shared_ptr<const iconpack::Pack> tankPack() {
  auto p = std::make_shared<iconpack::Pack>();
  iconpack::Icon tank;
  tank.name = "tank";
  tank.materials = {{{56, 66, 31, 255}, iconpack::kNoTexture}};
  tank.ranges = {200, 2000};
  iconpack::Part hull;
  hull.meshes = {box(2.0f)};
  iconpack::Part turret;
  turret.name = "turret";
  turret.offset = {0, 4.0f, 0};
  turret.meshes = {box(1.0f)};
  tank.parts = {hull, turret};
  tank.bounds = {-2, 0, -2, 2, 6, 2};
  p->icons = {tank};
  return p;
}

/// The eye 20 m up at the origin, looking north (-Z), a tank `ahead` metres away.
scene::DisplayBuffer tankAhead(double ahead) {
  scene::DisplayBuffer b;
  b.camera.y = 20;
  b.camera.pitchDeg = -2;
  b.camera.aspect = double(kW) / double(kH);
  b.camera.viewDistance = 5000;
  scene::DynamicInstance d;
  d.z = -ahead;
  b.dynamic.instances.push_back(d);
  return b;
}

/// The entity triangles of one frame of a tank `ahead` metres away.
std::uint64_t entityTriangles(Renderer& r, double ahead) {
  EXPECT_TRUE(r.draw(tankAhead(ahead)).ok());
  return r.stats().entityTriangles;
}

std::unique_ptr<Renderer> makeRenderer(bool lod) {
  RenderSettings s;
  s.width = kW;
  s.height = kH;
  s.icons = tankPack();
  s.objectLod = lod;
  auto r = Renderer::create(s);
  if (!r) return nullptr;
  return std::move(r.value());
}

TEST(EntityLod, aFarTankDrawsItsCoarserLevelAndNothingPastItsFarRange) {
  std::string why;
  SANDTABLE_REQUIRE(headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  auto r = makeRenderer(true);
  ASSERT_TRUE(r);
  const std::uint64_t near = entityTriangles(*r, 50), far = entityTriangles(*r, 800);
  EXPECT_EQ(near, 24u) << "level 0: 12 triangles each for the hull and the turret";
  EXPECT_EQ(far, 8u) << "level 1: 4 each";
  EXPECT_LT(far, near);
  EXPECT_EQ(r->stats().entitiesDrawn, 1u);
  EXPECT_EQ(entityTriangles(*r, 2100), 0u) << "past the far range: nothing";
  // The switch is at the near side of the bounding sphere: a tank whose
  // centre is just past 200 m still reaches inside it.
  EXPECT_EQ(entityTriangles(*r, 201), 24u);
}

TEST(EntityLod, withoutObjectLodEveryTankDrawsAtFullDetailOutToItsFarRange) {
  std::string why;
  SANDTABLE_REQUIRE(headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  auto r = makeRenderer(false);
  ASSERT_TRUE(r);
  EXPECT_EQ(entityTriangles(*r, 50), 24u);
  EXPECT_EQ(entityTriangles(*r, 800), 24u);
  EXPECT_EQ(entityTriangles(*r, 2100), 0u);
}

}  // namespace
}  // namespace sandtable::render
