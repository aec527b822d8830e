#pragma once
// Liang-Barsky clipping of segments and polylines to an axis-aligned
// rectangle: one implementation for culture loading (database metres, x
// and z) and the synthetic rivers (local metres, x and y).
//
// Thread safety: pure functions.
#include <optional>
#include <vector>

namespace sandtable::convert::clip {

/// The rectangle x0 <= x <= x1, y0 <= y <= y1.
struct Rect {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

/// The parameters of the part of a segment inside a rectangle.
struct Span {
  double t0 = 0, t1 = 1;
};

/// Liang-Barsky: the part of segment a-b inside `r` is a + t (b - a) for t
/// in [t0, t1] (0 <= t0 < t1 <= 1); none when no part of positive length
/// is inside (a segment that only touches the border).
std::optional<Span> segment(double ax, double ay, double bx, double by, const Rect& r);

/// The parts of a polyline inside `r`, each of two points or more. A point
/// where the line crosses the border is interpolated; every other point is
/// an input point, exactly. P is any point type whose coordinates are the
/// doubles P::*x and P::*y (for example &Vec2::x and &Vec2::z).
template <typename P>
std::vector<std::vector<P>> polyline(const std::vector<P>& pts, const Rect& r, double P::*x, double P::*y) {
  std::vector<std::vector<P>> parts;
  std::vector<P> cur;
  auto flush = [&] {
    if (cur.size() >= 2) parts.push_back(std::move(cur));
    cur.clear();
  };
  auto at = [&](const P& a, const P& b, double t) {
    P p = a;
    p.*x = a.*x + t * (b.*x - a.*x);
    p.*y = a.*y + t * (b.*y - a.*y);
    return p;
  };
  for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
    const P& a = pts[k];
    const P& b = pts[k + 1];
    const std::optional<Span> s = segment(a.*x, a.*y, b.*x, b.*y, r);
    if (!s) {
      flush();
      continue;
    }
    if (cur.empty() || s->t0 > 0) {
      flush();
      cur.push_back(s->t0 > 0 ? at(a, b, s->t0) : a);
    }
    cur.push_back(s->t1 < 1 ? at(a, b, s->t1) : b);
    if (s->t1 < 1) flush();
  }
  flush();
  return parts;
}

}  // namespace sandtable::convert::clip
