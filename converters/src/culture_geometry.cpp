// Plain double-precision geometry of the culture pipeline: ring areas,
// the rectangle clip that feeds the exact partition, and the outline of a
// widened polyline (docs/CULTURE.md, "Roads").
#include <cmath>
#include <numbers>

#include "culture_internal.h"

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

}  // namespace sandtable::convert::culture
