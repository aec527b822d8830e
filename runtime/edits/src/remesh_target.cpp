// The lattice squares that take refined patches (remesh_internal.h;
// docs/DYNAMIC.md, "Re-meshing"): which do, their fine regions and edge
// points (the shared-edge rules that keep neighbours free of T-junctions),
// and each one's new triangles: the fine lattice inside its fine region and
// the rest of the square triangulated to the region's border and along the
// square's diagonal.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>

#include "remesh_internal.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::edits::detail {

namespace {

using Patch = std::shared_ptr<const grid::RefinedSquare>;

/// The patch of grid square (i, j), or null (none, or outside the grid).
Patch patchAt(const grid::HeightField& h, std::int64_t i, std::int64_t j) {
  if (i < 0 || j < 0 || i + 1 >= std::int64_t(h.postsX()) || j + 1 >= std::int64_t(h.postsZ())) return nullptr;
  return h.refined(std::uint32_t(i), std::uint32_t(j));
}

/// Planes of grid square (i, j) (or a lattice square from its corner
/// posts) at fractions (fx, fz).
double planesAt(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, std::uint32_t span, double fx, double fz) {
  return terrain::planeHeight(fx, fz, double(h.elevation(i, j)), double(h.elevation(i + span, j)),
                              double(h.elevation(i, j + span)), double(h.elevation(i + span, j + span)));
}

/// Signed area in the module's up-facing sense (module_check's): positive
/// when (a, b, c) faces up with x = u east and z = v south.
double upArea(const UV& a, const UV& b, const UV& c) {
  const double d1x = b.u - a.u, d1z = b.v - a.v, d2x = c.u - a.u, d2z = c.v - a.v;
  return 0.5 * (d1z * d2x - d1x * d2z);
}

int sideIndex(SideBit s) { return s == kNorth ? 0 : s == kSouth ? 1 : s == kWest ? 2 : 3; }

SideBit opposite(SideBit s) {
  switch (s) {
    case kNorth: return kSouth;
    case kSouth: return kNorth;
    case kWest: return kEast;
    case kEast: return kWest;
  }
  return kNorth;
}

}  // namespace

double edgeHeight(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, bool vertical, double t) {
  // The two squares beside the edge, west (north) first.
  const std::int64_t ai = vertical ? std::int64_t(i) - 1 : i, aj = vertical ? j : std::int64_t(j) - 1;
  bool inside = false;
  if (const Patch a = patchAt(h, ai, aj)) {
    const double f = t * a->cells;
    const bool reaches = vertical ? a->a1 == a->cells && f >= a->b0 && f <= a->b1
                                  : a->b1 == a->cells && f >= a->a0 && f <= a->a1;
    if (reaches) {
      const double y = vertical ? grid::refinedHeight(*a, 1.0, t, inside) : grid::refinedHeight(*a, t, 1.0, inside);
      if (inside) return y;
    }
  }
  if (const Patch b = patchAt(h, i, j)) {
    const double f = t * b->cells;
    const bool reaches = vertical ? b->a0 == 0 && f >= b->b0 && f <= b->b1 : b->b0 == 0 && f >= b->a0 && f <= b->a1;
    if (reaches) {
      const double y = vertical ? grid::refinedHeight(*b, 0.0, t, inside) : grid::refinedHeight(*b, t, 0.0, inside);
      if (inside) return y;
    }
  }
  const double e0 = h.elevation(i, j);
  const double e1 = vertical ? h.elevation(i, j + 1) : h.elevation(i + 1, j);
  return e0 + t * (e1 - e0);
}

// ---------------------------------------------------------------- Patches

Target* Patches::target(int level, std::uint32_t gi, std::uint32_t gj) {
  const auto key = std::tuple{level, gi, gj};
  if (const auto it = memo_.find(key); it != memo_.end()) return it->second ? &*it->second : nullptr;
  std::optional<Target>& slot = memo_[key];
  const std::uint32_t span = 1u << level;
  // A full lattice square only: the narrow last one at the database's east
  // or south edge is not square, and its diagonal crosses fine triangles.
  if (std::uint64_t(gi) + span > h_.postsX() - 1 || std::uint64_t(gj) + span > h_.postsZ() - 1) return nullptr;
  Target t;
  t.level = level, t.gi = gi, t.gj = gj, t.span = span;
  double detailMax = 0;
  for (std::uint32_t z = 0; z < span; ++z) {
    for (std::uint32_t x = 0; x < span; ++x) {
      const Patch r = patchAt(h_, gi + x, gj + z);
      if (!r) continue;
      t.cells = std::max(t.cells, r->cells);
      if (level == 0) continue;
      const auto d = r->detail();
      for (std::uint32_t b = d[1]; b <= d[3]; ++b) {
        for (std::uint32_t a = d[0]; a <= d[2]; ++a) {
          const double plane = planesAt(h_, gi + x, gj + z, 1, double(a) / r->cells, double(b) / r->cells);
          detailMax = std::max(detailMax, std::fabs(double(r->at(a, b)) - plane));
        }
      }
    }
  }
  if (t.cells == 0) return nullptr;
  if (level > 0) {
    // A coarser level takes the patch on its own fine lattice, 2^level
    // times coarser (the levels halve their posts; a crater's 0.5 m
    // detail drawn at every level would multiply its triangles by the
    // number of levels).
    t.cells = std::max(1u, t.cells >> level);
    // The levels' error rule (scene::levelErrors): how far this square's
    // planes lie from the finest posts under it. A patch whose detail
    // departs less than that changes nothing the level's error does not
    // already allow; one that departs more is drawn.
    double error = 0;
    for (std::uint32_t z = 0; z <= span; ++z) {
      for (std::uint32_t x = 0; x <= span; ++x) {
        const double plane = planesAt(h_, gi, gj, span, double(x) / span, double(z) / span);
        error = std::max(error, std::fabs(double(h_.elevation(gi + x, gj + z)) - plane));
      }
    }
    if (!(detailMax > std::max(error, kDetailFloor))) return nullptr;
  }
  slot = std::move(t);
  return &*slot;
}

const std::vector<Target::Rect>& Patches::region(Target& t) {
  if (t.regionKnown) return t.rects;
  t.regionKnown = true;
  const std::uint32_t span = t.span;
  for (std::uint32_t z = 0; z < span; ++z) {
    for (std::uint32_t x = 0; x < span; ++x) {
      const std::uint32_t i = t.gi + x, j = t.gj + z;
      const Patch r = patchAt(h_, i, j);
      if (!r) continue;
      // Whether the far side of this square's edge draws a patch there: a
      // refined square in this target, or in a neighbouring target of the
      // level. Where it does not, the row or column of fine squares along
      // the edge is dropped: the far side's edge has only its posts, and
      // the fine posts on it lie on the straight edge (RefinedSquare's
      // rule), so the surface stays whole with no T-junction.
      auto farDraws = [&](int di, int dj, bool leavesTarget) {
        if (!patchAt(h_, std::int64_t(i) + di, std::int64_t(j) + dj)) return false;
        if (!leavesTarget) return true;
        const std::int64_t ni = std::int64_t(t.gi) + di * std::int64_t(span), nj = std::int64_t(t.gj) + dj * std::int64_t(span);
        return ni >= 0 && nj >= 0 && target(t.level, std::uint32_t(ni), std::uint32_t(nj)) != nullptr;
      };
      // The patch's detail only: its other fine posts lie on two planes
      // (RefinedSquare), which the rest triangles draw exactly.
      const auto d = r->detail();
      // Patch units to the target's (both powers of two; a coarser level's
      // are coarser), outward.
      const std::uint64_t n = r->cells, c = t.cells;
      const auto lo = [&](std::uint32_t f) { return std::uint32_t(f * c / n); };
      const auto hi = [&](std::uint32_t f) { return std::uint32_t((f * c + n - 1) / n); };
      std::uint32_t a0 = lo(d[0]), b0 = lo(d[1]), a1 = hi(d[2]), b1 = hi(d[3]);
      if (a0 == 0 && !farDraws(-1, 0, x == 0)) a0 = 1;
      if (a1 == c && !farDraws(1, 0, x + 1 == span)) a1 = t.cells - 1;
      if (b0 == 0 && !farDraws(0, -1, z == 0)) b0 = 1;
      if (b1 == c && !farDraws(0, 1, z + 1 == span)) b1 = t.cells - 1;
      if (a0 >= a1 || b0 >= b1) continue;
      t.rects.push_back({x * t.cells + a0, z * t.cells + b0, x * t.cells + a1, z * t.cells + b1});
    }
  }
  return t.rects;
}

void Patches::regionPostsOnSide(Target& t, SideBit s, std::vector<double>& out) {
  const auto n = std::uint32_t(t.n());
  for (const Target::Rect& r : region(t)) {
    const bool touches = (s == kWest && r.a0 == 0) || (s == kEast && r.a1 == n) || (s == kNorth && r.b0 == 0) ||
                         (s == kSouth && r.b1 == n);
    if (!touches) continue;
    const bool vertical = s == kWest || s == kEast;
    for (std::uint32_t k = vertical ? r.b0 : r.a0; k <= (vertical ? r.b1 : r.a1); ++k) {
      if (k > 0 && k < n) out.push_back(double(k) / n);
    }
  }
}

double Patches::detail(double U, double V) const {
  const double fu = std::floor(U), fv = std::floor(V);
  const bool onColumn = U == fu, onRow = V == fv;
  if (onColumn && onRow) return 0;  // a post: the patches carry its height
  if (onColumn || onRow) {
    const auto i = std::uint32_t(fu), j = std::uint32_t(fv);
    const double t = onColumn ? V - fv : U - fu;
    const double e0 = h_.elevation(i, j), e1 = onColumn ? h_.elevation(i, j + 1) : h_.elevation(i + 1, j);
    return edgeHeight(h_, i, j, onColumn, t) - (e0 + t * (e1 - e0));
  }
  const auto i = std::uint32_t(fu), j = std::uint32_t(fv);
  const Patch r = patchAt(h_, i, j);
  if (!r) return 0;
  bool inside = false;
  const double y = grid::refinedHeight(*r, U - fu, V - fv, inside);
  return inside ? y - planesAt(h_, i, j, 1, U - fu, V - fv) : 0;
}

double Patches::sideHeight(const Target& t, SideBit s, double f) const {
  const std::uint32_t gi = t.gi + (s == kEast ? t.span : 0), gj = t.gj + (s == kSouth ? t.span : 0);
  const bool vertical = s == kWest || s == kEast;
  if (t.level == 0) return edgeHeight(h_, gi, gj, vertical, f);
  const double e0 = h_.elevation(gi, gj);
  const double e1 = vertical ? h_.elevation(gi, gj + t.span) : h_.elevation(gi + t.span, gj);
  const double U = vertical ? double(gi) : gi + f * t.span, V = vertical ? gj + f * t.span : double(gj);
  return e0 + f * (e1 - e0) + detail(U, V);
}

double Patches::interiorHeight(const Target& t, double u, double v) const {
  if (t.level == 0) {
    const Patch r = patchAt(h_, t.gi, t.gj);
    return double(r->at(std::uint32_t(u), std::uint32_t(v)));
  }
  const double n = t.n();
  return planesAt(h_, t.gi, t.gj, t.span, u / n, v / n) + detail(t.gi + u / t.cells, t.gj + v / t.cells);
}

// ---------------------------------------------------------------- one target's mesh

namespace {

class TargetMesher {
 public:
  TargetMesher(Patches& p, Target& t, const std::array<double, 4>& cornerY, SquareMesh& out)
      : p_(p), t_(t), cornerY_(cornerY), m_(out) {}

  bool run() {
    m_ = SquareMesh{};
    m_.target = &t_;
    m_.n = t_.n();
    n_ = std::uint32_t(t_.n());
    onPost_.assign(std::size_t(n_ + 1) * (n_ + 1), kNone);
    offPost_.clear();
    rects_ = p_.region(t_);
    sidePoints();
    bool extra = false;
    for (const auto& s : side_) extra = extra || s.size() > 2;
    if (rects_.empty() && !extra) return false;  // the square's two planes, as it was
    vertices();
    fineTriangles();
    m_.restBegin = std::uint32_t(m_.tris.size());
    restTriangles();
    return true;
  }

 private:
  Patches& p_;
  Target& t_;
  std::array<double, 4> cornerY_;
  SquareMesh& m_;
  std::uint32_t n_ = 1;
  std::vector<Target::Rect> rects_;
  /// Per side (0 north, 1 south, 2 west, 3 east), the fractions of every
  /// vertex on it, corners included, sorted.
  std::array<std::vector<double>, 4> side_;
  /// Vertex ids by position: a fine post's in a dense table (most of
  /// them), any other point's (a neighbour's finer edge points) in a map.
  static constexpr std::uint32_t kNone = UINT32_MAX;
  std::vector<std::uint32_t> onPost_;
  std::map<std::pair<double, double>, std::uint32_t> offPost_;

  /// q's index in onPost_, or SIZE_MAX when q is not a fine post.
  std::size_t postIndex(const UV& q) const {
    const double n = double(n_);
    if (!(q.u >= 0 && q.u <= n && q.v >= 0 && q.v <= n) || q.u != std::floor(q.u) || q.v != std::floor(q.v)) {
      return SIZE_MAX;
    }
    return std::size_t(q.v) * (n_ + 1) + std::size_t(q.u);
  }
  /// The vertex at q, or kNone.
  std::uint32_t find(const UV& q) const {
    if (const std::size_t k = postIndex(q); k != SIZE_MAX) return onPost_[k];
    const auto it = offPost_.find({q.u, q.v});
    return it == offPost_.end() ? kNone : it->second;
  }

  /// Whether fine square (a, b) is in the fine region.
  bool inRegion(std::int64_t a, std::int64_t b) const {
    for (const Target::Rect& r : rects_) {
      if (a >= r.a0 && a < r.a1 && b >= r.b0 && b < r.b1) return true;
    }
    return false;
  }

  void sidePoints() {
    for (const SideBit s : {kNorth, kSouth, kWest, kEast}) {
      std::vector<double>& pts = side_[std::size_t(sideIndex(s))];
      pts = {0.0, 1.0};
      p_.regionPostsOnSide(t_, s, pts);
      // The neighbour's posts on the shared edge, when it takes patches
      // too: both squares then carry the union.
      const std::int64_t span = t_.span;
      const std::int64_t ni = std::int64_t(t_.gi) + (s == kWest ? -span : s == kEast ? span : 0);
      const std::int64_t nj = std::int64_t(t_.gj) + (s == kNorth ? -span : s == kSouth ? span : 0);
      if (ni >= 0 && nj >= 0) {
        if (Target* nb = p_.target(t_.level, std::uint32_t(ni), std::uint32_t(nj))) p_.regionPostsOnSide(*nb, opposite(s), pts);
      }
      std::sort(pts.begin(), pts.end());
      pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
    }
  }

  UV sideUV(SideBit s, double f) const {
    const double n = m_.n;
    switch (s) {
      case kNorth: return {f * n, 0};
      case kSouth: return {f * n, n};
      case kWest: return {0, f * n};
      case kEast: return {n, f * n};
    }
    return {};
  }

  std::uint8_t sidesOf(const UV& q) const {
    std::uint8_t s = 0;
    if (q.v == 0) s |= kNorth;
    if (q.v == m_.n) s |= kSouth;
    if (q.u == 0) s |= kWest;
    if (q.u == m_.n) s |= kEast;
    return s;
  }

  std::uint32_t add(const UV& q, double y) {
    const std::size_t k = postIndex(q);
    std::uint32_t* slot = k != SIZE_MAX ? &onPost_[k] : &offPost_.try_emplace({q.u, q.v}, kNone).first->second;
    if (*slot == kNone) {
      *slot = std::uint32_t(m_.uv.size());
      m_.uv.push_back(q);
      m_.y.push_back(y);
      m_.sides.push_back(sidesOf(q));
    }
    return *slot;
  }

  std::uint32_t id(const UV& q) const {
    const std::uint32_t v = find(q);
    assert(v != kNone);
    return v;
  }

  /// A vertex at (u, v): a corner's height is the caller's (its lattice
  /// vertex), a point on a side its side's rule, any other the target's.
  std::uint32_t point(const UV& q) {
    if (const std::uint32_t v = find(q); v != kNone) return v;
    const std::uint8_t s = sidesOf(q);
    if (s & kNorth && (s & (kWest | kEast))) return add(q, cornerY_[s & kWest ? 0 : 1]);
    if (s & kSouth && (s & (kWest | kEast))) return add(q, cornerY_[s & kWest ? 2 : 3]);
    if (s) {
      const SideBit side = s & kNorth ? kNorth : s & kSouth ? kSouth : s & kWest ? kWest : kEast;
      const bool vertical = side == kWest || side == kEast;
      return add(q, p_.sideHeight(t_, side, (vertical ? q.v : q.u) / m_.n));
    }
    return add(q, p_.interiorHeight(t_, q.u, q.v));
  }

  void vertices() {
    const double n = m_.n;
    for (const UV c : {UV{0, 0}, UV{n, 0}, UV{0, n}, UV{n, n}}) point(c);  // NW, NE, SW, SE
    for (const Target::Rect& r : rects_) {
      for (std::uint32_t b = r.b0; b <= r.b1; ++b) {
        for (std::uint32_t a = r.a0; a <= r.a1; ++a) point({double(a), double(b)});
      }
    }
    for (const SideBit s : {kNorth, kSouth, kWest, kEast}) {
      for (const double f : side_[std::size_t(sideIndex(s))]) point(sideUV(s, f));
    }
  }

  /// Points of side `s` strictly between fractions f0 and f1, in order.
  void between(SideBit s, double f0, double f1, std::vector<std::uint32_t>& out) const {
    const auto& pts = side_[std::size_t(sideIndex(s))];
    const double lo = std::min(f0, f1), hi = std::max(f0, f1);
    const std::size_t first = out.size();
    for (const double f : pts) {
      if (f > lo && f < hi) out.push_back(id(sideUV(s, f)));
    }
    if (f0 > f1) std::reverse(out.begin() + std::ptrdiff_t(first), out.end());
  }

  /// Adds triangle v (facing up) as it is or, where one of its edges on a
  /// side passes other vertices of that side (a finer neighbour's posts),
  /// as a fan from its centroid through them.
  void triangle(std::array<std::uint32_t, 3> v, module::Half half, bool isFine) {
    std::vector<std::uint32_t> ring;
    bool split = false;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = v[std::size_t(k)], b = v[std::size_t((k + 1) % 3)];
      ring.push_back(a);
      const std::uint8_t common = m_.sides[a] & m_.sides[b];
      if (!common) continue;
      const SideBit s = common & kNorth ? kNorth : common & kSouth ? kSouth : common & kWest ? kWest : kEast;
      const bool vertical = s == kWest || s == kEast;
      const std::size_t before = ring.size();
      between(s, (vertical ? m_.uv[a].v : m_.uv[a].u) / m_.n, (vertical ? m_.uv[b].v : m_.uv[b].u) / m_.n, ring);
      split = split || ring.size() > before;
    }
    if (!split) {
      m_.tris.push_back({v, half, isFine});
      return;
    }
    // The centroid lies on the triangle's plane: the mean of its heights.
    UV c{0, 0};
    double y = 0;
    for (const std::uint32_t k : v) c.u += m_.uv[k].u / 3, c.v += m_.uv[k].v / 3, y += m_.y[k] / 3;
    const auto ci = std::uint32_t(m_.uv.size());
    m_.uv.push_back(c);
    m_.y.push_back(y);
    m_.sides.push_back(0);
    for (std::size_t k = 0; k < ring.size(); ++k) {
      m_.tris.push_back({{ci, ring[k], ring[(k + 1) % ring.size()]}, half, isFine});
    }
  }

  void fineTriangles() {
    for (const Target::Rect& r : rects_) {
      for (std::uint32_t b = r.b0; b < r.b1; ++b) {
        for (std::uint32_t a = r.a0; a < r.a1; ++a) {
          const auto first = std::uint32_t(m_.tris.size());
          const std::uint32_t nw = id({double(a), double(b)}), ne = id({double(a + 1), double(b)});
          const std::uint32_t sw = id({double(a), double(b + 1)}), se = id({double(a + 1), double(b + 1)});
          // The square's diagonal runs along fine diagonals (a + b + 1 = n):
          // every fine triangle lies in one half of the square.
          triangle({nw, sw, ne}, a + b + 1 <= n_ ? module::Half::upper : module::Half::lower, true);
          triangle({ne, sw, se}, a + b + 1 >= n_ ? module::Half::lower : module::Half::upper, true);
          m_.fineTris[std::uint64_t(a) << 32 | b] = {first, std::uint32_t(m_.tris.size())};
        }
      }
    }
  }

  void restTriangles() {
    const double n = m_.n;
    std::vector<UV> pts;
    std::vector<std::uint32_t> ids;  // pts[k] is vertex ids[k]
    std::vector<std::pair<std::uint32_t, std::uint32_t>> cons;
    std::map<std::uint32_t, std::uint32_t> local;
    auto use = [&](std::uint32_t vid) {
      const auto [it, fresh] = local.try_emplace(vid, std::uint32_t(pts.size()));
      if (fresh) {
        pts.push_back(m_.uv[vid]);
        ids.push_back(vid);
      }
      return it->second;
    };
    for (const SideBit s : {kNorth, kSouth, kWest, kEast}) {
      const auto& f = side_[std::size_t(sideIndex(s))];
      for (std::size_t k = 0; k + 1 < f.size(); ++k) cons.push_back({use(id(sideUV(s, f[k]))), use(id(sideUV(s, f[k + 1])))});
    }
    // The fine region's border; where it runs along a side, the side's own
    // constraints (through the neighbour's points) are it.
    for (const Target::Rect& r : rects_) {
      for (std::uint32_t b = r.b0; b < r.b1; ++b) {
        for (std::uint32_t a = r.a0; a < r.a1; ++a) {
          const std::int64_t na[4][2] = {{a, std::int64_t(b) - 1}, {a, b + 1}, {std::int64_t(a) - 1, b}, {a + 1, b}};
          const UV ends[4][2] = {{{double(a), double(b)}, {double(a + 1), double(b)}},
                                 {{double(a), double(b + 1)}, {double(a + 1), double(b + 1)}},
                                 {{double(a), double(b)}, {double(a), double(b + 1)}},
                                 {{double(a + 1), double(b)}, {double(a + 1), double(b + 1)}}};
          for (int e = 0; e < 4; ++e) {
            if (inRegion(na[e][0], na[e][1])) continue;
            const std::uint32_t p = id(ends[e][0]), q = id(ends[e][1]);
            if (m_.sides[p] & m_.sides[q]) continue;
            cons.push_back({use(p), use(q)});
          }
        }
      }
    }
    // The square's SW-NE diagonal where it runs outside the fine region
    // (inside, the fine diagonals are it): runs of diagonal fine squares
    // not in the region, split at every vertex on them.
    std::uint32_t from = use(2);  // SW
    for (std::uint32_t k = 0; k < n_; ++k) {
      const bool fine = inRegion(k, n_ - 1 - k);
      const UV end{double(k + 1), double(n_ - 1 - k)};
      const std::uint32_t at = find(end);
      if (fine) {
        if (at != kNone) from = use(at);
        continue;
      }
      if (at == kNone) continue;  // no vertex there: the run goes on
      const std::uint32_t to = use(at);
      if (to != from) cons.push_back({from, to});
      from = to;
    }
    std::vector<std::array<std::uint32_t, 3>> faces;
    constrainedTriangulation(pts, cons, faces);
    for (const auto& f : faces) {
      const UV c{(pts[f[0]].u + pts[f[1]].u + pts[f[2]].u) / 3, (pts[f[0]].v + pts[f[1]].v + pts[f[2]].v) / 3};
      if (inRegion(std::int64_t(std::floor(c.u)), std::int64_t(std::floor(c.v))) &&
          inRegion(std::int64_t(std::ceil(c.u)) - 1, std::int64_t(std::ceil(c.v)) - 1)) {
        continue;  // the fine region's
      }
      std::array<std::uint32_t, 3> v = {ids[f[0]], ids[f[1]], ids[f[2]]};
      if (upArea(m_.uv[v[0]], m_.uv[v[1]], m_.uv[v[2]]) < 0) std::swap(v[1], v[2]);
      m_.tris.push_back({v, c.u + c.v <= n ? module::Half::upper : module::Half::lower, false});
    }
  }
};

}  // namespace

bool meshTarget(Patches& p, Target& t, const std::array<double, 4>& cornerY, SquareMesh& out) {
  TargetMesher mesher(p, t, cornerY, out);
  return mesher.run();
}

}  // namespace sandtable::edits::detail
