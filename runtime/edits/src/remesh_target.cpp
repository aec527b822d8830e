// One refined grid square at level 0 (remesh_internal.h; docs/DYNAMIC.md,
// "Re-meshing"): the fine lattice inside the patch, the rest of the square
// triangulated to the patch's border and along the square's diagonal, and
// the shared-edge rules that keep neighbours free of T-junctions.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>

#include "remesh_internal.h"

namespace sandtable::edits::detail {

namespace {

using Patch = std::shared_ptr<const grid::RefinedSquare>;

/// The patch of square (i, j), or null (none, or outside the grid).
Patch patchAt(const grid::HeightField& h, std::int64_t i, std::int64_t j) {
  if (i < 0 || j < 0 || i + 1 >= std::int64_t(h.postsX()) || j + 1 >= std::int64_t(h.postsZ())) return nullptr;
  return h.refined(std::uint32_t(i), std::uint32_t(j));
}

/// The fine region of square (i, j) whose patch is `r`: the patch, less
/// the row or column of fine squares along a square edge whose neighbour
/// has no patch (the neighbour's edge has only its two posts; the fine
/// posts on it lie on the straight edge anyway, RefinedSquare's rule, so
/// dropping them leaves the surface whole and no T-junction).
struct Region {
  std::uint32_t a0 = 0, b0 = 0, a1 = 0, b1 = 0;
  bool empty() const { return a0 >= a1 || b0 >= b1; }
};

Region fineRegion(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, const grid::RefinedSquare& r) {
  Region g{r.a0, r.b0, r.a1, r.b1};
  const std::uint32_t n = r.cells;
  if (g.a0 == 0 && !patchAt(h, std::int64_t(i) - 1, j)) g.a0 = 1;
  if (g.a1 == n && !patchAt(h, std::int64_t(i) + 1, j)) g.a1 = n - 1;
  if (g.b0 == 0 && !patchAt(h, i, std::int64_t(j) - 1)) g.b0 = 1;
  if (g.b1 == n && !patchAt(h, i, std::int64_t(j) + 1)) g.b1 = n - 1;
  return g;
}

/// Fractions (0 < t < 1) along the shared edge at which a square's fine
/// region has posts on its side `side`.
void regionPostsOnSide(const grid::RefinedSquare& r, const Region& g, SideBit side, std::vector<double>& out) {
  const double n = r.cells;
  const bool touches = (side == kWest && g.a0 == 0 && !g.empty()) || (side == kEast && g.a1 == r.cells && !g.empty()) ||
                       (side == kNorth && g.b0 == 0 && !g.empty()) || (side == kSouth && g.b1 == r.cells && !g.empty());
  if (!touches) return;
  const bool vertical = side == kWest || side == kEast;
  const std::uint32_t lo = vertical ? g.b0 : g.a0, hi = vertical ? g.b1 : g.a1;
  for (std::uint32_t k = lo; k <= hi; ++k) {
    if (k > 0 && k < r.cells) out.push_back(double(k) / n);
  }
}

SideBit opposite(SideBit s) {
  switch (s) {
    case kNorth: return kSouth;
    case kSouth: return kNorth;
    case kWest: return kEast;
    case kEast: return kWest;
  }
  return kNorth;
}

/// Signed area in the module's up-facing sense (module_check's): positive
/// when (a, b, c) faces up with x = u east and z = v south.
double upArea(const UV& a, const UV& b, const UV& c) {
  const double d1x = b.u - a.u, d1z = b.v - a.v, d2x = c.u - a.u, d2z = c.v - a.v;
  return 0.5 * (d1z * d2x - d1x * d2z);
}

class SquareMesher {
 public:
  SquareMesher(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, const std::array<double, 4>& cornerY,
               SquareMesh& out)
      : h_(h), i_(i), j_(j), cornerY_(cornerY), m_(out) {}

  bool run() {
    m_ = SquareMesh{};
    m_.i = i_, m_.j = j_;
    m_.patch = h_.refined(i_, j_);
    if (!m_.patch) return false;
    const grid::RefinedSquare& r = *m_.patch;
    n_ = r.cells;
    m_.n = double(n_);
    const Region g = fineRegion(h_, i_, j_, r);
    m_.fa0 = g.a0, m_.fb0 = g.b0, m_.fa1 = g.a1, m_.fb1 = g.b1;
    if (g.empty()) m_.fa0 = m_.fa1 = m_.fb0 = m_.fb1 = 0;
    sidePoints(g);
    bool extra = false;
    for (const auto& s : side_) extra = extra || s.size() > 2;
    if (m_.fineEmpty() && !extra) return false;  // the square's two planes, as it was
    vertices();
    fineTriangles();
    restTriangles();
    return true;
  }

 private:
  const grid::HeightField& h_;
  std::uint32_t i_, j_, n_ = 1;
  std::array<double, 4> cornerY_;
  SquareMesh& m_;
  /// Per side (index: 0 north, 1 south, 2 west, 3 east), the fractions of
  /// every vertex on it, corners included, sorted.
  std::array<std::vector<double>, 4> side_;
  std::map<std::pair<double, double>, std::uint32_t> byUV_;
  std::vector<std::uint32_t> fineId_;  ///< fine region posts, row-major

  static int sideIndex(SideBit s) { return s == kNorth ? 0 : s == kSouth ? 1 : s == kWest ? 2 : 3; }

  void sidePoints(const Region& g) {
    for (const SideBit s : {kNorth, kSouth, kWest, kEast}) {
      std::vector<double>& pts = side_[std::size_t(sideIndex(s))];
      pts = {0.0, 1.0};
      regionPostsOnSide(*m_.patch, g, s, pts);
      // The neighbour's posts on the shared edge, when it is refined too:
      // both squares then carry the union.
      const std::int64_t ni = std::int64_t(i_) + (s == kWest ? -1 : s == kEast ? 1 : 0);
      const std::int64_t nj = std::int64_t(j_) + (s == kNorth ? -1 : s == kSouth ? 1 : 0);
      if (const Patch nb = patchAt(h_, ni, nj)) {
        regionPostsOnSide(*nb, fineRegion(h_, std::uint32_t(ni), std::uint32_t(nj), *nb), opposite(s), pts);
      }
      std::sort(pts.begin(), pts.end());
      pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
    }
  }

  UV sideUV(SideBit s, double t) const {
    const double n = m_.n;
    switch (s) {
      case kNorth: return {t * n, 0};
      case kSouth: return {t * n, n};
      case kWest: return {0, t * n};
      case kEast: return {n, t * n};
    }
    return {};
  }

  double sideHeight(SideBit s, double t) const {
    switch (s) {
      case kNorth: return edgeHeight(h_, i_, j_, false, t);
      case kSouth: return edgeHeight(h_, i_, j_ + 1, false, t);
      case kWest: return edgeHeight(h_, i_, j_, true, t);
      case kEast: return edgeHeight(h_, i_ + 1, j_, true, t);
    }
    return 0;
  }

  std::uint8_t sidesOf(const UV& p) const {
    std::uint8_t s = 0;
    if (p.v == 0) s |= kNorth;
    if (p.v == m_.n) s |= kSouth;
    if (p.u == 0) s |= kWest;
    if (p.u == m_.n) s |= kEast;
    return s;
  }

  std::uint32_t add(const UV& p, double y) {
    const auto [it, fresh] = byUV_.try_emplace({p.u, p.v}, std::uint32_t(m_.uv.size()));
    if (fresh) {
      m_.uv.push_back(p);
      m_.y.push_back(y);
      m_.sides.push_back(sidesOf(p));
    }
    return it->second;
  }

  /// A point on the square's boundary: a corner's height is the caller's
  /// (its lattice vertex), any other point's its side's edge rule.
  std::uint32_t boundary(const UV& p) {
    const std::uint8_t s = sidesOf(p);
    if (s & kNorth && (s & (kWest | kEast))) return add(p, cornerY_[s & kWest ? 0 : 1]);
    if (s & kSouth && (s & (kWest | kEast))) return add(p, cornerY_[s & kWest ? 2 : 3]);
    const SideBit side = s & kNorth ? kNorth : s & kSouth ? kSouth : s & kWest ? kWest : kEast;
    const bool vertical = side == kWest || side == kEast;
    return add(p, sideHeight(side, (vertical ? p.v : p.u) / m_.n));
  }

  void vertices() {
    const double n = m_.n;
    for (const UV c : {UV{0, 0}, UV{n, 0}, UV{0, n}, UV{n, n}}) boundary(c);  // NW, NE, SW, SE
    if (!m_.fineEmpty()) {
      const grid::RefinedSquare& r = *m_.patch;
      const std::uint32_t w = m_.fa1 - m_.fa0 + 1;
      fineId_.resize(std::size_t(w) * (m_.fb1 - m_.fb0 + 1));
      for (std::uint32_t b = m_.fb0; b <= m_.fb1; ++b) {
        for (std::uint32_t a = m_.fa0; a <= m_.fa1; ++a) {
          const UV p{double(a), double(b)};
          fineId_[std::size_t(b - m_.fb0) * w + (a - m_.fa0)] = sidesOf(p) ? boundary(p) : add(p, double(r.at(a, b)));
        }
      }
    }
    for (const SideBit s : {kNorth, kSouth, kWest, kEast}) {
      for (const double t : side_[std::size_t(sideIndex(s))]) boundary(sideUV(s, t));
    }
  }

  std::uint32_t fine(std::uint32_t a, std::uint32_t b) const {
    return fineId_[std::size_t(b - m_.fb0) * (m_.fa1 - m_.fa0 + 1) + (a - m_.fa0)];
  }

  /// Points of side `s` strictly between fractions t0 and t1.
  void between(SideBit s, double t0, double t1, std::vector<std::uint32_t>& out) {
    const auto& pts = side_[std::size_t(sideIndex(s))];
    const double lo = std::min(t0, t1), hi = std::max(t0, t1);
    const std::size_t first = out.size();
    for (const double t : pts) {
      if (t > lo && t < hi) out.push_back(byUV_.at({sideUV(s, t).u, sideUV(s, t).v}));
    }
    if (t0 > t1) std::reverse(out.begin() + std::ptrdiff_t(first), out.end());
  }

  /// Adds triangle (a, b, c), facing up: as it is, or, where one of its
  /// edges on a square side passes other vertices of that side (a finer
  /// neighbour's posts), as a fan from its centroid through them.
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
    if (m_.fineEmpty()) return;
    const std::uint32_t n = n_;
    m_.fineStart.clear();
    for (std::uint32_t b = m_.fb0; b < m_.fb1; ++b) {
      for (std::uint32_t a = m_.fa0; a < m_.fa1; ++a) {
        m_.fineStart.push_back(std::uint32_t(m_.tris.size()));
        const std::uint32_t nw = fine(a, b), ne = fine(a + 1, b), sw = fine(a, b + 1), se = fine(a + 1, b + 1);
        // The square's diagonal runs along fine diagonals (a + b + 1 = n):
        // every fine triangle lies in one half of the square.
        triangle({nw, sw, ne}, a + b + 1 <= n ? module::Half::upper : module::Half::lower, true);
        triangle({ne, sw, se}, a + b + 1 >= n ? module::Half::lower : module::Half::upper, true);
      }
    }
    m_.fineStart.push_back(std::uint32_t(m_.tris.size()));
  }

  void restTriangles() {
    const double n = m_.n;
    std::vector<UV> pts;
    std::vector<std::uint32_t> ids;  // pts[k] is vertex ids[k]
    std::vector<std::pair<std::uint32_t, std::uint32_t>> cons;
    std::map<std::uint32_t, std::uint32_t> local;
    auto use = [&](std::uint32_t id) {
      const auto [it, fresh] = local.try_emplace(id, std::uint32_t(pts.size()));
      if (fresh) {
        pts.push_back(m_.uv[id]);
        ids.push_back(id);
      }
      return it->second;
    };
    for (const SideBit s : {kNorth, kSouth, kWest, kEast}) {
      const auto& t = side_[std::size_t(sideIndex(s))];
      for (std::size_t k = 0; k + 1 < t.size(); ++k) {
        const UV p = sideUV(s, t[k]), q = sideUV(s, t[k + 1]);
        cons.push_back({use(byUV_.at({p.u, p.v})), use(byUV_.at({q.u, q.v}))});
      }
    }
    const bool hole = !m_.fineEmpty();
    if (hole) {
      // The fine region's border; where it runs along a square side, the
      // side's own constraints (through the neighbour's points) are it.
      auto border = [&](std::uint32_t p, std::uint32_t q) {
        if (!(m_.sides[p] & m_.sides[q])) cons.push_back({use(p), use(q)});
      };
      for (std::uint32_t a = m_.fa0; a < m_.fa1; ++a) {
        border(fine(a, m_.fb0), fine(a + 1, m_.fb0));
        border(fine(a, m_.fb1), fine(a + 1, m_.fb1));
      }
      for (std::uint32_t b = m_.fb0; b < m_.fb1; ++b) {
        border(fine(m_.fa0, b), fine(m_.fa0, b + 1));
        border(fine(m_.fa1, b), fine(m_.fa1, b + 1));
      }
    }
    // The square's SW-NE diagonal, where it runs outside the fine region
    // (inside it the fine diagonals are it).
    const std::uint32_t sw = use(2), ne = use(1);
    const double lo = hole ? std::max(double(m_.fa0), n - double(m_.fb1)) : 1.0;
    const double hi = hole ? std::min(double(m_.fa1), n - double(m_.fb0)) : 0.0;
    if (lo <= hi) {
      const std::uint32_t enter = use(fine(std::uint32_t(lo), std::uint32_t(n - lo)));
      const std::uint32_t leave = use(fine(std::uint32_t(hi), std::uint32_t(n - hi)));
      if (lo > 0) cons.push_back({sw, enter});
      if (hi < n) cons.push_back({leave, ne});
    } else {
      cons.push_back({sw, ne});
    }
    std::vector<std::array<std::uint32_t, 3>> faces;
    constrainedTriangulation(pts, cons, faces);
    for (const auto& f : faces) {
      const UV c{(pts[f[0]].u + pts[f[1]].u + pts[f[2]].u) / 3, (pts[f[0]].v + pts[f[1]].v + pts[f[2]].v) / 3};
      if (hole && c.u > m_.fa0 && c.u < m_.fa1 && c.v > m_.fb0 && c.v < m_.fb1) continue;  // the fine region
      std::array<std::uint32_t, 3> v = {ids[f[0]], ids[f[1]], ids[f[2]]};
      if (upArea(m_.uv[v[0]], m_.uv[v[1]], m_.uv[v[2]]) < 0) std::swap(v[1], v[2]);
      m_.tris.push_back({v, c.u + c.v <= n ? module::Half::upper : module::Half::lower, false});
    }
  }
};

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

bool meshRefinedSquare(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, const std::array<double, 4>& cornerY,
                       SquareMesh& out) {
  SquareMesher mesher(h, i, j, cornerY, out);
  return mesher.run();
}

}  // namespace sandtable::edits::detail
