// The CPU half of drawing a load module (module_mesh.h): one level's
// vertices, indices and node blocks, with morph deltas, grid normals and
// water weights, and skirt feet raised once every level is resident. Runs
// on the pager's loader threads through moduleLevelPreparer, or on the
// render thread for a level that comes without a matching mesh.
#include "module_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>

#include "sandtable/formats/terrain_rule.h"
#include "sandtable/scene/lod.h"

namespace sandtable::render::detail {
namespace {

/// A lattice post and a skin vertex are the same point within this, metres.
constexpr double kPostTolerance = 1e-3;

}  // namespace

std::uint32_t packColour(Rgb c, SurfaceKind kind) {
  return c.r | (c.g << 8) | (c.b << 16) | (std::uint32_t(kind) << 24);
}

namespace {

SurfaceKind kindOf(std::uint32_t rgba) { return SurfaceKind(rgba >> 24); }

/// Drawn with the road texture (shadingFragmentGlsl).
bool isRoad(std::uint32_t rgba) {
  return kindOf(rgba) == SurfaceKind::road || kindOf(rgba) == SurfaceKind::marked;
}

}  // namespace

std::uint32_t packNormal(const Eigen::Vector3f& n) {
  const auto q = [](float v) {
    return std::uint32_t(std::int32_t(std::lround(std::clamp(v, -1.0f, 1.0f) * 511.0f)) & 0x3FF);
  };
  return q(n.x()) | (q(n.y()) << 10) | (q(n.z()) << 20);
}

namespace {

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

/// Tilts normal `n` at square point `q` by the slope of a refined square's
/// detail (its fine surface less the square's planes; docs/DYNAMIC.md), so
/// that a crater far smaller than a post is lit as one. Unchanged outside a
/// patch.
void addDetailSlope(const grid::HeightField& g, const terrain::SquarePoint& q, Eigen::Vector3d& n) {
  const auto r = g.refined(q.i, q.j);
  if (!r || r->cells == 0 || !(n.y() > 0)) return;
  const double nw = g.elevation(q.i, q.j), ne = g.elevation(q.i + 1, q.j);
  const double sw = g.elevation(q.i, q.j + 1), se = g.elevation(q.i + 1, q.j + 1);
  bool ok = true;
  const auto detail = [&](double fx, double fz) {
    bool inside = false;
    const double y = grid::refinedHeight(*r, fx, fz, inside);
    ok = ok && inside;
    return y - terrain::planeHeight(fx, fz, nw, ne, sw, se);
  };
  const double h = 0.5 / double(r->cells);
  const double x0 = std::max(0.0, q.fx - h), x1 = std::min(1.0, q.fx + h);
  const double z0 = std::max(0.0, q.fz - h), z1 = std::min(1.0, q.fz + h);
  const double ddx = (detail(x1, q.fz) - detail(x0, q.fz)) / ((x1 - x0) * g.spacing());
  const double ddz = (detail(q.fx, z1) - detail(q.fx, z0)) / ((z1 - z0) * g.spacing());
  if (!ok) return;
  const double sx = -n.x() / n.y() + ddx, sz = -n.z() / n.y() + ddz;
  n = Eigen::Vector3d(-sx, 1.0, -sz).normalized();
}

GridSample sampleGrid(const grid::HeightField& g, const std::array<float, 256>& water, double x, double z) {
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
  if (n.norm() > 0) n.normalize();
  if (g.anyRefined()) addDetailSlope(g, q, n);
  if (n.norm() > 0) out.normal = n.cast<float>();
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
  /// Heights are the level's: skirt feet are raised apart (raiseSkirtFeet).
  void reset(const module::Level& level, const std::vector<float>& delta, bool flat) {
    level_ = &level;
    delta_ = &delta;
    flat_ = flat;
    firstCopy_.assign(level.vertices.size(), UINT32_MAX);
    nextCopy_.clear();
    copyNode_.clear();
    normal_.clear();
    water_.clear();
    out_.clear();
    source_.clear();
    indices_.clear();
  }

  /// Smooth shading: the grid's normal and water weight at every vertex.
  void sampleGrid(const grid::HeightField& g, const std::vector<std::uint8_t>& waterMaterials,
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
          append(v, rgba, packNormal(n));
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
        append(v, rgba, packNormal(n));
      }
    }
  }

  /// Starts a quadtree node: vertices are shared only within one node, so
  /// each node's draw touches a short run of them.
  void beginNode(std::uint32_t node) { node_ = node; }

  std::size_t indexCount() const { return indices_.size(); }
  /// Hands the vertices, their sources and the indices to `mesh`, taking
  /// its old vectors as scratch (capacity kept on both sides).
  void takeInto(LevelMesh& mesh) {
    std::swap(mesh.vertices, out_);
    std::swap(mesh.source, source_);
    std::swap(mesh.indices, indices_);
  }

 private:
  GpuVertex vertex(std::uint32_t k, std::uint32_t rgba, std::uint32_t normal) const {
    const auto& v = level_->vertices[k];
    return {v.x, v.y, v.z, (*delta_)[k], rgba, normal, v.s, v.t};
  }
  void append(std::uint32_t k, std::uint32_t rgba, std::uint32_t normal) {
    out_.push_back(vertex(k, rgba, normal));
    source_.push_back(k);
  }

  /// The copy of source vertex k in colour `rgba` in this node, made on first use.
  std::uint32_t shared(std::uint32_t k, std::uint32_t rgba) {
    if (kindOf(rgba) == SurfaceKind::tint) rgba = packColour({water(k), 0, 0}, SurfaceKind::tint);
    for (std::uint32_t c = firstCopy_[k]; c != UINT32_MAX; c = nextCopy_[c]) {
      if (out_[c].rgba == rgba && copyNode_[c] == node_) return c;
    }
    const auto c = std::uint32_t(out_.size());
    append(k, rgba, normal_.empty() ? packNormal({0, 1, 0}) : normal_[k]);
    nextCopy_.push_back(firstCopy_[k]);
    copyNode_.push_back(node_);
    firstCopy_[k] = c;
    return c;
  }

  std::uint8_t water(std::uint32_t k) const { return water_.empty() ? 0 : water_[k]; }

  const module::Level* level_ = nullptr;
  const std::vector<float>* delta_ = nullptr;
  bool flat_ = false;
  std::vector<std::uint32_t> normal_;
  std::vector<std::uint8_t> water_;
  std::vector<std::uint32_t> firstCopy_, nextCopy_, copyNode_;
  std::uint32_t node_ = 0;
  std::vector<GpuVertex> out_;
  std::vector<std::uint32_t> source_;  ///< per out_ vertex: its level vertex
  std::vector<std::uint32_t> indices_;
};

/// Scratch shared by every level built on one thread.
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
  std::vector<std::uint8_t> offLattice;
  std::vector<float> area;
};

UploadScratch& scratch() {
  static thread_local UploadScratch s;
  return s;
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
void tightenSkirtFeet(const paging::ResidentModule& m, std::uint32_t levelIndex, const std::vector<std::uint8_t>& isFoot,
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

/// Marks the skirt feet of `level`: vertices that only skirt groups use and
/// that lie below the lattice surface. Not every vertex below the lattice
/// is a foot: a crater's floor and a ditch are skin below it
/// (docs/DYNAMIC.md), and raising them as feet would fill the crater.
void markFeet(const module::Level& level, const PostMap& posts, std::vector<std::uint8_t>& isFoot) {
  // 1: used by a skirt, 2: used by anything else.
  isFoot.assign(level.vertices.size(), 0);
  for (const module::Group& g : level.groups) {
    const std::uint8_t use = g.half == module::Half::skirt ? 1 : 2;
    const std::size_t end = std::min<std::size_t>(std::size_t(g.firstIndex) + g.indexCount, level.indices.size());
    for (std::size_t i = g.firstIndex; i < end; ++i) {
      if (level.indices[i] < level.vertices.size()) isFoot[level.indices[i]] |= use;
    }
  }
  for (std::size_t k = 0; k < level.vertices.size(); ++k) {
    if (isFoot[k] != 1) {
      isFoot[k] = 0;
      continue;
    }
    const auto& v = level.vertices[k];
    const auto yl = posts.heightAt(v.x, v.z);
    isFoot[k] = yl && v.y < *yl - 0.01;
  }
}

void buildLevelMesh(const paging::ResidentModule& m, std::uint32_t levelIndex, const MeshSettings& s, LevelMesh& out) {
  UploadScratch& sc = scratch();
  const module::Level& level = m.levels[levelIndex];
  const auto levels = std::uint32_t(m.levels.size());
  const module::Level* coarser = levelIndex + 1 < levels ? &m.levels[levelIndex + 1] : nullptr;
  // Finer levels may not be written yet: only this level and the next
  // coarser one are read.
  sc.posts.resize(levels);
  const std::uint32_t hi = std::min(levels, levelIndex + 2);
  for (std::uint32_t l = levelIndex; l < hi; ++l) sc.posts[l].build(m.levels[l]);
  const PostMap& posts = sc.posts[levelIndex];
  // Per source vertex: how far the next level's surface lies above this
  // one's at the same (x, z). Skirt feet do not move: they hang below the
  // lowest surface of every level there, so a skirt from a morphed edge
  // down to its unmoved foot still covers any neighbour's edge.
  sc.delta.assign(level.vertices.size(), 0.0f);
  markFeet(level, posts, sc.isFoot);
  for (std::size_t k = 0; k < level.vertices.size(); ++k) {
    const auto& v = level.vertices[k];
    if (!coarser || sc.isFoot[k]) continue;
    const auto yl = posts.heightAt(v.x, v.z);
    if (!yl) continue;
    if (const auto yc = sc.posts[levelIndex + 1].heightAt(v.x, v.z)) sc.delta[k] = float(*yc - *yl);
  }
  const bool flat = s.flat;
  LevelBuilder& builder = sc.builder;
  builder.reset(level, sc.delta, flat);
  if (!flat && s.grid) {
    builder.sampleGrid(*s.grid, s.waterMaterials, m.kx * s.moduleSize, m.kz * s.moduleSize);
  }
  const std::uint32_t side = scene::nodesPerSide(levelIndex, levels);
  const std::size_t nodes = std::size_t(side) * side;
  const MaterialColour fallback;
  const auto colourOf = [&](const module::Group& g) {
    if (!flat && g.priority == module::kPrioritySkin && g.material == s.uncoveredMaterial) {
      return packColour({}, SurfaceKind::tint);
    }
    const MaterialColour& mc = g.material < s.palette.size() ? s.palette[g.material] : fallback;
    const Rgb rgb = !flat ? mean(mc.upper, mc.lower) : g.half == module::Half::lower ? mc.lower : mc.upper;
    const SurfaceKind kind = !mc.road ? SurfaceKind::colour : mc.markings ? SurfaceKind::marked : SurfaceKind::road;
    return packColour(rgb, kind);
  };
  const std::uint32_t nodeSquares = s.nodeSquares;
  const double nodeMetres = double(nodeSquares) * level.spacing;
  const auto facingOf = [&](const module::Group& g) {
    if (g.half == module::Half::skirt) {
      // Out of the node the group belongs to (keyed by its north-west square).
      const std::uint32_t nx = std::max<std::uint32_t>(level.squaresX, 1);
      const std::uint32_t a = (g.square % nx) / std::max<std::uint32_t>(nodeSquares, 1);
      const std::uint32_t b = (g.square / nx) / std::max<std::uint32_t>(nodeSquares, 1);
      return Facing{Facing::outward, float((a + 0.5) * nodeMetres), float((b + 0.5) * nodeMetres)};
    }
    // Objects keep their own winding; ground faces up.
    return Facing{g.priority >= module::kPriorityObject ? Facing::asIs : Facing::up, 0, 0};
  };
  out.blocks.clear();
  out.priorities.reset();
  out.underlayMissing = 0;
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
  sc.offLattice.assign(squares, 0);
  const bool anyRefined = s.grid && s.grid->anyRefined();
  for (const module::Group& g : level.groups) {
    if (g.priority != module::kPrioritySkin || g.half == module::Half::skirt || g.square >= squares) continue;
    sc.skinTriangles[g.square] += g.indexCount / 3;
    // A square re-meshed with a refined patch (docs/DYNAMIC.md) has skin
    // off its lattice planes (by more than the height rounding of the
    // vertex and its posts): a lattice drawn there would cover a crater.
    // Only refined squares leave their planes: no scan on an unedited world.
    const double off = std::max(0.02, 2.0 * level.heightStep);
    for (std::uint32_t i = 0; anyRefined && i < g.indexCount && !sc.offLattice[g.square]; ++i) {
      const auto& v = level.vertices[level.indices[g.firstIndex + i]];
      const auto yl = posts.heightAt(v.x, v.z);
      sc.offLattice[g.square] = yl && std::abs(v.y - *yl) > off;
    }
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
    MeshBlock b{priority, std::vector<std::uint32_t>(ranges + 1, 0)};
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
      out.priorities.set(priority);
      out.blocks.push_back(std::move(b));
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
        sc.byNode[scene::nodeOfSquare(level, g.square, nodeSquares, side)].push_back(&g);
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
    if (sc.skinTriangles[q] <= 2 || sc.offLattice[q]) continue;
    anyCut = true;
    sc.squaresByNode[scene::nodeOfSquare(level, q, nodeSquares, side)].push_back(q);
  }
  if (anyCut) {
    MeshBlock b{kUnderlayPriority, std::vector<std::uint32_t>(nodes + 1, 0)};
    for (std::size_t n = 0; n < nodes; ++n) {
      b.start[n] = std::uint32_t(builder.indexCount());
      builder.beginNode(std::uint32_t(n));
      for (const std::uint32_t q : sc.squaresByNode[n]) {
        const std::uint32_t c = q % nx, r = q / nx;
        const std::uint32_t nw = posts.at(c, r), ne = posts.at(c + 1, r);
        const std::uint32_t sw = posts.at(c, r + 1), se = posts.at(c + 1, r + 1);
        if (nw == UINT32_MAX || ne == UINT32_MAX || sw == UINT32_MAX || se == UINT32_MAX) {
          ++out.underlayMissing;
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
      out.priorities.set(kUnderlayPriority);
      out.blocks.push_back(std::move(b));
    }
  }
  builder.takeInto(out);
}

void raiseSkirtFeet(const paging::ResidentModule& m, const std::vector<LevelMesh*>& meshes) {
  UploadScratch& sc = scratch();
  const auto levels = std::uint32_t(m.levels.size());
  sc.posts.resize(levels);
  for (std::uint32_t l = 0; l < levels; ++l) sc.posts[l].build(m.levels[l]);
  for (std::uint32_t l = 0; l < levels && l < meshes.size(); ++l) {
    LevelMesh* mesh = meshes[l];
    if (!mesh) continue;
    const module::Level& level = m.levels[l];
    // The feet as buildLevelMesh found them.
    sc.y.resize(level.vertices.size());
    for (std::size_t k = 0; k < level.vertices.size(); ++k) sc.y[k] = level.vertices[k].y;
    markFeet(level, sc.posts[l], sc.isFoot);
    tightenSkirtFeet(m, l, sc.isFoot, sc.posts, sc.y);
    mesh->feet.clear();
    for (std::size_t i = 0; i < mesh->source.size(); ++i) {
      const std::uint32_t k = mesh->source[i];
      if (sc.isFoot[k]) mesh->feet.push_back({std::uint32_t(i), sc.y[k]});
    }
    mesh->raised = true;
  }
}

MeshSettings meshSettings(const RenderSettings& s, std::uint32_t nodeSquares, double moduleSize) {
  MeshSettings m;
  m.flat = s.shading == Shading::flat;
  m.grid = s.grid;
  m.waterMaterials = s.waterMaterials;
  m.palette = s.palette;
  m.uncoveredMaterial = s.uncoveredMaterial;
  m.nodeSquares = nodeSquares;
  m.moduleSize = moduleSize;
  return m;
}

bool sameMeshSettings(const MeshSettings& a, const MeshSettings& b) {
  const auto sameColour = [](const MaterialColour& x, const MaterialColour& y) {
    const auto rgb = [](Rgb c) { return std::array<int, 3>{c.r, c.g, c.b}; };
    return rgb(x.upper) == rgb(y.upper) && rgb(x.lower) == rgb(y.lower) && x.road == y.road &&
           x.markings == y.markings;
  };
  return a.flat == b.flat && a.grid == b.grid && a.waterMaterials == b.waterMaterials &&
         a.uncoveredMaterial == b.uncoveredMaterial && a.nodeSquares == b.nodeSquares &&
         a.moduleSize == b.moduleSize &&
         std::equal(a.palette.begin(), a.palette.end(), b.palette.begin(), b.palette.end(), sameColour);
}

}  // namespace sandtable::render::detail

namespace sandtable::render {

std::function<void(paging::ResidentModule&, std::uint32_t)> moduleLevelPreparer(const RenderSettings& s,
                                                                        std::uint32_t nodeSquares,
                                                                        double moduleSize) {
  auto settings = std::make_shared<const detail::MeshSettings>(detail::meshSettings(s, nodeSquares, moduleSize));
  return [settings](paging::ResidentModule& m, std::uint32_t level) {
    if (level >= m.prepared.size() || level >= m.levels.size()) return;  // the pager sizes `prepared`
    auto* mesh = dynamic_cast<detail::LevelMesh*>(m.prepared[level].get());
    if (!mesh) {
      m.prepared[level] = std::make_unique<detail::LevelMesh>();
      mesh = static_cast<detail::LevelMesh*>(m.prepared[level].get());
    }
    mesh->raised = false;
    mesh->settings = settings;
    detail::buildLevelMesh(m, level, *settings, *mesh);
    if (level != 0) return;
    // Every level is written now: raise every level's skirt feet, before
    // the pager publishes level 0 (readers of the coarser levels meanwhile
    // read no feet: they hold finestLevel() > 0).
    std::vector<detail::LevelMesh*> meshes(m.levels.size(), nullptr);
    for (std::size_t l = 0; l < meshes.size(); ++l) {
      auto* built = dynamic_cast<detail::LevelMesh*>(m.prepared[l].get());
      if (built && built->settings == settings) meshes[l] = built;
    }
    detail::raiseSkirtFeet(m, meshes);
  };
}

}  // namespace sandtable::render
