#include "sandtable/converters/clip.h"

#include <algorithm>

namespace sandtable::convert::clip {

std::optional<Span> segment(double ax, double ay, double bx, double by, const Rect& r) {
  Span s;
  const double dx = bx - ax, dy = by - ay;
  // Edge e keeps the side where p[e] t <= q[e]: west, east, south, north.
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {ax - r.x0, r.x1 - ax, ay - r.y0, r.y1 - ay};
  for (int e = 0; e < 4; ++e) {
    if (p[e] == 0) {
      if (q[e] < 0) return std::nullopt;  // parallel to the edge, outside it
    } else {
      const double t = q[e] / p[e];
      if (p[e] < 0) s.t0 = std::max(s.t0, t);
      else s.t1 = std::min(s.t1, t);
    }
  }
  if (!(s.t0 < s.t1)) return std::nullopt;
  return s;
}

}  // namespace sandtable::convert::clip
