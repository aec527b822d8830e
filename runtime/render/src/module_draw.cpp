#include "module_draw.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <optional>

#include "sandtable/scene/camera_math.h"
#include "sandtable/formats/terrain_rule.h"
#include "terrain_shading.h"
#include "sandtable/scene/lod.h"

namespace sandtable::runtime::detail {
namespace {

/// Frames a GPU copy may go unused (e.g. turned away) before it is released.
constexpr std::uint64_t kKeepUnusedFrames = 90;
/// A lattice post and a skin vertex are the same point within this, metres.
constexpr double kPostTolerance = 1e-3;
/// The arena's first size; it doubles when full.
constexpr std::uint64_t kArenaInitialBytes = 8ull << 20;

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

/// Road texture: T across (u), S along (v), one repeat per road width.
constexpr int kRoadTextureSize = 128;

std::uint64_t cacheKey(std::uint32_t kx, std::uint32_t kz, std::uint32_t level) {
  return std::uint64_t(kx) | (std::uint64_t(kz) << 20) | (std::uint64_t(level) << 40);
}

std::uint32_t packColour(Rgb c, SurfaceKind kind) {
  return c.r | (c.g << 8) | (c.b << 16) | (std::uint32_t(kind) << 24);
}

SurfaceKind kindOf(std::uint32_t rgba) { return SurfaceKind(rgba >> 24); }

/// Drawn with the road texture (shadingFragmentGlsl).
bool isRoad(std::uint32_t rgba) {
  return kindOf(rgba) == SurfaceKind::road || kindOf(rgba) == SurfaceKind::marked;
}

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
  const terrain::SquarePoint q = terrain::squareAt(x / g.spacing(), z / g.spacing(), g.postsX(), g.postsZ());
  const std::uint32_t i = q.i, j = q.j;
  const std::array<double, 4> w = terrain::cornerWeights(q.fx, q.fz);  // NW, NE, SW, SE
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

/// Where each lattice post of a level is among its skin vertices: post
/// (c, r) -> a vertex of a skin triangle (priority 1, not a skirt) within
/// kPostTolerance of the post's (x, z), or UINT32_MAX. The builder's levels
/// need not begin with the lattice in row-major order (culture cutting
/// may reorder or add vertices), so posts are found by position. The
/// lattice's last column and row may be narrower (database edge): there
/// the post lies on the skin's east and south extent.
class PostMap {
 public:
  void build(const module::Level& level) {
    level_ = &level;
    nx_ = level.squaresX;
    nz_ = level.squaresZ;
    posts_.assign(std::size_t(nx_ + 1) * (nz_ + 1), UINT32_MAX);
    if (nx_ == 0 || nz_ == 0 || !(level.spacing > 0)) return;
    east_ = south_ = 0;
    forSkin(level, [&](std::uint32_t v) {
      east_ = std::max(east_, double(level.vertices[v].x));
      south_ = std::max(south_, double(level.vertices[v].z));
    });
    forSkin(level, [&](std::uint32_t v) {
      const auto& p = level.vertices[v];
      const auto c = index(p.x, nx_, east_), r = index(p.z, nz_, south_);
      if (c && r) {
        std::uint32_t& slot = posts_[std::size_t(*r) * (nx_ + 1) + *c];
        if (slot == UINT32_MAX) slot = v;
      }
    });
  }
  std::uint32_t at(std::uint32_t c, std::uint32_t r) const { return posts_[std::size_t(r) * (nx_ + 1) + c]; }

  /// The skin's lattice surface at module-local (x, z) (levelHeightAt's
  /// rule: each square split along its SW-NE diagonal); nullopt where a
  /// corner post is missing.
  std::optional<double> heightAt(double x, double z) const {
    if (nx_ == 0 || nz_ == 0 || !(level_->spacing > 0)) return std::nullopt;
    const double sp = level_->spacing;
    const std::uint32_t column = terrain::latticeCell(x, sp, nx_), row = terrain::latticeCell(z, sp, nz_);
    const std::uint32_t k[4] = {at(column, row), at(column + 1, row), at(column, row + 1), at(column + 1, row + 1)};
    for (const std::uint32_t v : k) {
      if (v == UINT32_MAX) return std::nullopt;
    }
    const auto& nw = level_->vertices[k[0]];
    const auto& ne = level_->vertices[k[1]];
    const auto& sw = level_->vertices[k[2]];
    const auto& se = level_->vertices[k[3]];
    const double w = std::max(double(ne.x - nw.x), 1e-9), h = std::max(double(sw.z - nw.z), 1e-9);
    const double u = std::clamp((x - nw.x) / w, 0.0, 1.0), v = std::clamp((z - nw.z) / h, 0.0, 1.0);
    return terrain::planeHeight(u, v, nw.y, ne.y, sw.y, se.y);
  }

 private:
  template <typename F>
  static void forSkin(const module::Level& level, F&& f) {
    for (const module::Group& g : level.groups) {
      if (g.priority != module::kPrioritySkin || g.half == module::Half::skirt) continue;
      const std::size_t end = std::min<std::size_t>(std::size_t(g.firstIndex) + g.indexCount, level.indices.size());
      for (std::size_t i = g.firstIndex; i < end; ++i) {
        if (level.indices[i] < level.vertices.size()) f(level.indices[i]);
      }
    }
  }
  std::optional<std::uint32_t> index(float coordinate, std::uint32_t n, double edge) const {
    const double x = coordinate, sp = level_->spacing;
    const double c = std::clamp(std::round(x / sp), 0.0, double(n));
    if (c < n && std::abs(x - c * sp) <= kPostTolerance) return std::uint32_t(c);
    if (std::abs(x - edge) <= kPostTolerance) return n;
    return std::nullopt;
  }
  const module::Level* level_ = nullptr;
  std::uint32_t nx_ = 0, nz_ = 0;
  double east_ = 0, south_ = 0;
  std::vector<std::uint32_t> posts_;
};

/// Which way a triangle must face (front: counter-clockwise, culled otherwise).
struct Facing {
  enum Kind : std::uint8_t { asIs, up, outward } kind = asIs;
  float cx = 0, cz = 0;  ///< outward: away from this point (the node's centre)
};

/// Builds one level's vertices and indices (module_draw.h: smooth shares
/// vertices within a node, flat gives each triangle its own three).
/// Reused from upload to upload: its vectors keep their capacity.
class LevelBuilder {
 public:
  /// `y`: each source vertex's height as uploaded (the level's, with
  /// skirt feet raised by tightenSkirtFeet).
  void reset(const module::Level& level, const std::vector<float>& y, const std::vector<float>& delta, bool flat) {
    level_ = &level;
    y_ = &y;
    delta_ = &delta;
    flat_ = flat;
    firstCopy_.assign(level.vertices.size(), UINT32_MAX);
    nextCopy_.clear();
    copyNode_.clear();
    normal_.clear();
    water_.clear();
    out_.clear();
    indices_.clear();
  }

  /// Smooth shading: the grid's normal and water weight at every vertex.
  void sampleGrid(const grid::GridFile& g, const std::vector<std::uint8_t>& waterMaterials,
                  double originX, double originZ) {
    std::array<float, 256> water{};
    for (const std::uint8_t m : waterMaterials) water[m] = 1.0f;
    normal_.resize(level_->vertices.size());
    water_.resize(level_->vertices.size());
    for (std::size_t k = 0; k < level_->vertices.size(); ++k) {
      const auto& v = level_->vertices[k];
      const GridSample s = detail::sampleGrid(g, water, originX + v.x, originZ + v.z);
      normal_[k] = packNormal(s.normal);
      water_[k] = std::uint8_t(std::lround(std::clamp(s.water, 0.0f, 1.0f) * 255.0f));
    }
  }

  /// Appends the triangles of `count` indices at `idx`, all in colour
  /// `rgba`, each wound as `facing` says.
  void triangles(const std::uint32_t* idx, std::uint32_t count, std::uint32_t rgba, bool skirt, Facing facing) {
    for (std::uint32_t t = 0; t + 2 < count; t += 3) {
      std::uint32_t k[3] = {idx[t], idx[t + 1], idx[t + 2]};
      const auto& a = level_->vertices[k[0]];
      const auto& b = level_->vertices[k[1]];
      const auto& c = level_->vertices[k[2]];
      const Eigen::Vector3f ab(b.x - a.x, b.y - a.y, b.z - a.z), ac(c.x - a.x, c.y - a.y, c.z - a.z);
      const Eigen::Vector3f f = ab.cross(ac);
      bool flip = false;
      if (facing.kind == Facing::up) flip = f.y() < 0;
      if (facing.kind == Facing::outward) {
        const float mx = (a.x + b.x + c.x) / 3 - facing.cx, mz = (a.z + b.z + c.z) / 3 - facing.cz;
        flip = f.x() * mx + f.z() * mz < 0;
      }
      if (flip) std::swap(k[1], k[2]);
      if (facing.kind == Facing::asIs) {
        // Objects (walls, roofs) are lit by their own faces, not the ground's.
        const Eigen::Vector3f n = f.norm() > 0 ? Eigen::Vector3f(f.normalized()) : Eigen::Vector3f(0, 1, 0);
        for (const std::uint32_t v : k) {
          indices_.push_back(std::uint32_t(out_.size()));
          out_.push_back(vertex(v, rgba, packNormal(n)));
          if (!flat_) {  // keep shared()'s lists parallel to out_; never shared
            nextCopy_.push_back(UINT32_MAX);
            copyNode_.push_back(UINT32_MAX);
          }
        }
        continue;
      }
      if (!flat_) {
        for (const std::uint32_t v : k) indices_.push_back(shared(v, rgba));
        continue;
      }
      Eigen::Vector3f n(0, 1, 0);
      // Skirts are lit as if they were the ground they continue (seed
      // Figure 86: the fill polygon takes the adjacent polygon's normal).
      if (!skirt) {
        Eigen::Vector3f up = f.y() < 0 ? Eigen::Vector3f(-f) : f;
        if (up.norm() > 0) n = up.normalized();
      }
      for (const std::uint32_t v : k) {
        indices_.push_back(std::uint32_t(out_.size()));
        out_.push_back(vertex(v, rgba, packNormal(n)));
      }
    }
  }

  /// Starts a quadtree node: vertices are shared only within one node, so
  /// each node's draw touches a short run of them.
  void beginNode(std::uint32_t node) { node_ = node; }

  std::size_t indexCount() const { return indices_.size(); }
  const std::vector<GpuVertex>& vertices() const { return out_; }
  const std::vector<std::uint32_t>& indices() const { return indices_; }

 private:
  GpuVertex vertex(std::uint32_t k, std::uint32_t rgba, std::uint32_t normal) const {
    const auto& v = level_->vertices[k];
    return {v.x, (*y_)[k], v.z, (*delta_)[k], rgba, normal, v.s, v.t};
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

  const module::Level* level_ = nullptr;
  const std::vector<float>* y_ = nullptr;
  const std::vector<float>* delta_ = nullptr;
  bool flat_ = false;
  std::vector<std::uint32_t> normal_;
  std::vector<std::uint8_t> water_;
  std::vector<std::uint32_t> firstCopy_, nextCopy_, copyNode_;
  std::uint32_t node_ = 0;
  std::vector<GpuVertex> out_;
  std::vector<std::uint32_t> indices_;
};

/// Scratch shared by every upload on the render thread.
struct UploadScratch {
  LevelBuilder builder;
  /// Per level, built for the levels an upload reads: this one and the
  /// next coarser, or every level when tightenSkirtFeet can run.
  std::vector<PostMap> posts;
  std::vector<float> y, delta;
  std::vector<std::uint8_t> isFoot;
  std::vector<std::vector<const module::Group*>> byNode;
  std::vector<std::vector<std::uint32_t>> squaresByNode;
  std::vector<std::uint32_t> colour, skinTriangles;
  std::vector<float> area;
};

UploadScratch& scratch() {
  static thread_local UploadScratch s;
  return s;
}

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

/// How far a tightened skirt foot hangs below the lowest surface of any
/// level at its edge, metres (the converter's margin, meshing/skirts.h).
constexpr double kSkirtFootMargin = 1.0;

/// Raises each skirt foot of level `levelIndex` from the module-wide
/// depth the file stores (the worst over every node line of the module)
/// to the depth its own stretch of edge needs (docs/VIEWER.md, "Seams"):
/// the margin plus the most that this level's surface lies above the
/// lowest surface of any level, sampled at the finest posts within one
/// spacing of the foot along both lattice directions. Every level's edge
/// is straight between the finest posts, a morphed edge lies between two
/// levels' surfaces, and the foot line between two feet lies at least the
/// smaller of their depths below this level's edge, so it stays under
/// every neighbour's edge. Needs every level resident (the caller's
/// check: the pager publishes finer levels later) and `posts` built for
/// each; where a post is missing the stored foot stays. `isFoot[k]` marks
/// the feet; `y` holds the level's heights and gets the raised ones.
void tightenSkirtFeet(const ResidentModule& m, std::uint32_t levelIndex, const std::vector<std::uint8_t>& isFoot,
                      const std::vector<PostMap>& posts, std::vector<float>& y) {
  if (m.levels.empty() || !(m.levels[0].spacing > 0)) return;
  const module::Level& level = m.levels[levelIndex];
  const PostMap& own = posts[levelIndex];
  const double s0 = m.levels[0].spacing;
  const int n = std::max(1, int(std::lround(level.spacing / s0)));
  // This level's height above the lowest level at (x, z); nullopt where a post is missing.
  const auto excess = [&](double x, double z) -> std::optional<double> {
    const auto top = own.heightAt(x, z);
    if (!top) return std::nullopt;
    double lowest = *top;
    for (const PostMap& p : posts) {
      const auto h = p.heightAt(x, z);
      if (!h) return std::nullopt;
      lowest = std::min(lowest, *h);
    }
    return *top - lowest;
  };
  for (std::size_t k = 0; k < level.vertices.size(); ++k) {
    if (!isFoot[k]) continue;
    const auto& v = level.vertices[k];
    const auto top = own.heightAt(v.x, v.z);
    double worst = 0;
    bool known = top.has_value();
    for (int i = -n; i <= n && known; ++i) {
      const auto a = excess(v.x + i * s0, v.z), b = excess(v.x, v.z + i * s0);
      known = a && b;
      if (known) worst = std::max({worst, *a, *b});
    }
    if (known) y[k] = std::max(v.y, float(*top - worst - kSkirtFootMargin));
  }
}

}  // namespace

// ------------------------------------------------------------------ arena

GpuArena::~GpuArena() {
  for (auto& f : fenced_) glDeleteSync(f.fence);
  if (buffer_) {
    glUnmapNamedBuffer(buffer_);
    glDeleteBuffers(1, &buffer_);
  }
}

namespace {

void insertFree(std::map<std::uint64_t, std::uint64_t>& free, std::uint64_t offset, std::uint64_t bytes) {
  auto it = free.emplace(offset, bytes).first;
  if (auto next = std::next(it); next != free.end() && it->first + it->second == next->first) {
    it->second += next->second;
    free.erase(next);
  }
  if (it != free.begin()) {
    if (auto prev = std::prev(it); prev->first + prev->second == it->first) {
      prev->second += it->second;
      free.erase(it);
    }
  }
}

}  // namespace

void GpuArena::grow(std::uint64_t atLeast) {
  const std::uint64_t old = capacity_;
  std::uint64_t bytes = std::max<std::uint64_t>(kArenaInitialBytes, 2 * old);
  while (bytes < old + atLeast) bytes *= 2;
  constexpr GLbitfield flags = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  GLuint next = 0;
  glCreateBuffers(1, &next);
  glNamedBufferStorage(next, GLsizeiptr(bytes), nullptr, flags);
  auto* map = static_cast<std::uint8_t*>(glMapNamedBufferRange(next, 0, GLsizeiptr(bytes), flags));
  if (buffer_) {
    // A copy on the GPU keeps every block at its offset.
    glCopyNamedBufferSubData(buffer_, next, 0, 0, GLsizeiptr(old));
    glUnmapNamedBuffer(buffer_);
    glDeleteBuffers(1, &buffer_);
  }
  buffer_ = next;
  map_ = map;
  capacity_ = bytes;
  insertFree(free_, old, bytes - old);
}

void GpuArena::recycle() {
  std::size_t done = 0;
  for (; done < fenced_.size(); ++done) {
    const GLenum r = glClientWaitSync(fenced_[done].fence, 0, 0);
    if (r != GL_ALREADY_SIGNALED && r != GL_CONDITION_SATISFIED) break;
    glDeleteSync(fenced_[done].fence);
    for (const Pending& p : fenced_[done].blocks) insertFree(free_, p.offset, p.bytes);
  }
  fenced_.erase(fenced_.begin(), fenced_.begin() + std::ptrdiff_t(done));
}

std::uint64_t GpuArena::allocate(std::uint64_t bytes) {
  const std::uint64_t need = std::max<std::uint64_t>((bytes + kUnit - 1) / kUnit * kUnit, kUnit);
  for (int attempt = 0; attempt < 3; ++attempt) {
    for (auto it = free_.begin(); it != free_.end(); ++it) {
      if (it->second < need) continue;
      const std::uint64_t offset = it->first, left = it->second - need;
      free_.erase(it);
      if (left > 0) free_.emplace(offset + need, left);
      return offset;
    }
    if (attempt == 0) recycle();
    else grow(need);
  }
  return 0;  // not reached: grow() made room
}

void GpuArena::release(std::uint64_t offset, std::uint64_t bytes) {
  if (bytes == 0) return;
  released_.push_back({offset, std::max<std::uint64_t>((bytes + kUnit - 1) / kUnit * kUnit, kUnit)});
}

void GpuArena::endFrame() {
  if (!released_.empty()) {
    fenced_.push_back({glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0), std::move(released_)});
    released_.clear();
  }
  recycle();
}

// ------------------------------------------------------------------ modules

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

void ModuleRenderer::storeEntry(Entry& e, const std::vector<GpuVertex>& vertices,
                                const std::vector<std::uint32_t>& indices) {
  freeEntry(e);
  e.vertexBytes = vertices.size() * sizeof(GpuVertex);
  e.indexBytes = indices.size() * sizeof(std::uint32_t);
  e.vertexOffset = arena_.allocate(e.vertexBytes);
  e.indexOffset = arena_.allocate(e.indexBytes);
  if (e.vertexBytes) std::memcpy(arena_.data() + e.vertexOffset, vertices.data(), e.vertexBytes);
  if (e.indexBytes) std::memcpy(arena_.data() + e.indexOffset, indices.data(), e.indexBytes);
  e.bytes = e.vertexBytes + e.indexBytes;
  gpuBytes_ += e.bytes;
  e.resident = true;
}

void ModuleRenderer::freeEntry(Entry& e) {
  if (!e.resident) return;
  arena_.release(e.vertexOffset, e.vertexBytes);
  arena_.release(e.indexOffset, e.indexBytes);
  gpuBytes_ -= e.bytes;
  e.resident = false;
  e.bytes = e.vertexBytes = e.indexBytes = 0;
}

void ModuleRenderer::upload(const ModuleDraw& d, std::uint32_t levelIndex, Entry& e, RenderStats& stats) {
  UploadScratch& sc = scratch();
  const module::Level& level = d.ref.level(levelIndex);
  const ResidentModule& m = d.ref.module();
  const auto levels = std::uint32_t(m.levels.size());
  const module::Level* coarser = levelIndex + 1 < levels ? &m.levels[levelIndex + 1] : nullptr;
  // Levels finer than the finest resident may be written meanwhile: only
  // read them once every level is resident.
  const std::uint32_t finest = d.ref.finestLevel();
  sc.posts.resize(levels);
  const std::uint32_t lo = finest == 0 ? 0 : levelIndex, hi = finest == 0 ? levels : std::min(levels, levelIndex + 2);
  for (std::uint32_t l = lo; l < hi; ++l) sc.posts[l].build(m.levels[l]);
  const PostMap& posts = sc.posts[levelIndex];
  // Per source vertex: how far the next level's surface lies above this
  // one's at the same (x, z). Skirt feet do not move: they hang below the
  // lowest surface of every level there, so a skirt from a morphed edge
  // down to its unmoved foot still covers any neighbour's edge.
  sc.delta.assign(level.vertices.size(), 0.0f);
  sc.y.resize(level.vertices.size());
  sc.isFoot.assign(level.vertices.size(), 0);
  for (std::size_t k = 0; k < level.vertices.size(); ++k) {
    const auto& v = level.vertices[k];
    sc.y[k] = v.y;
    const auto yl = posts.heightAt(v.x, v.z);
    sc.isFoot[k] = yl && v.y < *yl - 0.01;
    if (!coarser || !yl || sc.isFoot[k]) continue;
    if (const auto yc = sc.posts[levelIndex + 1].heightAt(v.x, v.z)) sc.delta[k] = float(*yc - *yl);
  }
  if (finest == 0) tightenSkirtFeet(m, levelIndex, sc.isFoot, sc.posts, sc.y);
  const bool flat = settings_.shading == Shading::flat;
  LevelBuilder& builder = sc.builder;
  builder.reset(level, sc.y, sc.delta, flat);
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
  const double nodeMetres = double(nodeSquares_) * level.spacing;
  const auto facingOf = [&](const module::Group& g) {
    if (g.half == module::Half::skirt) {
      // Out of the node the group belongs to (keyed by its north-west square).
      const std::uint32_t nx = std::max<std::uint32_t>(level.squaresX, 1);
      const std::uint32_t a = (g.square % nx) / std::max<std::uint32_t>(nodeSquares_, 1);
      const std::uint32_t b = (g.square / nx) / std::max<std::uint32_t>(nodeSquares_, 1);
      return Facing{Facing::outward, float((a + 0.5) * nodeMetres), float((b + 0.5) * nodeMetres)};
    }
    // Objects keep their own winding; ground faces up.
    return Facing{g.priority >= module::kPriorityObject ? Facing::asIs : Facing::up, 0, 0};
  };
  e.blocks.clear();
  e.priorities.reset();
  sc.byNode.resize(nodes);
  // Groups are sorted by priority: each priority is one run of groups,
  // emitted node by node so that any quadtree node is one index range.
  // The skin's skirts go to a block of their own (kSkirtPriority).
  const std::uint32_t nx = level.squaresX, nz = level.squaresZ;
  const std::size_t squares = std::size_t(nx) * nz;
  // Each grid half's main colour: the material covering most of its area.
  // A pinhole shows the underlay and a crack shows a skirt, so both take
  // it (the first group would often be the uncovered class, and a skirt's
  // own material is the uncovered class: either speckled a forest with tint).
  sc.colour.assign(2 * squares, packColour(fallback.upper, SurfaceKind::colour));
  sc.area.assign(2 * squares, -1.0f);
  sc.skinTriangles.assign(squares, 0);
  for (const module::Group& g : level.groups) {
    if (g.priority != module::kPrioritySkin || g.half == module::Half::skirt || g.square >= squares) continue;
    sc.skinTriangles[g.square] += g.indexCount / 3;
    float area = 0;
    for (std::uint32_t t = 0; t + 2 < g.indexCount; t += 3) {
      const auto& a = level.vertices[level.indices[g.firstIndex + t]];
      const auto& b = level.vertices[level.indices[g.firstIndex + t + 1]];
      const auto& c = level.vertices[level.indices[g.firstIndex + t + 2]];
      area += std::abs((b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z));
    }
    const std::size_t k = 2 * std::size_t(g.square) + (g.half == module::Half::lower);
    if (area > sc.area[k]) {
      sc.colour[k] = colourOf(g);
      sc.area[k] = area;
    }
  }
  // A skirt triangle takes the colour of the grid half just inside its
  // node, beside the triangle's middle.
  const auto skirtColour = [&](const std::uint32_t* k, const Facing& f) {
    const auto& a = level.vertices[k[0]];
    const auto& b = level.vertices[k[1]];
    const auto& c = level.vertices[k[2]];
    double x = (a.x + b.x + c.x) / 3.0, z = (a.z + b.z + c.z) / 3.0;
    const double dx = f.cx - x, dz = f.cz - z, len = std::hypot(dx, dz);
    const double step = 0.25 * level.spacing;
    if (len > 0) {
      x += step * dx / len;
      z += step * dz / len;
    }
    if (nx == 0 || nz == 0 || !(level.spacing > 0)) return packColour({}, SurfaceKind::tint);
    const double u = x / level.spacing, v = z / level.spacing;
    const auto sx = std::uint32_t(std::clamp(std::floor(u), 0.0, double(nx - 1)));
    const auto sz = std::uint32_t(std::clamp(std::floor(v), 0.0, double(nz - 1)));
    const bool lower = (u - sx) + (v - sz) > 1.0;
    const std::size_t k2 = 2 * (std::size_t(sz) * nx + sx) + lower;
    return sc.area[k2] >= 0 ? sc.colour[k2] : packColour({}, SurfaceKind::tint);
  };
  // The skirt block is bucketed by node and side (Block::sides): range
  // 4 n + s holds node n's skirts on side s (kSide*), so a frame can draw
  // only the sides whose neighbour is drawn differently.
  const auto sideOf = [&](const std::uint32_t* k, const Facing& f) {
    const auto& a = level.vertices[k[0]];
    const auto& b = level.vertices[k[1]];
    const auto& c = level.vertices[k[2]];
    const float dx = (a.x + b.x + c.x) / 3 - f.cx, dz = (a.z + b.z + c.z) / 3 - f.cz;
    if (std::abs(dx) >= std::abs(dz)) return dx < 0 ? kSideWest : kSideEast;
    return dz < 0 ? kSideNorth : kSideSouth;
  };
  const auto emitBlock = [&](std::uint8_t priority) {
    const bool sides = priority == kSkirtPriority;
    const std::size_t ranges = sides ? 4 * nodes : nodes;
    Block b{priority, std::vector<std::uint32_t>(ranges + 1, 0)};
    b.sides = sides;
    for (std::size_t n = 0; n < nodes; ++n) {
      builder.beginNode(std::uint32_t(n));
      for (std::uint32_t nodeSide = 0; nodeSide < (sides ? 4u : 1u); ++nodeSide) {
        b.start[sides ? 4 * n + nodeSide : n] = std::uint32_t(builder.indexCount());
        for (const module::Group* g : sc.byNode[n]) {
          const std::uint32_t* idx = level.indices.data() + g->firstIndex;
          if (g->half != module::Half::skirt) {
            const std::uint32_t rgba = colourOf(*g);
            b.roads |= isRoad(rgba);
            builder.triangles(idx, g->indexCount, rgba, false, facingOf(*g));
            continue;
          }
          const Facing f = facingOf(*g);
          for (std::uint32_t t = 0; t + 2 < g->indexCount; t += 3) {
            if (sides && sideOf(idx + t, f) != nodeSide) continue;
            const std::uint32_t rgba = skirtColour(idx + t, f);
            b.roads |= isRoad(rgba);
            builder.triangles(idx + t, 3, rgba, true, f);
          }
        }
      }
    }
    b.start[ranges] = std::uint32_t(builder.indexCount());
    if (b.start[ranges] > b.start[0]) {
      e.priorities.set(priority);
      e.blocks.push_back(std::move(b));
    }
  };
  for (std::size_t g0 = 0; g0 < level.groups.size();) {
    const std::uint8_t priority = level.groups[g0].priority;
    std::size_t g1 = g0;
    while (g1 < level.groups.size() && level.groups[g1].priority == priority) ++g1;
    for (const bool skirts : {false, true}) {
      if (skirts && priority != module::kPrioritySkin) break;
      for (auto& v : sc.byNode) v.clear();
      for (std::size_t k = g0; k < g1; ++k) {
        const module::Group& g = level.groups[k];
        if (priority == module::kPrioritySkin && (g.half == module::Half::skirt) != skirts) continue;
        sc.byNode[nodeOfSquare(level, g.square, nodeSquares_, side)].push_back(&g);
      }
      emitBlock(skirts ? kSkirtPriority : priority);
    }
    g0 = g1;
  }
  // The plain lattice under each culture-cut square (docs/VIEWER.md,
  // "Seams"): where cut triangles meet at T-junctions, rasterization may
  // leave pinholes, and the lattice beneath fills them. Uncut squares are
  // the lattice already. Posts are found by position (PostMap); a square
  // with a post missing gets no underlay.
  sc.squaresByNode.resize(nodes);
  for (auto& v : sc.squaresByNode) v.clear();
  bool anyCut = false;
  for (std::uint32_t q = 0; q < squares; ++q) {
    if (sc.skinTriangles[q] <= 2) continue;
    anyCut = true;
    sc.squaresByNode[nodeOfSquare(level, q, nodeSquares_, side)].push_back(q);
  }
  if (anyCut) {
    Block b{kUnderlayPriority, std::vector<std::uint32_t>(nodes + 1, 0)};
    for (std::size_t n = 0; n < nodes; ++n) {
      b.start[n] = std::uint32_t(builder.indexCount());
      builder.beginNode(std::uint32_t(n));
      for (const std::uint32_t q : sc.squaresByNode[n]) {
        const std::uint32_t c = q % nx, r = q / nx;
        const std::uint32_t nw = posts.at(c, r), ne = posts.at(c + 1, r);
        const std::uint32_t sw = posts.at(c, r + 1), se = posts.at(c + 1, r + 1);
        if (nw == UINT32_MAX || ne == UINT32_MAX || sw == UINT32_MAX || se == UINT32_MAX) {
          ++stats.underlayMissing;
          continue;
        }
        const std::uint32_t tris[2][3] = {{nw, sw, ne}, {ne, sw, se}};
        // Flat: lit straight up, as the seed's pinhole filler was.
        for (int h = 0; h < 2; ++h) {
          const std::uint32_t rgba = sc.colour[2 * std::size_t(q) + h];
          b.roads |= isRoad(rgba);
          builder.triangles(tris[h], 3, rgba, true, Facing{Facing::up, 0, 0});
        }
      }
    }
    b.start[nodes] = std::uint32_t(builder.indexCount());
    if (b.start[nodes] > b.start[0]) {
      e.priorities.set(kUnderlayPriority);
      e.blocks.push_back(std::move(b));
    }
  }
  storeEntry(e, builder.vertices(), builder.indices());
  e.generation = d.ref.generation();
  ++stats.uploads;
  stats.uploadBytes += e.bytes;
}

ModuleRenderer::Entry* ModuleRenderer::ready(std::uint64_t key) {
  auto it = cache_.find(key);
  return it != cache_.end() && it->second.resident ? &it->second : nullptr;
}

void ModuleRenderer::release(RenderStats& stats, const DisplayBuffer& buf) {
  const ModuleRect& w = buf.pagerWindow;
  for (auto it = cache_.begin(); it != cache_.end();) {
    const auto kx = std::int64_t(it->first & 0xFFFFF), kz = std::int64_t((it->first >> 20) & 0xFFFFF);
    const bool freed = !w.empty() && !w.contains(kx, kz);
    if (freed || it->second.lastFrame + kKeepUnusedFrames < buf.frame) {
      freeEntry(it->second);
      it = cache_.erase(it);
      ++stats.released;
    } else {
      ++it;
    }
  }
}

namespace {

/// Node (a, b) of a Morton index (lod.h's mortonIndex inverted).
std::pair<std::uint32_t, std::uint32_t> mortonCell(std::uint32_t m) {
  std::uint32_t a = 0, b = 0;
  for (std::uint32_t bit = 0; bit < 16; ++bit) {
    a |= ((m >> (2 * bit)) & 1u) << bit;
    b |= ((m >> (2 * bit + 1)) & 1u) << bit;
  }
  return {a, b};
}

/// Command list of a block priority (ModuleRenderer::lists_).
std::size_t listOf(std::uint8_t priority) {
  if (priority == module::kPrioritySkin) return 0;
  if (priority >= 254) return 1;  // skirts, underlay
  if (priority < module::kPriorityObject) return 2 + priority;
  return 101;
}

}  // namespace

void ModuleRenderer::prepare(const DisplayBuffer& buf, RenderStats& stats) {
  const auto t0 = std::chrono::steady_clock::now();
  nodeSquares_ = buf.nodeSquares;
  moduleSize_ = buf.moduleSize;
  drawn_.clear();
  cells_.clear();
  moduleCells_.assign(buf.modules.size(), {0, 0});
  const std::uint64_t budget = settings_.uploadBudgetBytes;
  std::uint64_t spent = 0;
  // Uploads go nearest first (nodes are grouped by module, nearest module
  // first). Every module's coarsest level goes up whatever the budget (it
  // is small), so a module with anything resident is never a hole; finer
  // levels wait for a later frame once the budget is spent (at least one
  // goes up each frame), and are drawn coarser meanwhile.
  const auto ensure = [&](const ModuleDraw& d, std::uint32_t level, bool force) {
    Entry& e = cache_[cacheKey(d.kx, d.kz, level)];
    e.lastFrame = buf.frame;
    if (e.resident && e.generation == d.ref.generation()) return;
    const module::Level& l = d.ref.level(level);
    const std::uint64_t estimate = l.vertices.size() * sizeof(GpuVertex) + l.indices.size() * sizeof(std::uint32_t);
    if (!force && budget > 0 && spent > 0 && spent + estimate > budget) {
      ++stats.uploadsDeferred;
      return;
    }
    upload(d, level, e, stats);
    spent += e.bytes;
  };
  for (std::size_t i0 = 0; i0 < buf.nodes.size();) {
    std::size_t i1 = i0;
    while (i1 < buf.nodes.size() && buf.nodes[i1].module == buf.nodes[i0].module) ++i1;
    const ModuleDraw& d = buf.modules[buf.nodes[i0].module];
    const auto levels = std::uint32_t(d.ref.module().levels.size());
    ensure(d, levels - 1, true);
    for (std::size_t k = i0; k < i1; ++k) ensure(d, buf.nodes[k].level, false);
    resolveModule(buf, i0, i1, stats);
    i0 = i1;
  }
  stats.uploadMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  buildCommands(buf);
}

void ModuleRenderer::resolveModule(const DisplayBuffer& buf, std::size_t i0, std::size_t i1, RenderStats& stats) {
  const ModuleDraw& d = buf.modules[buf.nodes[i0].module];
  const auto levels = std::uint32_t(d.ref.module().levels.size());
  const auto entryAt = [&](std::uint32_t l) { return ready(cacheKey(d.kx, d.kz, l)); };
  spans_.clear();
  bool anyFallback = false;
  for (std::size_t k = i0; k < i1; ++k) {
    const NodeDraw& nd = buf.nodes[k];
    std::uint32_t l = nd.level;
    while (l + 1 < levels && !entryAt(l)) ++l;
    if (!entryAt(l)) continue;  // nothing resident at all (cannot happen: the coarsest is forced)
    // In the finest level's node grid (Morton): level l's node m covers [m 4^l, (m + 1) 4^l).
    const std::uint32_t s0 = 2 * nd.level, s = 2 * l;
    std::uint64_t f = std::uint64_t(nd.first) << s0, t = std::uint64_t(nd.last) << s0;
    if (l != nd.level) {
      // The coarser level's nodes round it: the run widened to them.
      anyFallback = true;
      ++stats.nodesFallback;
      f = (f >> s) << s;
      t = ((t + (1ull << s) - 1) >> s) << s;
    }
    spans_.push_back({l, f, t, l == nd.level ? nd.morph : 0.0f, l != nd.level});
  }
  if (anyFallback) {
    // A widened run covers its siblings too: they and any run it overlaps
    // merge into it at the coarser of their levels (re-widened to it), so
    // no ground is drawn twice.
    std::sort(spans_.begin(), spans_.end(), [](const Span& a, const Span& b) { return a.f < b.f; });
    std::size_t out = 0;
    for (std::size_t k = 0; k < spans_.size(); ++k) {
      spans_[out++] = spans_[k];
      while (out >= 2 && spans_[out - 2].t > spans_[out - 1].f) {
        Span& a = spans_[out - 2];
        const Span& b = spans_[out - 1];
        a.level = std::max(a.level, b.level);
        a.t = std::max(a.t, b.t);
        a.morph = 0;
        a.fallback = true;
        const std::uint32_t s = 2 * a.level;
        a.f = (a.f >> s) << s;
        a.t = ((a.t + (1ull << s) - 1) >> s) << s;
        --out;
      }
    }
    spans_.resize(out);
  }
  // What covers each node of the finest level: where a skirt is needed.
  const std::uint32_t side0 = nodesPerSide(0, levels);
  const auto cells = std::uint32_t(cells_.size());
  cells_.resize(cells_.size() + std::size_t(side0) * side0);
  moduleCells_[buf.nodes[i0].module] = {cells, side0};
  for (const Span& sp : spans_) {
    for (std::uint64_t m = sp.f; m < sp.t; ++m) {
      const auto [x, z] = mortonCell(std::uint32_t(m));
      if (x < side0 && z < side0) cells_[cells + std::size_t(z) * side0 + x] = {sp.level, sp.morph};
    }
  }
  for (const Span& sp : spans_) {
    const std::uint32_t s = 2 * sp.level;
    drawn_.push_back({entryAt(sp.level), sp.level, std::uint32_t(sp.f >> s), std::uint32_t(sp.t >> s), sp.morph,
                      buf.nodes[i0].module, cells, side0});
  }
}

bool ModuleRenderer::drawnAt(std::uint32_t module, double x, double z, std::uint32_t& level,
                             float& morph) const {
  if (module >= moduleCells_.size() || moduleSize_ <= 0) return false;
  const auto [first, side] = moduleCells_[module];
  if (side == 0) return false;
  const double cell = moduleSize_ / side;
  const auto cx = std::uint32_t(std::clamp(std::floor(x / cell), 0.0, double(side - 1)));
  const auto cz = std::uint32_t(std::clamp(std::floor(z / cell), 0.0, double(side - 1)));
  const Cell& c = cells_[first + std::size_t(cz) * side + cx];
  if (c.level == UINT32_MAX) return false;
  level = c.level;
  morph = c.morph;
  return true;
}

bool ModuleRenderer::skirtNeeded(const Drawn& dr, std::uint32_t node, std::uint32_t side) const {
  const auto [a, b] = mortonCell(node);
  const std::uint32_t scale = 1u << dr.level, n = dr.side0;
  // The finest-level cells just across the side, from x0/z0 along the other axis.
  std::int64_t x = std::int64_t(a) * scale, z = std::int64_t(b) * scale;
  std::int64_t dx = 0, dz = 0;
  if (side == kSideNorth) --z, dx = 1;
  if (side == kSideSouth) z += scale, dx = 1;
  if (side == kSideWest) --x, dz = 1;
  if (side == kSideEast) x += scale, dz = 1;
  for (std::uint32_t k = 0; k < scale; ++k, x += dx, z += dz) {
    if (x < 0 || z < 0 || x >= n || z >= n) return true;  // another module's
    const Cell& c = cells_[dr.cells + std::size_t(z) * n + std::size_t(x)];
    if (c.level != dr.level || c.morph != dr.morph) return true;
  }
  return false;
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


void ModuleRenderer::buildCommands(const DisplayBuffer& buf) {
  for (auto& l : lists_) l.clear();
  drawData_.clear();
  framePriorities_.reset();
  roadLists_.reset();
  for (const Drawn& dr : drawn_) {
    const ModuleDraw& d = buf.modules[dr.module];
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

void ModuleRenderer::drawTerrain(const DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection,
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

void ModuleRenderer::drawDecals(const DisplayBuffer&, RenderStats& stats) {
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

void ModuleRenderer::finishFrame(const DisplayBuffer& buf, RenderStats& stats) {
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

PlainGridRun ModuleRenderer::drawPlainGrid(const Camera& camera, std::uint32_t squares, double spacing,
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
    for (std::uint32_t a = 0; a < side; ++a) order.push_back({mortonIndex(a, b), a + b * side});
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

  DisplayBuffer buf;
  buf.camera = camera;
  buf.camera.y = camera.y + height(0, 0);
  buf.originX = camera.x;
  buf.originZ = camera.z;
  buf.moduleSize = 0;
  buf.modules.resize(1);
  const Eigen::Matrix4f vp = detail::viewProjection(buf.camera, buf.originX, buf.originZ).cast<float>();
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

}  // namespace sandtable::runtime::detail
