#include "module_draw.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>

#include "sandtable/scene/camera_math.h"
#include "terrain_shading.h"
#include "sandtable/scene/lod.h"

namespace sandtable::runtime::detail {
namespace {

/// Frames a GPU copy may go unused (e.g. turned away) before it is released.
constexpr std::uint64_t kKeepUnusedFrames = 90;

const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in float aMorphDelta;
layout(location = 2) in vec4 aColour;
layout(location = 3) in vec4 aNormal;
layout(location = 4) in vec2 aTexCoord;
uniform mat4 uViewProjection;
uniform vec3 uOffset;
uniform float uMorph;
out vec4 vColour;
out vec3 vNormal;
out vec3 vPosition;
out vec2 vTexCoord;
void main() {
  vec3 p = aPosition + uOffset;
  p.y += uMorph * aMorphDelta;
  gl_Position = uViewProjection * vec4(p, 1.0);
  vColour = aColour;
  vNormal = aNormal.xyz;
  vPosition = p;
  vTexCoord = aTexCoord;
}
)";

// Appended to detail::shadingGlsl(). The kind is the same at all three
// corners of a triangle, so its interpolated value is exact.
const char* kFragmentMain = R"(
in vec4 vColour;
in vec3 vNormal;
in vec3 vPosition;
in vec2 vTexCoord;
uniform vec3 uEye;
out vec4 fragColor;
void main() {
  int kind = int(vColour.a * 3.0 + 0.5);
  fragColor = shadeSurface(kind, vColour.rgb, vTexCoord, vPosition.y, vNormal,
                           distance(vPosition, uEye));
}
)";

/// Road texture: T across (u), S along (v), one repeat per road width.
constexpr int kRoadTextureSize = 128;

std::uint64_t cacheKey(std::uint32_t kx, std::uint32_t kz, std::uint32_t level) {
  return std::uint64_t(kx) | (std::uint64_t(kz) << 20) | (std::uint64_t(level) << 40);
}

std::uint32_t packColour(Rgb c, SurfaceKind kind) {
  return c.r | (c.g << 8) | (c.b << 16) | (std::uint32_t(kind) << 24);
}

SurfaceKind kindOf(std::uint32_t rgba) { return SurfaceKind(rgba >> 24); }

std::uint32_t packNormal(const Eigen::Vector3f& n) {
  const auto q = [](float v) {
    return std::uint32_t(std::int32_t(std::lround(std::clamp(v, -1.0f, 1.0f) * 511.0f)) & 0x3FF);
  };
  return q(n.x()) | (q(n.y()) << 10) | (q(n.z()) << 20);
}

Rgb mean(Rgb a, Rgb b) {
  return {std::uint8_t((a.r + b.r + 1) / 2), std::uint8_t((a.g + b.g + 1) / 2),
          std::uint8_t((a.b + b.b + 1) / 2)};
}

/// The grid's surface at world (X, Z) metres from its north-west post:
/// normal and water weight interpolated on the grid triangle there, the
/// same split as Terrain::sampleXZ. Exactly a post's values on a post.
struct GridSample {
  Eigen::Vector3f normal{0, 1, 0};
  float water = 0;
};

GridSample sampleGrid(const grid::GridFile& g, const std::array<float, 256>& water, double x, double z) {
  const double maxI = double(g.postsX() - 1), maxJ = double(g.postsZ() - 1);
  const double u = std::clamp(x / g.spacing(), 0.0, maxI), v = std::clamp(z / g.spacing(), 0.0, maxJ);
  const auto i = std::uint32_t(std::min(std::floor(u), maxI - 1));
  const auto j = std::uint32_t(std::min(std::floor(v), maxJ - 1));
  const double fx = u - i, fz = v - j;
  // Weights of NW, NE, SW, SE.
  std::array<double, 4> w{};
  if (fx + fz <= 1.0) {
    w = {1.0 - fx - fz, fx, fz, 0.0};
  } else {
    w = {0.0, 1.0 - fz, 1.0 - fx, fx + fz - 1.0};
  }
  const std::array<std::array<std::uint32_t, 2>, 4> posts = {{{i, j}, {i + 1, j}, {i, j + 1}, {i + 1, j + 1}}};
  GridSample out;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  double wet = 0;
  for (int k = 0; k < 4; ++k) {
    if (w[k] == 0.0) continue;
    const auto p = g.normal(posts[k][0], posts[k][1]);
    n += w[k] * Eigen::Vector3d(p[0], p[1], p[2]);
    wet += w[k] * water[g.material(posts[k][0], posts[k][1])];
  }
  if (n.norm() > 0) out.normal = n.normalized().cast<float>();
  out.water = float(wet);
  return out;
}

/// Builds one level's vertices and indices (module_draw.h: smooth shares
/// vertices, flat gives each triangle its own three).
class LevelBuilder {
 public:
  LevelBuilder(const module::Level& level, const std::vector<float>& delta, bool flat)
      : level_(level), delta_(delta), flat_(flat), firstCopy_(level.vertices.size(), UINT32_MAX) {}

  /// Smooth shading: the grid's normal and water weight at every vertex.
  void sampleGrid(const grid::GridFile& g, const std::vector<std::uint8_t>& waterMaterials,
                  double originX, double originZ) {
    std::array<float, 256> water{};
    for (const std::uint8_t m : waterMaterials) water[m] = 1.0f;
    normal_.resize(level_.vertices.size());
    water_.resize(level_.vertices.size());
    for (std::size_t k = 0; k < level_.vertices.size(); ++k) {
      const auto& v = level_.vertices[k];
      const GridSample s = detail::sampleGrid(g, water, originX + v.x, originZ + v.z);
      normal_[k] = packNormal(s.normal);
      water_[k] = std::uint8_t(std::lround(std::clamp(s.water, 0.0f, 1.0f) * 255.0f));
    }
  }

  /// Appends the triangles of indices [first, first + count) of the level,
  /// all in colour `rgba`.
  void triangles(const std::uint32_t* idx, std::uint32_t count, std::uint32_t rgba, bool skirt) {
    for (std::uint32_t t = 0; t + 2 < count; t += 3) {
      if (!flat_) {
        for (int k = 0; k < 3; ++k) push(shared(idx[t + k], rgba));
        continue;
      }
      const auto& a = level_.vertices[idx[t]];
      const auto& b = level_.vertices[idx[t + 1]];
      const auto& c = level_.vertices[idx[t + 2]];
      Eigen::Vector3f n(0, 1, 0);
      // Skirts are lit as if they were the ground they continue (seed
      // Figure 86: the fill polygon takes the adjacent polygon's normal).
      if (!skirt) {
        const Eigen::Vector3f ab(b.x - a.x, b.y - a.y, b.z - a.z), ac(c.x - a.x, c.y - a.y, c.z - a.z);
        Eigen::Vector3f f = ab.cross(ac);
        if (f.y() < 0) f = -f;
        if (f.norm() > 0) n = f.normalized();
      }
      for (int k = 0; k < 3; ++k) {
        push(std::uint32_t(out_.size()));
        out_.push_back(vertex(idx[t + k], rgba, packNormal(n)));
      }
    }
  }

  /// Starts a quadtree node: vertices are shared only within one node, so
  /// each node's draw touches a short range of them (glDrawRangeElements;
  /// without a range, software GL transforms the whole buffer per draw).
  void beginNode(std::uint32_t node) {
    node_ = node;
    lo_ = UINT32_MAX;
    hi_ = 0;
  }
  /// Lowest and highest vertex index since beginNode (lo > hi: none).
  std::pair<std::uint32_t, std::uint32_t> nodeRange() const { return {lo_, hi_}; }

  std::size_t indexCount() const { return indices_.size(); }
  const std::vector<GpuVertex>& vertices() const { return out_; }
  const std::vector<std::uint32_t>& indices() const { return indices_; }

 private:
  GpuVertex vertex(std::uint32_t k, std::uint32_t rgba, std::uint32_t normal) const {
    const auto& v = level_.vertices[k];
    return {v.x, v.y, v.z, delta_[k], rgba, normal, v.s, v.t};
  }

  void push(std::uint32_t v) {
    indices_.push_back(v);
    lo_ = std::min(lo_, v);
    hi_ = std::max(hi_, v);
  }

  /// The copy of source vertex k in colour `rgba` in this node, made on first use.
  std::uint32_t shared(std::uint32_t k, std::uint32_t rgba) {
    if (kindOf(rgba) == SurfaceKind::tint) rgba = packColour({water(k), 0, 0}, SurfaceKind::tint);
    for (std::uint32_t c = firstCopy_[k]; c != UINT32_MAX; c = nextCopy_[c]) {
      if (out_[c].rgba == rgba && copyNode_[c] == node_) return c;
    }
    const auto c = std::uint32_t(out_.size());
    out_.push_back(vertex(k, rgba, normal_.empty() ? packNormal({0, 1, 0}) : normal_[k]));
    nextCopy_.push_back(firstCopy_[k]);
    copyNode_.push_back(node_);
    firstCopy_[k] = c;
    return c;
  }

  std::uint8_t water(std::uint32_t k) const { return water_.empty() ? 0 : water_[k]; }

  const module::Level& level_;
  const std::vector<float>& delta_;
  bool flat_;
  std::vector<std::uint32_t> normal_;
  std::vector<std::uint8_t> water_;
  std::vector<std::uint32_t> firstCopy_, nextCopy_, copyNode_;
  std::uint32_t node_ = 0, lo_ = UINT32_MAX, hi_ = 0;
  std::vector<GpuVertex> out_;
  std::vector<std::uint32_t> indices_;
};

/// Road texture texel (u across, v along, both 0..1): rgb multiplies the
/// road's colour (grain, darker shoulders), alpha is marking coverage
/// (white edge lines and a dashed centre line, SurfaceKind::marked).
std::array<std::uint8_t, 4> roadTexel(double u, double v, std::uint32_t hash) {
  const double noise = double(hash % 1000) / 1000.0;  // 0..1, per texel
  double shade = 0.90 + 0.10 * noise;
  const double edge = std::min(u, 1.0 - u);
  if (edge < 0.035) shade *= 0.70;  // worn shoulder
  double mark = 0;
  if (edge >= 0.045 && edge < 0.095) mark = 1;                    // edge line
  if (std::abs(u - 0.5) < 0.02 && v < 0.45) mark = 1;             // centre dash
  const auto byte = [](double x) { return std::uint8_t(std::lround(std::clamp(x, 0.0, 1.0) * 255.0)); };
  return {byte(shade), byte(shade), byte(shade), byte(mark * (0.85 + 0.15 * noise))};
}

}  // namespace

ModuleRenderer::~ModuleRenderer() {
  for (auto& [key, e] : cache_) glDeleteBuffers(1, &e.vbo);
  if (vao_) glDeleteVertexArrays(1, &vao_);
  if (roadTexture_) glDeleteTextures(1, &roadTexture_);
}

void ModuleRenderer::createRoadTexture() {
  constexpr int n = kRoadTextureSize;
  std::vector<std::uint8_t> texels(std::size_t(n) * n * 4);
  std::uint32_t hash = 0x9E3779B9u;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      hash = hash * 1664525u + 1013904223u;
      const auto t = roadTexel((x + 0.5) / n, (y + 0.5) / n, hash >> 8);
      std::copy(t.begin(), t.end(), texels.begin() + (std::ptrdiff_t(y) * n + x) * 4);
    }
  }
  const auto levels = GLsizei(std::log2(n)) + 1;
  glCreateTextures(GL_TEXTURE_2D, 1, &roadTexture_);
  glTextureStorage2D(roadTexture_, levels, GL_RGBA8, n, n);
  glTextureSubImage2D(roadTexture_, 0, 0, 0, n, n, GL_RGBA, GL_UNSIGNED_BYTE, texels.data());
  glGenerateTextureMipmap(roadTexture_);
  glTextureParameteri(roadTexture_, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);  // across
  glTextureParameteri(roadTexture_, GL_TEXTURE_WRAP_T, GL_REPEAT);         // along
  glTextureParameteri(roadTexture_, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTextureParameteri(roadTexture_, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  // Roads are seen at grazing angles: anisotropic filtering keeps their
  // markings from blurring into the asphalt, where the GPU does it in
  // hardware. llvmpipe filters anisotropically in software at seconds per
  // frame, so there the mipmaps alone must do.
  const std::string renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const bool software = renderer.find("llvmpipe") != std::string::npos ||
                        renderer.find("softpipe") != std::string::npos;
  if (!software && (epoxy_has_gl_extension("GL_EXT_texture_filter_anisotropic") ||
                    epoxy_has_gl_extension("GL_ARB_texture_filter_anisotropic"))) {
    GLfloat most = 1;
    glGetFloatv(GL_MAX_TEXTURE_MAX_ANISOTROPY_EXT, &most);
    glTextureParameterf(roadTexture_, GL_TEXTURE_MAX_ANISOTROPY_EXT, std::min(most, 8.0f));
  }
}

Status ModuleRenderer::create(const RenderSettings& s) {
  settings_ = s;
  auto program = GlProgram::build("module", kVertexShader, shadingGlsl() + kFragmentMain);
  if (!program) return program.problems();
  program_ = std::move(program.value());
  uOffset_ = program_.uniform("uOffset");
  uMorph_ = program_.uniform("uMorph");
  setShadingUniforms(program_, s);
  glCreateVertexArrays(1, &vao_);
  const auto attrib = [&](GLuint index, GLint size, GLenum type, GLboolean norm, GLuint offset) {
    glEnableVertexArrayAttrib(vao_, index);
    glVertexArrayAttribFormat(vao_, index, size, type, norm, offset);
    glVertexArrayAttribBinding(vao_, index, 0);
  };
  attrib(0, 3, GL_FLOAT, GL_FALSE, offsetof(GpuVertex, x));
  attrib(1, 1, GL_FLOAT, GL_FALSE, offsetof(GpuVertex, morphDelta));
  attrib(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, offsetof(GpuVertex, rgba));
  attrib(3, 4, GL_INT_2_10_10_10_REV, GL_TRUE, offsetof(GpuVertex, normal));
  attrib(4, 2, GL_FLOAT, GL_FALSE, offsetof(GpuVertex, s));
  createRoadTexture();
  return {};
}

void ModuleRenderer::upload(const ModuleDraw& d, std::uint32_t levelIndex, Entry& e) {
  const module::Level& level = d.ref.level(levelIndex);
  const ResidentModule& m = d.ref.module();
  const auto levels = std::uint32_t(m.levels.size());
  const module::Level* coarser = levelIndex + 1 < levels ? &m.levels[levelIndex + 1] : nullptr;
  // Per source vertex: how far the next level's surface lies above this
  // one's at the same (x, z). Skirt feet do not move: they hang below the
  // lowest surface of every level there, so a skirt from a morphed edge
  // down to its unmoved foot still covers any neighbour's edge.
  std::vector<float> delta(level.vertices.size(), 0.0f);
  if (coarser) {
    for (std::size_t k = 0; k < level.vertices.size(); ++k) {
      const auto& v = level.vertices[k];
      const auto yc = levelHeightAt(*coarser, v.x, v.z);
      const auto yl = levelHeightAt(level, v.x, v.z);
      const bool skirtFoot = yl && v.y < *yl - 0.01;
      if (yc && yl && !skirtFoot) delta[k] = float(*yc - *yl);
    }
  }
  const bool flat = settings_.shading == Shading::flat;
  LevelBuilder builder(level, delta, flat);
  if (!flat && settings_.grid) {
    builder.sampleGrid(*settings_.grid, settings_.waterMaterials, d.kx * moduleSize_, d.kz * moduleSize_);
  }
  const std::uint32_t side = nodesPerSide(levelIndex, levels);
  const std::size_t nodes = std::size_t(side) * side;
  const MaterialColour fallback;
  const auto colourOf = [&](const module::Group& g) {
    if (!flat && g.priority == module::kPrioritySkin && g.material == settings_.uncoveredMaterial) {
      return packColour({}, SurfaceKind::tint);
    }
    const MaterialColour& mc =
        g.material < settings_.palette.size() ? settings_.palette[g.material] : fallback;
    const Rgb rgb = !flat ? mean(mc.upper, mc.lower) : g.half == module::Half::lower ? mc.lower : mc.upper;
    const SurfaceKind kind = !mc.road ? SurfaceKind::colour : mc.markings ? SurfaceKind::marked : SurfaceKind::road;
    return packColour(rgb, kind);
  };
  e.blocks.clear();
  // Groups are sorted by priority: each priority is one run of groups,
  // emitted node by node so that any quadtree node is one index range.
  std::vector<std::vector<const module::Group*>> byNode(nodes);
  for (std::size_t g0 = 0; g0 < level.groups.size();) {
    const std::uint8_t priority = level.groups[g0].priority;
    std::size_t g1 = g0;
    for (auto& v : byNode) v.clear();
    for (; g1 < level.groups.size() && level.groups[g1].priority == priority; ++g1) {
      const module::Group& g = level.groups[g1];
      byNode[nodeOfSquare(level, g.square, nodeSquares_, side)].push_back(&g);
    }
    Block b{priority, std::vector<GLint>(nodes + 1, 0), std::vector<NodeRange>(nodes)};
    for (std::size_t n = 0; n < nodes; ++n) {
      b.start[n] = GLint(builder.indexCount());
      builder.beginNode(std::uint32_t(n));
      for (const module::Group* g : byNode[n]) {
        builder.triangles(level.indices.data() + g->firstIndex, g->indexCount, colourOf(*g),
                          g->half == module::Half::skirt);
      }
      b.range[n] = builder.nodeRange();
    }
    b.start[nodes] = GLint(builder.indexCount());
    e.blocks.push_back(std::move(b));
    g0 = g1;
  }
  // The plain lattice under culture-cut skin (docs/VIEWER.md, "Seams").
  if (needsUnderlay(level) &&
      level.vertices.size() >= std::size_t(level.squaresX + 1) * (level.squaresZ + 1)) {
    const std::uint32_t nx = level.squaresX, nz = level.squaresZ;
    std::vector<std::uint32_t> colour(2 * std::size_t(nx) * nz, packColour(fallback.upper, SurfaceKind::colour));
    std::vector<bool> seen(colour.size(), false);
    for (const module::Group& g : level.groups) {
      if (g.priority != module::kPrioritySkin || g.half == module::Half::skirt) continue;
      const std::size_t k = 2 * std::size_t(g.square) + (g.half == module::Half::lower);
      if (k < colour.size() && !seen[k]) {
        colour[k] = colourOf(g);
        seen[k] = true;
      }
    }
    const auto post = [&](std::uint32_t c, std::uint32_t r) { return std::uint32_t(r * (nx + 1) + c); };
    std::vector<std::vector<std::uint32_t>> squaresByNode(nodes);
    for (std::uint32_t q = 0; q < nx * nz; ++q) {
      squaresByNode[nodeOfSquare(level, q, nodeSquares_, side)].push_back(q);
    }
    Block b{kUnderlayPriority, std::vector<GLint>(nodes + 1, 0), std::vector<NodeRange>(nodes)};
    for (std::size_t n = 0; n < nodes; ++n) {
      b.start[n] = GLint(builder.indexCount());
      builder.beginNode(std::uint32_t(n));
      for (const std::uint32_t q : squaresByNode[n]) {
        const std::uint32_t c = q % nx, r = q / nx;
        const std::uint32_t tris[2][3] = {{post(c, r), post(c, r + 1), post(c + 1, r)},
                                          {post(c + 1, r), post(c, r + 1), post(c + 1, r + 1)}};
        // Flat: lit straight down, as the seed's pinhole filler was.
        for (int h = 0; h < 2; ++h) builder.triangles(tris[h], 3, colour[2 * std::size_t(q) + h], true);
      }
      b.range[n] = builder.nodeRange();
    }
    b.start[nodes] = GLint(builder.indexCount());
    e.blocks.push_back(std::move(b));
  }
  const auto& vertices = builder.vertices();
  const auto& indices = builder.indices();
  if (e.vbo) glDeleteBuffers(1, &e.vbo);
  glCreateBuffers(1, &e.vbo);
  gpuBytes_ -= e.bytes;
  e.indexOffset = vertices.size() * sizeof(GpuVertex);  // a multiple of 4, as indices need
  e.bytes = e.indexOffset + indices.size() * sizeof(std::uint32_t);
  gpuBytes_ += e.bytes;
  glNamedBufferStorage(e.vbo, GLsizeiptr(std::max<std::uint64_t>(e.bytes, 1)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  if (!vertices.empty()) glNamedBufferSubData(e.vbo, 0, GLsizeiptr(e.indexOffset), vertices.data());
  if (!indices.empty()) {
    glNamedBufferSubData(e.vbo, GLintptr(e.indexOffset), GLsizeiptr(indices.size() * sizeof(std::uint32_t)),
                         indices.data());
  }
  e.generation = d.ref.generation();
}


ModuleRenderer::Entry& ModuleRenderer::entryFor(const ModuleDraw& d, std::uint32_t level,
                                                std::uint64_t frame, RenderStats& stats) {
  Entry& e = cache_[cacheKey(d.kx, d.kz, level)];
  // A new generation is a different module in the pager's slot (or the
  // same one read again): the old copy is stale.
  if (!e.vbo || e.generation != d.ref.generation()) {
    upload(d, level, e);
    ++stats.uploads;
  }
  e.lastFrame = frame;
  return e;
}

void ModuleRenderer::release(RenderStats& stats, const DisplayBuffer& buf) {
  const ModuleRect& w = buf.pagerWindow;
  for (auto it = cache_.begin(); it != cache_.end();) {
    const auto kx = std::int64_t(it->first & 0xFFFFF), kz = std::int64_t((it->first >> 20) & 0xFFFFF);
    const bool freed = !w.empty() && !w.contains(kx, kz);
    if (freed || it->second.lastFrame + kKeepUnusedFrames < buf.frame) {
      glDeleteBuffers(1, &it->second.vbo);
      gpuBytes_ -= it->second.bytes;
      it = cache_.erase(it);
      ++stats.released;
    } else {
      ++it;
    }
  }
}

void ModuleRenderer::drawPriority(const DisplayBuffer& buf, std::uint8_t lo, std::uint8_t hi,
                                  const std::vector<Entry*>& entries) {
  std::uint32_t bound = UINT32_MAX;
  for (std::size_t k = 0; k < buf.nodes.size(); ++k) {
    const NodeDraw& nd = buf.nodes[k];
    const Entry& e = *entries[k];
    for (const Block& b : e.blocks) {
      if (b.priority < lo || b.priority > hi) continue;
      const std::size_t n = b.start.size() - 1;
      const GLint first = b.start[std::min<std::size_t>(nd.first, n)];
      const GLint last = b.start[std::min<std::size_t>(nd.last, n)];
      if (last <= first) continue;
      if (bound != k) {
        const ModuleDraw& d = buf.modules[nd.module];
        glVertexArrayVertexBuffer(vao_, 0, e.vbo, 0, sizeof(GpuVertex));
        glVertexArrayElementBuffer(vao_, e.vbo);
        const float ox = float(d.kx * buf.moduleSize - buf.originX);
        const float oz = float(d.kz * buf.moduleSize - buf.originZ);
        glUniform3f(uOffset_, ox, 0.0f, oz);
        glUniform1f(uMorph_, nd.morph);
        bound = std::uint32_t(k);
      }
      std::uint32_t lowest = UINT32_MAX, highest = 0;  // vertex range of the draw
      for (std::size_t m = std::min<std::size_t>(nd.first, n); m < std::min<std::size_t>(nd.last, n); ++m) {
        lowest = std::min(lowest, b.range[m].first);
        highest = std::max(highest, b.range[m].second);
      }
      const std::uint64_t offset = e.indexOffset + std::uint64_t(first) * sizeof(std::uint32_t);
      glDrawRangeElements(GL_TRIANGLES, lowest, highest, last - first, GL_UNSIGNED_INT,
                          reinterpret_cast<const void*>(offset));
    }
  }
}

void ModuleRenderer::prepare(const DisplayBuffer& buf, RenderStats& stats) {
  const auto t0 = std::chrono::steady_clock::now();
  nodeSquares_ = buf.nodeSquares;
  moduleSize_ = buf.moduleSize;
  entries_.clear();
  entries_.reserve(buf.nodes.size());
  for (const NodeDraw& nd : buf.nodes) {
    entries_.push_back(&entryFor(buf.modules[nd.module], nd.level, buf.frame, stats));
  }
  stats.uploadMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void ModuleRenderer::drawTerrain(const DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection) {
  program_.use();
  glBindVertexArray(vao_);
  glBindTextureUnit(0, roadTexture_);
  program_.setMatrix4("uViewProjection", viewProjection.data());
  setFrameShading(program_, buf);
  // Skirts hang as vertical walls that may face either way: no culling.
  glDisable(GL_CULL_FACE);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
  drawPriority(buf, module::kPrioritySkin, module::kPrioritySkin, entries_);
  // The plain lattice under culture-cut skin, pushed away from the eye, so
  // it shows only through pinholes where cut triangles meet at T-junctions.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(-1.0f, -4.0f);
  drawPriority(buf, kUnderlayPriority, kUnderlayPriority, entries_);
}

void ModuleRenderer::drawDecals(const DisplayBuffer& buf) {
  // The terrain pass left this program, its buffers and uniforms bound.
  std::vector<std::uint8_t> priorities;
  for (const Entry* e : entries_) {
    for (const Block& b : e->blocks) {
      if (b.priority > module::kPrioritySkin && b.priority < module::kPriorityObject) {
        priorities.push_back(b.priority);
      }
    }
  }
  std::sort(priorities.begin(), priorities.end());
  priorities.erase(std::unique(priorities.begin(), priorities.end()), priorities.end());
  glEnable(GL_POLYGON_OFFSET_FILL);
  glDepthMask(GL_FALSE);
  glDepthFunc(GL_GEQUAL);
  for (const std::uint8_t p : priorities) {
    // Reversed Z: a positive offset moves towards the eye.
    glPolygonOffset(1.0f, float(p));
    drawPriority(buf, p, p, entries_);
  }
  glDisable(GL_POLYGON_OFFSET_FILL);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
  drawPriority(buf, module::kPriorityObject, kUnderlayPriority - 1, entries_);
}

void ModuleRenderer::finishFrame(const DisplayBuffer& buf, RenderStats& stats) {
  entries_.clear();
  release(stats, buf);
  stats.cachedLevels = std::uint32_t(cache_.size());
  stats.gpuBytes = gpuBytes_;
}

}  // namespace sandtable::runtime::detail
