#include "object_draw.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdio>

#include "entity_draw.h"
#include "icon_textures.h"
#include "sandtable/base/hash.h"
#include "module_draw.h"
#include "sandtable/scene/camera_math.h"
#include "sandtable/scene/lod.h"
#include "terrain_shading.h"

namespace sandtable::render::detail {
namespace {

// Appended to shadingVertexGlsl(). The icon turns about Y by the heading
// (clockwise from north seen from above: north -Z goes to east +X at 90).
const char* kObjectVertexMain = R"(
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColour;
layout(location = 3) in vec4 aPlace;       // base x, y, z and heading (radians)
layout(location = 4) in vec2 aScaleFade;
layout(location = 5) in vec2 aUv;
layout(location = 6) in float aLayer;
uniform mat4 uViewProjection;
uniform vec3 uEye;
out vec3 vColour;
out float vLight;
out float vFog;
out vec2 vUv;
flat out float vLayer;
flat out float vFade;
void main() {
  vUv = aUv;
  vLayer = aLayer;
  float c = cos(aPlace.w), s = sin(aPlace.w);
  vec3 p = aPosition * aScaleFade.x;
  vec3 w = vec3(p.x * c - p.z * s, p.y, p.x * s + p.z * c) + aPlace.xyz;
  vec3 n = vec3(aNormal.x * c - aNormal.z * s, aNormal.y, aNormal.x * s + aNormal.z * c);
  gl_Position = uViewProjection * vec4(w, 1.0);
  vColour = aColour.rgb;
  vLight = sunLight(n);
  vFog = fogWeight(distance(w, uEye));
  vFade = aScaleFade.y;
}
)";

// Appended to iconFragmentGlsl().
const char* kObjectFragmentMain = R"(
in vec3 vColour;
in float vLight;
in float vFog;
in vec2 vUv;
flat in float vLayer;
flat in float vFade;
out vec4 fragColor;
void main() {
  if (fadedOut(vFade)) discard;
  vec3 colour;
  if (!iconColour(vColour, vUv, vLayer, colour)) discard;
  fragColor = vec4(mix(uFogColor, colour * vLight, vFog), 1.0);
}
)";

// Appended to shadingVertexGlsl(). One point per object, at the centre of
// its icon's sprite square, as many pixels wide as the square projects to.
// (Upright instanced quads, tried instead, cost llvmpipe a third more.)
// A sprite's instance holds that centre, the square's side (times the
// object's scale) and its impostor's layer (place()), so that one draw
// takes every icon's sprites. The fragment shader gets one flat vec4: fog
// weight, fade, layer and vLevel, the impostor's mipmap level with the
// fewest texels still at least the point's pixels (64 texels at level 0);
// llvmpipe sets up each point's inputs one by one on the render thread.
const char* kSpriteVertexMain = R"(
layout(location = 3) in vec4 aPlace;       // centre x, y, z and impostor layer
layout(location = 4) in vec2 aScaleFade;   // side and fade
uniform mat4 uViewProjection;
uniform vec3 uEye;
uniform float uFocal;    // pixels per unit at unit depth
flat out vec4 vSprite;   // fog weight, fade, layer, mipmap level
void main() {
  vec3 c = aPlace.xyz;
  gl_Position = uViewProjection * vec4(c, 1.0);
  gl_PointSize = max(uFocal * aScaleFade.x / max(gl_Position.w, 1e-3), 1.0);
  float level = float(clamp(int(floor(log2(64.0 / gl_PointSize))), 0, 6));
  vSprite = vec4(fogWeight(distance(c, uEye)), aScaleFade.y, aPlace.w, level);
}
)";

// Appended to iconFragmentGlsl(). The impostor's texel, alpha-tested,
// screen-door faded as the meshes are, fogged. One texelFetch of the
// point's level, nearest, rather than a filtered texture(): llvmpipe
// computes every fragment's derivatives and mipmap level and blends eight
// texels for a trilinear fetch from an array (the rasteriser threads' JIT
// samples for the trees fell by a fifth without it: docs/VIEWER.md,
// "Trees in view").
static_assert(kImpostorTexels == 64, "the sprite shaders' mipmap levels count from 64 texels");
const char* kSpriteFragmentMain = R"(
uniform sampler2DArray uImpostors;
flat in vec4 vSprite;
out vec4 fragColor;
void main() {
  int level = int(vSprite.w);
  int n = 64 >> level;
  ivec2 q = min(ivec2(vec2(gl_PointCoord.x, 1.0 - gl_PointCoord.y) * float(n)), ivec2(n - 1));
  vec4 t = texelFetch(uImpostors, ivec3(q, int(vSprite.z)), level);
  if (t.a < 0.5 || fadedOut(vSprite.y)) discard;
  fragColor = vec4(mix(uFogColor, t.rgb, vSprite.x), 1.0);
}
)";

// Appended to shadingVertexGlsl(). The icon seen from the south (+Z),
// orthographic over its sprite square, lit by the meshes' sun.
const char* kBakeVertexMain = R"(
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColour;
layout(location = 5) in vec2 aUv;
layout(location = 6) in float aLayer;
uniform float uCentre;
uniform float uHalf;
uniform float uDepth;
out vec3 vColour;
out float vLight;
out vec2 vUv;
flat out float vLayer;
void main() {
  gl_Position = vec4(aPosition.x / uHalf, (aPosition.y - uCentre) / uHalf, -aPosition.z / uDepth, 1.0);
  vColour = aColour.rgb;
  vLight = sunLight(aNormal);
  vUv = aUv;
  vLayer = aLayer;
}
)";

// Appended to shadingHeaderGlsl() and kIconTextureGlsl.
const char* kBakeFragmentMain = R"(
in vec3 vColour;
in float vLight;
in vec2 vUv;
flat in float vLayer;
out vec4 fragColor;
void main() {
  vec3 colour;
  if (!iconColour(vColour, vUv, vLayer, colour)) discard;
  fragColor = vec4(colour * vLight, 1.0);
}
)";

std::uint32_t packNormal(float x, float y, float z) {
  const float len = std::sqrt(x * x + y * y + z * z);
  const float k = len > 0 ? 1.0f / len : 0.0f;
  const auto q = [k](float v) {
    const long i = std::lround(std::clamp(v * k, -1.0f, 1.0f) * 511.0f);
    return std::uint32_t(i) & 0x3FFu;
  };
  return q(x) | (q(y) << 10) | (q(z) << 20);
}

std::uint32_t packRgba(const std::array<std::uint8_t, 4>& c) {
  return std::uint32_t(c[0]) | (std::uint32_t(c[1]) << 8) | (std::uint32_t(c[2]) << 16) |
         (std::uint32_t(c[3]) << 24);
}

void flattenIcon(const iconpack::Icon& icon, IconMeshes& out) {
  const auto base = std::int32_t(out.vertices.size());
  const std::size_t levels = icon.ranges.size();
  std::vector<std::vector<std::uint32_t>> perLevel(levels);
  bool textured = false;
  for (std::size_t p = 0; p < icon.parts.size(); ++p) {
    const iconpack::Part& part = icon.parts[p];
    if (part.state != iconpack::State::alive) continue;
    const auto origin = iconpack::partOrigin(icon, p);
    for (const iconpack::Mesh& m : part.meshes) {
      const auto first = std::uint32_t(out.vertices.size() - std::size_t(base));
      for (std::size_t v = 0; v < m.vertexCount(); ++v) {
        out.vertices.push_back(iconVertex(icon, m, v, origin, textured));
      }
      for (std::size_t l = 0; l < levels && l < m.levels.size(); ++l) {
        for (const std::uint32_t i : m.levels[l]) perLevel[l].push_back(first + i);
      }
    }
  }
  std::vector<IconLevelRange> ranges(levels);
  for (std::size_t l = 0; l < levels; ++l) {
    ranges[l] = {std::uint32_t(out.indices.size()), std::uint32_t(perLevel[l].size()), base};
    out.indices.insert(out.indices.end(), perLevel[l].begin(), perLevel[l].end());
  }
  out.ranges.push_back(std::move(ranges));
  out.textured.push_back(textured);
}

/// Frames a module's cells outlive its last draw (as the terrain's cache entries).
constexpr std::uint64_t kCellsKeptFrames = 90;
/// The cell tests' margins against rounding: relative (distances, pixels)
/// and in metres (planes, the view triangle, far ranges).
constexpr double kSlack = 1e-6, kSlackMetres = 1e-3;

/// A fixed number in [0, 1) for object k of module (kx, kz).
double unitHash(std::uint32_t kx, std::uint32_t kz, std::uint32_t k) {
  return hash::unit(hash::mix((std::uint64_t(kx) << 42) ^ (std::uint64_t(kz) << 21) ^ k));
}

/// The view triangle's three edges as inward unit normals, once per frame:
/// the per-object test is then three multiply-adds (a forest is hundreds
/// of thousands of objects a frame).
class DiscTest {
 public:
  explicit DiscTest(const paging::ViewTriangle& t) {
    const std::array<paging::GroundPoint, 3> v{t.apex, t.left, t.right};
    const double area = (v[1].x - v[0].x) * (v[2].z - v[0].z) - (v[1].z - v[0].z) * (v[2].x - v[0].x);
    const double sign = area < 0 ? -1.0 : 1.0;
    for (int k = 0; k < 3; ++k) {
      const paging::GroundPoint& a = v[std::size_t(k)];
      const paging::GroundPoint& b = v[std::size_t((k + 1) % 3)];
      const double ex = b.x - a.x, ez = b.z - a.z, len = std::sqrt(ex * ex + ez * ez);
      Edge& e = edges_[std::size_t(k)];
      if (len == 0) continue;  // a degenerate edge rejects nothing
      // Positive inside for a counter-clockwise (area > 0) triangle.
      e.nx = -sign * ez / len;
      e.nz = sign * ex / len;
      e.w = -(e.nx * a.x + e.nz * a.z);
    }
  }
  /// Whether a disc of radius r at (x, z) touches the triangle (world metres).
  bool touches(double x, double z, double r) const {
    for (const Edge& e : edges_) {
      if (e.nx * x + e.nz * z + e.w < -r) return false;
    }
    return true;
  }
  /// Whether every disc of radius <= r centred in the box [x0, x1] x [z0, z1]
  /// misses the triangle (-1), every point of the box is inside by
  /// kSlackMetres (1), or
  /// neither (0).
  int box(double x0, double x1, double z0, double z1, double r) const {
    bool inside = true;
    for (const Edge& e : edges_) {
      const double hi = std::max(e.nx * x0, e.nx * x1) + std::max(e.nz * z0, e.nz * z1) + e.w;
      const double lo = std::min(e.nx * x0, e.nx * x1) + std::min(e.nz * z0, e.nz * z1) + e.w;
      if (hi < -r) return -1;
      inside = inside && lo >= kSlackMetres;
    }
    return inside ? 1 : 0;
  }

 private:
  struct Edge {
    double nx = 0, nz = 0, w = 0;
  };
  std::array<Edge, 3> edges_;
};

}  // namespace

const char* const kIconTextureGlsl = R"(
// Screen-door fade: a fragment stays when the fade exceeds its cell of an
// ordered 4 x 4 threshold pattern.
const float kBayer[16] = float[](0.0, 8.0, 2.0, 10.0, 12.0, 4.0, 14.0, 6.0,
                                 3.0, 11.0, 1.0, 9.0, 15.0, 7.0, 13.0, 5.0);
bool fadedOut(float fade) {
  if (fade >= 1.0) return false;
  ivec2 q = ivec2(gl_FragCoord.xy) & 3;
  return fade * 16.0 <= kBayer[q.y * 4 + q.x];
}
#ifdef SANDTABLE_ICON_TEXTURE
uniform sampler2DArray uIconTextures;
#endif
// The material's colour, times its texture where it has one (layer >= 0);
// false for a cut-out texel (alpha under one half).
bool iconColour(vec3 base, vec2 uv, float layer, out vec3 colour) {
  colour = base;
#ifdef SANDTABLE_ICON_TEXTURE
  if (layer >= 0.0) {
    vec4 t = texture(uIconTextures, vec3(uv, layer));
    if (t.a < 0.5) return false;
    colour *= t.rgb;
  }
#endif
  return true;
}
)";

std::string iconFragmentGlsl(bool textured, const char* main) {
  return shadingHeaderGlsl() + (textured ? "#define SANDTABLE_ICON_TEXTURE\n" : "") + kIconTextureGlsl + main;
}

IconVertex iconVertex(const iconpack::Icon& icon, const iconpack::Mesh& m, std::size_t v,
                      const std::array<float, 3>& offset, bool& textured) {
  const bool known = m.material < icon.materials.size();
  const std::uint32_t rgba = known ? packRgba(icon.materials[m.material].rgba) : 0xFFFFFFFFu;
  const std::uint32_t texture = known ? icon.materials[m.material].texture : iconpack::kNoTexture;
  const bool uv = texture != iconpack::kNoTexture && m.texcoords.size() == 2 * m.vertexCount();
  textured = textured || uv;
  const float* pos = &m.positions[3 * v];
  const float* n = &m.normals[3 * v];
  const float s = uv ? m.texcoords[2 * v] : 0.0f, t = uv ? m.texcoords[2 * v + 1] : 0.0f;
  return {pos[0] + offset[0], pos[1] + offset[1], pos[2] + offset[2], packNormal(n[0], n[1], n[2]), rgba, s, t,
          uv ? float(texture) : -1.0f};
}

void bindIconVertex(GLuint vao) {
  const auto attrib = [&](GLuint loc, GLint n, GLenum type, GLboolean norm, GLuint offset) {
    glEnableVertexArrayAttrib(vao, loc);
    glVertexArrayAttribFormat(vao, loc, n, type, norm, offset);
    glVertexArrayAttribBinding(vao, loc, 0);
  };
  attrib(0, 3, GL_FLOAT, GL_FALSE, offsetof(IconVertex, x));
  attrib(1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, offsetof(IconVertex, normal));
  attrib(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, offsetof(IconVertex, rgba));
  attrib(5, 2, GL_FLOAT, GL_FALSE, offsetof(IconVertex, s));
  attrib(6, 1, GL_FLOAT, GL_FALSE, offsetof(IconVertex, layer));
}

/// Binds ObjectInstance's attributes (place 3, scale and fade 4) to `binding` of `vao`.
static void bindInstance(GLuint vao, GLuint binding) {
  const auto attrib = [&](GLuint loc, GLint n, GLuint offset) {
    glEnableVertexArrayAttrib(vao, loc);
    glVertexArrayAttribFormat(vao, loc, n, GL_FLOAT, GL_FALSE, offset);
    glVertexArrayAttribBinding(vao, loc, binding);
  };
  attrib(3, 4, offsetof(ObjectInstance, x));
  attrib(4, 2, offsetof(ObjectInstance, scale));
}

IconSprite spriteOf(const iconpack::Icon& icon) {
  const auto& b = icon.bounds;
  float reach = 0;
  for (const int k : {0, 2, 3, 5}) reach = std::max(reach, std::abs(b[std::size_t(k)]));
  IconSprite s;
  s.centre = 0.5f * (b[1] + b[4]);
  s.size = std::max(b[4] - b[1], 2.0f * reach);
  return s;
}

IconMeshes flattenIcons(const iconpack::Pack& pack) {
  IconMeshes out;
  for (const iconpack::Icon& icon : pack.icons) flattenIcon(icon, out);
  return out;
}

int iconLevelAt(const iconpack::Icon& icon, double distance, double viewDistance, double fadeFraction,
                float& fade) {
  fade = 1.0f;
  if (icon.ranges.empty()) return -1;
  const double far = std::min(double(icon.ranges.back()), viewDistance);
  if (!(distance < far)) return -1;
  const double band = std::clamp(fadeFraction, 0.0, 1.0) * far;
  if (band > 0 && distance > far - band) fade = float((far - distance) / band);
  for (std::size_t l = 0; l < icon.ranges.size(); ++l) {
    if (distance < double(icon.ranges[l])) return int(l);
  }
  return int(icon.ranges.size()) - 1;  // capped by the view distance
}

ObjectRenderer::~ObjectRenderer() {
  program_.reset();
  spriteProgram_.reset();
  glDeleteVertexArrays(1, &vao_);
  glDeleteVertexArrays(1, &spriteVao_);
  glDeleteTextures(1, &impostors_);
  glDeleteTextures(1, &textures_);
  texturedProgram_.reset();
  glDeleteBuffers(1, &vertexBuffer_);
  glDeleteBuffers(1, &indexBuffer_);
  glDeleteBuffers(1, &instanceBuffer_);
}

Status ObjectRenderer::create(const RenderSettings& s) {
  settings_ = s;
  for (const bool textured : {false, true}) {
    auto program = GlProgram::build(textured ? "textured object shader" : "object shader",
                                    shadingVertexGlsl() + kObjectVertexMain,
                                    iconFragmentGlsl(textured, kObjectFragmentMain));
    if (!program) return program.problems();
    GlProgram& p = textured ? texturedProgram_ : program_;
    p = std::move(program.value());
    p.use();
    setShadingUniforms(p, s);
    if (textured) p.set("uIconTextures", 2);
  }
  std::vector<std::string> warnings;
  textures_ = uploadIconTextures(*s.icons, warnings);
  for (const std::string& w : warnings) std::fprintf(stderr, "sandtable: warning: %s\n", w.c_str());

  IconMeshes meshes = flattenIcons(*s.icons);
  ranges_ = std::move(meshes.ranges);
  textured_ = std::move(meshes.textured);
  levelBase_.clear();
  std::uint32_t buckets = 0;
  for (const auto& r : ranges_) {
    levelBase_.push_back(buckets);
    buckets += std::uint32_t(r.size());
  }
  buckets_.assign(buckets, {});

  glCreateBuffers(1, &vertexBuffer_);
  glNamedBufferStorage(vertexBuffer_, GLsizeiptr(std::max<std::size_t>(1, meshes.vertices.size()) * sizeof(IconVertex)),
                       meshes.vertices.empty() ? nullptr : meshes.vertices.data(), 0);
  glCreateBuffers(1, &indexBuffer_);
  glNamedBufferStorage(indexBuffer_, GLsizeiptr(std::max<std::size_t>(1, meshes.indices.size()) * sizeof(std::uint32_t)),
                       meshes.indices.empty() ? nullptr : meshes.indices.data(), 0);
  glCreateBuffers(1, &instanceBuffer_);

  glCreateVertexArrays(1, &vao_);
  glVertexArrayVertexBuffer(vao_, 0, vertexBuffer_, 0, sizeof(IconVertex));
  glVertexArrayElementBuffer(vao_, indexBuffer_);
  bindIconVertex(vao_);
  bindInstance(vao_, 1);
  glVertexArrayBindingDivisor(vao_, 1, 1);

  sprites_.clear();
  for (const iconpack::Icon& icon : s.icons->icons) sprites_.push_back(spriteOf(icon));
  spriteBuckets_.assign(sprites_.size(), {});
  if (s.impostorPixels <= 0 || sprites_.empty()) return {};
  auto sprite = GlProgram::build("object sprite shader", shadingVertexGlsl() + kSpriteVertexMain,
                                 iconFragmentGlsl(false, kSpriteFragmentMain));
  if (!sprite) return sprite.problems();
  spriteProgram_ = std::move(sprite.value());
  spriteProgram_.use();
  setShadingUniforms(spriteProgram_, s);
  spriteProgram_.set("uImpostors", 1);
  glCreateVertexArrays(1, &spriteVao_);
  bindInstance(spriteVao_, 0);  // read per vertex: one point per object
  return bakeImpostors();
}

Status ObjectRenderer::bakeImpostors() {
  auto bake = GlProgram::build("impostor bake shader", shadingVertexGlsl() + kBakeVertexMain,
                               iconFragmentGlsl(textures_ != 0, kBakeFragmentMain));
  if (!bake) return bake.problems();
  const GlProgram& program = bake.value();
  program.use();
  setShadingUniforms(program, settings_);
  if (textures_ != 0) {
    program.set("uIconTextures", 2);
    glBindTextureUnit(2, textures_);
  }
  const GLsizei n = GLsizei(kImpostorTexels);
  impostors_ = createTextureArray(kImpostorTexels, std::uint32_t(sprites_.size()), GL_CLAMP_TO_EDGE);
  GLint oldFramebuffer = 0, oldViewport[4] = {0, 0, 0, 0};
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &oldFramebuffer);
  glGetIntegerv(GL_VIEWPORT, oldViewport);
  GLuint fbo = 0, depth = 0;
  glCreateRenderbuffers(1, &depth);
  glNamedRenderbufferStorage(depth, GL_DEPTH_COMPONENT24, n, n);
  glCreateFramebuffers(1, &fbo);
  glNamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glViewport(0, 0, n, n);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glBindVertexArray(vao_);
  for (std::size_t icon = 0; icon < sprites_.size(); ++icon) {
    glNamedFramebufferTextureLayer(fbo, GL_COLOR_ATTACHMENT0, impostors_, 0, GLint(icon));
    // Transparent, in the mean colour of foliage and bark, so that the
    // mipmaps' edge texels do not darken towards black.
    const GLfloat clear[4] = {0.25f, 0.3f, 0.2f, 0.0f};
    const GLfloat one = 1.0f;
    glClearNamedFramebufferfv(fbo, GL_COLOR, 0, clear);
    glClearNamedFramebufferfv(fbo, GL_DEPTH, 0, &one);
    const IconSprite& sp = sprites_[icon];
    if (sp.size <= 0 || ranges_[icon].empty() || ranges_[icon][0].count == 0) continue;
    program.set("uCentre", sp.centre);
    program.set("uHalf", 0.5f * sp.size);
    program.set("uDepth", sp.size);
    const IconLevelRange& r = ranges_[icon][0];
    glDrawElementsBaseVertex(GL_TRIANGLES, GLsizei(r.count), GL_UNSIGNED_INT,
                             reinterpret_cast<const void*>(std::uintptr_t(r.firstIndex) * sizeof(std::uint32_t)),
                             r.baseVertex);
  }
  glBindVertexArray(0);
  glGenerateTextureMipmap(impostors_);
  glBindFramebuffer(GL_FRAMEBUFFER, GLuint(oldFramebuffer));
  glViewport(oldViewport[0], oldViewport[1], oldViewport[2], oldViewport[3]);
  glDeleteFramebuffers(1, &fbo);
  glDeleteRenderbuffers(1, &depth);
  return {};
}

struct ObjectRenderer::Frame {
  const scene::DisplayBuffer& buf;
  const ModuleRenderer& modules;
  const std::vector<iconpack::Icon>& icons;
  Eigen::Vector3d eye;                    ///< relative to the buffer origin
  std::array<Eigen::Vector4d, 5> planes;  ///< side and far planes: n . p + w is a distance
  DiscTest triangle;
  double focal = 0;     ///< pixels per metre at one metre
  bool sprites = false;  ///< impostors drawn
  bool thinning = false;  ///< and thinned
  double fogDensity = 0, fogStart = 0;  ///< fogWeight()'s, 0 density: no fog
  /// The share of an object's own colour left by the fog at `distance`:
  /// the shaders' fogWeight() (terrain_shading.h).
  double fogWeight(double distance) const {
    const double k = fogDensity * std::max(distance - fogStart, 0.0);
    return std::exp(-k * k);
  }
};

void ObjectRenderer::consider(const Frame& f, std::uint32_t m, std::size_t i, scene::ObjectLook look,
                              RenderStats& stats) {
  const scene::ModuleDraw& d = f.buf.modules[m];
  const paging::ResidentModule& rm = d.ref.module();
  const module::Object& o = rm.objects[i];
  std::uint32_t level = 0;
  float morph = 0;
  if (!f.modules.drawnAt(m, o.x, o.z, level, morph)) return;
  const std::vector<float>& y0 = d.ref.level(level).objectY;
  if (i >= y0.size()) return;
  const float* y1 = morph > 0 && level + 1 < rm.levels.size() && i < rm.levels[level + 1].objectY.size()
                        ? &rm.levels[level + 1].objectY[i]
                        : nullptr;
  place(f, d, std::uint32_t(i), o, y0[i], y1, morph, look, stats);
}

void ObjectRenderer::place(const Frame& f, const scene::ModuleDraw& d, std::uint32_t i, const module::Object& o,
                           float y0, const float* y1, float morph, scene::ObjectLook look, RenderStats& stats) {
  const scene::DisplayBuffer& buf = f.buf;
  const scene::Camera& cam = buf.camera;
  const double mx = double(d.kx) * buf.moduleSize, mz = double(d.kz) * buf.moduleSize;
  const double gx = mx + o.x - buf.originX - f.eye.x(), gz = mz + o.z - buf.originZ - f.eye.z();
  if (gx * gx + gz * gz >= farRange_[o.icon] * farRange_[o.icon]) return;
  const double half = 0.5 * double(o.height);
  const double radius = std::sqrt(double(o.radius) * double(o.radius) + half * half);
  if (!f.triangle.touches(mx + o.x, mz + o.z, radius)) return;
  double y = y0;
  if (y1 != nullptr) y += double(morph) * (double(*y1) - y);
  const Eigen::Vector3d centre(mx + o.x - buf.originX, y + half, mz + o.z - buf.originZ);
  float fade = 1;
  const double distance = (centre - f.eye).norm();
  const int iconLevel = settings_.objectLod
                            ? iconLevelAt(f.icons[o.icon], distance, cam.viewDistance, settings_.objectFade, fade)
                            : (distance < cam.viewDistance ? 0 : -1);
  if (iconLevel < 0 || fade <= 0) return;
  const Eigen::Vector4d c(centre.x(), centre.y(), centre.z(), 1.0);
  for (const auto& p : f.planes) {
    if (p.dot(c) < -radius) return;
  }
  if (look != scene::ObjectLook::standing) {
    divert(f.icons[o.icon], o, look, mx + o.x, y, mz + o.z);
    return;
  }
  ObjectInstance instance{float(centre.x()), float(y),   float(centre.z()),
                          float(module::headingRadians(o.heading)), o.scale, fade};
  const double pixels = double(sprites_[o.icon].size) * double(o.scale) * f.focal / std::max(distance, 1e-3);
  if (f.sprites && pixels < settings_.impostorPixels) {
    const double thin = settings_.objectThinPixels;
    if (thin > 0 && pixels < thin) {
      // Kept with probability (pixels / thin)^2, by where it stands, so
      // the same ones stay from frame to frame; the kept grow (up to
      // twice) to keep the cover of the many they stand for. Times the
      // share of its colour the fog leaves: a tree at fog weight 0.1 shows
      // a tenth of its contrast, so nine in ten are not worth llvmpipe's
      // setup and shading; the kept are not grown for those, and the
      // forest fades into the fog by density as each tree does by colour.
      const double keep = (pixels / thin) * (pixels / thin) * f.fogWeight(distance);
      if (unitHash(d.kx, d.kz, i) >= keep) {
        ++stats.objectsThinned;
        return;
      }
      instance.scale *= float(std::min(thin / pixels, 2.0));
    }
    const IconSprite& sp = sprites_[o.icon];
    spriteBuckets_[o.icon].push_back({instance.x, instance.y + sp.centre * instance.scale, instance.z, float(o.icon),
                             sp.size * instance.scale, instance.fade});
  } else {
    buckets_[levelBase_[o.icon] + std::uint32_t(iconLevel)].push_back(instance);
  }
  ++stats.objectsDrawn;
}

ObjectRenderer::ModuleObjects* ObjectRenderer::cellsOf(const scene::DisplayBuffer& buf, std::uint32_t m) {
  const scene::ModuleDraw& d = buf.modules[m];
  const paging::ResidentModule& rm = d.ref.module();
  if (rm.levels.empty()) return nullptr;
  ModuleObjects& mo = cells_[(std::uint64_t(d.kx) << 32) | d.kz];
  mo.lastFrame = frame_;
  if (mo.module == &rm && mo.generation == d.ref.generation()) return &mo;
  // Built once per module arrival: the only per-object work outside the
  // objects a frame keeps.
  const std::vector<iconpack::Icon>& icons = settings_.icons->icons;
  mo.module = &rm;
  mo.generation = d.ref.generation();
  // The cells of ModuleRenderer::drawnAt: one drawn level and morph each.
  mo.side = scene::nodesPerSide(0, std::uint32_t(rm.levels.size()));
  const double cellSize = buf.moduleSize / double(mo.side);
  const auto cellOf = [&](double v) {
    return std::uint32_t(std::clamp(std::floor(v / cellSize), 0.0, double(mo.side - 1)));
  };
  const std::size_t n = std::size_t(mo.side) * mo.side;
  mo.cells.assign(n, {});
  mo.y.assign(rm.levels.size(), {});
  mo.levelY.assign(rm.levels.size(), {});
  std::vector<std::uint32_t> cellOfObject(rm.objects.size(), UINT32_MAX);
  for (std::size_t i = 0; i < rm.objects.size(); ++i) {
    const module::Object& o = rm.objects[i];
    if (o.icon >= icons.size()) continue;  // validate refuses these
    cellOfObject[i] = cellOf(o.z) * mo.side + cellOf(o.x);
    ++mo.cells[cellOfObject[i]].count;
  }
  std::uint32_t first = 0;
  for (auto& c : mo.cells) {
    c.first = first;
    first += c.count;
    c.count = 0;
    c.minX = c.minZ = c.minHalf = c.minFar = INFINITY;
    c.maxX = c.maxZ = c.maxHalf = c.maxFar = -INFINITY;
  }
  mo.order.assign(first, 0);
  mo.key.assign(first, 0);
  for (std::size_t i = 0; i < rm.objects.size(); ++i) {
    if (cellOfObject[i] == UINT32_MAX) continue;
    const module::Object& o = rm.objects[i];
    ModuleObjects::Cell& c = mo.cells[cellOfObject[i]];
    mo.order[c.first + c.count++] = std::uint32_t(i);
    const float half = 0.5f * o.height;
    const float far = icons[o.icon].ranges.empty() ? INFINITY : icons[o.icon].ranges.back();
    c.minX = std::min(c.minX, o.x), c.maxX = std::max(c.maxX, o.x);
    c.minZ = std::min(c.minZ, o.z), c.maxZ = std::max(c.maxZ, o.z);
    c.maxRadius = std::max(c.maxRadius, float(std::sqrt(double(o.radius) * double(o.radius) + double(half) * half)));
    c.minHalf = std::min(c.minHalf, half), c.maxHalf = std::max(c.maxHalf, half);
    c.maxSprite = std::max(c.maxSprite, sprites_[o.icon].size * o.scale);
    c.minFar = std::min(c.minFar, icons[o.icon].ranges.empty() ? -INFINITY : far);  // none: never drawn with LoD
    c.maxFar = std::max(c.maxFar, far);
  }
  // An object is kept where hash < (s focal / (distance thin))^2, s its
  // sprite side times its scale: where hash / s^2 < (focal / (distance
  // thin))^2. Sorted by that key, the objects a cell can keep at its
  // nearest distance are a prefix.
  std::vector<std::pair<double, std::uint32_t>> byKey;
  for (const auto& c : mo.cells) {
    byKey.clear();
    for (std::uint32_t k = c.first; k < c.first + c.count; ++k) {
      const module::Object& o = rm.objects[mo.order[k]];
      const double side = double(sprites_[o.icon].size) * double(o.scale);
      const double hash = unitHash(d.kx, d.kz, mo.order[k]);
      byKey.emplace_back(side > 0 ? hash / (side * side) : INFINITY, mo.order[k]);
    }
    std::sort(byKey.begin(), byKey.end());
    for (std::uint32_t k = 0; k < c.count; ++k) {
      mo.key[c.first + k] = byKey[k].first;
      mo.order[c.first + k] = byKey[k].second;
    }
  }
  // In that order too, so that a frame reads them in sequence.
  mo.objects.clear();
  for (const std::uint32_t i : mo.order) mo.objects.push_back(rm.objects[i]);
  return &mo;
}

void ObjectRenderer::collectCell(const Frame& f, std::uint32_t m, ModuleObjects& mo, std::uint32_t cell,
                                 RenderStats& stats) {
  const ModuleObjects::Cell& c = mo.cells[cell];
  if (c.count == 0) return;
  const scene::DisplayBuffer& buf = f.buf;
  const scene::ModuleDraw& d = buf.modules[m];
  const double cellSize = buf.moduleSize / double(mo.side);
  const double cx = (double(cell % mo.side) + 0.5) * cellSize, cz = (double(cell / mo.side) + 0.5) * cellSize;
  const auto all = [&] {
    for (std::uint32_t k = c.first; k < c.first + c.count; ++k) consider(f, m, mo.order[k], scene::ObjectLook::standing, stats);
  };
  std::uint32_t level = 0;
  float morph = 0;
  if (!f.modules.drawnAt(m, cx, cz, level, morph)) return;  // every object of the cell fails it
  // The bases' box, relative to the buffer origin, and the eye's ground
  // distance to it. The box tests keep a margin (kSlack, kSlackMetres)
  // against rounding: they only decide what to visit, the objects' own tests
  // decide what is drawn.
  const double mx = double(d.kx) * buf.moduleSize - buf.originX, mz = double(d.kz) * buf.moduleSize - buf.originZ;
  const double x0 = mx + c.minX, x1 = mx + c.maxX, z0 = mz + c.minZ, z1 = mz + c.maxZ;
  const auto gap = [](double v, double lo, double hi) { return std::max({lo - v, 0.0, v - hi}); };
  const auto reach = [](double v, double lo, double hi) { return std::max(std::abs(v - lo), std::abs(v - hi)); };
  const double gx = gap(f.eye.x(), x0, x1), gz = gap(f.eye.z(), z0, z1);
  const double vd = buf.camera.viewDistance;
  const double maxFar = std::min(settings_.objectLod ? double(c.maxFar) : INFINITY, vd);
  if (gx * gx + gz * gz >= (maxFar + kSlackMetres) * (maxFar + kSlackMetres)) return;  // all past their far range
  const int ground = f.triangle.box(x0 + buf.originX, x1 + buf.originX, z0 + buf.originZ, z1 + buf.originZ,
                                    double(c.maxRadius) + kSlackMetres);
  if (ground < 0) return;
  // Level l's objectY in the cells' order and each cell's bounds, made the
  // first time the level is drawn; false while it has none.
  const auto levelY = [&](std::uint32_t l) {
    const std::vector<float>& y = d.ref.level(l).objectY;
    if (y.size() < d.ref.module().objects.size()) return false;
    auto& bounds = mo.y[l];
    if (bounds.empty()) {
      bounds.assign(mo.cells.size(), {INFINITY, -INFINITY});
      auto& ordered = mo.levelY[l];
      ordered.resize(mo.order.size());
      for (std::size_t k = 0; k < mo.cells.size(); ++k) {
        const auto& ck = mo.cells[k];
        for (std::uint32_t j = ck.first; j < ck.first + ck.count; ++j) {
          ordered[j] = y[mo.order[j]];
          bounds[k][0] = std::min(bounds[k][0], ordered[j]);
          bounds[k][1] = std::max(bounds[k][1], ordered[j]);
        }
      }
    }
    return true;
  };
  if (!levelY(level)) return all();
  std::array<float, 2> yb = mo.y[level][cell];
  // The next coarser level's, where the morph moves towards it (as consider()).
  const std::vector<float>* ys1 = nullptr;
  if (morph > 0 && level + 1 < d.ref.module().levels.size()) {
    const std::size_t have = d.ref.module().levels[level + 1].objectY.size();
    if (have > 0 && !levelY(level + 1)) return all();  // some objects morph, some not
    if (have > 0) {
      ys1 = &mo.levelY[level + 1];
      yb = {std::min(yb[0], mo.y[level + 1][cell][0]), std::max(yb[1], mo.y[level + 1][cell][1])};
    }
  }
  const std::vector<float>& ys0 = mo.levelY[level];
  const auto visit = [&](std::uint32_t k) {
    place(f, d, mo.order[k], mo.objects[k], ys0[k], ys1 != nullptr ? &(*ys1)[k] : nullptr, morph,
          scene::ObjectLook::standing, stats);
  };
  // The centres' box; its frustum test as the objects' (n . c >= -radius).
  const double y0 = double(yb[0]) + c.minHalf, y1 = double(yb[1]) + c.maxHalf;
  bool inView = ground > 0;
  for (const auto& p : f.planes) {
    const double hi = std::max(p.x() * x0, p.x() * x1) + std::max(p.y() * y0, p.y() * y1) +
                      std::max(p.z() * z0, p.z() * z1) + p.w();
    const double lo = std::min(p.x() * x0, p.x() * x1) + std::min(p.y() * y0, p.y() * y1) +
                      std::min(p.z() * z0, p.z() * z1) + p.w();
    if (hi < -double(c.maxRadius) - kSlackMetres) return;
    inView = inView && lo >= kSlackMetres;
  }
  const double gy = gap(f.eye.y(), y0, y1);
  const double near = std::sqrt(gx * gx + gy * gy + gz * gz) * (1 - kSlack);
  const double far = std::hypot(reach(f.eye.x(), x0, x1), reach(f.eye.y(), y0, y1), reach(f.eye.z(), z0, z1)) *
                     (1 + kSlack);
  const double minFar = std::min(settings_.objectLod ? double(c.minFar) : INFINITY, vd);
  const double thin = settings_.objectThinPixels;
  const double pixels = double(c.maxSprite) * f.focal / std::max(near, 1e-3) * (1 + kSlack);
  // Wholly in range and view, every object a sprite under the thinning size:
  // only the prefix whose key is under the bound at the nearest distance can
  // be kept; the rest are thinned.
  if (!f.thinning || !inView || !(far < minFar) || !(pixels < std::min(thin, settings_.impostorPixels))) {
    for (std::uint32_t k = c.first; k < c.first + c.count; ++k) visit(k);
    return;
  }
  // The fog only lowers the chance (place()): its weight at the nearest
  // distance bounds the cell's.
  const double perSide = f.focal / (std::max(near, 1e-3) * thin);
  const double keep = perSide * perSide * f.fogWeight(near) * (1 + kSlack);
  const auto begin = mo.key.begin() + c.first, end = begin + c.count;
  const auto visited = std::uint32_t(std::lower_bound(begin, end, keep) - begin);
  for (std::uint32_t k = c.first; k < c.first + visited; ++k) visit(k);
  stats.objectsThinned += c.count - visited;
}

void ObjectRenderer::collect(const scene::DisplayBuffer& buf, const ModuleRenderer& modules, RenderStats& stats) {
  for (auto& b : buckets_) b.clear();
  for (auto& b : spriteBuckets_) b.clear();
  diverted_.clear();
  ++frame_;
  const std::vector<scene::ObjectOverride>& overrides = buf.dynamic.objectOverrides;
  const scene::Camera& cam = buf.camera;
  const std::vector<iconpack::Icon>& icons = settings_.icons->icons;
  // Pixels per metre at one metre: an object is a sprite where
  // size * focal < impostorPixels * distance.
  Frame f{buf,
          modules,
          icons,
          Eigen::Vector3d(cam.x - buf.originX, cam.y, cam.z - buf.originZ),
          scene::frustumPlanes(scene::viewProjection(cam, buf.originX, buf.originZ)),
          DiscTest(buf.triangle),
          0.5 * double(settings_.height) / std::tan(0.5 * cam.vfovDeg() * kDegToRad),
          impostors_ != 0 && settings_.objectLod,
          false};
  f.thinning = f.sprites && settings_.objectThinPixels > 0;
  if (settings_.fog) {
    f.fogDensity = scene::fogDensityFor(cam.viewDistance);
    f.fogStart = scene::kFogClearFraction * cam.viewDistance;
  }
  for (auto& p : f.planes) p /= std::max(p.head<3>().norm(), 1e-12);
  // Past its far range (capped at the view distance) an object is not
  // drawn; the ground distance is a cheap lower bound of the eye's.
  farRange_.resize(icons.size());
  for (std::size_t k = 0; k < icons.size(); ++k) {
    const double far = settings_.objectLod && !icons[k].ranges.empty() ? double(icons[k].ranges.back()) : INFINITY;
    farRange_[k] = std::min(far, cam.viewDistance);
  }
  for (std::uint32_t m = 0; m < buf.modules.size(); ++m) {
    const scene::ModuleDraw& d = buf.modules[m];
    if (!d.ref || d.ref.placeholder()) continue;
    const paging::ResidentModule& rm = d.ref.module();
    if (rm.objects.empty()) continue;
    auto [changed, changedEnd] = scene::overridesOfModule(overrides, d.kx, d.kz);
    if (changed == changedEnd) {
      if (ModuleObjects* mo = cellsOf(buf, m)) {
        for (std::uint32_t c = 0; c < mo->cells.size(); ++c) collectCell(f, m, *mo, c, stats);
        continue;
      }
    }
    // A module with changed objects: each in index order, its overrides walked beside it.
    for (std::size_t i = 0; i < rm.objects.size(); ++i) {
      const module::Object& o = rm.objects[i];
      if (o.icon >= icons.size()) continue;  // validate refuses these
      while (changed != changedEnd && changed->index < i) ++changed;
      const scene::ObjectLook look = changed != changedEnd && changed->index == i ? changed->look : scene::ObjectLook::standing;
      if (look == scene::ObjectLook::destroyed) {
        ++stats.objectsRemoved;
        continue;
      }
      consider(f, m, i, look, stats);
    }
  }
  // Modules out of the view for a while give their cells back.
  std::erase_if(cells_, [&](const auto& e) { return e.second.lastFrame + kCellsKeptFrames < frame_; });
}

void ObjectRenderer::divert(const iconpack::Icon& icon, const module::Object& o, scene::ObjectLook look, double x, double y,
                            double z) {
  scene::DynamicInstance d;
  d.icon = o.icon;
  d.x = x;
  d.y = y;
  d.z = z;
  d.scale = o.scale;
  const double headingDeg = module::headingRadians(o.heading) / kDegToRad;
  if (look == scene::ObjectLook::knockedOver) {
    // Laid forward about its base, its body z becomes its height: lifted so
    // that its lowest point (the bounds' least z) rests on the ground.
    d.orientation = lyingQuaternion(headingDeg);
    d.y += std::max(0.0, -double(icon.bounds[2])) * double(o.scale);
  } else {
    d.orientation = headingQuaternion(headingDeg);
    d.dead = true;  // stump, ruins: the dead model (the alive one if it has none)
  }
  diverted_.push_back(d);
}

void ObjectRenderer::draw(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection,
                          const ModuleRenderer& modules, RenderStats& stats) {
  if (!buf.moduleMode || settings_.colour == ColourMode::height) return;
  collect(buf, modules, stats);
  submit(buf, viewProjection, stats);
}

void ObjectRenderer::warmUp(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection) {
  if (settings_.colour == ColourMode::height) return;
  for (auto& b : buckets_) b.clear();
  for (auto& b : spriteBuckets_) b.clear();
  for (std::size_t icon = 0; icon < ranges_.size(); ++icon) {
    if (!ranges_[icon].empty()) {
      // In front of the warm-up eye and big enough to shade fragments, both
      // the kept and the discarded (faded) kind; a sprite too.
      buckets_[levelBase_[icon]].push_back({0.0f, 0.0f, -20.0f, 0.0f, 1.0f, 0.5f});
      spriteBuckets_[icon].push_back({0.0f, sprites_[icon].centre, -20.0f, float(icon), sprites_[icon].size, 0.5f});
      break;
    }
  }
  RenderStats ignored;
  submit(buf, viewProjection, ignored);
}

void ObjectRenderer::submit(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, RenderStats& stats) {
  stream_.clear();
  for (const auto& b : buckets_) stream_.insert(stream_.end(), b.begin(), b.end());
  for (const auto& b : spriteBuckets_) stream_.insert(stream_.end(), b.begin(), b.end());
  if (stream_.empty()) return;
  const std::uint64_t bytes = stream_.size() * sizeof(ObjectInstance);
  // A new store each frame: the driver orphans the last one instead of
  // waiting for the GPU to finish reading it.
  glNamedBufferData(instanceBuffer_, GLsizeiptr(bytes), stream_.data(), GL_STREAM_DRAW);
  glVertexArrayVertexBuffer(vao_, 1, instanceBuffer_, 0, sizeof(ObjectInstance));
  for (const GlProgram* p : {&program_, &texturedProgram_}) {
    p->use();
    p->setMatrix4("uViewProjection", viewProjection.data());
    setFrameShading(*p, buf);
  }
  if (textures_ != 0) glBindTextureUnit(2, textures_);
  glBindVertexArray(vao_);
  glDisable(GL_CULL_FACE);  // imported models need not be closed
  GLuint baseInstance = 0;
  const GlProgram* current = nullptr;
  for (std::size_t icon = 0; icon < ranges_.size(); ++icon) {
    // llvmpipe pays for a texture fetch in every fragment of a program
    // that has one, so icons without textures keep the plain program.
    const GlProgram* wanted = textures_ != 0 && textured_[icon] ? &texturedProgram_ : &program_;
    for (std::size_t l = 0; l < ranges_[icon].size(); ++l) {
      const auto n = GLsizei(buckets_[levelBase_[icon] + l].size());
      const IconLevelRange& r = ranges_[icon][l];
      if (n > 0 && r.count > 0) {
        if (current != wanted) {
          wanted->use();
          current = wanted;
        }
        glDrawElementsInstancedBaseVertexBaseInstance(
            GL_TRIANGLES, GLsizei(r.count), GL_UNSIGNED_INT,
            reinterpret_cast<const void*>(std::uintptr_t(r.firstIndex) * sizeof(std::uint32_t)), n, r.baseVertex,
            baseInstance);
        ++stats.objectDraws;
        stats.objectInstances += std::uint32_t(n);
        stats.objectTriangles += std::uint64_t(n) * (r.count / 3);
      }
      baseInstance += GLuint(n);
    }
  }
  glBindVertexArray(0);
  drawSprites(buf, viewProjection, baseInstance, stats);
}

void ObjectRenderer::drawSprites(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, GLuint first,
                                 RenderStats& stats) {
  if (impostors_ == 0) return;
  bool any = false;
  for (const auto& b : spriteBuckets_) any = any || !b.empty();
  if (!any) return;
  const scene::Camera& cam = buf.camera;
  spriteProgram_.use();
  spriteProgram_.setMatrix4("uViewProjection", viewProjection.data());
  setFrameShading(spriteProgram_, buf);
  spriteProgram_.set("uFocal", float(0.5 * double(settings_.height) / std::tan(0.5 * cam.vfovDeg() * kDegToRad)));
  glBindTextureUnit(1, impostors_);
  glVertexArrayVertexBuffer(spriteVao_, 0, instanceBuffer_, 0, sizeof(ObjectInstance));
  glBindVertexArray(spriteVao_);
  glEnable(GL_PROGRAM_POINT_SIZE);
  GLsizei n = 0;
  for (const auto& b : spriteBuckets_) n += GLsizei(b.size());
  glDrawArrays(GL_POINTS, GLint(first), n);
  ++stats.objectDraws;
  stats.objectSprites += std::uint32_t(n);
  glDisable(GL_PROGRAM_POINT_SIZE);
  glBindVertexArray(0);
}

}  // namespace sandtable::render::detail
