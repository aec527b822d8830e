// Plain double-precision geometry of the culture pipeline: ring areas,
// the rectangle clip that feeds the exact partition, and the outline of a
// widened polyline (docs/CULTURE.md, "Roads").
#include <algorithm>
#include <cmath>
#include <numbers>

#include <ogr_geometry.h>

#include <memory>

#include "culture_internal.h"
#include "sandtable/converters/elevation.h"  // cancelRequested

namespace sandtable::convert::culture {

double signedArea(const Ring& r) {
  double a = 0;
  const std::size_t n = r.size();
  for (std::size_t k = 0; k < n; ++k) a += cross(r[k], r[(k + 1) % n]);
  return 0.5 * a;
}

Box boxOf(const Ring& r) {
  Box b;
  for (const Vec2& p : r) b.add(p);
  return b;
}

namespace {

/// One Sutherland-Hodgman step against the axis-aligned line x = v (xAxis)
/// or z = v, keeping the side `keepGreater` (points on the line are kept).
Ring clipAxis(const Ring& in, bool xAxis, double v, bool keepGreater) {
  Ring out;
  const std::size_t n = in.size();
  if (n == 0) return out;
  out.reserve(n + 4);
  auto c = [&](Vec2 p) { return xAxis ? p.x : p.z; };
  auto inside = [&](Vec2 p) { return keepGreater ? c(p) >= v : c(p) <= v; };
  auto cut = [&](Vec2 p, Vec2 q) {
    if (lexLess(q, p)) std::swap(p, q);  // the same point whichever way the edge runs
    const double t = (v - c(p)) / (c(q) - c(p));
    return xAxis ? Vec2{v, p.z + t * (q.z - p.z)} : Vec2{p.x + t * (q.x - p.x), v};
  };
  Vec2 prev = in[n - 1];
  bool prevIn = inside(prev);
  for (std::size_t k = 0; k < n; ++k) {
    const Vec2 cur = in[k];
    const bool curIn = inside(cur);
    if (curIn) {
      if (!prevIn) out.push_back(cut(prev, cur));
      out.push_back(cur);
    } else if (prevIn) {
      out.push_back(cut(prev, cur));
    }
    prev = cur;
    prevIn = curIn;
  }
  return out;
}

}  // namespace

Ring clipRingToRect(const Ring& ring, const Box& rect) {
  const Box b = boxOf(ring);
  if (!b.overlaps(rect)) return {};
  Ring r = ring;
  if (b.x0 < rect.x0) r = clipAxis(r, true, rect.x0, true);
  if (b.x1 > rect.x1) r = clipAxis(r, true, rect.x1, false);
  if (b.z0 < rect.z0) r = clipAxis(r, false, rect.z0, true);
  if (b.z1 > rect.z1) r = clipAxis(r, false, rect.z1, false);
  Ring out;
  out.reserve(r.size());
  for (const Vec2& p : r) {
    if (out.empty() || !(out.back() == p)) out.push_back(p);
  }
  while (out.size() > 1 && out.front() == out.back()) out.pop_back();
  if (out.size() < 3) out.clear();
  return out;
}

namespace {

/// Appends the outline points where one side of the road passes a vertex
/// `v`, coming along the segment with unit left normal nA and leaving along
/// the one with nB. `s` is +1 for the left side, -1 for the right; `outer`
/// says the bend turns away from this side.
void passVertex(Ring& r, Vec2 v, Vec2 nA, Vec2 nB, double s, double h, bool outer, bool straight) {
  const Vec2 a = v + (s * h) * nA, b = v + (s * h) * nB;
  if (straight) {
    r.push_back(a);
    return;
  }
  r.push_back(a);
  if (outer) {
    // Mitre while its tip stays within one width of the vertex (turns up
    // to 120 degrees), else bevel.
    const double c = 1.0 + dot(nA, nB);
    if (c >= 0.5) r.push_back(v + (s * h / c) * (nA + nB));
  } else {
    r.push_back(v);  // the inner side runs through the vertex
  }
  r.push_back(b);
}

}  // namespace

void outlineOf(const Polyline& line, double width, std::vector<Ring>& out) {
  Polyline p = line;
  const bool closed = p.size() >= 4 && p.front() == p.back();
  if (closed) p.pop_back();
  const std::size_t n = p.size();
  const std::size_t segs = closed ? n : n - 1;
  if (n < 2 || !(width > 0)) return;
  const double h = 0.5 * width;
  std::vector<Vec2> d(segs), nrm(segs);
  for (std::size_t i = 0; i < segs; ++i) {
    const Vec2 e = p[(i + 1) % n] - p[i];
    const double len = length(e);
    if (!(len > 0)) return;  // callers remove repeated points
    d[i] = (1.0 / len) * e;
    nrm[i] = {-d[i].z, d[i].x};
  }
  // Vertex i joins segment i-1 (in) to segment i (out).
  auto turnAt = [&](std::size_t in, std::size_t outSeg, bool& straight) {
    const double t = cross(d[in], d[outSeg]);
    straight = std::fabs(t) <= 1e-12 && dot(d[in], d[outSeg]) > 0;
    return t;
  };
  if (!closed) {
    Ring r;
    r.push_back(p[0] - h * nrm[0]);
    for (std::size_t i = 1; i + 1 < n; ++i) {  // right side, forward
      bool straight = false;
      const double t = turnAt(i - 1, i, straight);
      passVertex(r, p[i], nrm[i - 1], nrm[i], -1.0, h, t > 0, straight);
    }
    r.push_back(p[n - 1] - h * nrm[segs - 1]);
    r.push_back(p[n - 1] + h * nrm[segs - 1]);
    for (std::size_t i = n - 2; i >= 1; --i) {  // left side, backward
      bool straight = false;
      const double t = turnAt(i - 1, i, straight);
      passVertex(r, p[i], nrm[i], nrm[i - 1], 1.0, h, t < 0, straight);
    }
    r.push_back(p[0] + h * nrm[0]);
    out.push_back(std::move(r));
    return;
  }
  // A loop: its two sides are separate rings; one of them is a hole.
  Ring right, left;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t in = (i + n - 1) % n;
    bool straight = false;
    const double t = turnAt(in, i, straight);
    passVertex(right, p[i], nrm[in], nrm[i], -1.0, h, t > 0, straight);
  }
  for (std::size_t k = n; k-- > 0;) {
    const std::size_t in = (k + n - 1) % n;
    bool straight = false;
    const double t = turnAt(in, k, straight);
    passVertex(left, p[k], nrm[k], nrm[in], 1.0, h, t < 0, straight);
  }
  out.push_back(std::move(right));
  out.push_back(std::move(left));
}

/// A join piece where line ends meet: an octagon around the end `c`
/// whose sides lie half a width from it, one side square to the line's
/// last segment (from `from` to `c`), so the wedge between two butt ends at
/// an angle is covered and nothing sticks out past the road's own sides.
Ring octagon(Vec2 c, Vec2 from, double width) {
  const double r = 0.5 * width / std::cos(std::numbers::pi / 8);
  const double base = std::atan2(c.z - from.z, c.x - from.x);
  Ring o;
  for (int k = 0; k < 8; ++k) {
    const double a = base + (k + 0.5) * std::numbers::pi / 4;
    o.push_back({c.x + r * std::cos(a), c.z + r * std::sin(a)});
  }
  return o;
}

namespace {

/// Vertices per Douglas-Peucker run: DP is quadratic on a line that zigzags
/// (each split peels off one vertex), so long lines are simplified in
/// blocks that share their end vertices.
constexpr std::size_t kSimplifyBlock = 1024;

/// Appends the simplified p[first..last] to `out`, without its first vertex.
void simplifyBlock(const Polyline& p, std::size_t first, std::size_t last, double tol, Polyline& out) {
  OGRLineString ls;
  ls.setNumPoints(int(last - first + 1), FALSE);
  for (std::size_t k = first; k <= last; ++k) ls.setPoint(int(k - first), p[k].x, p[k].z);
  const std::unique_ptr<OGRGeometry> g(ls.Simplify(tol));
  if (!g || wkbFlatten(g->getGeometryType()) != wkbLineString || g->toLineString()->getNumPoints() < 2) {
    out.insert(out.end(), p.begin() + std::ptrdiff_t(first) + 1, p.begin() + std::ptrdiff_t(last) + 1);
    return;
  }
  const OGRLineString* s = g->toLineString();
  for (int k = 1; k < s->getNumPoints(); ++k) out.push_back({s->getX(k), s->getY(k)});
}

}  // namespace

Polyline simplifiedLine(const Polyline& p, double tol) {
  if (p.size() <= 2 || !(tol > 0)) return p;
  Polyline raw{p.front()};
  for (std::size_t first = 0; first + 1 < p.size(); first += kSimplifyBlock) {
    simplifyBlock(p, first, std::min(first + kSimplifyBlock, p.size() - 1), tol, raw);
  }
  Polyline out;
  for (const Vec2& v : raw) {
    if (out.empty() || !(out.back() == v)) out.push_back(v);
  }
  const bool loop = p.size() >= 4 && p.front() == p.back();
  if (out.size() < 2 || (loop && out.size() < 4)) return p;
  return out;
}

namespace {

/// The rings of a union, each simplified as a closed line (its first
/// vertex kept). Rings are winding-counted downstream, so a simplified ring
/// that crosses itself or a neighbour still covers what it should, within
/// `tol`.
std::vector<Ring> simplifiedRings(std::vector<Ring> rings, double tol) {
  for (Ring& r : rings) {
    if (r.size() <= 4) continue;
    Polyline closed = r;
    closed.push_back(r.front());
    Polyline s = simplifiedLine(closed, tol);
    if (s.size() < 4) continue;
    s.pop_back();
    r = std::move(s);
  }
  return rings;
}

void throwIfCancelled() {
  if (cancelRequested()) throw Cancelled{};
}

/// Appends the outline rings of `part` in chunks of kWidenChunk segments,
/// one ring set per chunk. A loop is walked once round plus one segment,
/// so the join at its closing vertex lies inside a chunk.
void chunkOutlines(const Polyline& part, double width, std::vector<std::vector<Ring>>& leaves) {
  Polyline q = part;
  const bool closed = q.size() >= 4 && q.front() == q.back();
  if (q.size() <= kWidenChunk + 1) {
    leaves.emplace_back();
    outlineOf(q, width, leaves.back());
    return;
  }
  if (closed) q.push_back(q[1]);
  const std::size_t last = q.size() - 1;
  for (std::size_t i = 0;;) {
    const std::size_t j = std::min(i + kWidenChunk, last);
    leaves.emplace_back();
    outlineOf(Polyline(q.begin() + std::ptrdiff_t(i), q.begin() + std::ptrdiff_t(j) + 1), width, leaves.back());
    if (j == last) break;
    i = j - 1;  // overlap one segment: the join at j is inside the next chunk
  }
}

}  // namespace

std::vector<Ring> widenLine(const std::vector<Polyline>& parts, const std::vector<bool>& joinStart,
                            const std::vector<bool>& joinEnd, double width, double tolerance) {
  std::vector<std::vector<Ring>> sets;
  if (parts.empty()) return {};
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const Polyline& q = parts[p];
    chunkOutlines(q, width, sets);
    if (joinStart[p]) sets.back().push_back(octagon(q.front(), q[1], width));
    if (joinEnd[p]) sets.back().push_back(octagon(q.back(), q[q.size() - 2], width));
  }
  double tol = 0.5 * tolerance;
  if (sets.size() == 1) return simplifiedRings(unionRings(sets.front()), tol);
  for (auto& s : sets) {
    throwIfCancelled();
    s = simplifiedRings(unionRings(s), tol);
  }
  // Pairwise, neighbours first: consecutive chunks overlap, so each union
  // stays about as small as the line it covers.
  while (sets.size() > 1) {
    tol *= 0.5;
    std::vector<std::vector<Ring>> next;
    next.reserve((sets.size() + 1) / 2);
    for (std::size_t k = 0; k + 1 < sets.size(); k += 2) {
      throwIfCancelled();
      std::vector<Ring> both = std::move(sets[k]);
      both.insert(both.end(), std::make_move_iterator(sets[k + 1].begin()), std::make_move_iterator(sets[k + 1].end()));
      next.push_back(simplifiedRings(unionRings(both), tol));
    }
    if (sets.size() % 2 == 1) next.push_back(std::move(sets.back()));
    sets = std::move(next);
  }
  return std::move(sets.front());
}

}  // namespace sandtable::convert::culture
