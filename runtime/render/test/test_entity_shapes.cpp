// What the entity pass builds on the CPU (entity_draw.h): icons split into
// a body, a turret that turns about its ring and a gun that elevates about
// its trunnion (on the turret or on the hull), dead states falling back
// to the living, the quaternions of headings and of knocked-over objects,
// trails that fade with age and stay at least a pixel or so wide, flashes
// that grow and go out, and contact shadows under the footprint.
#include <gtest/gtest.h>

#include <cmath>

#include "../src/entity_draw.h"

namespace sandtable::render::detail {
namespace {

/// A box mesh of one triangle pair at height y over [x0, x1] x [z0, z1].
iconpack::Mesh quad(float x0, float x1, float y, float z0, float z1) {
  iconpack::Mesh m;
  m.positions = {x0, y, z0, x1, y, z0, x1, y, z1, x0, y, z1};
  m.normals = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
  m.levels = {{0, 2, 1, 0, 3, 2}};
  return m;
}

/// "tank": a hull quad 7 x 3.5 m, a turret part 1.6 m up whose mesh reaches
/// 6 m forward (the gun), and a dead wreck; "jeep": a hull only.
iconpack::Pack pack() {
  iconpack::Pack p;
  iconpack::Icon tank;
  tank.name = "tank";
  tank.materials = {{{56, 66, 31, 255}, iconpack::kNoTexture}};
  tank.ranges = {5000};
  iconpack::Part hull;
  hull.meshes = {quad(-1.75f, 1.75f, 0.5f, -3.5f, 3.5f)};
  iconpack::Part turret;
  turret.name = "turret";
  turret.offset = {0, 1.6f, 0};
  turret.meshes = {quad(-0.1f, 0.1f, 0.4f, -6.0f, 0.0f)};
  iconpack::Part wreck;
  wreck.state = iconpack::State::dead;
  wreck.meshes = {quad(-1.5f, 1.5f, 0.3f, -3.0f, 3.0f)};
  tank.parts = {hull, turret, wreck};
  iconpack::Icon jeep;
  jeep.name = "jeep";
  jeep.materials = tank.materials;
  jeep.ranges = {3000};
  jeep.parts = {hull};
  p.icons = {tank, jeep};
  return p;
}

TEST(EntityShapes, theTurretTurnsAboutItsRingAndTheDeadFallBackToTheLiving) {
  const EntityMeshes m = flattenEntityIcons(pack());
  ASSERT_EQ(m.shapes.size(), 2u);
  const EntityShape& alive = m.shapes[0][0][0];
  EXPECT_EQ(alive.body.count, 6u);    // the hull's two triangles
  EXPECT_EQ(alive.turret.count, 6u);  // the turret's
  EXPECT_FLOAT_EQ(alive.pivot[1], 1.6f);
  // The turret's vertices are in its own frame: its ring at the origin, so
  // they keep the part's own coordinates (0.4 m up, not 2.0).
  const IconVertex& t = m.vertices[std::size_t(alive.turret.baseVertex) + m.indices[alive.turret.firstIndex]];
  EXPECT_FLOAT_EQ(t.y, 0.4f);
  // The hull's vertices are in the body frame.
  const IconVertex& h = m.vertices[std::size_t(alive.body.baseVertex) + m.indices[alive.body.firstIndex]];
  EXPECT_FLOAT_EQ(h.y, 0.5f);
  // Dead: the wreck alone, no turret.
  const EntityShape& dead = m.shapes[0][1][0];
  EXPECT_EQ(dead.body.count, 6u);
  EXPECT_EQ(dead.turret.count, 0u);
  EXPECT_NE(dead.body.baseVertex, alive.body.baseVertex);
  // The jeep has no dead parts: dead, it draws as it did alive.
  EXPECT_EQ(m.shapes[1][1][0].body.baseVertex, m.shapes[1][0][0].body.baseVertex);
  EXPECT_EQ(m.shapes[1][1][0].body.count, m.shapes[1][0][0].body.count);
  // The bounding radius covers the gun turned anywhere: 6 m of gun from a
  // ring 1.6 m up, and the hull's corners.
  EXPECT_GE(m.reach[0], std::hypot(6.0f, 0.4f));
  EXPECT_GE(m.reach[0], std::hypot(1.75f, 0.5f, 3.5f) - 1e-5f);
  // The shadow's footprint is the hull's, not the gun's overhang.
  EXPECT_FLOAT_EQ(m.footprint[0][2], -3.5f);
  EXPECT_FLOAT_EQ(m.footprint[0][5], 3.5f);
}

TEST(EntityShapes, theGunElevatesAboutItsTrunnionOnTheTurretOrOnTheHull) {
  // A tank: hull, turret at the ring 1.6 m up, gun on the turret at its
  // trunnion (0.4 m up, 1.9 m ahead of the ring), a 4 m barrel. A tank
  // destroyer: the gun on the hull, no turret.
  iconpack::Pack p = pack();
  iconpack::Icon& tank = p.icons[0];
  tank.parts[1].meshes = {quad(-1.4f, 1.4f, 0.7f, -1.9f, 1.6f)};  // the turret's roof only
  iconpack::Part gun;
  gun.name = "Gun";  // any case
  gun.parent = 1;
  gun.offset = {0, 0.4f, -1.9f};
  gun.meshes = {quad(-0.1f, 0.1f, 0.1f, -4.1f, -0.1f)};
  tank.parts.insert(tank.parts.begin() + 2, gun);
  iconpack::Icon destroyer = p.icons[1];
  destroyer.name = "destroyer";
  gun.parent = 0;
  gun.offset = {0, 1.2f, -2.0f};
  destroyer.parts.push_back(gun);
  p.icons.push_back(destroyer);
  const EntityMeshes m = flattenEntityIcons(p);
  const EntityShape& t = m.shapes[0][0][0];
  EXPECT_EQ(t.body.count, 6u);
  EXPECT_EQ(t.turret.count, 6u);  // the gun is not the turret's any more
  EXPECT_EQ(t.gun.count, 6u);
  EXPECT_TRUE(t.gunTurns);
  EXPECT_EQ(t.gunPivot, (std::array<float, 3>{0, 0.4f, -1.9f}));  // in the turret's frame
  EXPECT_FLOAT_EQ(t.pivot[1], 1.6f);
  // The gun's vertices are in its own frame: the trunnion at the origin.
  const IconVertex& g = m.vertices[std::size_t(t.gun.baseVertex) + m.indices[t.gun.firstIndex]];
  EXPECT_FLOAT_EQ(g.y, 0.1f);
  EXPECT_FLOAT_EQ(g.z, -4.1f);
  // Reach: the muzzle from the trunnion, plus the trunnion from the ring, plus the ring.
  EXPECT_GE(m.reach[0], std::hypot(4.1f, 0.1f));
  EXPECT_GE(m.reach[0] + 1e-5f, std::hypot(4.1f, 0.1f) + std::hypot(0.4f, 1.9f) + 1.6f);
  // The dead wreck has no gun.
  EXPECT_EQ(m.shapes[0][1][0].gun.count, 0u);
  // The destroyer's gun hangs from the hull: it pitches in the body frame and never turns.
  const EntityShape& d = m.shapes[2][0][0];
  EXPECT_EQ(d.turret.count, 0u);
  EXPECT_EQ(d.gun.count, 6u);
  EXPECT_FALSE(d.gunTurns);
  EXPECT_EQ(d.gunPivot, (std::array<float, 3>{0, 1.2f, -2.0f}));
  // Neither gun widens the shadow's footprint.
  EXPECT_FLOAT_EQ(m.footprint[2][2], -3.5f);
}

TEST(EntityShapes, everyLevelKeepsTheBodyTurretAndGunGroupsOverOneVertexRun) {
  // Two levels: the hull and turret lose a triangle at level 1; the gun
  // hangs from the turret at both.
  iconpack::Pack p = pack();
  iconpack::Icon& tank = p.icons[0];
  tank.ranges = {300, 5000};
  iconpack::Part gun;
  gun.name = "gun";
  gun.parent = 1;
  gun.offset = {0, 0.4f, -1.9f};
  gun.meshes = {quad(-0.1f, 0.1f, 0.1f, -4.1f, -0.1f)};
  tank.parts.insert(tank.parts.begin() + 2, gun);
  for (iconpack::Part& part : tank.parts) {
    for (iconpack::Mesh& mesh : part.meshes) {
      const std::vector<std::uint32_t> full = mesh.levels[0];
      mesh.levels = {full, part.name == "gun" ? full : std::vector<std::uint32_t>(full.begin(), full.begin() + 3)};
    }
  }
  const EntityMeshes m = flattenEntityIcons(p);
  const EntityLevels& alive = m.shapes[0][0];
  ASSERT_EQ(alive.size(), 2u);
  EXPECT_EQ(alive[0].body.count, 6u);
  EXPECT_EQ(alive[1].body.count, 3u);
  EXPECT_EQ(alive[1].turret.count, 3u);
  EXPECT_EQ(alive[1].gun.count, 6u);
  // One vertex run and the same pivots at every level.
  EXPECT_EQ(alive[1].body.baseVertex, alive[0].body.baseVertex);
  EXPECT_EQ(alive[1].gun.baseVertex, alive[0].gun.baseVertex);
  EXPECT_NE(alive[1].body.firstIndex, alive[0].body.firstIndex);
  EXPECT_EQ(alive[1].pivot, alive[0].pivot);
  EXPECT_EQ(alive[1].gunPivot, alive[0].gunPivot);
  EXPECT_TRUE(alive[1].gunTurns);
  // The same vertices: level 1's first turret index is level 0's.
  EXPECT_EQ(m.indices[alive[1].turret.firstIndex], m.indices[alive[0].turret.firstIndex]);
  // The dead wreck has two levels too; the jeep one (its ranges).
  EXPECT_EQ(m.shapes[0][1].size(), 2u);
  EXPECT_EQ(m.shapes[1][0].size(), 1u);
}

Eigen::Vector3d rotate(const std::array<float, 4>& q, const Eigen::Vector3d& v) {
  return Eigen::Quaterniond(q[3], q[0], q[1], q[2]) * v;
}

TEST(EntityShapes, headingsTurnForwardClockwiseAndKnockedOverObjectsLieAlongTheirHeading) {
  const Eigen::Vector3d forward(0, 0, -1), up(0, 1, 0);
  // Heading 90: forward (north, -Z) turns to east (+X), as the object shader's heading does.
  EXPECT_TRUE(rotate(headingQuaternion(90), forward).isApprox(Eigen::Vector3d(1, 0, 0), 1e-6));
  EXPECT_TRUE(rotate(headingQuaternion(180), forward).isApprox(Eigen::Vector3d(0, 0, 1), 1e-6));
  EXPECT_TRUE(rotate(headingQuaternion(33), up).isApprox(up, 1e-6));
  // Knocked over at heading 90: its top points east, its front down.
  EXPECT_TRUE(rotate(lyingQuaternion(90), up).isApprox(Eigen::Vector3d(1, 0, 0), 1e-6));
  EXPECT_TRUE(rotate(lyingQuaternion(90), forward).isApprox(Eigen::Vector3d(0, -1, 0), 1e-6));
}

EffectView view() {
  EffectView v;
  v.eye = {0, 10, 0};
  v.right = {1, 0, 0};
  v.up = {0, 1, 0};
  v.focal = 1000;
  return v;
}

TEST(EntityShapes, trailsFadeWithAgeAndStayVisibleFarAway) {
  scene::Trail t;
  t.lifeS = 2;
  t.points = {{-10, 10, -100, 1.5f}, {0, 10, -100, 1.0f}, {10, 10, -100, 0.0f}};
  std::vector<EffectVertex> out;
  appendTrail(t, view(), 1.5, out);
  ASSERT_EQ(out.size(), 12u);  // two segments, two triangles each
  const auto alpha = [](const EffectVertex& v) { return int(v.rgba >> 24); };
  // 0.85 x (1 - age / life): the oldest end faintest, the newest strongest.
  EXPECT_EQ(alpha(out[0]), int(std::lround(0.85 * 0.25 * 255)));
  EXPECT_EQ(alpha(out[6 + 4]), int(std::lround(0.85 * 255)));
  // A segment crossing the view is widened across it (up and down, here).
  EXPECT_NEAR(std::abs(out[0].y - out[1].y), 2 * 0.3, 1e-5);  // 0.3 m beats 1.5 px at 100 m
  // Ten kilometres away the ribbon is 1.5 pixels wide, not 0.6 m.
  scene::Trail far = t;
  for (auto& p : far.points) p.z = -10000;
  out.clear();
  appendTrail(far, view(), 1.5, out);
  const double half = std::abs(double(out[0].y) - double(out[1].y)) / 2;
  EXPECT_NEAR(half, 0.5 * 1.5 * std::hypot(10000.0, 10.0) / 1000, 0.01);
  // One point, or no life: nothing.
  out.clear();
  t.points.resize(1);
  appendTrail(t, view(), 1.5, out);
  EXPECT_TRUE(out.empty());
}

TEST(EntityShapes, flashesGrowAndGoOutAfterTheirDuration) {
  std::vector<EffectVertex> out;
  scene::Flash f;
  f.z = -50;
  f.radiusM = 6;
  f.durationS = 0.5f;
  f.ageS = 0;
  appendFlash(f, view(), 10, out);
  ASSERT_EQ(out.size(), 6u);
  const double r0 = std::abs(double(out[1].x) - double(out[0].x)) / 2;
  EXPECT_NEAR(r0, 0.35 * 6, 1e-5);
  EXPECT_EQ(int(out[0].rgba >> 24), 255);
  out.clear();
  f.ageS = 0.375f;  // three quarters: sqrt(0.75) of the growth, alpha 1 - 0.75^2
  appendFlash(f, view(), 10, out);
  ASSERT_EQ(out.size(), 6u);
  EXPECT_NEAR(std::abs(double(out[1].x) - double(out[0].x)) / 2, 6 * (0.35 + 0.65 * std::sqrt(0.75)), 1e-4);
  EXPECT_EQ(int(out[0].rgba >> 24), int(std::lround((1 - 0.5625) * 255)));
  // The centre is lifted a quarter of the radius: a ground burst is a dome.
  EXPECT_NEAR((double(out[0].y) + double(out[2].y)) / 2, 0.25 * 6 * (0.35 + 0.65 * std::sqrt(0.75)), 1e-4);
  out.clear();
  f.ageS = 0.5f;
  appendFlash(f, view(), 10, out);
  EXPECT_TRUE(out.empty());
}

TEST(EntityShapes, contactShadowLiesOnTheFootprintInTheEntitysTilt) {
  std::vector<EffectVertex> out;
  const std::array<float, 6> footprint{-1.75f, 0, -3.5f, 1.75f, 0, 3.5f};  // no height: not moved by the sun
  appendShadow(Eigen::Vector3d(10, 100, 20), headingQuaternion(90), 1, footprint, out);
  ASSERT_EQ(out.size(), 6u);
  // Heading 90: the 7 m length runs east-west; 0.5 m of margin all round.
  double minX = 1e9, maxX = -1e9, minZ = 1e9, maxZ = -1e9;
  for (const EffectVertex& v : out) {
    minX = std::min(minX, double(v.x));
    maxX = std::max(maxX, double(v.x));
    minZ = std::min(minZ, double(v.z));
    maxZ = std::max(maxZ, double(v.z));
    EXPECT_NEAR(v.y, 100.06, 1e-4);
  }
  EXPECT_NEAR(maxX - minX, 8, 1e-4);
  EXPECT_NEAR(maxZ - minZ, 4.5, 1e-4);
  EXPECT_NEAR((minX + maxX) / 2, 10, 1e-4);
}

}  // namespace
}  // namespace sandtable::render::detail
