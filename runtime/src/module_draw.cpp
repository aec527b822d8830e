#include "module_draw.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>

#include "camera_math.h"
#include "sandtable/runtime/lod.h"

namespace sandtable::runtime::detail {
namespace {

/// Frames a GPU copy may go unused (e.g. turned away) before it is released.
constexpr std::uint64_t kKeepUnusedFrames = 90;

const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in float aMorphDelta;
layout(location = 2) in vec4 aColour;
layout(location = 3) in vec4 aNormal;
uniform mat4 uViewProjection;
uniform vec3 uOffset;
uniform float uMorph;
uniform vec3 uEye;
out vec3 vColour;
out vec3 vNormal;
out float vDistance;
void main() {
  vec3 p = aPosition + uOffset;
  p.y += uMorph * aMorphDelta;
  gl_Position = uViewProjection * vec4(p, 1.0);
  vColour = aColour.rgb;
  vNormal = aNormal.xyz;
  vDistance = distance(p, uEye);
}
)";

const char* kFragmentShader = R"(#version 450 core
in vec3 vColour;
in vec3 vNormal;
in float vDistance;
uniform vec3 uSun;
uniform vec3 uFogColor;
uniform float uFogDensity;
uniform float uFogStart;
uniform bool uFog;
out vec4 fragColor;
void main() {
  vec3 n = normalize(vNormal);
  vec3 color = vColour * (0.45 + 0.55 * max(dot(n, uSun), 0.0));
  if (uFog) {
    float k = uFogDensity * max(vDistance - uFogStart, 0.0);
    color = mix(uFogColor, color, exp(-k * k));
  }
  fragColor = vec4(color, 1.0);
}
)";

std::uint64_t cacheKey(std::uint32_t kx, std::uint32_t kz, std::uint32_t level) {
  return std::uint64_t(kx) | (std::uint64_t(kz) << 20) | (std::uint64_t(level) << 40);
}

std::uint32_t packRgb(Rgb c) { return c.r | (c.g << 8) | (c.b << 16) | (0xFFu << 24); }

std::uint32_t packNormal(const Eigen::Vector3f& n) {
  const auto q = [](float v) {
    return std::uint32_t(std::int32_t(std::lround(std::clamp(v, -1.0f, 1.0f) * 511.0f)) & 0x3FF);
  };
  return q(n.x()) | (q(n.y()) << 10) | (q(n.z()) << 20);
}

}  // namespace

ModuleRenderer::~ModuleRenderer() {
  for (auto& [key, e] : cache_) glDeleteBuffers(1, &e.vbo);
  if (program_) glDeleteProgram(program_);
  if (vao_) glDeleteVertexArrays(1, &vao_);
}

std::string ModuleRenderer::create(const RenderSettings& s, const Eigen::Vector3f& sun) {
  settings_ = s;
  std::string error;
  program_ = linkProgram(kVertexShader, kFragmentShader, error);
  if (!program_) return "module " + error;
  uViewProjection_ = glGetUniformLocation(program_, "uViewProjection");
  uOffset_ = glGetUniformLocation(program_, "uOffset");
  uMorph_ = glGetUniformLocation(program_, "uMorph");
  uEye_ = glGetUniformLocation(program_, "uEye");
  uFogDensity_ = glGetUniformLocation(program_, "uFogDensity");
  uFogStart_ = glGetUniformLocation(program_, "uFogStart");
  const Eigen::Vector3f fog(s.background.r / 255.0f, s.background.g / 255.0f, s.background.b / 255.0f);
  glProgramUniform3fv(program_, glGetUniformLocation(program_, "uSun"), 1, sun.data());
  glProgramUniform3fv(program_, glGetUniformLocation(program_, "uFogColor"), 1, fog.data());
  glProgramUniform1i(program_, glGetUniformLocation(program_, "uFog"), s.fog);
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
  return {};
}

namespace {

/// Appends the triangles of one group as de-indexed vertices.
void appendGroup(const module::Level& level, const module::Group& g, std::uint32_t rgba,
                 const std::vector<float>& delta, std::vector<GpuVertex>& out) {
  for (std::uint32_t t = 0; t + 2 < g.indexCount; t += 3) {
    const std::uint32_t* idx = level.indices.data() + g.firstIndex + t;
    const auto& a = level.vertices[idx[0]];
    const auto& b = level.vertices[idx[1]];
    const auto& c = level.vertices[idx[2]];
    Eigen::Vector3f n(0, 1, 0);
    // Skirts are lit as if they were the ground they continue (seed
    // Figure 86: the fill polygon takes the adjacent polygon's normal).
    if (g.half != module::Half::skirt) {
      const Eigen::Vector3f ab(b.x - a.x, b.y - a.y, b.z - a.z), ac(c.x - a.x, c.y - a.y, c.z - a.z);
      Eigen::Vector3f f = ab.cross(ac);
      if (f.y() < 0) f = -f;
      if (f.norm() > 0) n = f.normalized();
    }
    const std::uint32_t pn = packNormal(n);
    for (int k = 0; k < 3; ++k) {
      const auto& v = level.vertices[idx[k]];
      out.push_back({v.x, v.y, v.z, delta[idx[k]], rgba, pn});
    }
  }
}

}  // namespace

void ModuleRenderer::upload(const ModuleDraw& d, std::uint32_t levelIndex, std::uint32_t nodeSquares,
                            Entry& e) {
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
  const std::uint32_t side = nodesPerSide(levelIndex, levels);
  const std::size_t nodes = std::size_t(side) * side;
  const MaterialColour fallback;
  const auto colourOf = [&](const module::Group& g) {
    const MaterialColour& mc =
        g.material < settings_.palette.size() ? settings_.palette[g.material] : fallback;
    return packRgb(g.half == module::Half::lower ? mc.lower : mc.upper);
  };
  std::vector<GpuVertex> out;
  out.reserve(level.indices.size() + (needsUnderlay(level) ? 6ull * level.squaresX * level.squaresZ : 0));
  e.blocks.clear();
  // Groups are sorted by priority: each priority is one run of groups,
  // emitted node by node so that any quadtree node is one vertex range.
  std::vector<std::vector<const module::Group*>> byNode(nodes);
  for (std::size_t g0 = 0; g0 < level.groups.size();) {
    const std::uint8_t priority = level.groups[g0].priority;
    std::size_t g1 = g0;
    for (auto& v : byNode) v.clear();
    for (; g1 < level.groups.size() && level.groups[g1].priority == priority; ++g1) {
      const module::Group& g = level.groups[g1];
      byNode[nodeOfSquare(level, g.square, nodeSquares, side)].push_back(&g);
    }
    Block b{priority, std::vector<GLint>(nodes + 1, 0)};
    for (std::size_t n = 0; n < nodes; ++n) {
      b.start[n] = GLint(out.size());
      for (const module::Group* g : byNode[n]) appendGroup(level, *g, colourOf(*g), delta, out);
    }
    b.start[nodes] = GLint(out.size());
    e.blocks.push_back(std::move(b));
    g0 = g1;
  }
  // The plain lattice under culture-cut skin (docs/VIEWER.md, "Seams").
  if (needsUnderlay(level) &&
      level.vertices.size() >= std::size_t(level.squaresX + 1) * (level.squaresZ + 1)) {
    const std::uint32_t nx = level.squaresX, nz = level.squaresZ;
    std::vector<std::uint32_t> colour(2 * std::size_t(nx) * nz, packRgb(fallback.upper));
    std::vector<bool> seen(colour.size(), false);
    for (const module::Group& g : level.groups) {
      if (g.priority != module::kPrioritySkin || g.half == module::Half::skirt) continue;
      const std::size_t k = 2 * std::size_t(g.square) + (g.half == module::Half::lower);
      if (k < colour.size() && !seen[k]) {
        colour[k] = colourOf(g);
        seen[k] = true;
      }
    }
    const auto post = [&](std::uint32_t c, std::uint32_t r) { return std::size_t(r) * (nx + 1) + c; };
    const std::uint32_t up = packNormal({0, 1, 0});
    std::vector<std::vector<std::uint32_t>> squaresByNode(nodes);
    for (std::uint32_t q = 0; q < nx * nz; ++q) {
      squaresByNode[nodeOfSquare(level, q, nodeSquares, side)].push_back(q);
    }
    Block b{kUnderlayPriority, std::vector<GLint>(nodes + 1, 0)};
    for (std::size_t n = 0; n < nodes; ++n) {
      b.start[n] = GLint(out.size());
      for (const std::uint32_t q : squaresByNode[n]) {
        const std::uint32_t c = q % nx, r = q / nx;
        const std::size_t tris[2][3] = {{post(c, r), post(c, r + 1), post(c + 1, r)},
                                        {post(c + 1, r), post(c, r + 1), post(c + 1, r + 1)}};
        for (int h = 0; h < 2; ++h) {
          for (const std::size_t v : tris[h]) {
            const auto& p = level.vertices[v];
            out.push_back({p.x, p.y, p.z, delta[v], colour[2 * std::size_t(q) + h], up});
          }
        }
      }
    }
    b.start[nodes] = GLint(out.size());
    e.blocks.push_back(std::move(b));
  }
  if (e.vbo) glDeleteBuffers(1, &e.vbo);
  glCreateBuffers(1, &e.vbo);
  gpuBytes_ -= e.bytes;
  e.bytes = out.size() * sizeof(GpuVertex);
  gpuBytes_ += e.bytes;
  glNamedBufferStorage(e.vbo, GLsizeiptr(std::max<std::uint64_t>(e.bytes, 1)),
                       out.empty() ? nullptr : out.data(), 0);
  e.generation = d.ref.generation();
}

ModuleRenderer::Entry& ModuleRenderer::entryFor(const ModuleDraw& d, std::uint32_t level,
                                                std::uint64_t frame, RenderStats& stats) {
  Entry& e = cache_[cacheKey(d.kx, d.kz, level)];
  // A new generation is a different module in the pager's slot (or the
  // same one read again): the old copy is stale.
  if (!e.vbo || e.generation != d.ref.generation()) {
    upload(d, level, nodeSquares_, e);
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
        const float ox = float(d.kx * buf.moduleSize - buf.originX);
        const float oz = float(d.kz * buf.moduleSize - buf.originZ);
        glUniform3f(uOffset_, ox, 0.0f, oz);
        glUniform1f(uMorph_, nd.morph);
        bound = std::uint32_t(k);
      }
      glDrawArrays(GL_TRIANGLES, first, last - first);
    }
  }
}

void ModuleRenderer::draw(const DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection,
                          RenderStats& stats) {
  const auto t0 = std::chrono::steady_clock::now();
  nodeSquares_ = buf.nodeSquares;
  std::vector<Entry*> entries;
  entries.reserve(buf.nodes.size());
  for (const NodeDraw& nd : buf.nodes) {
    entries.push_back(&entryFor(buf.modules[nd.module], nd.level, buf.frame, stats));
  }
  stats.uploadMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  const Camera& cam = buf.camera;
  glUseProgram(program_);
  glBindVertexArray(vao_);
  glUniformMatrix4fv(uViewProjection_, 1, GL_FALSE, viewProjection.data());
  glUniform3f(uEye_, float(cam.x - buf.originX), float(cam.y), float(cam.z - buf.originZ));
  glUniform1f(uFogDensity_, float(fogDensityFor(cam.viewDistance)));
  glUniform1f(uFogStart_, float(kFogClearFraction * cam.viewDistance));
  // Skirts hang as vertical walls that may face either way: no culling.
  glDisable(GL_CULL_FACE);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
  drawPriority(buf, module::kPrioritySkin, module::kPrioritySkin, entries);
  // The plain lattice under culture-cut skin, pushed away from the eye, so
  // it shows only through pinholes where cut triangles meet at T-junctions.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(-1.0f, -4.0f);
  drawPriority(buf, kUnderlayPriority, kUnderlayPriority, entries);

  std::vector<std::uint8_t> priorities;
  for (const Entry* e : entries) {
    for (const Block& b : e->blocks) {
      if (b.priority > module::kPrioritySkin && b.priority < module::kPriorityObject) {
        priorities.push_back(b.priority);
      }
    }
  }
  std::sort(priorities.begin(), priorities.end());
  priorities.erase(std::unique(priorities.begin(), priorities.end()), priorities.end());
  glDepthMask(GL_FALSE);
  glDepthFunc(GL_GEQUAL);
  for (const std::uint8_t p : priorities) {
    // Reversed Z: a positive offset moves towards the eye.
    glPolygonOffset(1.0f, float(p));
    drawPriority(buf, p, p, entries);
  }
  glDisable(GL_POLYGON_OFFSET_FILL);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
  drawPriority(buf, module::kPriorityObject, kUnderlayPriority - 1, entries);

  release(stats, buf);
  stats.cachedLevels = std::uint32_t(cache_.size());
  stats.gpuBytes = gpuBytes_;
}

}  // namespace sandtable::runtime::detail
