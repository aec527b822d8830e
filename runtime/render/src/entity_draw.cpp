#include "entity_draw.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <tuple>

#include "icon_textures.h"
#include "module_draw.h"
#include "sandtable/scene/camera_math.h"
#include "terrain_shading.h"

namespace sandtable::render::detail {
namespace {

// Appended to shadingVertexGlsl(). The gun (aGun.w != 0) pitches about X
// at its trunnion, in the turret's frame; the turret (aPivot.w != 0) turns
// about Y at its ring; then the quaternion takes the body to the world.
// Zero angles and pivots leave a vertex exactly as it was (cos 0 = 1,
// sin 0 = 0): the body and the turret draw as they did before the gun.
const char* kEntityVertexMain = R"(
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColour;
layout(location = 3) in vec4 aPlace;     // origin x, y, z and scale
layout(location = 4) in vec4 aRotation;  // body to world quaternion (x, y, z, w)
layout(location = 5) in vec2 aUv;
layout(location = 6) in float aLayer;
layout(location = 7) in vec4 aPivot;     // turret ring x, y, z (body frame) and angle (radians)
layout(location = 8) in vec4 aGun;       // gun trunnion x, y, z (turret frame) and elevation (radians)
uniform mat4 uViewProjection;
uniform vec3 uEye;
out vec3 vColour;
out float vLight;
out float vFog;
out vec2 vUv;
flat out float vLayer;
vec3 rotateQ(vec4 q, vec3 v) {
  vec3 t = 2.0 * cross(q.xyz, v);
  return v + q.w * t + cross(q.xyz, t);
}
// Clockwise seen from above, as a heading turns north (-Z) to east (+X).
vec3 turnY(vec3 v, float a) {
  float c = cos(a), s = sin(a);
  return vec3(v.x * c - v.z * s, v.y, v.x * s + v.z * c);
}
// Up for a positive angle, as an elevation raises the muzzle (forward -Z to +Y).
vec3 pitchX(vec3 v, float a) {
  float c = cos(a), s = sin(a);
  return vec3(v.x, v.y * c - v.z * s, v.y * s + v.z * c);
}
void main() {
  vec3 turret = pitchX(aPosition, aGun.w) + aGun.xyz;
  vec3 body = turnY(turret, aPivot.w) + aPivot.xyz;
  vec3 w = rotateQ(aRotation, body * aPlace.w) + aPlace.xyz;
  vec3 n = rotateQ(aRotation, turnY(pitchX(aNormal, aGun.w), aPivot.w));
  gl_Position = uViewProjection * vec4(w, 1.0);
  vColour = aColour.rgb;
  vLight = sunLight(n);
  vFog = fogWeight(distance(w, uEye));
  vUv = aUv;
  vLayer = aLayer;
}
)";

// Appended to iconFragmentGlsl(): the object pass's colours without its fade.
const char* kEntityFragmentMain = R"(
in vec3 vColour;
in float vLight;
in float vFog;
in vec2 vUv;
flat in float vLayer;
out vec4 fragColor;
void main() {
  vec3 colour;
  if (!iconColour(vColour, vUv, vLayer, colour)) discard;
  fragColor = vec4(mix(uFogColor, colour * vLight, vFog), 1.0);
}
)";

// Appended to shadingVertexGlsl().
const char* kEffectVertexMain = R"(
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec2 aUv;
layout(location = 2) in vec4 aColour;
uniform mat4 uViewProjection;
uniform vec3 uEye;
out vec2 vUv;
out vec4 vColour;
out float vFog;
void main() {
  gl_Position = uViewProjection * vec4(aPosition, 1.0);
  vUv = aUv;
  vColour = aColour;
  vFog = fogWeight(distance(aPosition, uEye));
}
)";

// Appended to shadingHeaderGlsl(). Premultiplied output, blended with
// (ONE, ONE_MINUS_SRC_ALPHA). Trails thin out towards their edges; a flash
// is a disc with a white-hot core over its colour, soft at the rim.
const char* kEffectFragmentMain = R"(
uniform int uKind;  // 0 trail, 1 flash, 2 contact shadow
in vec2 vUv;
in vec4 vColour;
in float vFog;
out vec4 fragColor;
void main() {
  vec3 c = vColour.rgb;
  float a;
  if (uKind == 0) {
    a = vColour.a * (1.0 - vUv.y * vUv.y);
  } else if (uKind == 2) {
    // A rounded rectangle, darkest under the body, soft at the rim.
    vec2 q = max(abs(vUv) - vec2(0.55), vec2(0.0)) / 0.45;
    a = vColour.a * (1.0 - smoothstep(0.0, 1.0, length(q)));
  } else {
    float d = length(vUv);
    if (d > 1.0) discard;
    c = mix(c, vec3(1.0, 0.97, 0.85), 1.0 - smoothstep(0.0, 0.6, d));
    a = vColour.a * (1.0 - smoothstep(0.55, 1.0, d));
  }
  c = mix(uFogColor, c, vFog);
  fragColor = vec4(c * a, a);
}
)";

bool named(const std::string& name, const char* want) {
  std::string lower = name;
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  return lower == want;
}

/// Whether part p is part `root` or hangs from it.
bool under(const iconpack::Icon& icon, std::size_t p, std::size_t root) {
  for (auto k = std::int32_t(p); k != iconpack::kBody && std::size_t(k) < icon.parts.size();
       k = icon.parts[std::size_t(k)].parent) {
    if (std::size_t(k) == root) return true;
    if (icon.parts[std::size_t(k)].parent >= k) break;  // decode forbids it; never loop
  }
  return false;
}

/// The origin of part p (which hangs from `root`) in root's frame: the
/// offsets summed up to it, so that a child's own offset comes out exact.
std::array<float, 3> originIn(const iconpack::Icon& icon, std::size_t p, std::size_t root) {
  std::array<float, 3> o{0, 0, 0};
  for (auto k = std::int32_t(p); std::size_t(k) != root; k = icon.parts[std::size_t(k)].parent) {
    for (std::size_t a = 0; a < 3; ++a) o[a] += icon.parts[std::size_t(k)].offset[a];
  }
  return o;
}

/// The first part of `state` named `want` (any case), or none.
std::optional<std::size_t> findPart(const iconpack::Icon& icon, iconpack::State state, const char* want) {
  for (std::size_t p = 0; p < icon.parts.size(); ++p) {
    if (icon.parts[p].state == state && named(icon.parts[p].name, want)) return p;
  }
  return std::nullopt;
}

bool hasState(const iconpack::Icon& icon, iconpack::State s) {
  return std::any_of(icon.parts.begin(), icon.parts.end(), [s](const iconpack::Part& p) { return p.state == s; });
}

double length(const std::array<float, 3>& v) { return std::hypot(double(v[0]), double(v[1]), double(v[2])); }

/// One state of one icon: body, turret and gun index ranges per level over
/// one vertex run.
EntityLevels flattenState(const iconpack::Icon& icon, iconpack::State state, EntityMeshes& out, float& reach,
                         std::array<float, 6>& body3) {
  EntityShape shape;
  const auto base = std::int32_t(out.vertices.size());
  const std::optional<std::size_t> turretPart = findPart(icon, state, "turret");
  const std::optional<std::size_t> gunPart = findPart(icon, state, "gun");
  if (turretPart) shape.pivot = iconpack::partOrigin(icon, *turretPart);
  if (gunPart) {
    shape.gunTurns = turretPart && under(icon, *gunPart, *turretPart);
    shape.gunPivot = shape.gunTurns ? originIn(icon, *gunPart, *turretPart) : iconpack::partOrigin(icon, *gunPart);
  }
  enum Group { kBodyGroup, kTurretGroup, kGunGroup };
  const std::size_t levels = std::max<std::size_t>(1, icon.ranges.size());
  std::vector<std::array<std::vector<std::uint32_t>, 3>> groups(levels);  // [level][group]
  for (std::size_t p = 0; p < icon.parts.size(); ++p) {
    const iconpack::Part& part = icon.parts[p];
    if (part.state != state) continue;
    // The gun's own frame first: it may hang from the turret.
    const Group group = gunPart && under(icon, p, *gunPart)           ? kGunGroup
                        : turretPart && under(icon, p, *turretPart) ? kTurretGroup
                                                                     : kBodyGroup;
    // The part's origin in its group's frame, and how far that frame's
    // origin can be from the body's, turned anywhere.
    std::array<float, 3> offset = iconpack::partOrigin(icon, p);
    double pivotLength = 0;
    if (group == kGunGroup) {
      offset = originIn(icon, p, *gunPart);
      pivotLength = length(shape.gunPivot) + (shape.gunTurns ? length(shape.pivot) : 0.0);
    } else if (group == kTurretGroup) {
      for (std::size_t k = 0; k < 3; ++k) offset[k] -= shape.pivot[k];
      pivotLength = length(shape.pivot);
    }
    for (const iconpack::Mesh& m : part.meshes) {
      const auto first = std::uint32_t(out.vertices.size() - std::size_t(base));
      for (std::size_t v = 0; v < m.vertexCount(); ++v) {
        const IconVertex iv = iconVertex(icon, m, v, offset, shape.textured);
        out.vertices.push_back(iv);
        const double r = std::hypot(double(iv.x), double(iv.y), double(iv.z));
        reach = std::max(reach, float(r + pivotLength));
        if (group != kBodyGroup) continue;
        const std::array<float, 3> at{iv.x, iv.y, iv.z};
        for (std::size_t k = 0; k < 3; ++k) {
          body3[k] = std::min(body3[k], at[k]);
          body3[k + 3] = std::max(body3[k + 3], at[k]);
        }
      }
      for (std::size_t l = 0; l < levels && l < m.levels.size(); ++l) {
        for (const std::uint32_t i : m.levels[l]) groups[l][group].push_back(first + i);
      }
    }
  }
  const auto append = [&](const std::vector<std::uint32_t>& indices) {
    const IconLevelRange range{std::uint32_t(out.indices.size()), std::uint32_t(indices.size()), base};
    out.indices.insert(out.indices.end(), indices.begin(), indices.end());
    return range;
  };
  EntityLevels perLevel(levels, shape);
  for (std::size_t l = 0; l < levels; ++l) {
    perLevel[l].body = append(groups[l][kBodyGroup]);
    perLevel[l].turret = append(groups[l][kTurretGroup]);
    perLevel[l].gun = append(groups[l][kGunGroup]);
  }
  return perLevel;
}

std::array<float, 4> toArray(const Eigen::Quaterniond& q) {
  const Eigen::Quaterniond n = q.normalized();
  return {float(n.x()), float(n.y()), float(n.z()), float(n.w())};
}

std::uint32_t packColour(std::uint8_t r, std::uint8_t g, std::uint8_t b, double alpha) {
  const auto a = std::uint32_t(std::lround(std::clamp(alpha, 0.0, 1.0) * 255.0));
  return std::uint32_t(r) | (std::uint32_t(g) << 8) | (std::uint32_t(b) << 16) | (a << 24);
}

/// The pixels a trail's ribbon and a flash are at least wide.
constexpr double kTrailMinPixels = 1.5;
constexpr double kFlashMinPixels = 10;

}  // namespace

EntityMeshes flattenEntityIcons(const iconpack::Pack& pack) {
  EntityMeshes out;
  for (const iconpack::Icon& icon : pack.icons) {
    float reach = 0;
    std::array<float, 6> body{INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY}, deadBody = body;
    std::array<EntityLevels, 2> shapes;
    shapes[0] = flattenState(icon, iconpack::State::alive, out, reach, body);
    // No dead parts: the dead draw as the living (a jeep has no wreck).
    shapes[1] = hasState(icon, iconpack::State::dead)
                    ? flattenState(icon, iconpack::State::dead, out, reach, deadBody)
                    : shapes[0];
    out.shapes.push_back(shapes);
    out.reach.push_back(reach);
    out.footprint.push_back(body[0] <= body[3] ? body : std::array<float, 6>{0, 0, 0, 0, 0, 0});
  }
  return out;
}

std::array<float, 4> headingQuaternion(double headingDeg) {
  // Clockwise from above is a negative turn about +Y (right-handed).
  return toArray(Eigen::Quaterniond(Eigen::AngleAxisd(-headingDeg * kDegToRad, Eigen::Vector3d::UnitY())));
}

std::array<float, 4> lyingQuaternion(double headingDeg) {
  const Eigen::Quaterniond heading(Eigen::AngleAxisd(-headingDeg * kDegToRad, Eigen::Vector3d::UnitY()));
  // -90 degrees about the right axis takes up (+Y) to forward (-Z).
  const Eigen::Quaterniond down(Eigen::AngleAxisd(-0.5 * kPi, Eigen::Vector3d::UnitX()));
  return toArray(heading * down);
}

EffectView effectViewOf(const scene::DisplayBuffer& buf, std::uint32_t imageHeight) {
  const scene::Camera& cam = buf.camera;
  EffectView v;
  v.originX = buf.originX;
  v.originZ = buf.originZ;
  v.eye = {cam.x - buf.originX, cam.y, cam.z - buf.originZ};
  const double h = cam.headingDeg * kDegToRad, p = cam.pitchDeg * kDegToRad;
  const Eigen::Vector3d forward(std::cos(p) * std::sin(h), std::sin(p), -std::cos(p) * std::cos(h));
  v.right = Eigen::Vector3d(std::cos(h), 0.0, std::sin(h));
  v.up = v.right.cross(forward).normalized();
  v.focal = 0.5 * double(imageHeight) / std::tan(0.5 * cam.vfovDeg() * kDegToRad);
  return v;
}

namespace {

/// Two triangles over the corners (-1,-1), (1,-1), (1,1), (-1,1) of a quad.
template <typename Corner>
void appendQuad(const Corner& corner, std::vector<EffectVertex>& out) {
  for (const auto& [u, v] : {std::pair{-1.f, -1.f}, {1.f, -1.f}, {1.f, 1.f}, {-1.f, -1.f}, {1.f, 1.f}, {-1.f, 1.f}}) {
    out.push_back(corner(u, v));
  }
}

}  // namespace

void appendTrail(const scene::Trail& trail, const EffectView& view, double minPixels, std::vector<EffectVertex>& out) {
  const std::size_t n = trail.points.size();
  if (n < 2 || !(trail.lifeS > 0)) return;
  struct Edge {
    Eigen::Vector3d left, right;
    std::uint32_t rgba;
  };
  std::vector<Edge> edges(n);
  const auto at = [&](std::size_t i) {
    const scene::TrailPoint& q = trail.points[i];
    return Eigen::Vector3d(q.x - view.originX, q.y, q.z - view.originZ);
  };
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = at(i);
    const Eigen::Vector3d along = at(std::min(i + 1, n - 1)) - at(i > 0 ? i - 1 : 0);
    const Eigen::Vector3d toEye = view.eye - p;
    Eigen::Vector3d side = along.cross(toEye);
    side = side.norm() > 1e-9 ? side.normalized() : view.right;
    const double half = std::max(0.3, 0.5 * minPixels * toEye.norm() / view.focal);
    const double alpha = 0.85 * std::clamp(1.0 - double(trail.points[i].ageS) / double(trail.lifeS), 0.0, 1.0);
    edges[i] = {p - side * half, p + side * half, packColour(trail.rgb[0], trail.rgb[1], trail.rgb[2], alpha)};
  }
  const auto vertex = [](const Eigen::Vector3d& p, float v, std::uint32_t rgba) {
    return EffectVertex{float(p.x()), float(p.y()), float(p.z()), 0.0f, v, rgba};
  };
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Edge& a = edges[i];
    const Edge& b = edges[i + 1];
    out.push_back(vertex(a.left, -1, a.rgba));
    out.push_back(vertex(a.right, 1, a.rgba));
    out.push_back(vertex(b.left, -1, b.rgba));
    out.push_back(vertex(a.right, 1, a.rgba));
    out.push_back(vertex(b.right, 1, b.rgba));
    out.push_back(vertex(b.left, -1, b.rgba));
  }
}

void appendShadow(const Eigen::Vector3d& origin, const std::array<float, 4>& orientation, float scale,
                  const std::array<float, 6>& bounds, std::vector<EffectVertex>& out) {
  const Eigen::Quaterniond q(orientation[3], orientation[0], orientation[1], orientation[2]);
  constexpr double kMargin = 0.5, kLift = 0.06;
  // Pushed half the way a real shadow would fall from the fixed sun, so it
  // shows beside the body rather than only under it.
  const auto sun = sunDirection();
  const double lean = 0.5 * std::max(0.0, double(bounds[4])) * double(scale) / std::max(double(sun[1]), 0.1);
  const Eigen::Vector3d shift(-double(sun[0]) * lean, 0.0, -double(sun[2]) * lean);
  const double x0 = bounds[0] - kMargin, x1 = bounds[3] + kMargin;
  const double z0 = bounds[2] - kMargin, z1 = bounds[5] + kMargin;
  if (!(x1 > x0 && z1 > z0)) return;
  const std::uint32_t rgba = packColour(0, 0, 0, 0.5);
  const auto corner = [&](float u, float v) {
    const Eigen::Vector3d body(u < 0 ? x0 : x1, kLift / std::max(double(scale), 1e-6), v < 0 ? z0 : z1);
    const Eigen::Vector3d p = origin + q.normalized() * (body * double(scale)) + shift;
    return EffectVertex{float(p.x()), float(p.y()), float(p.z()), u, v, rgba};
  };
  appendQuad(corner, out);
}

void appendFlash(const scene::Flash& flash, const EffectView& view, double minPixels, std::vector<EffectVertex>& out) {
  if (!(flash.durationS > 0) || flash.ageS < 0 || flash.ageS >= flash.durationS) return;
  const double f = double(flash.ageS) / double(flash.durationS);
  double r = double(flash.radiusM) * (0.35 + 0.65 * std::sqrt(f));
  // Lifted by a quarter of its radius: a ground burst shows as a dome.
  const Eigen::Vector3d c(flash.x - view.originX, flash.y + 0.25 * r, flash.z - view.originZ);
  r = std::max(r, 0.5 * minPixels * (c - view.eye).norm() / view.focal);
  const std::uint32_t rgba = packColour(255, 120, 30, 1.0 - f * f);
  const auto corner = [&](float u, float v) {
    const Eigen::Vector3d p = c + view.right * (double(u) * r) + view.up * (double(v) * r);
    return EffectVertex{float(p.x()), float(p.y()), float(p.z()), u, v, rgba};
  };
  appendQuad(corner, out);
}

EntityRenderer::~EntityRenderer() {
  program_.reset();
  texturedProgram_.reset();
  effectProgram_.reset();
  glDeleteVertexArrays(1, &vao_);
  glDeleteVertexArrays(1, &effectVao_);
  glDeleteBuffers(1, &vertexBuffer_);
  glDeleteBuffers(1, &indexBuffer_);
  glDeleteBuffers(1, &instanceBuffer_);
  glDeleteBuffers(1, &effectBuffer_);
  if (ownTextures_) glDeleteTextures(1, &textures_);
}

Status EntityRenderer::create(const RenderSettings& s, GLuint textures) {
  settings_ = s;
  EntityMeshes meshes = flattenEntityIcons(*s.icons);
  shapes_ = std::move(meshes.shapes);
  reach_ = std::move(meshes.reach);
  footprint_ = std::move(meshes.footprint);
  farRange_.clear();
  for (const iconpack::Icon& icon : s.icons->icons) {
    farRange_.push_back(icon.ranges.empty() ? INFINITY : double(icon.ranges.back()));
  }
  bool anyTextured = false;
  for (const auto& st : shapes_) anyTextured = anyTextured || st[0][0].textured || st[1][0].textured;
  textures_ = textures;
  if (textures_ == 0 && anyTextured) {
    std::vector<std::string> warnings;
    textures_ = uploadIconTextures(*s.icons, warnings);
    ownTextures_ = textures_ != 0;
    for (const std::string& w : warnings) std::fprintf(stderr, "sandtable: warning: %s\n", w.c_str());
  }
  for (const bool textured : {false, true}) {
    if (textured && textures_ == 0) continue;
    auto program = GlProgram::build(textured ? "textured entity shader" : "entity shader",
                                    shadingVertexGlsl() + kEntityVertexMain,
                                    iconFragmentGlsl(textured, kEntityFragmentMain));
    if (!program) return program.problems();
    GlProgram& p = textured ? texturedProgram_ : program_;
    p = std::move(program.value());
    p.use();
    setShadingUniforms(p, s);
    if (textured) p.set("uIconTextures", 2);
  }
  auto effects = GlProgram::build("effects shader", shadingVertexGlsl() + kEffectVertexMain,
                                  shadingHeaderGlsl() + kEffectFragmentMain);
  if (!effects) return effects.problems();
  effectProgram_ = std::move(effects.value());
  effectProgram_.use();
  setShadingUniforms(effectProgram_, s);

  glCreateBuffers(1, &vertexBuffer_);
  glNamedBufferStorage(vertexBuffer_,
                       GLsizeiptr(std::max<std::size_t>(1, meshes.vertices.size()) * sizeof(IconVertex)),
                       meshes.vertices.empty() ? nullptr : meshes.vertices.data(), 0);
  glCreateBuffers(1, &indexBuffer_);
  glNamedBufferStorage(indexBuffer_,
                       GLsizeiptr(std::max<std::size_t>(1, meshes.indices.size()) * sizeof(std::uint32_t)),
                       meshes.indices.empty() ? nullptr : meshes.indices.data(), 0);
  glCreateBuffers(1, &instanceBuffer_);
  glCreateVertexArrays(1, &vao_);
  glVertexArrayVertexBuffer(vao_, 0, vertexBuffer_, 0, sizeof(IconVertex));
  glVertexArrayElementBuffer(vao_, indexBuffer_);
  bindIconVertex(vao_);
  const auto instanceAttrib = [&](GLuint loc, GLuint offset) {
    glEnableVertexArrayAttrib(vao_, loc);
    glVertexArrayAttribFormat(vao_, loc, 4, GL_FLOAT, GL_FALSE, offset);
    glVertexArrayAttribBinding(vao_, loc, 1);
  };
  instanceAttrib(3, offsetof(EntityInstanceGpu, x));
  instanceAttrib(4, offsetof(EntityInstanceGpu, q));
  instanceAttrib(7, offsetof(EntityInstanceGpu, px));
  instanceAttrib(8, offsetof(EntityInstanceGpu, gx));
  glVertexArrayBindingDivisor(vao_, 1, 1);

  glCreateBuffers(1, &effectBuffer_);
  glCreateVertexArrays(1, &effectVao_);
  const auto effectAttrib = [&](GLuint loc, GLint n, GLenum type, GLboolean norm, GLuint offset) {
    glEnableVertexArrayAttrib(effectVao_, loc);
    glVertexArrayAttribFormat(effectVao_, loc, n, type, norm, offset);
    glVertexArrayAttribBinding(effectVao_, loc, 0);
  };
  effectAttrib(0, 3, GL_FLOAT, GL_FALSE, offsetof(EffectVertex, x));
  effectAttrib(1, 2, GL_FLOAT, GL_FALSE, offsetof(EffectVertex, u));
  effectAttrib(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, offsetof(EffectVertex, rgba));
  return {};
}

double EntityRenderer::drawnY(const scene::DisplayBuffer& buf, const ModuleRenderer* modules, const scene::DynamicInstance& d) {
  if (!d.onSurface || !modules || !buf.moduleMode || !(buf.moduleSize > 0) || !settings_.grid) return d.y;
  const double kxf = std::floor(d.x / buf.moduleSize), kzf = std::floor(d.z / buf.moduleSize);
  if (kxf < 0 || kzf < 0) return d.y;
  const auto kx = std::uint32_t(kxf), kz = std::uint32_t(kzf);
  for (std::uint32_t m = 0; m < buf.modules.size(); ++m) {
    const scene::ModuleDraw& md = buf.modules[m];
    if (md.kx != kx || md.kz != kz || !md.ref) continue;
    std::uint32_t level = 0;
    float morph = 0;
    if (!modules->drawnAt(m, d.x - kxf * buf.moduleSize, d.z - kzf * buf.moduleSize, level, morph)) return d.y;
    if (level == 0 && morph == 0) return d.y;
    const auto levels = std::uint32_t(md.ref.module().levels.size());
    if (!clamp_ || levels > clampLevels_) {
      const auto squares = std::uint32_t(std::lround(buf.moduleSize / settings_.grid->spacing()));
      clamp_.emplace(settings_.grid, squares, levels);
      clampLevels_ = levels;
    }
    const auto drawn = clamp_->surfaceXZ(d.x, d.z, world::DrawnLevel{level, morph});
    const auto finest = clamp_->surfaceXZ(d.x, d.z);
    return drawn && finest ? d.y + (*drawn - *finest) : d.y;
  }
  return d.y;
}

int EntityRenderer::levelOf(const scene::DynamicInstance& d, double distance, double radius,
                            double viewDistance) const {
  const iconpack::Icon& icon = settings_.icons->icons[d.icon];
  // The sphere's near side: an entity is drawn out to where all of it has
  // left the far range, and takes a coarser level only once all of it is
  // past the switch range.
  const double nearSide = std::max(0.0, distance - radius);
  const bool inRange = nearSide < std::min(farRange_[d.icon], viewDistance);
  if (!settings_.objectLod || icon.ranges.empty()) return inRange ? 0 : -1;
  float fade = 1;  // entities pop: a tank half dithered away would read as a ghost
  return iconLevelAt(icon, nearSide, viewDistance, 0.0, fade);
}

void EntityRenderer::add(const scene::DisplayBuffer& buf, const scene::DynamicInstance& d, double y,
                         const std::array<Eigen::Vector4d, 5>& planes, RenderStats& stats) {
  if (d.icon >= shapes_.size()) return;
  const scene::Camera& cam = buf.camera;
  const Eigen::Vector3d origin(d.x - buf.originX, y, d.z - buf.originZ);
  const Eigen::Vector3d eye(cam.x - buf.originX, cam.y, cam.z - buf.originZ);
  const double radius = double(reach_[d.icon]) * double(d.scale);
  const double distance = (origin - eye).norm();
  const int level = levelOf(d, distance, radius, cam.viewDistance);
  if (level < 0) return;
  const Eigen::Vector4d c(origin.x(), origin.y(), origin.z(), 1.0);
  for (const auto& p : planes) {
    if (p.dot(c) < -radius) return;
  }
  // Shadows only where they are worth seeing: within a kilometre.
  if (d.shadow && distance < 1000) {
    appendShadow(origin, d.orientation, d.scale, footprint_[d.icon], shadowVertices_);
  }
  const EntityLevels& levels = shapes_[d.icon][d.dead ? 1 : 0];
  const EntityShape& shape = levels[std::min(std::size_t(level), levels.size() - 1)];
  EntityInstanceGpu g{};
  g.x = float(origin.x());
  g.y = float(origin.y());
  g.z = float(origin.z());
  g.scale = d.scale;
  std::copy(d.orientation.begin(), d.orientation.end(), g.q);
  if (shape.body.count > 0) {
    stream_.push_back(g);
    draws_.push_back({shape.body, shape.textured});
  }
  const auto turretTurn = [&] {
    g.px = shape.pivot[0];
    g.py = shape.pivot[1];
    g.pz = shape.pivot[2];
    g.turretRad = float(double(d.turretAzimuthDeg) * kDegToRad);
  };
  if (shape.turret.count > 0) {
    turretTurn();
    stream_.push_back(g);
    draws_.push_back({shape.turret, shape.textured});
  }
  if (shape.gun.count > 0) {
    // A gun on the hull (no turret above it) keeps the hull's frame.
    if (shape.gunTurns) {
      turretTurn();
    } else {
      g.px = g.py = g.pz = g.turretRad = 0;
    }
    g.gx = shape.gunPivot[0];
    g.gy = shape.gunPivot[1];
    g.gz = shape.gunPivot[2];
    g.gunRad = float(double(d.gunElevationDeg) * kDegToRad);
    stream_.push_back(g);
    draws_.push_back({shape.gun, shape.textured});
  }
  ++stats.entitiesDrawn;
}

void EntityRenderer::collect(const scene::DisplayBuffer& buf, const ModuleRenderer* modules,
                             const std::vector<scene::DynamicInstance>& diverted, RenderStats& stats) {
  draws_.clear();
  stream_.clear();
  shadowVertices_.clear();
  auto planes = scene::frustumPlanes(scene::viewProjection(buf.camera, buf.originX, buf.originZ));
  for (auto& p : planes) p /= std::max(p.head<3>().norm(), 1e-12);
  for (const scene::DynamicInstance& d : buf.dynamic.instances) add(buf, d, drawnY(buf, modules, d), planes, stats);
  // Changed static objects already stand on the drawn level (the object pass placed them).
  const std::uint32_t before = stats.entitiesDrawn;
  for (const scene::DynamicInstance& d : diverted) add(buf, d, d.y, planes, stats);
  stats.objectsChangedDrawn += stats.entitiesDrawn - before;
  stats.entitiesDrawn = before;
}

void EntityRenderer::submit(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, RenderStats& stats) {
  if (stream_.empty()) return;
  // Instances of one group (one icon state's body, turret or gun) side by
  // side, so that each group is one instanced draw however many entities
  // show it; the untextured program's first. Stable: equal groups keep
  // the order the entities came in.
  order_.resize(stream_.size());
  for (std::size_t k = 0; k < order_.size(); ++k) order_[k] = std::uint32_t(k);
  const auto key = [&](std::uint32_t k) {
    const Draw& d = draws_[k];
    return std::tuple(d.textured, d.range.baseVertex, d.range.firstIndex);
  };
  std::stable_sort(order_.begin(), order_.end(), [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
  sorted_.clear();
  for (const std::uint32_t k : order_) sorted_.push_back(stream_[k]);
  glNamedBufferData(instanceBuffer_, GLsizeiptr(sorted_.size() * sizeof(EntityInstanceGpu)), sorted_.data(),
                    GL_STREAM_DRAW);
  glVertexArrayVertexBuffer(vao_, 1, instanceBuffer_, 0, sizeof(EntityInstanceGpu));
  for (const GlProgram* p : {&program_, &texturedProgram_}) {
    if (!*p) continue;
    p->use();
    p->setMatrix4("uViewProjection", viewProjection.data());
    setFrameShading(*p, buf);
  }
  if (textures_ != 0) glBindTextureUnit(2, textures_);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);
  glDepthMask(GL_TRUE);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);  // imported models need not be closed
  glBindVertexArray(vao_);
  const GlProgram* current = nullptr;
  for (std::size_t first = 0; first < order_.size();) {
    std::size_t last = first + 1;
    while (last < order_.size() && key(order_[last]) == key(order_[first])) ++last;
    const Draw& d = draws_[order_[first]];
    const GlProgram* wanted = d.textured && textures_ != 0 ? &texturedProgram_ : &program_;
    if (wanted != current) {
      wanted->use();
      current = wanted;
    }
    const auto instances = GLsizei(last - first);
    glDrawElementsInstancedBaseVertexBaseInstance(
        GL_TRIANGLES, GLsizei(d.range.count), GL_UNSIGNED_INT,
        reinterpret_cast<const void*>(std::uintptr_t(d.range.firstIndex) * sizeof(std::uint32_t)), instances,
        d.range.baseVertex, GLuint(first));
    stats.entityTriangles += std::uint64_t(d.range.count / 3) * std::uint64_t(instances);
    first = last;
  }
  glBindVertexArray(0);
}

void EntityRenderer::drawEffects(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection,
                                 RenderStats& stats) {
  const scene::DynamicScene& dyn = buf.dynamic;
  if (dyn.trails.empty() && dyn.flashes.empty() && shadowVertices_.empty()) return;
  const EffectView view = effectViewOf(buf, settings_.height);
  trailVertices_.clear();
  flashVertices_.clear();
  for (const scene::Trail& t : dyn.trails) {
    const std::size_t before = trailVertices_.size();
    appendTrail(t, view, kTrailMinPixels, trailVertices_);
    stats.trailsDrawn += trailVertices_.size() > before;
  }
  for (const scene::Flash& f : dyn.flashes) {
    const std::size_t before = flashVertices_.size();
    appendFlash(f, view, kFlashMinPixels, flashVertices_);
    stats.flashesDrawn += flashVertices_.size() > before;
  }
  // One stream: shadows, trails, flashes.
  const auto shadows = GLsizei(shadowVertices_.size()), trails = GLsizei(trailVertices_.size());
  const auto flashes = GLsizei(flashVertices_.size());
  if (shadows + trails + flashes == 0) return;
  shadowVertices_.insert(shadowVertices_.end(), trailVertices_.begin(), trailVertices_.end());
  shadowVertices_.insert(shadowVertices_.end(), flashVertices_.begin(), flashVertices_.end());
  glNamedBufferData(effectBuffer_, GLsizeiptr(shadowVertices_.size() * sizeof(EffectVertex)), shadowVertices_.data(),
                    GL_STREAM_DRAW);
  glVertexArrayVertexBuffer(effectVao_, 0, effectBuffer_, 0, sizeof(EffectVertex));
  effectProgram_.use();
  effectProgram_.setMatrix4("uViewProjection", viewProjection.data());
  setFrameShading(effectProgram_, buf);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);
  glDepthMask(GL_FALSE);  // seen through each other, hidden by the ground
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glDisable(GL_CULL_FACE);
  glBindVertexArray(effectVao_);
  if (shadows > 0) {
    // Reversed Z: a positive offset pulls the shadow towards the eye, over
    // the ground it lies on (as the decals do).
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.0f, 8.0f);
    effectProgram_.set("uKind", 2);
    glDrawArrays(GL_TRIANGLES, 0, shadows);
    glDisable(GL_POLYGON_OFFSET_FILL);
  }
  if (trails > 0) {
    effectProgram_.set("uKind", 0);
    glDrawArrays(GL_TRIANGLES, shadows, trails);
  }
  if (flashes > 0) {
    effectProgram_.set("uKind", 1);
    glDrawArrays(GL_TRIANGLES, shadows + trails, flashes);
  }
  glBindVertexArray(0);
  glDisable(GL_BLEND);
  glDepthMask(GL_TRUE);
}

void EntityRenderer::draw(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection,
                          const ModuleRenderer* modules, const std::vector<scene::DynamicInstance>& diverted,
                          RenderStats& stats) {
  if (settings_.colour == ColourMode::height) return;  // data pixels: terrain heights only
  collect(buf, modules, diverted, stats);
  submit(buf, viewProjection, stats);
  drawEffects(buf, viewProjection, stats);
}

void EntityRenderer::warmUp(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection) {
  if (settings_.colour == ColourMode::height || shapes_.empty()) return;
  scene::DisplayBuffer b;
  b.camera = buf.camera;
  b.originX = buf.originX;
  b.originZ = buf.originZ;
  scene::DynamicInstance d;
  d.z = -20;
  d.shadow = true;  // its shadow too
  d.orientation = headingQuaternion(30);
  d.turretAzimuthDeg = 10;
  d.gunElevationDeg = 5;
  // The tank's turret and gun if there are: every group's draws compile the same program.
  b.dynamic.instances.push_back(d);
  scene::Trail t;
  t.points = {{-2, 1, -20, 0.5f}, {2, 2, -22, 0.1f}};
  b.dynamic.trails.push_back(t);
  b.dynamic.flashes.push_back({0, 1, -20, 0.1f, 0.5f, 3});
  RenderStats ignored;
  draw(b, viewProjection, nullptr, {}, ignored);
}

}  // namespace sandtable::render::detail
