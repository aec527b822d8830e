// One grid triangle's points: placed on the vertex step or rounded to
// float, unified, merged within the tolerance (corners fixed, edge points
// along their edge) and each merged polygon triangulated.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "culture_level_work.h"

namespace sandtable::convert {
namespace culture {

/// p as written: on the vertex step where the level has one, else
/// rounded to float. Edge points keep their edge's coordinate (a
/// multiple of the step); an inner point that the step would carry
/// across the diagonal goes onto it (the step's points on the diagonal
/// are exact) and becomes a diagonal point.
CP LevelWork::placed(CP p, const Tri& t) const {
  if (!stepped_ || (p.on == 0 && !t.exactDiag)) {
    p.p = round(p.p);
    return p;
  }
  if (p.on & kDiag) {
    p.p = round(p.p);  // diagPoint put it on the step already
    return p;
  }
  const Vec2 q{roundStep(p.p.x), roundStep(p.p.z)};
  if (p.on == 0 && !t.insideDiag(t.f(q))) {
    const double dx = t.x1 - t.x0;
    p.p = round(t.diagPoint(std::clamp((q.x - t.x0) / dx, 0.0, 1.0)));
    p.on = kDiag;
    return p;
  }
  p.p = round(q);
  return p;
}


double LevelWork::area2(const OutTri& o) const {
  return cross(points_[o.b].p - points_[o.a].p, points_[o.c].p - points_[o.a].p);
}


/// Polygons of layers [first, end) in the triangle, points unified.
void LevelWork::gather(std::size_t sq, const Tri& t, std::size_t first, std::size_t end) {
  polys_.clear();
  flat_.clear();
  for (std::size_t l = first; l < end; ++l) {
    if (modes_[l] == Mode::whole) {
      polys_.push_back({std::uint32_t(l), labels_[l], {}});
      for (int k = 0; k < 3; ++k) addPoint({t.c[k], t.cb[k]}, t);
      continue;
    }
    if (modes_[l] != Mode::cut) continue;
    const ModuleCell::Layer& layer = cell_.layers[l];
    const LevelLayer& ll = layers_[l];
    bool any = false;
    for (std::uint32_t k = ll.start[sq]; k < ll.start[sq + 1]; ++k) {
      const Piece& piece = layer.geo.pieces[ll.pieces[k]];
      if (!piece.box.overlaps(t.box)) continue;
      clipPiece(piece.pts, t, clipped_, clipTmp_);
      if (clipped_.empty()) continue;
      any = true;
      polys_.push_back({std::uint32_t(l), piece.label, {}});
      for (const CP& p : clipped_) addPoint(p, t);
    }
    if (!any && l == 0) {
      // No skin piece reached the triangle (never expected): the label
      // at its centroid covers it.
      polys_.push_back({0, labelAt(0, sq, (1.0 / 3.0) * (t.c[0] + t.c[1] + t.c[2])), {}});
      for (int k = 0; k < 3; ++k) addPoint({t.c[k], t.cb[k]}, t);
    }
  }
  // Points are rounded to float (what is written) as they are added;
  // equal points are unified. Points that rounding puts on two edges
  // are that corner.
  for (int pass = 0; pass < 2; ++pass) {
    order_.resize(flat_.size());
    std::iota(order_.begin(), order_.end(), 0);
    std::sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) {
      return lexLess(flat_[a].first.p, flat_[b].first.p) || (flat_[a].first.p == flat_[b].first.p && a < b);
    });
    points_.clear();
    pointOf_.assign(flat_.size(), 0);
    for (std::size_t k = 0; k < order_.size(); ++k) {
      const CP& cp = flat_[order_[k]].first;
      if (points_.empty() || !(points_.back().p == cp.p)) points_.push_back({cp.p, cp.on, false, 0});
      else points_.back().on |= cp.on;
      pointOf_[order_[k]] = std::uint32_t(points_.size() - 1);
    }
    bool moved = false;
    for (auto& f : flat_) {
      const SnapPoint& sp = points_[pointOf_[&f - flat_.data()]];
      if (bits(sp.on) < 2) continue;
      const Vec2 corner = round(t.cornerOf(sp.on));
      if (!(f.first.p == corner)) f.first.p = corner, moved = true;
      f.first.on = sp.on;
    }
    if (!moved) break;
  }
  for (std::size_t k = 0; k < flat_.size(); ++k) {
    auto& ids = polys_[flat_[k].second].ids;
    if (ids.empty() || ids.back() != pointOf_[k]) ids.push_back(pointOf_[k]);
  }
  for (Poly& p : polys_) {
    while (p.ids.size() > 1 && p.ids.front() == p.ids.back()) p.ids.pop_back();
  }
}


/// Merges points closer than the tolerance: corners never move, edge
/// points move only along their edge (or onto its corners), inner points
/// anywhere. Deterministic: by kind, then position. What happens to a
/// point on an edge depends only on the points on that edge, so the two
/// grid triangles sharing it (in this module or the next) agree.
void LevelWork::snap(const Tri& t) {
  const std::size_t n = points_.size();
  std::vector<std::uint32_t>& ord = snapOrder_;
  ord.resize(n);
  std::iota(ord.begin(), ord.end(), 0u);
  std::stable_sort(ord.begin(), ord.end(), [&](std::uint32_t a, std::uint32_t b) {
    return bits(points_[a].on) > bits(points_[b].on);
  });
  reps_.clear();
  const double tol2 = tol_ * tol_;
  // An edge point this close to an end of its edge goes to that end, so
  // that two points on the two edges of a corner of 45 degrees or more
  // are never left closer than the tolerance: 2 R sin(22.5 deg) = tol.
  const double cornerR = tol_ / (2.0 * std::sin(std::numbers::pi / 8));
  points_.reserve(n + 3);  // cornerPoint adds at most the three corners: `p` stays valid
  for (std::uint32_t i : ord) {
    SnapPoint& p = points_[i];
    p.rep = i;
    if (p.fixed || bits(p.on) >= 2 || tol_ <= 0) {
      reps_.push_back(i);
      continue;
    }
    if (bits(p.on) == 1) {
      for (int k = 0; k < 3 && p.rep == i; ++k) {
        if ((t.cb[k] & p.on) != p.on) continue;
        const Vec2 corner = round(t.c[k]);
        const Vec2 d = corner - p.p;
        if (dot(d, d) < cornerR * cornerR) p.rep = cornerPoint(corner, t.cb[k]);
      }
      if (p.rep != i) continue;
    }
    double best = tol2;
    for (std::uint32_t r : reps_) {
      const SnapPoint& q = points_[r];
      if ((p.on & ~q.on) != 0) continue;
      const Vec2 d = q.p - p.p;
      const double d2 = dot(d, d);
      if (d2 < best) best = d2, p.rep = r;
    }
    if (p.rep == i) reps_.push_back(i);
  }
}


/// The point at a corner of the triangle (added when no polygon has it).
std::uint32_t LevelWork::cornerPoint(Vec2 corner, std::uint8_t on) {
  for (std::uint32_t r : reps_) {
    if (points_[r].p == corner) return r;
  }
  const std::uint32_t ci = std::uint32_t(points_.size());
  points_.push_back({corner, on, false, ci});
  reps_.push_back(ci);
  return ci;
}


/// Triangulates every merged polygon into tris_ (a fan when that is
/// valid, else ear clipping). Returns false when a merge left a polygon
/// that cannot be triangulated (folded); its merged points are then fixed
/// for the next attempt.
bool LevelWork::triangulate() {
  tris_.clear();
  bool ok = true;
  for (std::uint32_t k = 0; k < polys_.size(); ++k) {
    std::vector<std::uint32_t>& m = mapped_;
    m.clear();
    for (std::uint32_t id : polys_[k].ids) {
      const std::uint32_t r = points_[id].rep;
      if (m.empty() || m.back() != r) m.push_back(r);
    }
    while (m.size() > 1 && m.front() == m.back()) m.pop_back();
    if (m.size() < 3) continue;
    if (!fanOrClip(k, m)) {
      ok = false;
      for (std::uint32_t id : polys_[k].ids) {
        if (points_[id].rep != id) points_[id].fixed = true;
      }
    }
  }
  return ok;
}


/// Triangulates one merged polygon, keeping every vertex where it can:
/// a vertex on a straight stretch of the outline (after a neighbouring
/// sliver merged away) still lies on the grid triangle's edge that the
/// next triangle, or the next module, has a vertex on.
bool LevelWork::fanOrClip(std::uint32_t poly, std::vector<std::uint32_t>& m) {
  auto a2 = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    return cross(points_[b].p - points_[a].p, points_[c].p - points_[a].p);
  };
  const std::size_t before = tris_.size();
  // A fan from some vertex (for a convex polygon with one straight
  // vertex, from that one).
  const std::size_t n0 = m.size();
  for (std::size_t k = 0; k < n0; ++k) {
    bool fanOk = true;
    for (std::size_t i = 1; i + 1 < n0 && fanOk; ++i) fanOk = a2(m[k], m[(k + i) % n0], m[(k + i + 1) % n0]) > kAreaEps;
    if (!fanOk) continue;
    for (std::size_t i = 1; i + 1 < n0; ++i) tris_.push_back({poly, m[k], m[(k + i) % n0], m[(k + i + 1) % n0]});
    return true;
  }
  // Ear clipping: cut a positive ear with no other vertex in it or on
  // it; only when there is none, drop a flat vertex.
  auto inOrOn = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t q) {
    const Vec2 p = points_[q].p;
    if (p == points_[a].p || p == points_[b].p || p == points_[c].p) return false;
    return a2(a, b, q) >= 0 && a2(b, c, q) >= 0 && a2(c, a, q) >= 0;
  };
  while (m.size() >= 3) {
    const std::size_t n = m.size();
    bool cutOne = false;
    for (std::size_t i = 0; i < n && !cutOne; ++i) {
      const std::uint32_t a = m[(i + n - 1) % n], b = m[i], c = m[(i + 1) % n];
      if (a2(a, b, c) <= kAreaEps) continue;
      bool empty = true;
      for (std::uint32_t q : m) {
        if (q != a && q != b && q != c && inOrOn(a, b, c, q)) {
          empty = false;
          break;
        }
      }
      if (!empty) continue;
      tris_.push_back({poly, a, b, c});
      m.erase(m.begin() + std::ptrdiff_t(i));
      cutOne = true;
    }
    if (cutOne) continue;
    for (std::size_t i = 0; i < n && !cutOne; ++i) {
      const std::uint32_t a = m[(i + n - 1) % n], b = m[i], c = m[(i + 1) % n];
      if (std::fabs(a2(a, b, c)) <= kAreaEps) {
        m.erase(m.begin() + std::ptrdiff_t(i));
        cutOne = true;
      }
    }
    if (!cutOne) {
      tris_.resize(before);
      return false;
    }
  }
  return true;
}


/// Counts points left closer than the tolerance (a merge was refused).
void LevelWork::countClose() {
  const double tol2 = tol_ * tol_;
  for (std::size_t a = 0; a < reps_.size(); ++a) {
    for (std::size_t b = a + 1; b < reps_.size(); ++b) {
      const SnapPoint& p = points_[reps_[a]];
      const SnapPoint& q = points_[reps_[b]];
      if (p.rep != reps_[a] || q.rep != reps_[b]) continue;
      const Vec2 d = q.p - p.p;
      if (dot(d, d) < tol2) ++stats_.unmerged;
    }
  }
}


}  // namespace culture
}  // namespace sandtable::convert
