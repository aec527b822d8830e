// The module renderer's GL side: its programs and vertex layout, the
// per-frame command lists (written into a fenced ring of mapped buffers),
// the terrain and decal passes, and the plain-grid benchmark draw.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>

#include "module_draw.h"
#include "sandtable/scene/camera_math.h"
#include "sandtable/scene/lod.h"
#include "terrain_shading.h"

namespace sandtable::render::detail {
namespace {

// Appended to detail::shadingVertexGlsl().
const char* kVertexMain = R"(
layout(location = 0) in vec3 aPosition;
layout(location = 1) in float aMorphDelta;
layout(location = 2) in vec4 aColour;
layout(location = 3) in vec4 aNormal;
layout(location = 4) in vec2 aTexCoord;
// Per draw (divisor 1, the command's baseInstance): module offset x, z
// from the buffer origin, and the node's morph factor.
layout(location = 5) in vec4 aDraw;
uniform mat4 uViewProjection;
uniform vec3 uEye;
out vec4 vColour;
out vec3 vTint;
out float vLight;
out float vFog;
out float vHeight;
out vec2 vTexCoord;
void main() {
  vec3 p = aPosition + vec3(aDraw.x, 0.0, aDraw.y);
  p.y += aDraw.z * aMorphDelta;
  gl_Position = uViewProjection * vec4(p, 1.0);
  vColour = aColour;
  vTint = elevationTint(p.y);
  vLight = sunLight(aNormal.xyz);
  vFog = fogWeight(distance(p, uEye));
  vHeight = p.y;
  vTexCoord = aTexCoord;
}
)";

// Appended to detail::shadingFragmentGlsl(). The kind is the same at all
// three corners of a triangle, so its interpolated value is exact.
const char* kFragmentMain = R"(
in vec4 vColour;
in vec3 vTint;
in float vLight;
in float vFog;
in float vHeight;
in vec2 vTexCoord;
out vec4 fragColor;
void main() {
  int kind = int(vColour.a * 3.0 + 0.5);
  fragColor = shadeSurface(kind, vColour.rgb, vTexCoord, vHeight, vTint, vLight, vFog);
}
)";

/// Command list of a block priority (ModuleRenderer::lists_).
std::size_t listOf(std::uint8_t priority) {
  if (priority == module::kPrioritySkin) return 0;
  if (priority >= 254) return 1;  // skirts, underlay
  if (priority < module::kPriorityObject) return 2 + priority;
  return 101;
}

}  // namespace

ModuleRenderer::~ModuleRenderer() {
  for (GLsync& f : ringFence_) {
    if (f) glDeleteSync(f);
  }
  if (commandBuffer_) {
    glUnmapNamedBuffer(commandBuffer_);
    glDeleteBuffers(1, &commandBuffer_);
  }
  if (drawBuffer_) {
    glUnmapNamedBuffer(drawBuffer_);
    glDeleteBuffers(1, &drawBuffer_);
  }
  if (vao_) glDeleteVertexArrays(1, &vao_);
  if (roadTexture_) glDeleteTextures(1, &roadTexture_);
}

Status ModuleRenderer::create(const RenderSettings& s) {
  settings_ = s;
  for (const bool roads : {true, false}) {
    auto program = GlProgram::build(roads ? "module" : "module (no roads)", shadingVertexGlsl() + kVertexMain,
                                    shadingFragmentGlsl(roads) + kFragmentMain);
    if (!program) return program.problems();
    GlProgram& p = roads ? program_ : plainProgram_;
    p = std::move(program.value());
    setShadingUniforms(p, s);
  }
  glCreateVertexArrays(1, &vao_);
  const auto attrib = [&](GLuint index, GLint size, GLenum type, GLboolean norm, GLuint offset, GLuint binding) {
    glEnableVertexArrayAttrib(vao_, index);
    glVertexArrayAttribFormat(vao_, index, size, type, norm, offset);
    glVertexArrayAttribBinding(vao_, index, binding);
  };
  attrib(0, 3, GL_FLOAT, GL_FALSE, offsetof(GpuVertex, x), 0);
  attrib(1, 1, GL_FLOAT, GL_FALSE, offsetof(GpuVertex, morphDelta), 0);
  attrib(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, offsetof(GpuVertex, rgba), 0);
  attrib(3, 4, GL_INT_2_10_10_10_REV, GL_TRUE, offsetof(GpuVertex, normal), 0);
  attrib(4, 2, GL_FLOAT, GL_FALSE, offsetof(GpuVertex, s), 0);
  attrib(5, 4, GL_FLOAT, GL_FALSE, 0, 1);
  glVertexArrayBindingDivisor(vao_, 1, 1);
  createRoadTexture();
  arena_.allocate(0);  // maps the arena now, not in the first frame
  arena_.release(0, GpuArena::kUnit);
  ensureRing(1024, 256);
  return {};
}

void ModuleRenderer::ensureRing(std::uint64_t commands, std::uint64_t draws) {
  if (commands <= ringCommands_ && draws <= ringDraws_) return;
  // The old rings may still be read by frames in flight: wait for them
  // (rare: only when a frame needs more room than any before).
  for (GLsync& f : ringFence_) {
    if (!f) continue;
    while (glClientWaitSync(f, GL_SYNC_FLUSH_COMMANDS_BIT, 1'000'000'000) == GL_TIMEOUT_EXPIRED) {
    }
    glDeleteSync(f);
    f = nullptr;
  }
  constexpr GLbitfield flags = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  const auto make = [&](GLuint& buffer, std::uint64_t bytes) -> void* {
    if (buffer) {
      glUnmapNamedBuffer(buffer);
      glDeleteBuffers(1, &buffer);
    }
    glCreateBuffers(1, &buffer);
    glNamedBufferStorage(buffer, GLsizeiptr(bytes), nullptr, flags);
    return glMapNamedBufferRange(buffer, 0, GLsizeiptr(bytes), flags);
  };
  ringCommands_ = std::max<std::uint64_t>(2 * ringCommands_, commands);
  ringDraws_ = std::max<std::uint64_t>(2 * ringDraws_, draws);
  commandMap_ = static_cast<Command*>(make(commandBuffer_, kRing * ringCommands_ * sizeof(Command)));
  drawMap_ = static_cast<DrawData*>(make(drawBuffer_, kRing * ringDraws_ * sizeof(DrawData)));
}

void ModuleRenderer::appendSkirts(const Drawn& dr, const Block& b, GLuint firstIndex, GLint baseVertex,
                                  GLuint instance) {
  auto& list = lists_[listOf(b.priority)];
  const std::size_t ranges = b.start.size() - 1;
  bool open = false;  // the last command can still grow
  for (std::uint32_t node = dr.first; node < dr.last; ++node) {
    for (std::uint32_t side = 0; side < 4; ++side) {
      const std::size_t r = std::size_t(node) * 4 + side;
      if (r >= ranges) return;
      const std::uint32_t first = b.start[r], last = b.start[r + 1];
      if (last <= first) continue;
      if (!skirtNeeded(dr, node, side)) {
        open = false;
        continue;
      }
      if (open && list.back().firstIndex + list.back().count == firstIndex + first) {
        list.back().count += last - first;
      } else {
        list.push_back({last - first, 1, firstIndex + first, baseVertex, instance});
      }
      open = true;
    }
  }
  if (b.roads) roadLists_.set(listOf(b.priority));
}


void ModuleRenderer::buildCommands(const scene::DisplayBuffer& buf) {
  for (auto& l : lists_) l.clear();
  drawData_.clear();
  framePriorities_.reset();
  roadLists_.reset();
  for (const Drawn& dr : drawn_) {
    const scene::ModuleDraw& d = buf.modules[dr.module];
    const auto instance = GLuint(drawData_.size());
    drawData_.push_back({float(d.kx * buf.moduleSize - buf.originX), float(d.kz * buf.moduleSize - buf.originZ),
                         dr.morph, 0.0f});
    const Entry& e = *dr.entry;
    framePriorities_ |= e.priorities;
    const auto baseVertex = GLint(e.vertexOffset / sizeof(GpuVertex));
    const auto firstIndex = GLuint(e.indexOffset / sizeof(std::uint32_t));
    for (const Block& b : e.blocks) {
      if (b.sides) {
        appendSkirts(dr, b, firstIndex, baseVertex, instance);
        continue;
      }
      const std::size_t n = b.start.size() - 1;
      const std::uint32_t first = b.start[std::min<std::size_t>(dr.first, n)];
      const std::uint32_t last = b.start[std::min<std::size_t>(dr.last, n)];
      if (last <= first) continue;
      const std::size_t list = listOf(b.priority);
      lists_[list].push_back({last - first, 1, firstIndex + first, baseVertex, instance});
      if (b.roads) roadLists_.set(list);
    }
  }
  std::uint64_t total = 0;
  for (const auto& l : lists_) total += l.size();
  ensureRing(std::max<std::uint64_t>(total, 1), std::max<std::size_t>(drawData_.size(), 1));
  // This slice was last used kRing frames ago: wait until the GPU is done with it.
  if (GLsync& f = ringFence_[ringSlot_]) {
    while (glClientWaitSync(f, GL_SYNC_FLUSH_COMMANDS_BIT, 1'000'000'000) == GL_TIMEOUT_EXPIRED) {
    }
    glDeleteSync(f);
    f = nullptr;
  }
  Command* commands = commandMap_ + std::uint64_t(ringSlot_) * ringCommands_;
  std::uint64_t at = 0;
  for (std::size_t k = 0; k < kLists; ++k) {
    listOffset_[k] = (std::uint64_t(ringSlot_) * ringCommands_ + at) * sizeof(Command);
    if (!lists_[k].empty()) std::memcpy(commands + at, lists_[k].data(), lists_[k].size() * sizeof(Command));
    at += lists_[k].size();
  }
  if (!drawData_.empty()) {
    std::memcpy(drawMap_ + std::uint64_t(ringSlot_) * ringDraws_, drawData_.data(),
                drawData_.size() * sizeof(DrawData));
  }
}

void ModuleRenderer::bindArena() {
  glVertexArrayVertexBuffer(vao_, 0, arena_.buffer(), 0, sizeof(GpuVertex));
  glVertexArrayElementBuffer(vao_, arena_.buffer());
  glVertexArrayVertexBuffer(vao_, 1, drawBuffer_, GLintptr(std::uint64_t(ringSlot_) * ringDraws_ * sizeof(DrawData)),
                            sizeof(DrawData));
  glBindBuffer(GL_DRAW_INDIRECT_BUFFER, commandBuffer_);
}

void ModuleRenderer::multiDraw(std::size_t list, RenderStats& stats) {
  const auto& l = lists_[list];
  if (l.empty()) return;
  const GlProgram* p = roadLists_[list] ? &program_ : &plainProgram_;
  if (p != used_) {
    p->use();
    used_ = p;
  }
  glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, reinterpret_cast<const void*>(listOffset_[list]),
                              GLsizei(l.size()), 0);
  ++stats.drawCalls;
  stats.draws += std::uint32_t(l.size());
  for (const Command& c : l) stats.trianglesDrawn += c.count / 3;
}

void ModuleRenderer::drawTerrain(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection,
                                 RenderStats& stats) {
  for (GlProgram* p : {&program_, &plainProgram_}) {
    p->setMatrix4("uViewProjection", viewProjection.data());
    setFrameShading(*p, buf);
  }
  used_ = nullptr;
  glBindVertexArray(vao_);
  bindArena();
  glBindTextureUnit(0, roadTexture_);
  // Ground faces up and skirts face out of their node (module_draw.h):
  // back faces are never the nearest surface that matters.
  glEnable(GL_CULL_FACE);
  glCullFace(GL_BACK);
  glFrontFace(GL_CCW);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
  multiDraw(0, stats);
  // Skirts and the plain lattice under culture-cut skin, pushed away from
  // the eye, so they show only through cracks and pinholes, never through
  // the skin in front of them.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(-1.0f, -4.0f);
  multiDraw(1, stats);
  glDisable(GL_POLYGON_OFFSET_FILL);
}

void ModuleRenderer::drawDecals(const scene::DisplayBuffer&, RenderStats& stats) {
  // The terrain pass left this program, its buffers and uniforms bound.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glDepthMask(GL_FALSE);
  glDepthFunc(GL_GEQUAL);
  for (std::uint32_t p = module::kPrioritySkin + 1; p < module::kPriorityObject; ++p) {
    if (!framePriorities_[p]) continue;
    // Reversed Z: a positive offset moves towards the eye.
    glPolygonOffset(1.0f, float(p));
    multiDraw(2 + p, stats);
  }
  glDisable(GL_POLYGON_OFFSET_FILL);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
  // Objects keep their own winding: both faces. Height frames hold the
  // terrain's height, so buildings are left out of them.
  if (settings_.colour == ColourMode::height) return;
  glDisable(GL_CULL_FACE);
  multiDraw(101, stats);
}

void ModuleRenderer::finishFrame(const scene::DisplayBuffer& buf, RenderStats& stats) {
  GLsync& f = ringFence_[ringSlot_];
  if (f) glDeleteSync(f);
  f = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  ringSlot_ = (ringSlot_ + 1) % kRing;
  drawn_.clear();
  release(stats, buf);
  arena_.endFrame();
  stats.cachedLevels = std::uint32_t(cache_.size());
  stats.gpuBytes = gpuBytes_;
}

PlainGridRun ModuleRenderer::drawPlainGrid(const scene::Camera& camera, std::uint32_t squares, double spacing,
                                           std::uint32_t nodeSquares, std::uint32_t frames,
                                           const std::function<void()>& beginFrame) {
  PlainGridRun run;
  squares = std::max<std::uint32_t>(squares / std::max<std::uint32_t>(nodeSquares, 1), 1) * nodeSquares;
  const std::uint32_t posts = squares + 1, side = squares / nodeSquares;
  // Gentle hills, so that fill and depth behave like ground: one vertex
  // per post, the grid centred under the eye, lit by its own normals.
  const double half = 0.5 * squares * spacing, amplitude = 40.0;
  const auto height = [&](double x, double z) {
    return amplitude * std::sin(x / 700.0) * std::cos(z / 900.0);
  };
  std::vector<GpuVertex> vertices;
  vertices.reserve(std::size_t(posts) * posts);
  for (std::uint32_t r = 0; r < posts; ++r) {
    for (std::uint32_t c = 0; c < posts; ++c) {
      const double x = c * spacing - half, z = r * spacing - half;
      const double dx = amplitude / 700.0 * std::cos(x / 700.0) * std::cos(z / 900.0);
      const double dz = -amplitude / 900.0 * std::sin(x / 700.0) * std::sin(z / 900.0);
      const Eigen::Vector3f n = Eigen::Vector3f(float(-dx), 1.0f, float(-dz)).normalized();
      vertices.push_back({float(x), float(height(x, z)), float(z), 0.0f, packColour({}, SurfaceKind::tint),
                          packNormal(n), 0.0f, 0.0f});
    }
  }
  // Nodes in Morton order, two counter-clockwise triangles a square, as
  // the modules' skin.
  std::vector<std::uint32_t> indices, start(std::size_t(side) * side + 1, 0);
  indices.reserve(std::size_t(squares) * squares * 6);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> order;
  for (std::uint32_t b = 0; b < side; ++b) {
    for (std::uint32_t a = 0; a < side; ++a) order.push_back({scene::mortonIndex(a, b), a + b * side});
  }
  std::sort(order.begin(), order.end());
  for (std::size_t k = 0; k < order.size(); ++k) {
    start[k] = std::uint32_t(indices.size());
    const std::uint32_t a = order[k].second % side, b = order[k].second / side;
    for (std::uint32_t r = b * nodeSquares; r < (b + 1) * nodeSquares; ++r) {
      for (std::uint32_t c = a * nodeSquares; c < (a + 1) * nodeSquares; ++c) {
        const std::uint32_t nw = r * posts + c, ne = nw + 1, sw = nw + posts, se = sw + 1;
        indices.insert(indices.end(), {nw, sw, ne, ne, sw, se});
      }
    }
  }
  start.back() = std::uint32_t(indices.size());
  Entry e;
  storeEntry(e, vertices, indices);
  e.blocks.push_back({module::kPrioritySkin, start});
  e.priorities.set(module::kPrioritySkin);
  run.triangles = indices.size() / 3;

  scene::DisplayBuffer buf;
  buf.camera = camera;
  buf.camera.y = camera.y + height(0, 0);
  buf.originX = camera.x;
  buf.originZ = camera.z;
  buf.moduleSize = 0;
  buf.modules.resize(1);
  // Unqualified: camera_math.h's projection, whichever namespace holds it.
  const Eigen::Matrix4f vp = scene::viewProjection(buf.camera, buf.originX, buf.originZ).cast<float>();
  const auto nodes = std::uint32_t(order.size());
  drawn_.clear();
  // One draw per node, as a module drawn at full LoD.
  for (std::uint32_t n = 0; n < nodes; ++n) drawn_.push_back({&e, 0, n, n + 1, 0.0f, 0});
  for (std::uint32_t f = 0; f < frames; ++f) {
    beginFrame();
    const auto t0 = std::chrono::steady_clock::now();
    RenderStats stats;
    buildCommands(buf);
    drawTerrain(buf, vp, stats);
    glFinish();
    run.frameMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    run.draws = stats.draws;
    GLsync& fence = ringFence_[ringSlot_];
    if (fence) glDeleteSync(fence);
    fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
    ringSlot_ = (ringSlot_ + 1) % kRing;
  }
  drawn_.clear();
  freeEntry(e);
  arena_.endFrame();
  return run;
}

}  // namespace sandtable::render::detail
