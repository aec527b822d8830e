// The built-in procedural models (builtin_models.h) against their
// construction worked out by hand: triangles (a box 12, an n-gon prism
// 4n - 4, an 8-sided cylinder 28, an 8-sided cone 14, the boat's 7-corner
// loft 24), bounding boxes from the dimensions in the source, facing north,
// standing on y = 0, unit normals that agree with the winding, and every
// face wound outward (the winding number behind it one more than in front,
// never negative). Then the definition file: names resolved on model, dead
// and component lines, an unknown name refused, base-below for the
// grounded ones, and the sample file.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include "sandtable/formats/dis_icons.h"
#include "sandtable/icons/builtin_models.h"
#include "sandtable/icons/icon_build.h"

using namespace sandtable;
using namespace sandtable::icons;

namespace {

const std::string kSource = SANDTABLE_SOURCE_DIR;

using V3 = std::array<double, 3>;

struct Expected {
  const char* name;
  std::size_t triangles;
  V3 min, max;  ///< bounding box, metres
};

// Worked out from the dimensions in builtin_models.cpp.
const std::vector<Expected>& expected() {
  static const std::vector<Expected> e{
      // 8-sided cylinder: radius 0.25 (corners at 0, 90, 180, 270 degrees), 0 to 0.8 m.
      {"builtin:stump", 28, {-0.25, 0, -0.25}, {0.25, 0.8, 0.25}},
      // Hull 2 x 20 (hexagonal tracks) + 12 + 12; turret 20 + 28; gun 12 + 28. Barrel tip at z -6,
      // cupola top 1.6 + 0.9, tracks and hull +-1.75 wide, 3.5 m behind.
      {"builtin:tank", 152, {-1.75, 0, -6.0}, {1.75, 2.5, 3.5}},
      {"builtin:tank-hull", 64, {-1.75, 0, -3.5}, {1.75, 1.6, 3.5}},
      {"builtin:tank-turret", 48, {-1.4, 0, -1.9}, {1.4, 0.9, 1.6}},
      // The mantlet (0.7 x 0.5 x 0.25, from 0.2 ahead of the trunnion to 0.05 behind) and the
      // barrel from 0.1 to 4.1 m ahead, both about the trunnion (0, 0.4, -1.9 of the turret).
      {"builtin:tank-gun", 40, {-0.35, -0.25, -4.1}, {0.35, 0.25, 0.05}},
      {"builtin:truck", 11 * 12, {-1.25, 0, -3.5}, {1.25, 3.0, 3.5}},
      {"builtin:jeep", 6 * 12, {-0.85, 0, -1.7}, {0.85, 1.5, 1.7}},
      // Loft: 2 x (7 - 2) caps + 2 x 7 sides; 6 boxes; mast top at 9 m.
      {"builtin:boat", 24 + 6 * 12, {-3.0, 0, -12.5}, {3.0, 9.0, 12.5}},
      // Fuselage 28, nose 14, wings, tailplanes and fin 5 x 12, canopy 12; wing tips at +-4.5,
      // nose apex at -6, fin top 3.2.
      {"builtin:jet", 28 + 14 + 5 * 12 + 12, {-4.5, 0, -6.0}, {4.5, 3.2, 6.0}},
      // Body 28, nose 14, 4 boxes; fins +-0.3 about the axis at 0.3 m.
      {"builtin:missile", 28 + 14 + 4 * 12, {-0.3, 0, -1.5}, {0.3, 0.6, 1.5}},
      // Slab 1.8 x 1.4 turned 25 degrees about (0.3, -0.3): x reach 0.9 cos 25 + 0.7 sin 25.
      {"builtin:wreck", 3 * 12, {-1.5, 0, -3.0}, {1.5, 1.25, 3.0}},
      // Roof overhang +-5.3 x +-4.4, chimney top 6 m.
      {"builtin:house", 12 + 8 + 2 * 12 + 4 * 12, {-5.3, 0, -4.4}, {5.3, 6.0, 4.4}},
      {"builtin:ruins", 9 * 12, {-5.0, 0, -4.0}, {5.0, 2.2, 4.0}},
  };
  return e;
}

/// Every triangle of a model as three corners.
std::vector<std::array<V3, 3>> triangles(const Model& m) {
  std::vector<std::array<V3, 3>> out;
  for (const Mesh& mesh : m.meshes) {
    for (std::size_t k = 0; k < mesh.indices.size(); k += 3) {
      std::array<V3, 3> t;
      for (std::size_t c = 0; c < 3; ++c) {
        const std::size_t v = 3 * std::size_t(mesh.indices[k + c]);
        t[c] = {mesh.positions[v], mesh.positions[v + 1], mesh.positions[v + 2]};
      }
      out.push_back(t);
    }
  }
  return out;
}

V3 sub(V3 a, V3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(V3 a, V3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V3 cross(V3 a, V3 b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double norm(V3 a) { return std::sqrt(dot(a, a)); }

/// The winding number of the triangles about p: the sum of their solid
/// angles (Van Oosterom and Strackee) over 4 pi. Inside a closed surface
/// wound counter-clockwise from outside it is 1, outside 0; inside an
/// inside-out one, -1.
double winding(const std::vector<std::array<V3, 3>>& tris, V3 p) {
  double sum = 0;
  for (const auto& t : tris) {
    const V3 a = sub(t[0], p), b = sub(t[1], p), c = sub(t[2], p);
    const double la = norm(a), lb = norm(b), lc = norm(c);
    sum += 2 * std::atan2(dot(a, cross(b, c)), la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la);
  }
  return sum / (4 * std::numbers::pi);
}

Result<iconpack::Pack> buildText(const std::string& text) {
  auto defs = parseDefinitions(std::as_bytes(std::span(text.data(), text.size())), "defs.txt", kSource);
  if (!defs) return defs.problems();
  return buildPack(defs.value());
}

const iconpack::Icon* find(const iconpack::Pack& p, const std::string& name) {
  for (const auto& i : p.icons) {
    if (i.name == name) return &i;
  }
  return nullptr;
}

TEST(BuiltinModels, everyNameLoadsAndTheTreeIsTheTreeModel) {
  std::vector<std::string> names;
  for (const BuiltinModel& b : builtinModels()) names.emplace_back(b.name);
  EXPECT_EQ(names, (std::vector<std::string>{"builtin:tree", "builtin:stump", "builtin:tank", "builtin:tank-hull",
                                             "builtin:tank-turret", "builtin:tank-gun", "builtin:truck", "builtin:jeep",
                                             "builtin:boat", "builtin:jet", "builtin:missile", "builtin:wreck",
                                             "builtin:house", "builtin:ruins", "builtin:rock"}));
  for (const std::string& n : names) {
    const auto m = builtinModel(n);
    ASSERT_TRUE(m) << n;
    EXPECT_EQ(m->source, n);
    EXPECT_EQ(m->meshes.size(), m->materials.size()) << n;  // one mesh per material
    EXPECT_LT(m->triangleCount(), 200u) << n;
  }
  const auto tree = builtinModel("builtin:tree");
  ASSERT_TRUE(tree);
  EXPECT_EQ(triangles(tree.value()), triangles(treeModel()));
  ASSERT_EQ(tree->materials.size(), 2u);
  EXPECT_EQ(tree->materials[1].baseColour, treeModel().materials[1].baseColour);
  EXPECT_FALSE(builtinModel("builtin:tanks"));
  EXPECT_FALSE(builtinModel("tank"));
  EXPECT_TRUE(isBuiltinName("builtin:anything"));
  EXPECT_FALSE(isBuiltinName("models/builtin.glb"));
  // Grounded: the static ones that stand on a flat foot.
  for (const BuiltinModel& b : builtinModels()) {
    const bool grounded = b.name == "builtin:tree" || b.name == "builtin:stump" || b.name == "builtin:house" ||
                          b.name == "builtin:ruins" || b.name == "builtin:rock";
    EXPECT_EQ(b.grounded, grounded) << b.name;
  }
}

TEST(BuiltinModels, trianglesAndBoundsAreTheHandWorkedOnes) {
  for (const Expected& e : expected()) {
    SCOPED_TRACE(e.name);
    const auto m = builtinModel(e.name);
    ASSERT_TRUE(m);
    EXPECT_EQ(m->triangleCount(), e.triangles);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(m->bounds.min[a], e.min[a], 1e-5) << "axis " << a;
      EXPECT_NEAR(m->bounds.max[a], e.max[a], 1e-5) << "axis " << a;
    }
  }
  // The rock: 4 rings of 10 (3 bands of 20 triangles), 10 to the apex, a
  // 10-triangle foot. Heights are exact; each corner's radius is its ring's
  // times 0.88 to 1.12, stretched 1.15 in x and 0.9 in z. The widest ring
  // (1.0 m) has corners at 0 and 180 degrees (x) and at 72 and 108 (z,
  // sin 72 = 0.951). It is then centred on its footprint.
  const auto rock = builtinModel("builtin:rock");
  ASSERT_TRUE(rock);
  EXPECT_EQ(rock->triangleCount(), 80u);
  EXPECT_NEAR(rock->bounds.min[1], 0, 1e-6);
  EXPECT_NEAR(rock->bounds.max[1], 1.3, 1e-6);
  for (const float x : {-rock->bounds.min[0], rock->bounds.max[0]}) {
    EXPECT_GE(x, 1.0 * 0.88 * 1.15 - 1e-5);
    EXPECT_LE(x, 1.0 * 1.12 * 1.15 + 1e-5);
  }
  for (const float z : {-rock->bounds.min[2], rock->bounds.max[2]}) {
    EXPECT_GE(z, 1.0 * 0.88 * 0.9 * std::sin(0.4 * std::numbers::pi) - 1e-5);
    EXPECT_LE(z, 1.0 * 1.12 * 0.9 + 1e-5);
  }
  EXPECT_EQ(triangles(rock.value()), triangles(builtinModel("builtin:rock").value()));  // the same rock every time
}

TEST(BuiltinModels, theTankIsItsHullWithTheTurretOnTheRoofAndTheGunOnTheTurret) {
  const auto tank = builtinModel("builtin:tank"), hull = builtinModel("builtin:tank-hull"),
             turret = builtinModel("builtin:tank-turret"), gun = builtinModel("builtin:tank-gun");
  ASSERT_TRUE(tank && hull && turret && gun);
  auto sorted = [](std::vector<std::array<V3, 3>> t) {
    std::sort(t.begin(), t.end());
    return t;
  };
  std::vector<std::array<V3, 3>> joined = triangles(hull.value());
  for (auto t : triangles(turret.value())) {
    for (V3& c : t) c[1] += double(kTankTurretRingHeight);
    joined.push_back(t);
  }
  for (auto t : triangles(gun.value())) {
    for (V3& c : t) {
      for (int a = 0; a < 3; ++a) c[a] += double(kTankGunTrunnion[a]) + (a == 1 ? double(kTankTurretRingHeight) : 0.0);
    }
    joined.push_back(t);
  }
  const auto a = sorted(triangles(tank.value())), b = sorted(joined);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    for (std::size_t c = 0; c < 3; ++c) {
      for (int x = 0; x < 3; ++x) ASSERT_NEAR(a[k][c][x], b[k][c][x], 1e-5);
    }
  }
  EXPECT_FLOAT_EQ(kTankTurretRingHeight, 1.6f);
  EXPECT_FLOAT_EQ(hull->bounds.max[1], kTankTurretRingHeight);  // the turret sits on the roof
  // The trunnion on the barrel's axis at the turret's front face.
  EXPECT_EQ(kTankGunTrunnion, (std::array<float, 3>{0.0f, 0.4f, -1.9f}));
  EXPECT_FLOAT_EQ(turret->bounds.min[2], kTankGunTrunnion[2]);
  EXPECT_NEAR(0.5 * (gun->bounds.min[1] + gun->bounds.max[1]), 0, 1e-6);
}

/// The vertex of a model with the most negative z.
V3 foremost(const Model& m) {
  V3 best{0, 0, INFINITY};
  for (const Mesh& mesh : m.meshes) {
    for (std::size_t v = 0; v < mesh.positions.size(); v += 3) {
      if (mesh.positions[v + 2] < best[2]) best = {mesh.positions[v], mesh.positions[v + 1], mesh.positions[v + 2]};
    }
  }
  return best;
}

/// Mean position of the vertices of the material named `name`.
V3 centreOf(const Model& m, const std::string& name) {
  V3 sum{0, 0, 0};
  std::size_t n = 0;
  for (const Mesh& mesh : m.meshes) {
    if (m.materials[mesh.material].name != name) continue;
    for (std::size_t v = 0; v < mesh.positions.size(); v += 3, ++n) {
      for (int a = 0; a < 3; ++a) sum[a] += mesh.positions[v + a];
    }
  }
  EXPECT_GT(n, 0u) << name;
  for (double& s : sum) s /= double(n ? n : 1);
  return sum;
}

TEST(BuiltinModels, vehiclesFaceNorth) {
  // The tank's foremost point is the barrel's muzzle: on its axis 1.6 + 0.4 m up, 0.12 m radius.
  const V3 muzzle = foremost(builtinModel("builtin:tank").value());
  EXPECT_NEAR(muzzle[2], -6.0, 1e-5);
  EXPECT_LE(std::abs(muzzle[0]), 0.12 + 1e-5);
  EXPECT_NEAR(muzzle[1], 2.0, 0.12 + 1e-5);
  // The jet's and the missile's: their nose cones' apexes on the fuselage axis.
  const V3 nose = foremost(builtinModel("builtin:jet").value());
  EXPECT_NEAR(nose[0], 0, 1e-6);
  EXPECT_NEAR(nose[1], 0.6, 1e-6);
  EXPECT_NEAR(nose[2], -6.0, 1e-6);
  const V3 tip = foremost(builtinModel("builtin:missile").value());
  EXPECT_NEAR(tip[0], 0, 1e-6);
  EXPECT_NEAR(tip[1], 0.3, 1e-6);
  EXPECT_NEAR(tip[2], -1.5, 1e-6);
  // The boat's bow is a point on the centre line, 12.5 m ahead.
  const V3 bow = foremost(builtinModel("builtin:boat").value());
  EXPECT_NEAR(bow[0], 0, 1e-6);
  EXPECT_NEAR(bow[2], -12.5, 1e-6);
  // Windscreens ahead of the middle; the jet's canopy too; the house's door on its north wall.
  for (const char* n : {"builtin:truck", "builtin:jeep", "builtin:boat", "builtin:jet"}) {
    EXPECT_LT(centreOf(builtinModel(n).value(), "glass")[2], -0.3) << n;
  }
  EXPECT_NEAR(centreOf(builtinModel("builtin:house").value(), "door")[2], -4.01, 1e-5);
  // The truck's cab (the glass) is ahead of its cargo box.
  const auto truck = builtinModel("builtin:truck").value();
  EXPECT_LT(centreOf(truck, "glass")[2], centreOf(truck, "canvas")[2]);
}

TEST(BuiltinModels, normalsAreUnitAndOutwardOnClosedSolids) {
  for (const BuiltinModel& b : builtinModels()) {
    if (b.name == "builtin:tree") continue;  // its trunk is an open tube (TreeModel tests it)
    SCOPED_TRACE(std::string(b.name));
    const Model m = b.make();
    // Stands on the ground, but for the gun: its origin is its trunnion.
    if (b.name != "builtin:tank-gun") {
      EXPECT_NEAR(m.bounds.min[1], 0, 1e-6);
    }
    EXPECT_NEAR(0.5 * (m.bounds.min[0] + m.bounds.max[0]), 0, 1e-5);  // centred on its footprint
    // The gun overhangs the hull; the turret narrows to the front.
    if (b.name != "builtin:tank" && b.name != "builtin:tank-turret" && b.name != "builtin:tank-gun") {
      EXPECT_NEAR(0.5 * (m.bounds.min[2] + m.bounds.max[2]), 0, 1e-5);
    }
    const auto tris = triangles(m);
    std::size_t inward = 0, disagree = 0, open = 0;
    for (const Mesh& mesh : m.meshes) {
      for (std::size_t v = 0; v < mesh.normals.size(); v += 3) {
        const V3 n{mesh.normals[v], mesh.normals[v + 1], mesh.normals[v + 2]};
        ASSERT_NEAR(norm(n), 1.0, 1e-5);
      }
      for (std::size_t k = 0; k < mesh.indices.size(); k += 3) {
        V3 c{0, 0, 0}, p[3];
        for (std::size_t i = 0; i < 3; ++i) {
          const std::size_t v = 3 * std::size_t(mesh.indices[k + i]);
          p[i] = {mesh.positions[v], mesh.positions[v + 1], mesh.positions[v + 2]};
          for (int a = 0; a < 3; ++a) c[a] += p[i][a] / 3;
        }
        const V3 face = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        const double area2 = norm(face);
        ASSERT_GT(area2, 1e-8) << "degenerate triangle";
        const V3 n{face[0] / area2, face[1] / area2, face[2] / area2};
        // Each corner's normal leans the way the winding faces.
        for (std::size_t i = 0; i < 3; ++i) {
          const std::size_t v = 3 * std::size_t(mesh.indices[k + i]);
          disagree += dot({mesh.normals[v], mesh.normals[v + 1], mesh.normals[v + 2]}, n) <= 0;
        }
        // 1 mm in front of the face: outside this solid (winding 0, or more
        // where another solid overlaps it); 1 mm behind: one more. An
        // inside-out solid shows as -1, a hole or a flipped face as a
        // winding that is not a whole number.
        const double eps = 1e-3;
        const double front = winding(tris, {c[0] + eps * n[0], c[1] + eps * n[1], c[2] + eps * n[2]});
        const double behind = winding(tris, {c[0] - eps * n[0], c[1] - eps * n[1], c[2] - eps * n[2]});
        open += std::abs(front - std::round(front)) > 1e-3 || std::abs(behind - std::round(behind)) > 1e-3;
        inward += std::round(front) < 0 || std::round(behind) < 1;
      }
    }
    EXPECT_EQ(disagree, 0u);
    EXPECT_EQ(open, 0u);
    EXPECT_EQ(inward, 0u);
  }
}

TEST(BuiltinModels, aBoxFaceNormalPointsAwayFromTheBoxCentre) {
  // The brief's own check on the simplest built-in box, the jeep's body
  // (-0.75..0.75, 0.35..1.0, -1.7..1.7): every triangle of the "body"
  // mesh faces away from (0, 0.675, 0).
  const Model jeep = builtinModel("builtin:jeep").value();
  for (const Mesh& mesh : jeep.meshes) {
    if (jeep.materials[mesh.material].name != "body") continue;
    ASSERT_EQ(mesh.triangleCount(), 12u);
    for (std::size_t k = 0; k < mesh.indices.size(); k += 3) {
      V3 p[3], c{0, 0, 0};
      for (std::size_t i = 0; i < 3; ++i) {
        const std::size_t v = 3 * std::size_t(mesh.indices[k + i]);
        p[i] = {mesh.positions[v], mesh.positions[v + 1], mesh.positions[v + 2]};
        for (int a = 0; a < 3; ++a) c[a] += p[i][a] / 3;
      }
      EXPECT_GT(dot(cross(sub(p[1], p[0]), sub(p[2], p[0])), sub(c, {0, 0.675, 0})), 0) << "triangle " << k / 3;
    }
  }
}

TEST(BuiltinModels, colours) {
  auto colour = [](const char* model, const char* material) {
    const Model m = builtinModel(model).value();
    for (const Material& mat : m.materials) {
      if (mat.name == material) return mat.baseColour;
    }
    ADD_FAILURE() << model << " has no material " << material;
    return std::array<float, 4>{};
  };
  // Dark olive green: green over red over blue, dark.
  const auto olive = colour("builtin:tank", "armour");
  EXPECT_GT(olive[1], olive[0]);
  EXPECT_GT(olive[0], olive[2]);
  EXPECT_LT(olive[1], 0.4f);
  // The wreck is blackened; the stump's bark is the tree trunk's brown.
  const auto charred = colour("builtin:wreck", "charred");
  EXPECT_LT(charred[0] + charred[1] + charred[2], 0.3f);
  EXPECT_EQ(colour("builtin:stump", "bark"), treeModel().materials[0].baseColour);
  for (const BuiltinModel& b : builtinModels()) {
    for (const Material& mat : b.make().materials) EXPECT_EQ(mat.baseColour[3], 1.0f) << b.name;
  }
}

TEST(BuiltinIcons, namesResolveOnModelDeadAndComponentLines) {
  const std::string text =
      "sandtable-icons 1\n"
      "icon tank\n  model builtin:tank-hull\n  component turret builtin:tank-turret offset=0,1.6,0\n"
      "  component gun builtin:tank-gun offset=0,0.4,-1.9 parent=turret\n"
      "  dead builtin:wreck\n  component hatch builtin:rock offset=0,1.25,0 state=dead\n"
      "icon house\n  model builtin:house\n  dead builtin:ruins\n  lod 1\n";
  auto r = buildText(text);
  ASSERT_TRUE(r) << r.error();
  const iconpack::Icon* tank = find(r.value(), "tank");
  const iconpack::Icon* house = find(r.value(), "house");
  ASSERT_TRUE(tank && house);
  ASSERT_EQ(tank->parts.size(), 5u);  // hull, turret, gun; wreck, its component
  EXPECT_EQ(tank->parts[1].name, "turret");
  EXPECT_EQ(tank->parts[1].offset, (std::array<float, 3>{0, 1.6f, 0}));
  EXPECT_EQ(tank->parts[2].name, "gun");
  EXPECT_EQ(tank->parts[2].parent, 1);
  EXPECT_EQ(tank->parts[2].offset, kTankGunTrunnion);
  EXPECT_EQ(tank->parts[3].state, iconpack::State::dead);
  EXPECT_EQ(iconpack::triangleCount(*tank, 0), 152u);
  EXPECT_EQ(iconpack::triangleCount(*tank, 0, iconpack::State::dead), 36u + 80u);
  // The articulated tank's alive bounds are the one-piece tank's; a vehicle keeps its foot.
  const std::array<float, 6> box{-1.75f, 0, -6.0f, 1.75f, 2.5f, 3.5f};
  for (std::size_t a = 0; a < 6; ++a) EXPECT_NEAR(tank->bounds[a], box[a], 1e-5) << a;
  // The cylinder: the farthest corner from the vertical axis is the muzzle's, (0.12, z -6).
  EXPECT_NEAR(tank->cylinderRadius, std::hypot(0.12, 6.0), 1e-5);
  EXPECT_NEAR(tank->cylinderHeight, 2.5, 1e-5);
  // A building is lowered by kDefaultBaseBelow unless the file says otherwise.
  EXPECT_FLOAT_EQ(house->bounds[1], -kDefaultBaseBelow);
  EXPECT_FLOAT_EQ(house->bounds[4], 6.0f);
  auto level = buildText("sandtable-icons 1\nicon h\n  model builtin:house\n  base-below 0\n  lod 1\n");
  ASSERT_TRUE(level) << level.error();
  EXPECT_FLOAT_EQ(level->icons.at(0).bounds[1], 0.0f);
}

TEST(BuiltinIcons, anUnknownBuiltinIsRefusedNamingTheKnownOnes) {
  const std::string text = "sandtable-icons 1\nicon a\n  model builtin:tree\nicon b\n  model builtin:tanks\n";
  auto r = buildText(text);
  ASSERT_FALSE(r);
  ASSERT_EQ(r.problems().size(), 1u);
  EXPECT_EQ(r.problems()[0].offset, text.find("icon b"));
  EXPECT_NE(r.error().find("'builtin:tanks' is not a built-in model"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("builtin:tank-turret"), std::string::npos) << r.error();
  auto comp = buildText("sandtable-icons 1\nicon a\n  model builtin:jeep\n  component g builtin:gun offset=0,1,0\n");
  ASSERT_FALSE(comp);
  EXPECT_NE(comp.error().find("'builtin:gun' is not a built-in model"), std::string::npos) << comp.error();
}

TEST(BuiltinIcons, theSampleFileBuildsEveryIconWithoutWarnings) {
  auto defs = readDefinitions(kSource + "/samples/icons.txt");
  ASSERT_TRUE(defs) << defs.error();
  auto r = buildPack(defs.value());
  ASSERT_TRUE(r) << r.error();
  EXPECT_TRUE(r.warnings().empty()) << r.warnings().front().str();  // no level dropped
  const iconpack::Pack& p = r.value();
  std::vector<std::string> names;
  for (const auto& i : p.icons) names.push_back(i.name);
  EXPECT_EQ(names, (std::vector<std::string>{"tree", "tree-small", "tree-tall", "tank", "truck", "jeep", "boat", "jet",
                                             "missile", "house", "rock"}));
  const iconpack::Icon& tree = *find(p, "tree");
  EXPECT_EQ(iconpack::triangleCount(tree, 0), 80u);
  EXPECT_EQ(iconpack::triangleCount(tree, 0, iconpack::State::dead), 28u);  // the stump
  const iconpack::Icon& tank = *find(p, "tank");
  EXPECT_TRUE(tank.armed && !tank.resupply);
  ASSERT_EQ(tank.dis.size(), 4u);
  EXPECT_EQ(tank.dis[0], (iconpack::DisPattern{{1, 1, 225, 1, 1, 3, 0}, 0}));
  EXPECT_EQ(iconpack::disText(tank.dis[1]), "1.1.*.1");
  ASSERT_GE(tank.parts.size(), 4u);
  EXPECT_EQ(tank.parts[1].name, "turret");
  EXPECT_EQ(tank.parts[2].name, "gun");  // on the turret, at its trunnion
  EXPECT_EQ(tank.parts[2].parent, 1);
  EXPECT_EQ(tank.parts[2].offset, kTankGunTrunnion);
  EXPECT_EQ(iconpack::triangleCount(tank, 0), 152u);  // the one-piece tank's
  EXPECT_EQ(iconpack::triangleCount(tank, 0, iconpack::State::dead), 36u);
  EXPECT_TRUE(find(p, "truck")->resupply && !find(p, "truck")->armed);
  EXPECT_TRUE(!find(p, "jeep")->armed && !find(p, "jeep")->resupply);
  EXPECT_TRUE(find(p, "jet")->armed);
  EXPECT_EQ(iconpack::triangleCount(*find(p, "house"), 0, iconpack::State::dead), 108u);  // the ruins
  for (const auto& icon : p.icons) {
    SCOPED_TRACE(icon.name);
    EXPECT_FALSE(icon.ranges.empty());
    for (std::size_t l = 1; l < icon.ranges.size(); ++l) {
      EXPECT_GT(icon.ranges[l], icon.ranges[l - 1]);
      EXPECT_LE(double(iconpack::triangleCount(icon, l)), 0.9 * double(iconpack::triangleCount(icon, l - 1)));
    }
  }
  auto bytes = iconpack::encode(p);
  ASSERT_TRUE(bytes) << bytes.error();
  auto back = iconpack::decode(bytes.value(), "icons.pack");
  ASSERT_TRUE(back) << back.error();
  EXPECT_EQ(back.value(), p);
}

// The sample's dis lines put each kind of vehicle on the network to the
// icon a reader expects (SISO-REF-010 types; docs/ICONS.md §3.1).
TEST(BuiltinIcons, theSampleMapsDisTypesToItsVehicles) {
  auto defs = readDefinitions(kSource + "/samples/icons.txt");
  ASSERT_TRUE(defs) << defs.error();
  auto r = buildPack(defs.value());
  ASSERT_TRUE(r) << r.error();
  const iconpack::Pack& p = r.value();
  const iconpack::DisIconMap map(p);
  struct Case {
    iconpack::DisType type;
    const char* icon;
    iconpack::DisMatchBy by;
  };
  using By = iconpack::DisMatchBy;
  const Case cases[] = {
      {{1, 1, 225, 1, 1, 3, 0}, "tank", By::pattern},   // the US tank of the tank's own line
      {{1, 1, 222, 1, 2, 1, 0}, "tank", By::pattern},   // a Russian tank: 1.1.*.1
      {{1, 1, 222, 2, 1, 0, 0}, "tank", By::pattern},   // a Russian armoured fighting vehicle
      {{1, 1, 225, 3, 1, 0, 0}, "tank", By::pattern},   // a US armoured utility vehicle (APC)
      {{1, 1, 225, 7, 1, 2, 0}, "truck", By::pattern},  // a US large wheeled utility vehicle
      {{1, 1, 222, 6, 1, 0, 0}, "jeep", By::pattern},   // a small wheeled utility vehicle
      {{1, 2, 225, 1, 3, 0, 0}, "jet", By::pattern},    // any air platform
      {{1, 3, 222, 6, 1, 0, 0}, "boat", By::pattern},   // any surface platform
      {{2, 2, 225, 1, 1, 0, 0}, "missile", By::pattern},  // any munition
      {{1, 1, 225, 4, 1, 0, 0}, "tank", By::kindDomain},  // self-propelled artillery: no line, a land default
      {{1, 4, 225, 1, 1, 0, 0}, "boat", By::defaultName},  // a submarine: no pattern, the "boat" default
      {{3, 1, 225, 1, 0, 0, 0}, "tree", By::firstIcon},    // a life form: nothing fits, icon 0
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.icon);
    const iconpack::DisMatch m = map.match(c.type);
    ASSERT_LT(m.icon, p.icons.size());
    EXPECT_EQ(p.icons[m.icon].name, c.icon);
    EXPECT_EQ(m.by, c.by);
  }
}

}  // namespace
