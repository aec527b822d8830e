// A grid triangle of a level (Tri) and the convex pieces of a layer
// clipped to it (Sutherland-Hodgman, diagonal first).
#include <algorithm>
#include <cmath>
#include <vector>

#include "culture_level_work.h"

namespace sandtable::convert {
namespace culture {

/// Does segment a-b cross the open interior of t (by more than kTouchEps)?
bool touches(const Seg& s, const Tri& t) {
  double lo = 0, hi = 1;
  for (int k = 0; k < 3; ++k) {
    const Vec2 e = t.c[(k + 1) % 3] - t.c[k];
    const double len = length(e);
    const double fa = cross(e, s.a - t.c[k]) / len - kTouchEps, fb = cross(e, s.b - t.c[k]) / len - kTouchEps;
    if (fa <= 0 && fb <= 0) return false;
    if (fa > 0 && fb > 0) continue;
    const double r = fa / (fa - fb);
    if (fa <= 0) lo = std::max(lo, r);
    else hi = std::min(hi, r);
    if (lo >= hi) return false;
  }
  return lo < hi;
}

bool convexContains(const Ring& pts, Vec2 p) {
  const std::size_t n = pts.size();
  for (std::size_t k = 0; k < n; ++k) {
    if (cross(pts[(k + 1) % n] - pts[k], p - pts[k]) < -1e-9) return false;
  }
  return true;
}

/// Clips a convex piece to the triangle: diagonal first, then its vertical
/// and horizontal edges. Crossing points depend only on the (ordered)
/// segment and the line, so neighbouring pieces and triangles agree.
void clipPiece(const Ring& piece, const Tri& t, std::vector<CP>& out, std::vector<CP>& tmp) {
  out.clear();
  tmp.clear();
  const double dx = t.x1 - t.x0, dz = t.z1 - t.z0, dd = dx * dx + dz * dz;
  {
    const std::size_t n = piece.size();
    Vec2 prev = piece[n - 1];
    double fp = t.f(prev);
    bool pin = t.insideDiag(fp);
    auto cut = [&](Vec2 p, double fpv, Vec2 q, double fqv) {
      if (lexLess(q, p)) std::swap(p, q), std::swap(fpv, fqv);
      const double s = fpv / (fpv - fqv);
      const Vec2 x = s == 0 ? p : s == 1 ? q : p + s * (q - p);
      const double u = ((x.x - t.x0) * dx + (t.z1 - x.z) * dz) / dd;
      return CP{t.diagPoint(u), kDiag};
    };
    for (std::size_t k = 0; k < n; ++k) {
      const Vec2 cur = piece[k];
      const double fc = t.f(cur);
      const bool cin = t.insideDiag(fc);
      if (cin) {
        if (!pin) tmp.push_back(cut(prev, fp, cur, fc));
        tmp.push_back({cur, std::uint8_t(fc == 0 ? kDiag : 0)});
      } else if (pin) {
        tmp.push_back(cut(prev, fp, cur, fc));
      }
      prev = cur, fp = fc, pin = cin;
    }
  }
  auto axis = [&](const std::vector<CP>& in, std::vector<CP>& res, bool xAxis, double v, bool keepGreater) {
    res.clear();
    const std::size_t n = in.size();
    if (n == 0) return;
    auto c = [&](Vec2 p) { return xAxis ? p.x : p.z; };
    auto inside = [&](Vec2 p) { return keepGreater ? c(p) >= v : c(p) <= v; };
    const std::uint8_t bit = xAxis ? kVert : kHorz;
    auto cut = [&](CP p, CP q) {
      if (lexLess(q.p, p.p)) std::swap(p, q);
      const double s = (v - c(p.p)) / (c(q.p) - c(p.p));
      const double o = s == 0 ? (xAxis ? p.p.z : p.p.x) : s == 1 ? (xAxis ? q.p.z : q.p.x)
                              : (xAxis ? p.p.z + s * (q.p.z - p.p.z) : p.p.x + s * (q.p.x - p.p.x));
      return CP{xAxis ? Vec2{v, o} : Vec2{o, v}, std::uint8_t(bit | (p.on & q.on))};
    };
    CP prev = in[n - 1];
    bool pin = inside(prev.p);
    for (std::size_t k = 0; k < n; ++k) {
      const CP cur = in[k];
      const bool cin = inside(cur.p);
      if (cin) {
        if (!pin) res.push_back(cut(prev, cur));
        res.push_back(cur);
      } else if (pin) {
        res.push_back(cut(prev, cur));
      }
      prev = cur, pin = cin;
    }
  };
  axis(tmp, out, true, t.xe, t.upper);
  axis(out, tmp, false, t.ze, t.upper);
  // Edge flags from the coordinates too; points on two edges are corners.
  out.clear();
  for (CP p : tmp) {
    if (p.p.x == t.xe) p.on |= kVert;
    if (p.p.z == t.ze) p.on |= kHorz;
    if (t.f(p.p) == 0) p.on |= kDiag;
    if (bits(p.on) >= 2) p.p = t.cornerOf(p.on), p.on = std::uint8_t(p.on & 7);
    if (!out.empty() && out.back().p == p.p) {
      out.back().on |= p.on;
      continue;
    }
    out.push_back(p);
  }
  while (out.size() > 1 && out.front().p == out.back().p) {
    out.front().on |= out.back().on;
    out.pop_back();
  }
  if (out.size() < 3) out.clear();
}

}  // namespace culture
}  // namespace sandtable::convert
