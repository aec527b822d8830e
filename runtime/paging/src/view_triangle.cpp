#include "sandtable/paging/view_triangle.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace sandtable::paging {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

/// Extent along u of the part of segment (a, b) inside the band lo <= v <= hi,
/// merged into [umin, umax]. Points are (u, v) in grid units.
void mergeClippedEdge(GroundPoint a, GroundPoint b, double lo, double hi, double& umin,
                      double& umax) {
  if (a.z > b.z) std::swap(a, b);
  if (b.z < lo || a.z > hi) return;
  auto uAt = [&](double v) {
    if (b.z == a.z) return a.x;
    return a.x + (b.x - a.x) * (v - a.z) / (b.z - a.z);
  };
  const double u0 = a.z >= lo ? a.x : uAt(lo);
  const double u1 = b.z <= hi ? b.x : uAt(hi);
  umin = std::min({umin, u0, u1});
  umax = std::max({umax, u0, u1});
}

/// Interval of squares, inclusive; empty when first > last.
struct Interval {
  std::int64_t first = std::numeric_limits<std::int64_t>::max();
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  bool empty() const { return first > last; }
  void merge(const Interval& o) {
    first = std::min(first, o.first);
    last = std::max(last, o.last);
  }
};

/// Squares of row r (band r <= v <= r + 1) that the triangle touches. The
/// triangle cut by the band is a convex polygon whose corners are triangle
/// vertices or edge crossings, so clipping the three edges finds its extent.
Interval rowExtent(const std::array<GroundPoint, 3>& tri, std::int64_t r) {
  const double lo = double(r), hi = double(r + 1);
  double umin = std::numeric_limits<double>::infinity();
  double umax = -umin;
  for (int e = 0; e < 3; ++e) mergeClippedEdge(tri[e], tri[(e + 1) % 3], lo, hi, umin, umax);
  if (!(umin <= umax)) return {};
  return {static_cast<std::int64_t>(std::floor(umin)), static_cast<std::int64_t>(std::floor(umax))};
}

}  // namespace

GroundPoint headingVector(double headingDeg) {
  const double h = headingDeg * kDegToRad;
  return {std::sin(h), -std::cos(h)};
}

double verticalFovDeg(double hfovDeg, double aspect) {
  return 2.0 * std::atan(std::tan(hfovDeg * kDegToRad / 2.0) / aspect) * kRadToDeg;
}

double groundHalfAngleDeg(double hfovDeg, double vfovDeg, double pitchDeg, double maxDeg) {
  // Camera ray = forward + a * right + b * up with |a| = tan(hfov/2) and
  // |b| = tan(vfov/2). Pitching by p tilts forward/up in the vertical plane,
  // so the ray's horizontal part is (cos p - b sin p) ahead and a to the side.
  const double a = std::tan(hfovDeg * kDegToRad / 2.0);
  const double tb = std::tan(vfovDeg * kDegToRad / 2.0);
  const double p = pitchDeg * kDegToRad;
  double widest = hfovDeg / 2.0;
  for (const double b : {tb, -tb}) {
    const double ahead = std::cos(p) - b * std::sin(p);
    // A corner ray pointing backwards means the footprint wraps round the eye.
    const double angle = ahead <= 0 ? 90.0 : std::atan2(a, ahead) * kRadToDeg;
    widest = std::max(widest, angle);
  }
  return std::min(widest, maxDeg);
}

ViewTriangle makeViewTriangle(const ViewTriangleParams& p) {
  const GroundPoint look = headingVector(p.headingDeg);
  const GroundPoint apex{p.eyeX - look.x * p.pullback, p.eyeZ - look.z * p.pullback};
  const double half = std::clamp(p.halfAngleDeg, 1e-3, 89.0);
  const double side = (p.viewDistance + p.pullback) / std::cos(half * kDegToRad);
  const GroundPoint l = headingVector(p.headingDeg - half);
  const GroundPoint r = headingVector(p.headingDeg + half);
  return {apex, {apex.x + l.x * side, apex.z + l.z * side}, {apex.x + r.x * side, apex.z + r.z * side}};
}

SquareBox boundingSquares(const ViewTriangle& t, double spacing, std::uint32_t squaresX,
                          std::uint32_t squaresZ) {
  const double minX = std::min({t.apex.x, t.left.x, t.right.x}) / spacing;
  const double maxX = std::max({t.apex.x, t.left.x, t.right.x}) / spacing;
  const double minZ = std::min({t.apex.z, t.left.z, t.right.z}) / spacing;
  const double maxZ = std::max({t.apex.z, t.left.z, t.right.z}) / spacing;
  auto clampTo = [](double v, std::uint32_t n) {
    return static_cast<std::int64_t>(std::clamp(std::floor(v), -1.0, double(n)));
  };
  SquareBox b{clampTo(minX, squaresX), clampTo(maxX, squaresX), clampTo(minZ, squaresZ),
              clampTo(maxZ, squaresZ)};
  b.minI = std::max<std::int64_t>(b.minI, 0);
  b.minJ = std::max<std::int64_t>(b.minJ, 0);
  b.maxI = std::min<std::int64_t>(b.maxI, std::int64_t(squaresX) - 1);
  b.maxJ = std::min<std::int64_t>(b.maxJ, std::int64_t(squaresZ) - 1);
  return b;
}

std::vector<RowSpan> selectSquares(const ViewTriangle& t, double spacing, std::uint32_t squaresX,
                                   std::uint32_t squaresZ, std::uint32_t grow) {
  std::vector<RowSpan> spans;
  if (squaresX == 0 || squaresZ == 0 || !(spacing > 0)) return spans;
  const std::array<GroundPoint, 3> tri = {
      GroundPoint{t.apex.x / spacing, t.apex.z / spacing},
      GroundPoint{t.left.x / spacing, t.left.z / spacing},
      GroundPoint{t.right.x / spacing, t.right.z / spacing}};
  const double vmin = std::min({tri[0].z, tri[1].z, tri[2].z});
  const double vmax = std::max({tri[0].z, tri[1].z, tri[2].z});
  if (!std::isfinite(vmin) || !std::isfinite(vmax)) return spans;
  const std::int64_t g = grow;
  // Only rows that can reach the grid after growing are worth scanning.
  const std::int64_t firstRow = std::max<std::int64_t>(std::int64_t(std::floor(vmin)), -g);
  const std::int64_t lastRow =
      std::min<std::int64_t>(std::int64_t(std::floor(vmax)), std::int64_t(squaresZ) - 1 + g);
  if (firstRow > lastRow) return spans;

  std::vector<Interval> raw(std::size_t(lastRow - firstRow + 1));
  for (std::int64_t r = firstRow; r <= lastRow; ++r) raw[std::size_t(r - firstRow)] = rowExtent(tri, r);

  // Grow by g squares each way: row j takes the union of rows j-g..j+g,
  // widened by g. The triangle is convex, so that union is one interval.
  const std::int64_t outFirst = std::max<std::int64_t>(firstRow - g, 0);
  const std::int64_t outLast = std::min<std::int64_t>(lastRow + g, std::int64_t(squaresZ) - 1);
  for (std::int64_t j = outFirst; j <= outLast; ++j) {
    Interval u;
    for (std::int64_t r = std::max(j - g, firstRow); r <= std::min(j + g, lastRow); ++r) {
      u.merge(raw[std::size_t(r - firstRow)]);
    }
    if (u.empty()) continue;
    const std::int64_t a = std::max<std::int64_t>(u.first - g, 0);
    const std::int64_t b = std::min<std::int64_t>(u.last + g, std::int64_t(squaresX) - 1);
    if (a > b) continue;
    spans.push_back({std::uint32_t(j), std::uint32_t(a), std::uint32_t(b)});
  }
  return spans;
}

std::uint64_t countSquares(const std::vector<RowSpan>& spans) {
  std::uint64_t n = 0;
  for (const auto& s : spans) n += s.squares();
  return n;
}

}  // namespace sandtable::paging
