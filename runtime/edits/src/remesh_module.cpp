// A touched module rebuilt from its base and the edited heights
// (remesh_internal.h; docs/DYNAMIC.md, "Re-meshing"): vertices moved by
// their lattice plane's change, refined squares re-triangulated at level 0
// with their decals clipped, skirts, heights, normals and object bases.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>

#include "remesh_internal.h"
#include "sandtable/formats/terrain_rule.h"
#include "sandtable/meshing/assemble.h"
#include "sandtable/meshing/lattice.h"
#include "sandtable/meshing/normals.h"
#include "sandtable/meshing/skirts.h"

namespace sandtable::edits::detail {

namespace {

using meshing::LevelLattice;
using module::Group;
using module::Half;
using module::Level;
using module::Vertex;

bool isSkirt(const Group& g) { return g.half == Half::skirt; }
bool isSkin(const Group& g) { return !isSkirt(g) && g.priority == module::kPrioritySkin; }
bool isDecal(const Group& g) {
  return !isSkirt(g) && g.priority > module::kPrioritySkin && g.priority < module::kPriorityObject;
}

bool groupBefore(const Group& a, const Group& b) {
  if (a.priority != b.priority) return a.priority < b.priority;
  if (a.square != b.square) return a.square < b.square;
  if (a.half != b.half) return a.half < b.half;
  return a.material < b.material;
}

/// Barycentric weights of p in triangle (a, b, c) (map coordinates).
std::array<double, 3> barycentric(const UV& a, const UV& b, const UV& c, const UV& p) {
  const double d = (b.v - c.v) * (a.u - c.u) + (c.u - b.u) * (a.v - c.v);
  if (d == 0) return {1.0 / 3, 1.0 / 3, 1.0 / 3};
  const double wa = ((b.v - c.v) * (p.u - c.u) + (c.u - b.u) * (p.v - c.v)) / d;
  const double wb = ((c.v - a.v) * (p.u - c.u) + (a.u - c.u) * (p.v - c.v)) / d;
  return {wa, wb, 1.0 - wa - wb};
}

double upArea(const UV& a, const UV& b, const UV& c) {
  const double d1x = b.u - a.u, d1z = b.v - a.v, d2x = c.u - a.u, d2z = c.v - a.v;
  return 0.5 * (d1z * d2x - d1x * d2z);
}

/// Height of level 0's drawn surface at post coordinates (U, V) (grid
/// posts, fractional): a refined square's fine lattice inside its patch,
/// else the square's planes (the edited ground the re-mesher draws).
double level0Surface(const grid::HeightField& h, double U, double V) {
  const terrain::SquarePoint q = terrain::squareAt(U, V, h.postsX(), h.postsZ());
  if (h.anyRefined()) {
    if (const auto r = h.refined(q.i, q.j)) {
      bool inside = false;
      const double y = grid::refinedHeight(*r, q.fx, q.fz, inside);
      if (inside) return y;
    }
  }
  const std::uint32_t i1 = std::min(q.i + 1, h.postsX() - 1), j1 = std::min(q.j + 1, h.postsZ() - 1);
  return terrain::planeHeight(q.fx, q.fz, double(h.elevation(q.i, q.j)), double(h.elevation(i1, q.j)),
                              double(h.elevation(q.i, j1)), double(h.elevation(i1, j1)));
}

/// Height of a level's lattice triangles at window post coordinates (U, V)
/// (fractional grid posts).
double latticeSurface(const LevelLattice& lat, const meshing::ModuleWindow& w, int l, double U, double V) {
  const std::uint32_t step = 1u << l;
  const terrain::LatticeSpan x = terrain::latticeSpan(U, w.i0, w.i1, step);
  const terrain::LatticeSpan z = terrain::latticeSpan(V, w.j0, w.j1, step);
  const std::size_t a = (x.a - w.i0) / step, b = (z.a - w.j0) / step, n = lat.xs.size();
  return terrain::planeHeight(x.fraction(U), z.fraction(V), double(lat.heights[b * n + a]), double(lat.heights[b * n + a + 1]),
                              double(lat.heights[(b + 1) * n + a]), double(lat.heights[(b + 1) * n + a + 1]));
}

/// One group's worth of triangles waiting to be sorted into the level.
struct PendingGroup {
  Group g;
  std::uint32_t first = 0;  ///< into Rebuilder::scratch_
};

class Rebuilder {
 public:
  Rebuilder(const RebuildInput& in, RebuildStats& stats) : in_(in), stats_(stats) {}

  module::Module run() {
    const module::Module& base = *in_.base;
    const int levels = int(base.levels.size());
    w_ = meshing::moduleWindow(*in_.heights, in_.squares, levels, in_.kx, in_.kz);
    for (int l = 0; l < levels; ++l) {
      before_.push_back(meshing::levelLattice(*in_.before, w_, l));
      after_.push_back(meshing::levelLattice(*in_.heights, w_, l));
    }
    node_ = meshing::nodeSquares(in_.squares, levels);
    depths_ = meshing::skirtDepths(after_, w_, node_);
    lineVertices_.resize(std::size_t(levels));
    fineStep_.resize(std::size_t(levels));
    stats_.patchSquares.assign(std::size_t(levels), 0);
    refinedSquares();
    module::Module out;
    out.kx = base.kx;
    out.kz = base.kz;
    out.scattering = base.scattering;
    out.levels.resize(base.levels.size());
    // Every level's triangles first: level 0's fine edge points deepen
    // every level's skirts.
    for (int l = 0; l < levels; ++l) rebuildLevel(l, out.levels[std::size_t(l)]);
    deepenSkirts();
    for (int l = 0; l < levels; ++l) finish(l, out.levels[std::size_t(l)]);
    out.objects = *in_.objects;
    placeObjects(out, *in_.heights, in_.squares);
    return out;
  }

  /// The window's refined grid squares (grid post of their north-west corner).
  void refinedSquares() {
    if (!in_.heights->anyRefined()) return;
    for (std::uint32_t j = w_.j0; j < w_.j1; ++j) {
      for (std::uint32_t i = w_.i0; i < w_.i1; ++i) {
        if (in_.heights->refined(i, j)) refined_.push_back({i, j});
      }
    }
  }

 private:
  const RebuildInput& in_;
  RebuildStats& stats_;
  meshing::ModuleWindow w_;
  std::vector<LevelLattice> before_, after_;
  std::vector<LevelLattice> draped_;  ///< after_, heights as the re-draped lattice vertices carry them
  std::uint32_t node_ = 1;
  std::vector<float> depths_;
  /// Per level, the targets' vertices on lattice lines (skirt tops), and
  /// where they are in grid posts (skirt depths).
  std::vector<std::vector<std::uint32_t>> lineVertices_;
  struct LinePoint {
    double U = 0, V = 0;  ///< fractional grid posts
    bool vertical = false;  ///< on a post column (else a post row)
    double y = 0;
  };
  std::vector<LinePoint> linePoints_;
  Patches patches_{*in_.heights};
  std::vector<std::pair<std::uint32_t, std::uint32_t>> refined_;  ///< the window's refined grid squares
  std::vector<SquareMesh> meshes_;  ///< this level's targets
  std::vector<std::uint32_t> scratch_;
  std::vector<PendingGroup> pending_;
  std::vector<std::uint32_t> freshFrom_;  ///< per level: vertices from here on got no base normal
  /// Per level and vertex, the fine step (grid posts) of the patch whose
  /// surface gives its normal; 0: the posts' normals.
  std::vector<std::vector<double>> fineStep_;

  std::uint16_t skirtMaterial(const Level& b) const {
    for (const Group& g : b.groups) {
      if (isSkirt(g)) return g.material;
    }
    return 0;
  }

  /// Lattice square (column a, row b) geometry of `lat`.
  static void squareOf(const LevelLattice& lat, std::uint32_t square, std::size_t& a, std::size_t& b) {
    const std::size_t nx = lat.xs.size() - 1;
    a = square % nx;
    b = square / nx;
  }

  /// The ground under (x, z) on level l before and after the edit: the
  /// half-plane `half` of lattice square `square` (or the plane under the
  /// point when `half` is skirt: objects). Empty where none of the
  /// square's posts changed.
  std::optional<std::pair<double, double>> planes(int l, std::uint32_t square, Half half, double x, double z) const {
    const LevelLattice& o = before_[std::size_t(l)];
    const LevelLattice& n = after_[std::size_t(l)];
    const std::size_t w = o.xs.size();
    std::size_t a = 0, b = 0;
    if (half == Half::skirt) {
      a = terrain::latticeCell(x, o.spacing, std::uint32_t(w - 1));
      b = terrain::latticeCell(z, o.spacing, std::uint32_t(o.zs.size() - 1));
    } else {
      squareOf(o, square, a, b);
    }
    const std::size_t k[4] = {b * w + a, b * w + a + 1, (b + 1) * w + a, (b + 1) * w + a + 1};
    bool same = true;
    for (const std::size_t c : k) same = same && o.heights[c] == n.heights[c];
    if (same) return std::nullopt;
    const double fx = (x - o.xs[a]) / (o.xs[a + 1] - o.xs[a]), fz = (z - o.zs[b]) / (o.zs[b + 1] - o.zs[b]);
    auto plane = [&](const LevelLattice& lat) {
      const double nw = lat.heights[k[0]], ne = lat.heights[k[1]], sw = lat.heights[k[2]], se = lat.heights[k[3]];
      return half == Half::skirt ? terrain::planeHeight(fx, fz, nw, ne, sw, se)
                                 : terrain::halfPlane(half, fx, fz, nw, ne, sw, se);
    };
    return std::pair{plane(o), plane(n)};
  }

  /// Where a kept vertex at height y over ground `was` goes when the ground
  /// becomes `now`. A vertex on the ground but for the base pack's height
  /// quantisation goes exactly onto the new ground: moving it by the change
  /// would carry the old rounding into the next encoding, up to a whole
  /// step off the planes (validate's lattice and planarity checks allow
  /// half a step).
  /// Where the ground did not move (a square's edge whose posts kept their
  /// heights), nothing moves: the neighbour across the edge keeps it too.
  static double follow(double y, double was, double now, double step) {
    if (now == was) return y;
    if (std::fabs(y - was) <= 0.5 * step + 1e-6 * std::max(1.0, std::fabs(was))) return now;
    return y + (now - was);
  }

  void rebuildLevel(int l, Level& out) {
    const Level& b = in_.base->levels[std::size_t(l)];
    const LevelLattice& lat = after_[std::size_t(l)];
    const std::size_t nx = lat.xs.size() - 1, nz = lat.zs.size() - 1, posts = (nx + 1) * (nz + 1);
    out.spacing = b.spacing;
    out.squaresX = b.squaresX;
    out.squaresZ = b.squaresZ;
    out.heightStep = b.heightStep;
    // The base's vertices: the lattice posts first (as the builder writes
    // them), or put there when a base level does not have them so.
    std::vector<Vertex> verts;
    std::uint32_t shift = 0;
    bool latticeFirst = b.vertices.size() >= posts;
    for (std::size_t k = 0; latticeFirst && k < posts; ++k) {
      latticeFirst = b.vertices[k].x == float(lat.xs[k % (nx + 1)]) && b.vertices[k].z == float(lat.zs[k / (nx + 1)]);
    }
    if (!latticeFirst) {
      shift = std::uint32_t(posts);
      for (std::size_t k = 0; k < posts; ++k) {
        verts.push_back({float(lat.xs[k % (nx + 1)]), before_[std::size_t(l)].heights[k], float(lat.zs[k / (nx + 1)]), 0, 0});
      }
    }
    verts.insert(verts.end(), b.vertices.begin(), b.vertices.end());
    // Which group owns each vertex (its first skin, decal or object group).
    std::vector<std::uint32_t> owner(verts.size(), UINT32_MAX);
    for (std::uint32_t gi = 0; gi < b.groups.size(); ++gi) {
      const Group& g = b.groups[gi];
      if (isSkirt(g)) continue;
      for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; ++k) {
        std::uint32_t& o = owner[b.indices[k] + shift];
        if (o == UINT32_MAX) o = gi;
      }
    }
    // Kept vertices (skirts are rebuilt), moved with their plane.
    std::vector<std::uint32_t> remap(verts.size(), UINT32_MAX);
    out.vertices.clear();
    const bool normals = !b.normals.empty();
    out.normals.clear();
    for (std::uint32_t v = 0; v < verts.size(); ++v) {
      if (v >= posts && owner[v] == UINT32_MAX) continue;
      Vertex p = verts[v];
      if (v < posts) {
        const double was = before_[std::size_t(l)].heights[v], now = after_[std::size_t(l)].heights[v];
        if (was != now) p.y = float(follow(p.y, was, now, b.heightStep));
      } else {
        const Group& g = b.groups[owner[v]];
        const Half half = g.priority < module::kPriorityObject ? g.half : Half::skirt;
        if (const auto ground = planes(l, g.square, half, p.x, p.z)) {
          p.y = float(follow(p.y, ground->first, ground->second, b.heightStep));
        }
      }
      remap[v] = std::uint32_t(out.vertices.size());
      out.vertices.push_back(p);
      if (normals) out.normals.push_back(v >= shift ? b.normals[v - shift] : 0u);
    }
    // The skirts hang from the re-draped lattice vertices, shared.
    LevelLattice draped = lat;
    for (std::size_t k = 0; k < posts; ++k) draped.heights[k] = out.vertices[k].y;
    draped_.push_back(std::move(draped));

    // The lattice squares that take patches: at level 0 every refined grid
    // square, coarser where the detail matters (Patches::target).
    std::vector<const SquareMesh*> target(nx * nz, nullptr);
    meshes_.clear();
    if (!refined_.empty()) {
      const std::uint32_t span = 1u << l;
      std::vector<std::pair<std::uint32_t, std::uint32_t>> qs;
      for (const auto& [i, j] : refined_) qs.push_back({(j - w_.j0) / span, (i - w_.i0) / span});
      std::sort(qs.begin(), qs.end());
      qs.erase(std::unique(qs.begin(), qs.end()), qs.end());
      meshes_.reserve(qs.size());
      for (const auto& [sb, sa] : qs) {
        if (sa >= nx || sb >= nz) continue;
        Target* t = patches_.target(l, w_.i0 + sa * span, w_.j0 + sb * span);
        if (!t) continue;
        const std::size_t nw = sb * (nx + 1) + sa;
        const std::array<double, 4> corners = {out.vertices[nw].y, out.vertices[nw + 1].y, out.vertices[nw + nx + 1].y,
                                               out.vertices[nw + nx + 2].y};
        SquareMesh m;
        if (!meshTarget(patches_, *t, corners, m)) continue;
        meshes_.push_back(std::move(m));
        target[sb * nx + sa] = &meshes_.back();
        ++stats_.patchSquares[std::size_t(l)];
        if (l == 0) ++stats_.refinedSquares;
      }
    }
    const std::uint32_t kept = std::uint32_t(out.vertices.size());

    pending_.clear();
    scratch_.clear();
    std::optional<module::Surface> baseSurface;  // the base skin's classes, for the new triangles
    for (const Group& g : b.groups) {
      if (isSkirt(g)) continue;
      const SquareMesh* m = g.square < target.size() ? target[g.square] : nullptr;
      if (m && isSkin(g)) continue;  // replaced below
      if (m && isDecal(g)) {
        clipDecal(l, b, g, *m, out);
        continue;
      }
      PendingGroup p{g, std::uint32_t(scratch_.size())};
      for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; ++k) {
        scratch_.push_back(remap[b.indices[k] + shift]);
      }
      pending_.push_back(p);
    }
    if (!meshes_.empty()) {
      baseSurface.emplace(b, false);
      for (const SquareMesh& m : meshes_) skin(l, m, *baseSurface, out);
    }
    // Groups in the level's order, each one run of indices.
    std::stable_sort(pending_.begin(), pending_.end(),
                     [](const PendingGroup& x, const PendingGroup& y) { return groupBefore(x.g, y.g); });
    out.groups.clear();
    out.indices.clear();
    for (const PendingGroup& p : pending_) {
      Group g = p.g;
      const bool merge = !out.groups.empty() && !groupBefore(out.groups.back(), g) && !groupBefore(g, out.groups.back());
      if (!merge) {
        g.firstIndex = std::uint32_t(out.indices.size());
        g.indexCount = 0;
        out.groups.push_back(g);
      }
      out.indices.insert(out.indices.end(), scratch_.begin() + p.first, scratch_.begin() + p.first + p.g.indexCount);
      out.groups.back().indexCount += p.g.indexCount;
    }
    freshFrom_.push_back(normals ? kept : 0);
  }

  /// Module-local x and z of (u, v) in target `m`.
  std::array<double, 2> local(const SquareMesh& m, const UV& p) const {
    const double s = in_.heights->spacing();
    const Target& t = *m.target;
    return {(double(t.gi - w_.i0) + p.u / t.cells) * s, (double(t.gj - w_.j0) + p.v / t.cells) * s};
  }

  /// Appends vertex (u, v) of target `m` at height y, skin texture.
  std::uint32_t addVertex(Level& out, const SquareMesh& m, const UV& p, double y) {
    const auto [x, z] = local(m, p);
    const double s0 = module::skinTextureOffset(after_[0].moduleX), t0 = module::skinTextureOffset(after_[0].moduleZ);
    const Vertex vx{float(x), float(y), float(z), float((s0 + double(float(x))) / module::kSkinTextureRepeat),
                    float((t0 + double(float(z))) / module::kSkinTextureRepeat)};
    out.vertices.push_back(vx);
    return std::uint32_t(out.vertices.size() - 1);
  }

  /// Splits fine triangle `tri` along the crater floor's edge (where `f`,
  /// linear on it, is 0) into its floor part (into `floor`) and the rest
  /// (into `ground`), both on its plane and wound as it is. A crossing
  /// point is shared by the two triangles of an edge (`crossings`) and
  /// computed from the edge's ends in one order, so no T-junction opens.
  /// False, touching nothing, when the edge crosses an edge on the square's
  /// side: the neighbour square would need the same point.
  bool splitAtFloor(int l, const SquareMesh& m, const SquareMesh::Tri& tri, const std::vector<double>& f,
                    const std::vector<std::uint32_t>& id, const Target& t,
                    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t>& crossings, Level& out,
                    std::vector<std::uint32_t>& floor, std::vector<std::uint32_t>& ground) {
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = tri.v[std::size_t(e)], b = tri.v[std::size_t((e + 1) % 3)];
      if ((f[a] > 0) != (f[b] > 0) && (m.sides[a] & m.sides[b])) return false;
    }
    std::vector<double>& step = fineStep_[std::size_t(l)];
    const auto crossing = [&](std::uint32_t a, std::uint32_t b) {
      if (b < a) std::swap(a, b);
      const auto [it, fresh] = crossings.try_emplace({a, b}, 0u);
      if (fresh) {
        const double s = f[a] / (f[a] - f[b]);
        const UV p{m.uv[a].u + s * (m.uv[b].u - m.uv[a].u), m.uv[a].v + s * (m.uv[b].v - m.uv[a].v)};
        it->second = addVertex(out, m, p, m.y[a] + s * (m.y[b] - m.y[a]));
        step.resize(out.vertices.size(), 0);
        step[it->second] = 1.0 / t.cells;
      }
      return it->second;
    };
    std::vector<std::uint32_t> in, outside;  // the two polygons, in the triangle's order
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = tri.v[std::size_t(e)], b = tri.v[std::size_t((e + 1) % 3)];
      (f[a] > 0 ? in : outside).push_back(id[a]);
      if ((f[a] > 0) != (f[b] > 0)) {
        const std::uint32_t x = crossing(a, b);
        in.push_back(x);
        outside.push_back(x);
      }
    }
    const auto fan = [](const std::vector<std::uint32_t>& poly, std::vector<std::uint32_t>& into) {
      for (std::size_t k = 1; k + 1 < poly.size(); ++k) into.insert(into.end(), {poly[0], poly[k], poly[k + 1]});
    };
    fan(in, floor);
    fan(outside, ground);
    return true;
  }

  /// A target's new skin: its triangles, each with the base skin's class
  /// under its centre, or the crater class below the ground before.
  void skin(int l, const SquareMesh& m, const module::Surface& surface, Level& out) {
    const Target& t = *m.target;
    const std::size_t nx = after_[std::size_t(l)].xs.size() - 1, sa = (t.gi - w_.i0) >> l, sb = (t.gj - w_.j0) >> l;
    const std::uint32_t square = std::uint32_t(sb * nx + sa);
    const std::size_t nw = sb * (nx + 1) + sa;
    const std::uint32_t corner[4] = {std::uint32_t(nw), std::uint32_t(nw + 1), std::uint32_t(nw + nx + 1),
                                     std::uint32_t(nw + nx + 2)};
    std::vector<double>& step = fineStep_[std::size_t(l)];
    std::vector<std::uint32_t> id(m.uv.size());
    for (std::size_t k = 0; k < m.uv.size(); ++k) {
      if (k < 4) {
        id[k] = corner[k];
        continue;
      }
      id[k] = addVertex(out, m, m.uv[k], m.y[k]);
      step.resize(out.vertices.size(), 0);
      step[id[k]] = t.inRegion(m.uv[k].u, m.uv[k].v) ? 1.0 / t.cells : 0.0;
      if (m.sides[k]) {
        lineVertices_[std::size_t(l)].push_back(id[k]);
        linePoints_.push_back({double(t.gi) + m.uv[k].u / t.cells, double(t.gj) + m.uv[k].v / t.cells,
                               (m.sides[k] & (kWest | kEast)) != 0, m.y[k]});
      }
    }
    const LevelLattice& o = before_[std::size_t(l)];
    const std::size_t w = o.xs.size();
    const double onw = o.heights[sb * w + sa], one = o.heights[sb * w + sa + 1];
    const double osw = o.heights[(sb + 1) * w + sa], ose = o.heights[(sb + 1) * w + sa + 1];
    // One pending group per (half, material), in triangle order.
    std::vector<std::pair<std::pair<Half, std::uint16_t>, std::vector<std::uint32_t>>> runs;
    // A run's index (not a reference: making another run may move them).
    const auto runOf = [&runs](Half half, std::uint16_t material) {
      auto it = std::find_if(runs.begin(), runs.end(), [&](const auto& r) { return r.first == std::pair{half, material}; });
      if (it != runs.end()) return std::size_t(it - runs.begin());
      runs.push_back({{half, material}, {}});
      return runs.size() - 1;
    };
    // How far each vertex lies below the ground before, less the floor's
    // threshold: positive on the crater's floor.
    std::vector<double> f(m.uv.size());
    for (std::size_t k = 0; k < m.uv.size(); ++k) {
      f[k] = terrain::planeHeight(m.uv[k].u / m.n, m.uv[k].v / m.n, onw, one, osw, ose) - m.y[k] - kCraterFloorDepth;
    }
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> crossings;
    for (const SquareMesh::Tri& tri : m.tris) {
      UV c{0, 0};
      for (const std::uint32_t k : tri.v) c.u += m.uv[k].u / 3, c.v += m.uv[k].v / 3;
      const auto [cx, cz] = local(m, c);
      const std::uint16_t ground = surface.skin(cx, cz).material;
      int floorCorners = 0;
      for (const std::uint32_t k : tri.v) floorCorners += f[k] > 0;
      const std::size_t groundRun = runOf(tri.half, ground);
      if (!tri.fine || !in_.options->craterMaterial || floorCorners == 0) {
        for (const std::uint32_t k : tri.v) runs[groundRun].second.push_back(id[k]);
        continue;
      }
      const std::size_t floorRun = runOf(tri.half, *in_.options->craterMaterial);
      if (floorCorners == 3 ||
          !splitAtFloor(l, m, tri, f, id, t, crossings, out, runs[floorRun].second, runs[groundRun].second)) {
        // Whole, or crossing the square's side (where the neighbour square
        // could not split at the same point): by its centre.
        const double depth = (f[tri.v[0]] + f[tri.v[1]] + f[tri.v[2]]) / 3;
        for (const std::uint32_t k : tri.v) runs[depth > 0 ? floorRun : groundRun].second.push_back(id[k]);
      }
    }
    for (const auto& [key, idx] : runs) {
      if (idx.empty()) continue;
      Group g;
      g.square = square;
      g.half = key.first;
      g.priority = module::kPrioritySkin;
      g.material = key.second;
      g.indexCount = std::uint32_t(idx.size());
      pending_.push_back({g, std::uint32_t(scratch_.size())});
      scratch_.insert(scratch_.end(), idx.begin(), idx.end());
    }
  }

  /// A decal group of a refined square, clipped against the square's new
  /// triangles of its half: each piece on its triangle's plane, texture
  /// coordinates interpolated from the decal triangle.
  void clipDecal(int l, const Level& b, const Group& g, const SquareMesh& m, Level& out) {
    const Target& tg = *m.target;
    const std::array<double, 2> origin = local(m, {0, 0});  // not a structured binding: clang 14 cannot capture one
    const double s = in_.heights->spacing();
    auto toUV = [&](const Vertex& p) {
      return UV{(double(p.x) - origin[0]) / s * tg.cells, (double(p.z) - origin[1]) / s * tg.cells};
    };
    PendingGroup pg{g, std::uint32_t(scratch_.size())};
    pg.g.indexCount = 0;
    std::vector<std::uint32_t> candidates;
    std::vector<UV> poly;
    std::vector<double>& step = fineStep_[std::size_t(l)];
    for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; k += 3) {
      std::array<Vertex, 3> dv;
      std::array<UV, 3> d;
      for (int q = 0; q < 3; ++q) {
        dv[std::size_t(q)] = b.vertices[b.indices[k + std::uint32_t(q)]];
        d[std::size_t(q)] = toUV(dv[std::size_t(q)]);
      }
      candidates.clear();
      if (!m.fineTris.empty()) {
        const double n = m.n;
        const auto a0 = std::uint32_t(std::clamp(std::floor(std::min({d[0].u, d[1].u, d[2].u})), 0.0, n));
        const auto a1 = std::uint32_t(std::clamp(std::ceil(std::max({d[0].u, d[1].u, d[2].u})), 0.0, n));
        const auto b0 = std::uint32_t(std::clamp(std::floor(std::min({d[0].v, d[1].v, d[2].v})), 0.0, n));
        const auto b1 = std::uint32_t(std::clamp(std::ceil(std::max({d[0].v, d[1].v, d[2].v})), 0.0, n));
        for (std::uint32_t fb = b0; fb < b1; ++fb) {
          for (std::uint32_t fa = a0; fa < a1; ++fa) {
            const auto it = m.fineTris.find(std::uint64_t(fa) << 32 | fb);
            if (it == m.fineTris.end()) continue;
            for (std::uint32_t t = it->second.first; t < it->second.second; ++t) candidates.push_back(t);
          }
        }
      }
      for (std::uint32_t t = m.restBegin; t < m.tris.size(); ++t) candidates.push_back(t);
      for (const std::uint32_t t : candidates) {
        const SquareMesh::Tri& tri = m.tris[t];
        if (tri.half != g.half) continue;
        const std::array<UV, 3> c = {m.uv[tri.v[0]], m.uv[tri.v[1]], m.uv[tri.v[2]]};
        intersectTriangles(d, c, poly);
        if (poly.size() < 3) continue;
        double area = 0;
        for (std::size_t q = 1; q + 1 < poly.size(); ++q) area += upArea(poly[0], poly[q], poly[q + 1]);
        if (std::fabs(area) < 1e-9) continue;  // a sliver along a shared edge
        if (area < 0) std::reverse(poly.begin(), poly.end());
        const auto first = std::uint32_t(out.vertices.size());
        for (const UV& p : poly) {
          const auto wc = barycentric(c[0], c[1], c[2], p);
          const double y = wc[0] * m.y[tri.v[0]] + wc[1] * m.y[tri.v[1]] + wc[2] * m.y[tri.v[2]];
          const auto wd = barycentric(d[0], d[1], d[2], p);
          const double st[2] = {wd[0] * dv[0].s + wd[1] * dv[1].s + wd[2] * dv[2].s,
                                wd[0] * dv[0].t + wd[1] * dv[1].t + wd[2] * dv[2].t};
          const auto [x, z] = local(m, p);
          out.vertices.push_back({float(x), float(y), float(z), float(std::max(0.0, st[0])), float(std::clamp(st[1], 0.0, 1.0))});
        }
        step.resize(out.vertices.size(), 0);
        for (std::uint32_t q = first; q < out.vertices.size(); ++q) step[q] = tri.fine ? 1.0 / tg.cells : 0.0;
        for (std::uint32_t q = 1; q + 1 < poly.size(); ++q) {
          scratch_.insert(scratch_.end(), {first, first + q, first + q + 1});
          pg.g.indexCount += 3;
        }
      }
    }
    if (pg.g.indexCount > 0) pending_.push_back(pg);
  }

  /// Every level's skirts must also hang below level 0's fine edge points
  /// on its node lines, and level 0's below every other level there (a
  /// crater on a node edge dips below every lattice; a rim rises above):
  /// skirtDepths' rule at those points too.
  void deepenSkirts() {
    const int levels = int(after_.size());
    for (const LinePoint& p : linePoints_) {
      // Each level's surface there, with and without the patch's detail
      // (whether a level draws it at this very point is its neighbours'
      // business too): the deepest need of either.
      const double d = patches_.detail(p.U, p.V);
      std::vector<std::array<double, 2>> surf(static_cast<std::size_t>(levels));
      double lowest = p.y;
      for (int l = 0; l < levels; ++l) {
        const double plane = latticeSurface(after_[std::size_t(l)], w_, l, p.U, p.V);
        surf[std::size_t(l)] = {plane, plane + d};
        lowest = std::min({lowest, plane, plane + d});
      }
      const double c = p.vertical ? p.U : p.V;
      const std::uint32_t first = p.vertical ? w_.i0 : w_.j0, last = p.vertical ? w_.i1 : w_.j1;
      const auto line = std::uint32_t(std::llround(c));
      for (int l = 0; l < levels; ++l) {
        const std::uint32_t edge = node_ << l;  // node edge in level-0 posts
        if ((line - first) % edge != 0 && line != last) continue;
        const double top = std::max({surf[std::size_t(l)][0], surf[std::size_t(l)][1], p.y});
        const auto need = float(top - lowest + meshing::kSkirtMargin);
        depths_[std::size_t(l)] = std::max(depths_[std::size_t(l)], need);
      }
    }
  }

  void finish(int l, Level& out) {
    const Level& b = in_.base->levels[std::size_t(l)];
    meshing::finishLevel(draped_[std::size_t(l)], node_, depths_[std::size_t(l)], skirtMaterial(b), out,
                         lineVertices_[std::size_t(l)]);
    if (b.normals.empty()) {
      out.normals.clear();
      return;
    }
    normals(l, out);
  }

  /// Normals: the base's where the ground did not change, the builder's
  /// rule (meshing::gridNormal) elsewhere, the fine surface's inside a
  /// refined patch on level 0.
  void normals(int l, Level& out) {
    const double s = in_.heights->spacing();
    const double x0 = after_[0].moduleX, z0 = after_[0].moduleZ;
    const std::uint32_t fresh = freshFrom_[std::size_t(l)];
    out.normals.resize(out.vertices.size(), 0);
    for (std::uint32_t k = 0; k < out.vertices.size(); ++k) {
      const Vertex& p = out.vertices[k];
      const double X = x0 + p.x, Z = z0 + p.z;
      if (k < fresh && !dirty(X / s, Z / s)) continue;
      const std::vector<double>& step = fineStep_[std::size_t(l)];
      if (k < step.size() && step[k] > 0) {
        const double U = X / s, V = Z / s, d = 0.5 * step[k];
        const double gx = (level0Surface(*in_.heights, U + d, V) - level0Surface(*in_.heights, U - d, V)) / (2 * d * s);
        const double gz = (level0Surface(*in_.heights, U, V + d) - level0Surface(*in_.heights, U, V - d)) / (2 * d * s);
        out.normals[k] = meshing::packNormal({-gx, 1.0, -gz});
        continue;
      }
      out.normals[k] = meshing::packNormal(meshing::gridNormal(*in_.heights, X, Z));
    }
  }

  bool dirty(double U, double V) const {
    const grid::PostRect& r = in_.dirty;
    return U + 1 >= double(r.i0) && U <= double(r.i1) && V + 1 >= double(r.j0) && V <= double(r.j1);
  }
};

}  // namespace

module::Module rebuildModule(const RebuildInput& in, RebuildStats& stats) {
  Rebuilder r(in, stats);
  return r.run();
}

void placeObjects(module::Module& m, const grid::HeightField& h, std::uint32_t squares) {
  module::placeBases(m);
  if (m.levels.empty() || !h.anyRefined()) return;
  const double s = h.spacing();
  const double U0 = double(m.kx) * squares, V0 = double(m.kz) * squares;
  Patches patches(h);
  std::vector<std::optional<module::Surface>> surfaces(m.levels.size());
  for (std::size_t k = 0; k < m.objects.size(); ++k) {
    const double U = U0 + double(m.objects[k].x) / s, V = V0 + double(m.objects[k].z) / s;
    const terrain::SquarePoint q = terrain::squareAt(U, V, h.postsX(), h.postsZ());
    if (!h.refined(q.i, q.j)) continue;
    // On every level whose square there takes the patch: the skin drawn
    // there (the fine lattice, or the rest triangles, which leave the
    // level's planes where the patch is wider than its detail).
    for (std::size_t l = 0; l < m.levels.size(); ++l) {
      const std::uint32_t span = 1u << l;
      if (!patches.target(int(l), q.i / span * span, q.j / span * span)) continue;
      if (!surfaces[l]) surfaces[l].emplace(m.levels[l], false);
      const module::Surface::Hit hit = surfaces[l]->skin(m.objects[k].x, m.objects[k].z);
      if (std::isfinite(hit.y)) m.levels[l].objectY[k] = hit.y;
    }
  }
}

}  // namespace sandtable::edits::detail
