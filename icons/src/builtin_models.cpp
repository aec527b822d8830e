// The built-in procedural models (see builtin_models.h): each one a few
// convex solids (boxes, prisms, cylinders, cones, a lofted hull) in flat
// base colours, under 200 triangles. Dimensions are written out here and
// tabulated in docs/ICONS.md §4; the tests check them from the numbers.
#include "sandtable/icons/builtin_models.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include "sandtable/base/hash.h"
#include "sandtable/icons/icon_build.h"

namespace sandtable::icons {
namespace {

using Vec2 = std::array<float, 2>;
using Vec3 = std::array<float, 3>;

/// The axis a prism is extruded along. Its cross-section is given in the
/// other two axes in increasing order: X -> (y, z), Y -> (x, z), Z -> (x, y).
enum class Axis { x, y, z };

/// An RGB base colour; alpha is 1.
struct Colour {
  float r, g, b;
};

/// Builds a model from convex solids, one mesh per material. Faces are
/// wound counter-clockwise seen from outside; flat faces get their own
/// vertices (flat normals), smooth sides (cylinders, cones, the rock)
/// share theirs so that the simplifier can take sides away.
class Shape {
 public:
  explicit Shape(std::string_view source) { model_.source = std::string(source); }

  /// The index of the material `name`, added on first use.
  std::uint32_t material(const char* name, Colour c) {
    for (std::uint32_t k = 0; k < model_.materials.size(); ++k) {
      if (model_.materials[k].name == name) return k;
    }
    Material m;
    m.name = name;
    m.baseColour = {c.r, c.g, c.b, 1.0f};
    model_.materials.push_back(m);
    const auto index = static_cast<std::uint32_t>(model_.meshes.size());
    Mesh mesh;
    mesh.material = index;
    model_.meshes.push_back(std::move(mesh));
    return index;
  }

  /// Later solids are moved by `o` (a component placed on its parent).
  void moveTo(Vec3 o) { origin_ = o; }

  /// A box between two corners.
  void box(std::uint32_t mat, Vec3 lo, Vec3 hi) {
    prism(mat, Axis::y, {{lo[0], lo[2]}, {hi[0], lo[2]}, {hi[0], hi[2]}, {lo[0], hi[2]}}, lo[1], hi[1]);
  }

  /// A box standing on y = `y0` up to `y1`, its footprint `sx` by `sz`
  /// about (cx, cz), turned `yawDegrees` about the vertical.
  void turnedBox(std::uint32_t mat, Vec2 c, float sx, float sz, float yawDegrees, float y0, float y1) {
    const double a = yawDegrees * std::numbers::pi / 180;
    const auto ca = float(std::cos(a)), sa = float(std::sin(a));
    std::vector<Vec2> p;
    for (const Vec2 k : {Vec2{-1, -1}, Vec2{1, -1}, Vec2{1, 1}, Vec2{-1, 1}}) {
      const float x = k[0] * sx / 2, z = k[1] * sz / 2;
      p.push_back({c[0] + x * ca - z * sa, c[1] + x * sa + z * ca});
    }
    prism(mat, Axis::y, p, y0, y1);
  }

  /// A convex polygon extruded along `axis` from `from` to `to`: its caps
  /// fanned from the first corner, its sides flat or (`smooth`) sharing
  /// vertices with normals halfway between the two sides' normals.
  void prism(std::uint32_t mat, Axis axis, std::vector<Vec2> poly, float from, float to, bool smooth = false,
             std::optional<std::uint32_t> capMat = std::nullopt) {
    const std::vector<Vec2> p = rightHanded(axis, std::move(poly));
    const std::size_t n = p.size();
    Mesh& cap = mesh(capMat.value_or(mat));
    addCap(cap, axis, p, to, +1);
    addCap(cap, axis, p, from, -1);
    Mesh& m = mesh(mat);
    const std::vector<Vec2> vn = cornerNormals(p);
    const auto first = static_cast<std::uint32_t>(m.vertexCount());
    if (smooth) {
      for (std::size_t i = 0; i < n; ++i) {
        const Vec3 nn{vn[i][0], vn[i][1], 0};
        vertex(m, axis, {p[i][0], p[i][1], from}, nn);
        vertex(m, axis, {p[i][0], p[i][1], to}, nn);
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t j = (i + 1) % n;
      std::uint32_t a0, a1, b0, b1;  // bottom and top of corners i and j
      if (smooth) {
        a0 = first + std::uint32_t(2 * i), b0 = a0 + 1;
        a1 = first + std::uint32_t(2 * j), b1 = a1 + 1;
      } else {
        const Vec2 d{p[j][0] - p[i][0], p[j][1] - p[i][1]};
        const float len = std::hypot(d[0], d[1]);
        const Vec3 nn{d[1] / len, -d[0] / len, 0};  // outward for a counter-clockwise polygon
        a0 = vertex(m, axis, {p[i][0], p[i][1], from}, nn);
        a1 = vertex(m, axis, {p[j][0], p[j][1], from}, nn);
        b1 = vertex(m, axis, {p[j][0], p[j][1], to}, nn);
        b0 = vertex(m, axis, {p[i][0], p[i][1], to}, nn);
      }
      m.indices.insert(m.indices.end(), {a0, a1, b1, a0, b1, b0});
    }
  }

  /// A right circular cylinder about an axis through `centre` (in the
  /// section's coordinates): a smooth `sides`-gon prism whose first corner
  /// lies along the section's first axis.
  void cylinder(std::uint32_t mat, Axis axis, Vec2 centre, float radius, float from, float to, int sides,
                std::optional<std::uint32_t> capMat = std::nullopt) {
    prism(mat, axis, regular(centre, radius, sides), from, to, true, capMat);
  }

  /// A cone: a `sides`-gon base about `centre` at `base`, its apex on the
  /// axis at `apex` (either side of the base); smooth sides, a flat base.
  void cone(std::uint32_t mat, Axis axis, Vec2 centre, float radius, float base, float apex, int sides) {
    const std::vector<Vec2> p = rightHanded(axis, regular(centre, radius, sides));
    const Vec2 c = rightHanded(axis, {centre})[0];
    const float s = apex > base ? 1.0f : -1.0f, h = std::abs(apex - base);
    Mesh& m = mesh(mat);
    addCap(m, axis, p, base, -s);
    const auto first = static_cast<std::uint32_t>(m.vertexCount());
    for (const Vec2& q : p) {
      // The side's normal: radial times the height plus the axis times the radius.
      const Vec2 r{q[0] - c[0], q[1] - c[1]};
      const float len = std::hypot(h, radius);
      vertex(m, axis, {q[0], q[1], base}, {r[0] / radius * h / len, r[1] / radius * h / len, s * radius / len});
    }
    const std::uint32_t top = vertex(m, axis, {c[0], c[1], apex}, {0, 0, s});
    const auto n = static_cast<std::uint32_t>(p.size());
    for (std::uint32_t i = 0; i < n; ++i) {
      const std::uint32_t a = first + i, b = first + (i + 1) % n;
      if (s > 0) {
        m.indices.insert(m.indices.end(), {a, b, top});
      } else {
        m.indices.insert(m.indices.end(), {b, a, top});
      }
    }
  }

  /// A hull lofted from a polygon on y = `y0` to one with as many corners on
  /// y = `y1`, both (x, z) and convex, corner i above corner i. Each side
  /// quad is two flat triangles (a quad between unlike polygons need not be
  /// planar).
  void loft(std::uint32_t mat, std::vector<Vec2> bottom, std::vector<Vec2> top, float y0, float y1) {
    bottom = rightHanded(Axis::y, std::move(bottom));
    top = rightHanded(Axis::y, std::move(top));
    Mesh& m = mesh(mat);
    addCap(m, Axis::y, top, y1, +1);
    addCap(m, Axis::y, bottom, y0, -1);
    const std::size_t n = top.size();
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t j = (i + 1) % n;
      const Vec3 a0{bottom[i][0], bottom[i][1], y0}, a1{bottom[j][0], bottom[j][1], y0};
      const Vec3 b0{top[i][0], top[i][1], y1}, b1{top[j][0], top[j][1], y1};
      flatTriangle(m, Axis::y, a0, a1, b1);
      flatTriangle(m, Axis::y, a0, b1, b0);
    }
  }

  /// A closed smooth surface given by its corners (world frame, before the
  /// move) and triangles wound outward; vertex normals are the area-weighted
  /// means of the triangles' normals.
  void surface(std::uint32_t mat, const std::vector<Vec3>& pos, const std::vector<std::uint32_t>& tris) {
    Mesh& m = mesh(mat);
    std::vector<Vec3> normals(pos.size(), Vec3{0, 0, 0});
    for (std::size_t k = 0; k < tris.size(); k += 3) {
      const Vec3 n = cross(pos[tris[k]], pos[tris[k + 1]], pos[tris[k + 2]]);  // length: twice the area
      for (std::size_t c = 0; c < 3; ++c) {
        for (int a = 0; a < 3; ++a) normals[tris[k + c]][a] += n[a];
      }
    }
    const auto first = static_cast<std::uint32_t>(m.vertexCount());
    for (std::size_t v = 0; v < pos.size(); ++v) worldVertex(m, pos[v], unit(normals[v]));
    for (const std::uint32_t t : tris) m.indices.push_back(first + t);
  }

  /// A flat convex polygon (world frame) facing `normal`, fanned from a
  /// centre vertex (so that it may be only star-shaped).
  void flatFan(std::uint32_t mat, const std::vector<Vec3>& ring, Vec3 normal) {
    Mesh& m = mesh(mat);
    Vec3 c{0, 0, 0};
    for (const Vec3& q : ring) {
      for (int a = 0; a < 3; ++a) c[a] += q[a] / float(ring.size());
    }
    const std::uint32_t centre = worldVertex(m, c, normal);
    const auto first = static_cast<std::uint32_t>(m.vertexCount());
    for (const Vec3& q : ring) worldVertex(m, q, normal);
    const auto n = static_cast<std::uint32_t>(ring.size());
    for (std::uint32_t i = 0; i < n; ++i) {
      std::uint32_t a = first + i, b = first + (i + 1) % n;
      const Vec3 t = cross(c, ring[i], ring[(i + 1) % n]);
      if (t[0] * normal[0] + t[1] * normal[1] + t[2] * normal[2] < 0) std::swap(a, b);
      m.indices.insert(m.indices.end(), {centre, a, b});
    }
  }

  Model finish() {
    model_.sourceMeshes = static_cast<std::uint32_t>(model_.meshes.size());
    optimiseModel(model_);
    return std::move(model_);
  }

 private:
  Model model_;
  Vec3 origin_{0, 0, 0};

  Mesh& mesh(std::uint32_t mat) { return model_.meshes.at(mat); }

  static Vec3 cross(Vec3 a, Vec3 b, Vec3 c) {
    const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  }
  static Vec3 unit(Vec3 v) {
    const float len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return {v[0] / len, v[1] / len, v[2] / len};
  }

  static std::vector<Vec2> regular(Vec2 centre, float radius, int sides) {
    std::vector<Vec2> p;
    for (int s = 0; s < sides; ++s) {
      const double a = 2 * std::numbers::pi * s / sides;
      p.push_back({centre[0] + radius * float(std::cos(a)), centre[1] + radius * float(std::sin(a))});
    }
    return p;
  }

  /// The section in (u, v) with u x v along the axis (X: (y, z); Y: (z, x);
  /// Z: (x, y)), turned counter-clockwise: then the cap at the far end faces
  /// along the axis and a side's outward normal is (dv, -du).
  static std::vector<Vec2> rightHanded(Axis axis, std::vector<Vec2> p) {
    if (axis == Axis::y) {
      for (Vec2& q : p) std::swap(q[0], q[1]);
    }
    double area = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const Vec2& a = p[i];
      const Vec2& b = p[(i + 1) % p.size()];
      area += double(a[0]) * b[1] - double(b[0]) * a[1];
    }
    if (area < 0) std::reverse(p.begin(), p.end());
    return p;
  }

  /// (u, v, w) in the axis's right-handed frame to the world's (x, y, z).
  static Vec3 toWorld(Axis axis, Vec3 q) {
    switch (axis) {
      case Axis::x: return {q[2], q[0], q[1]};
      case Axis::y: return {q[1], q[2], q[0]};
      case Axis::z: return q;
    }
    return q;
  }

  /// Unit outward normals at the corners of a counter-clockwise polygon:
  /// the mean of the two sides' normals.
  static std::vector<Vec2> cornerNormals(const std::vector<Vec2>& p) {
    const std::size_t n = p.size();
    std::vector<Vec2> side(n), corner(n);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2& a = p[i];
      const Vec2& b = p[(i + 1) % n];
      const float len = std::hypot(b[0] - a[0], b[1] - a[1]);
      side[i] = {(b[1] - a[1]) / len, -(b[0] - a[0]) / len};
    }
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2& s0 = side[(i + n - 1) % n];
      const Vec2& s1 = side[i];
      const float len = std::hypot(s0[0] + s1[0], s0[1] + s1[1]);
      corner[i] = {(s0[0] + s1[0]) / len, (s0[1] + s1[1]) / len};
    }
    return corner;
  }

  std::uint32_t worldVertex(Mesh& m, Vec3 p, Vec3 n) {
    m.positions.insert(m.positions.end(), {p[0] + origin_[0], p[1] + origin_[1], p[2] + origin_[2]});
    m.normals.insert(m.normals.end(), {n[0], n[1], n[2]});
    return static_cast<std::uint32_t>(m.vertexCount() - 1);
  }

  std::uint32_t vertex(Mesh& m, Axis axis, Vec3 q, Vec3 n) {
    return worldVertex(m, toWorld(axis, q), toWorld(axis, n));
  }

  /// The cap of a counter-clockwise section at w, facing +w (`facing` 1) or
  /// -w (-1), fanned from its first corner.
  void addCap(Mesh& m, Axis axis, const std::vector<Vec2>& p, float w, float facing) {
    const auto first = static_cast<std::uint32_t>(m.vertexCount());
    for (const Vec2& q : p) vertex(m, axis, {q[0], q[1], w}, {0, 0, facing});
    for (std::uint32_t i = 1; i + 1 < p.size(); ++i) {
      if (facing > 0) {
        m.indices.insert(m.indices.end(), {first, first + i, first + i + 1});
      } else {
        m.indices.insert(m.indices.end(), {first, first + i + 1, first + i});
      }
    }
  }

  /// One triangle, given in the axis's frame and wound outward, with its
  /// own vertices and its geometric normal.
  void flatTriangle(Mesh& m, Axis axis, Vec3 a, Vec3 b, Vec3 c) {
    const Vec3 n = unit(cross(a, b, c));
    const std::uint32_t i = vertex(m, axis, a, n), j = vertex(m, axis, b, n), k = vertex(m, axis, c, n);
    m.indices.insert(m.indices.end(), {i, j, k});
  }
};

// ---- colours ---------------------------------------------------------------

constexpr Colour kOlive{0.22f, 0.26f, 0.12f};     // dark olive green armour
constexpr Colour kTrack{0.10f, 0.10f, 0.08f};     // tracks and tyres
constexpr Colour kDrab{0.30f, 0.33f, 0.17f};      // olive drab soft-skins
constexpr Colour kCanvas{0.46f, 0.42f, 0.29f};    // the truck's cargo cover
constexpr Colour kGlass{0.16f, 0.22f, 0.28f};     // windows and canopies
constexpr Colour kHullGrey{0.42f, 0.45f, 0.48f};  // naval haze grey
constexpr Colour kLightGrey{0.72f, 0.74f, 0.76f};
constexpr Colour kDarkGrey{0.22f, 0.23f, 0.25f};
constexpr Colour kJetGrey{0.55f, 0.58f, 0.62f};
constexpr Colour kWhite{0.86f, 0.86f, 0.82f};
constexpr Colour kPlaster{0.80f, 0.74f, 0.60f};
constexpr Colour kRoof{0.58f, 0.22f, 0.14f};      // tiles
constexpr Colour kDoor{0.30f, 0.19f, 0.10f};
constexpr Colour kRuin{0.56f, 0.53f, 0.48f};
constexpr Colour kRubble{0.42f, 0.40f, 0.37f};
constexpr Colour kRock{0.46f, 0.45f, 0.43f};
constexpr Colour kCharred{0.07f, 0.065f, 0.06f};  // burnt-out hulls
constexpr Colour kRust{0.24f, 0.13f, 0.07f};
constexpr Colour kBark{0.40f, 0.26f, 0.13f};      // the tree's trunk colour
constexpr Colour kCutWood{0.72f, 0.57f, 0.36f};

// ---- vehicles ----------------------------------------------------------------

/// Tracks (two hexagonal prisms with sloped ends), a lower hull between
/// them and an upper hull with a sloped glacis: 7.0 x 1.6 x 3.5 m, the roof
/// at kTankTurretRingHeight.
void addTankHull(Shape& s) {
  const std::uint32_t armour = s.material("armour", kOlive), track = s.material("track", kTrack);
  const std::vector<Vec2> trackSide{{0, -3.1f}, {0, 3.1f}, {0.5f, 3.5f}, {1.0f, 3.2f}, {1.0f, -3.2f}, {0.5f, -3.5f}};
  s.prism(track, Axis::x, trackSide, -1.75f, -1.1f);
  s.prism(track, Axis::x, trackSide, 1.1f, 1.75f);
  s.box(armour, {-1.1f, 0.35f, -3.2f}, {1.1f, 1.0f, 3.2f});
  s.prism(armour, Axis::x, {{1.0f, -3.5f}, {1.0f, 3.5f}, {kTankTurretRingHeight, 3.5f}, {kTankTurretRingHeight, -2.5f}},
          -1.75f, 1.75f);
}

/// Turret (a hexagonal prism narrowing to the front) and a cupola; its
/// origin is the turret ring's centre on the roof. The gun is apart
/// (addTankGun), so that it can elevate.
void addTankTurret(Shape& s) {
  const std::uint32_t armour = s.material("armour", kOlive);
  s.prism(armour, Axis::y, {{-0.9f, -1.9f}, {0.9f, -1.9f}, {1.4f, -0.8f}, {1.4f, 1.6f}, {-1.4f, 1.6f}, {-1.4f, -0.8f}},
          0.0f, 0.7f);
  s.cylinder(armour, Axis::y, {0.6f, 0.6f}, 0.35f, 0.7f, 0.9f, 8);
}

/// The mantlet and a 4 m gun barrel, written in the turret's frame (the
/// barrel's axis 0.4 m up, its muzzle at z = -6.0); kTankGunTrunnion, on
/// that axis at the turret's front face, is where it elevates.
void addTankGun(Shape& s) {
  const std::uint32_t armour = s.material("armour", kOlive);
  s.box(armour, {-0.35f, 0.15f, -2.1f}, {0.35f, 0.65f, -1.85f});
  s.cylinder(armour, Axis::z, {0.0f, 0.4f}, 0.12f, -6.0f, -2.0f, 8);
}

Model tankHullModel() {
  Shape s("builtin:tank-hull");
  addTankHull(s);
  return s.finish();
}

Model tankTurretModel() {
  Shape s("builtin:tank-turret");
  addTankTurret(s);
  return s.finish();
}

/// The gun in its own frame: the trunnion at the origin.
Model tankGunModel() {
  Shape s("builtin:tank-gun");
  s.moveTo({-kTankGunTrunnion[0], -kTankGunTrunnion[1], -kTankGunTrunnion[2]});
  addTankGun(s);
  return s.finish();
}

Model tankModel() {
  Shape s("builtin:tank");
  addTankHull(s);
  s.moveTo({0, kTankTurretRingHeight, 0});
  addTankTurret(s);
  addTankGun(s);
  return s.finish();
}

/// A 6x6 cargo truck: chassis, engine hood, cab with a windscreen, a canvas
/// cargo box, six wheels as boxes.
Model truckModel() {
  Shape s("builtin:truck");
  const std::uint32_t body = s.material("body", kDrab), canvas = s.material("canvas", kCanvas);
  const std::uint32_t tyre = s.material("tyre", kTrack), glass = s.material("glass", kGlass);
  s.box(body, {-1.0f, 0.55f, -3.5f}, {1.0f, 1.0f, 3.5f});
  s.box(body, {-1.0f, 1.0f, -3.5f}, {1.0f, 1.9f, -2.5f});
  s.box(body, {-1.2f, 1.0f, -2.5f}, {1.2f, 2.8f, -1.1f});
  s.box(glass, {-1.0f, 2.0f, -2.53f}, {1.0f, 2.6f, -2.49f});
  s.box(canvas, {-1.25f, 1.1f, -0.9f}, {1.25f, 3.0f, 3.5f});
  for (const float z : {-2.8f, 1.5f, 2.8f}) {
    s.box(tyre, {-1.25f, 0.0f, z - 0.5f}, {-0.85f, 1.0f, z + 0.5f});
    s.box(tyre, {0.85f, 0.0f, z - 0.5f}, {1.25f, 1.0f, z + 0.5f});
  }
  return s.finish();
}

/// A small open utility vehicle: body, windscreen, four wheels as boxes.
Model jeepModel() {
  Shape s("builtin:jeep");
  const std::uint32_t body = s.material("body", kDrab), tyre = s.material("tyre", kTrack);
  const std::uint32_t glass = s.material("glass", kGlass);
  s.box(body, {-0.75f, 0.35f, -1.7f}, {0.75f, 1.0f, 1.7f});
  s.box(glass, {-0.72f, 1.0f, -0.45f}, {0.72f, 1.5f, -0.4f});
  for (const float z : {-1.1f, 1.1f}) {
    s.box(tyre, {-0.85f, 0.0f, z - 0.35f}, {-0.55f, 0.7f, z + 0.35f});
    s.box(tyre, {0.55f, 0.0f, z - 0.35f}, {0.85f, 0.7f, z + 0.35f});
  }
  return s.finish();
}

/// A 25 m patrol boat: a hull lofted from a narrow keel outline to a deck
/// with a pointed bow, a cabin, a wheelhouse with windows, a mast, a bow gun.
/// Its keel is at y = 0; the hull is 2.5 m deep.
Model boatModel() {
  Shape s("builtin:boat");
  const std::uint32_t hull = s.material("hull", kHullGrey), upper = s.material("superstructure", kLightGrey);
  const std::uint32_t dark = s.material("fittings", kDarkGrey), glass = s.material("glass", kGlass);
  const std::vector<Vec2> keel{{0, -10.5f}, {1.5f, -7.0f}, {1.9f, -2.0f}, {1.9f, 12.0f},
                               {-1.9f, 12.0f}, {-1.9f, -2.0f}, {-1.5f, -7.0f}};
  const std::vector<Vec2> deck{{0, -12.5f}, {2.6f, -8.0f}, {3.0f, -2.0f}, {3.0f, 12.5f},
                               {-3.0f, 12.5f}, {-3.0f, -2.0f}, {-2.6f, -8.0f}};
  s.loft(hull, keel, deck, 0.0f, 2.5f);
  s.box(upper, {-2.0f, 2.5f, -3.0f}, {2.0f, 4.8f, 4.5f});
  s.box(upper, {-1.6f, 4.8f, -2.6f}, {1.6f, 6.0f, 0.5f});
  s.box(glass, {-1.5f, 5.2f, -2.63f}, {1.5f, 5.8f, -2.58f});
  s.box(dark, {-0.1f, 6.0f, -0.6f}, {0.1f, 9.0f, -0.4f});
  s.box(dark, {-0.5f, 2.5f, -8.0f}, {0.5f, 3.1f, -7.0f});
  s.box(dark, {-0.06f, 2.79f, -9.5f}, {0.06f, 2.91f, -7.4f});
  return s.finish();
}

/// A 12 m jet: an 8-sided fuselage with a nose cone, swept wings,
/// tailplanes, a tail fin and a canopy; the fuselage's belly at y = 0.
Model jetModel() {
  Shape s("builtin:jet");
  const std::uint32_t skin = s.material("skin", kJetGrey), glass = s.material("glass", kGlass);
  s.cylinder(skin, Axis::z, {0, 0.6f}, 0.6f, -4.0f, 6.0f, 8);
  s.cone(skin, Axis::z, {0, 0.6f}, 0.6f, -4.0f, -6.0f, 8);
  for (const float side : {-1.0f, 1.0f}) {
    s.prism(skin, Axis::y, {{0.4f * side, -1.0f}, {4.5f * side, 2.4f}, {4.5f * side, 3.4f}, {0.4f * side, 3.2f}}, 0.5f,
            0.7f);
    s.prism(skin, Axis::y, {{0.3f * side, 4.4f}, {2.0f * side, 5.6f}, {2.0f * side, 6.0f}, {0.3f * side, 6.0f}}, 0.62f,
            0.72f);
  }
  s.prism(skin, Axis::x, {{1.1f, 3.6f}, {3.2f, 5.5f}, {3.2f, 6.0f}, {1.1f, 6.0f}}, -0.06f, 0.06f);
  s.prism(glass, Axis::x, {{1.0f, -3.4f}, {1.5f, -2.6f}, {1.5f, -1.6f}, {1.0f, -1.0f}}, -0.35f, 0.35f);
  return s.finish();
}

/// A 3 m missile: an 8-sided body with a nose cone, four tail fins and four
/// canards (each pair one thin box through the body).
Model missileModel() {
  Shape s("builtin:missile");
  const std::uint32_t body = s.material("body", kWhite), fin = s.material("fins", kDarkGrey);
  s.cylinder(body, Axis::z, {0, 0.3f}, 0.1f, -1.2f, 1.5f, 8);
  s.cone(fin, Axis::z, {0, 0.3f}, 0.1f, -1.2f, -1.5f, 8);
  s.box(fin, {-0.3f, 0.285f, 0.9f}, {0.3f, 0.315f, 1.5f});
  s.box(fin, {-0.015f, 0.0f, 0.9f}, {0.015f, 0.6f, 1.5f});
  s.box(fin, {-0.18f, 0.29f, -0.6f}, {0.18f, 0.31f, -0.4f});
  s.box(fin, {-0.01f, 0.12f, -0.6f}, {0.01f, 0.48f, -0.4f});
  return s.finish();
}

// ---- buildings, rocks, dead states ---------------------------------------

/// A 10 x 8 m house: walls, gable ends, two roof slabs overhanging 0.3 m
/// at the gables and 0.4 m at the eaves, a chimney; door and windows on
/// the north (front) wall.
Model houseModel() {
  Shape s("builtin:house");
  const std::uint32_t wall = s.material("walls", kPlaster), roof = s.material("roof", kRoof);
  const std::uint32_t door = s.material("door", kDoor), glass = s.material("glass", kGlass);
  s.box(wall, {-5.0f, 0.0f, -4.0f}, {5.0f, 3.0f, 4.0f});
  s.prism(wall, Axis::x, {{3.0f, -4.0f}, {3.0f, 4.0f}, {5.15f, 0.0f}}, -5.0f, 5.0f);
  // Slope 0.55: from the eaves (2.78 m, 0.4 m out) to the ridge (5.2 m), 0.15 m thick.
  for (const float side : {-1.0f, 1.0f}) {
    s.prism(roof, Axis::x, {{2.78f, 4.4f * side}, {5.2f, 0.0f}, {5.35f, 0.0f}, {2.93f, 4.4f * side}}, -5.3f, 5.3f);
  }
  s.box(roof, {2.5f, 4.0f, 1.0f}, {3.1f, 6.0f, 1.6f});
  s.box(door, {-0.5f, 0.0f, -4.04f}, {0.5f, 2.1f, -3.98f});
  s.box(glass, {-3.4f, 1.2f, -4.04f}, {-2.2f, 2.2f, -3.98f});
  s.box(glass, {2.2f, 1.2f, -4.04f}, {3.4f, 2.2f, -3.98f});
  return s.finish();
}

/// The house's dead state: broken walls 0.5 to 2.2 m high on its 10 x 8 m
/// footprint, and three heaps of rubble.
Model ruinsModel() {
  Shape s("builtin:ruins");
  const std::uint32_t wall = s.material("walls", kRuin), rubble = s.material("rubble", kRubble);
  s.box(wall, {-5.0f, 0.0f, -4.0f}, {-1.6f, 1.4f, -3.7f});
  s.box(wall, {0.4f, 0.0f, -4.0f}, {5.0f, 0.7f, -3.7f});
  s.box(wall, {4.7f, 0.0f, -3.7f}, {5.0f, 2.2f, 0.8f});
  s.box(wall, {4.7f, 0.0f, 1.6f}, {5.0f, 0.5f, 4.0f});
  s.box(wall, {-5.0f, 0.0f, 3.7f}, {2.5f, 1.0f, 4.0f});
  s.box(wall, {-5.0f, 0.0f, -3.7f}, {-4.7f, 1.8f, 2.0f});
  s.turnedBox(rubble, {1.0f, -2.8f}, 1.6f, 0.8f, 20.0f, 0.0f, 0.45f);
  s.turnedBox(rubble, {3.4f, 2.6f}, 1.2f, 0.7f, -35.0f, 0.0f, 0.35f);
  s.turnedBox(rubble, {-2.6f, 1.5f}, 1.0f, 1.0f, 10.0f, 0.0f, 0.3f);
  return s.finish();
}

/// A boulder: a 10-sided body of revolution with four rings and an apex,
/// each ring corner's radius varied by 0.88 to 1.12 (a fixed hash, so every
/// build makes the same rock), stretched 1.15 in x and 0.9 in z, then
/// centred on its footprint; a flat foot on y = 0. Smooth normals.
Model rockModel() {
  constexpr int kSides = 10;
  constexpr std::array<Vec2, 4> kRings{{{0.0f, 0.8f}, {0.45f, 1.0f}, {0.85f, 0.9f}, {1.15f, 0.55f}}};  // y, radius
  constexpr float kApex = 1.3f, kStretchX = 1.15f, kStretchZ = 0.9f;
  Shape s("builtin:rock");
  const std::uint32_t stone = s.material("stone", kRock);
  std::vector<Vec3> pos;
  for (std::size_t r = 0; r < kRings.size(); ++r) {
    for (int i = 0; i < kSides; ++i) {
      const double f = 0.88 + 0.24 * hash::unit(hash::mix(0x726f636bull + r * kSides + std::uint64_t(i)));
      const double a = 2 * std::numbers::pi * i / kSides;
      const double radius = kRings[r][1] * f;
      pos.push_back({float(radius * std::cos(a) * kStretchX), kRings[r][0], float(radius * std::sin(a) * kStretchZ)});
    }
  }
  pos.push_back({0.0f, kApex, 0.0f});
  // The varied radii move the footprint's box off the axis: centre it.
  std::array<float, 4> box{INFINITY, INFINITY, -INFINITY, -INFINITY};  // min x, min z, max x, max z
  for (const Vec3& q : pos) {
    box = {std::min(box[0], q[0]), std::min(box[1], q[2]), std::max(box[2], q[0]), std::max(box[3], q[2])};
  }
  for (Vec3& q : pos) q[0] -= (box[0] + box[2]) / 2, q[2] -= (box[1] + box[3]) / 2;
  const auto apex = static_cast<std::uint32_t>(pos.size() - 1);
  std::vector<std::uint32_t> tris;
  auto at = [](std::size_t r, int i) { return static_cast<std::uint32_t>(r * kSides + std::size_t(i % kSides)); };
  for (std::size_t r = 0; r + 1 < kRings.size(); ++r) {
    for (int i = 0; i < kSides; ++i) {
      // Angle grows from +x towards +z: (i, i+1, above) is counter-clockwise from outside.
      tris.insert(tris.end(), {at(r, i), at(r + 1, i + 1), at(r, i + 1), at(r, i), at(r + 1, i), at(r + 1, i + 1)});
    }
  }
  for (int i = 0; i < kSides; ++i) tris.insert(tris.end(), {at(3, i), apex, at(3, i + 1)});
  s.surface(stone, pos, tris);
  const std::vector<Vec3> foot(pos.begin(), pos.begin() + kSides);
  s.flatFan(stone, foot, {0, -1, 0});
  return s.finish();
}

/// A burnt-out hull for any vehicle: a low 6 x 3 m body, a sloped upper
/// deck and a slab of wreckage askew on it, charred black and rust.
Model wreckModel() {
  Shape s("builtin:wreck");
  const std::uint32_t charred = s.material("charred", kCharred), rust = s.material("rust", kRust);
  s.box(charred, {-1.5f, 0.0f, -3.0f}, {1.5f, 0.55f, 3.0f});
  s.prism(charred, Axis::x, {{0.55f, -2.6f}, {0.55f, 2.8f}, {0.95f, 2.3f}, {0.95f, -1.8f}}, -1.3f, 1.3f);
  s.turnedBox(rust, {0.3f, -0.3f}, 1.8f, 1.4f, 25.0f, 0.95f, 1.25f);
  return s.finish();
}

/// The tree's dead state: its trunk (8 sides, 0.25 m radius, bark brown)
/// cut 0.8 m above the ground, the cut face pale wood.
Model stumpModel() {
  Shape s("builtin:stump");
  const std::uint32_t bark = s.material("bark", kBark), cut = s.material("cut", kCutWood);
  s.cylinder(bark, Axis::y, {0, 0}, 0.25f, 0.0f, 0.8f, 8, cut);
  return s.finish();
}

constexpr std::array<BuiltinModel, 15> kBuiltins{{
    {"builtin:tree", true, treeModel},
    {"builtin:stump", true, stumpModel},
    {"builtin:tank", false, tankModel},
    {"builtin:tank-hull", false, tankHullModel},
    {"builtin:tank-turret", false, tankTurretModel},
    {"builtin:tank-gun", false, tankGunModel},
    {"builtin:truck", false, truckModel},
    {"builtin:jeep", false, jeepModel},
    {"builtin:boat", false, boatModel},
    {"builtin:jet", false, jetModel},
    {"builtin:missile", false, missileModel},
    {"builtin:wreck", false, wreckModel},
    {"builtin:house", true, houseModel},
    {"builtin:ruins", true, ruinsModel},
    {"builtin:rock", true, rockModel},
}};

}  // namespace

std::span<const BuiltinModel> builtinModels() { return kBuiltins; }

bool isBuiltinName(std::string_view file) { return file.starts_with(kBuiltinPrefix); }

const BuiltinModel* findBuiltin(std::string_view file) {
  for (const BuiltinModel& b : builtinModels()) {
    if (b.name == file) return &b;
  }
  return nullptr;
}

std::optional<Model> builtinModel(std::string_view file) {
  const BuiltinModel* b = findBuiltin(file);
  if (!b) return std::nullopt;
  return b->make();
}

std::string builtinNames() {
  std::string s;
  for (const BuiltinModel& b : builtinModels()) {
    if (!s.empty()) s += ", ";
    s += b.name;
  }
  return s;
}

}  // namespace sandtable::icons
