#include "sandtable/edits/profile.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace sandtable::edits {

namespace {

Box pointsBox(const std::vector<std::array<double, 2>>& points, double grow) {
  Box b{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
        -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const auto& p : points) {
    b.x0 = std::min(b.x0, p[0]);
    b.z0 = std::min(b.z0, p[1]);
    b.x1 = std::max(b.x1, p[0]);
    b.z1 = std::max(b.z1, p[1]);
  }
  if (points.empty()) return {};
  return {b.x0 - grow, b.z0 - grow, b.x1 + grow, b.z1 + grow};
}

/// Half the base of a berm or ditch: crest (or floor) half-width plus the
/// run of one side.
double halfBase(const edit::Edit& e) { return 0.5 * e.width + e.height / e.sideSlope; }

/// The trapezoid's rise at distance s from the centreline: full height on
/// the crest, falling by sideSlope per metre beyond it.
double trapezoid(const edit::Edit& e, double s) {
  const double over = s - 0.5 * e.width;
  if (over <= 0) return e.height;
  return std::max(0.0, e.height - e.sideSlope * over);
}

double distanceToPolygonEdge(const std::vector<std::array<double, 2>>& pts, double x, double z) {
  std::vector<std::array<double, 2>> ring = pts;
  ring.push_back(pts.front());
  return distanceToPolyline(ring, x, z);
}

}  // namespace

double craterDelta(double radius, double depth, double r) {
  const double rim = kRimFraction * depth;
  if (r <= radius) {
    const double q = r / radius;
    return -depth + (depth + rim) * (q * q);
  }
  const double outer = kRimOuter * radius;
  if (r >= outer) return 0;
  const double q = (outer - r) / (outer - radius);
  return rim * (q * q);
}

double craterVolumeRemoved(double radius, double depth) {
  const double rim = kRimFraction * depth;
  const double r0sq = radius * radius * depth / (depth + rim);
  return std::numbers::pi * r0sq * depth / 2.0;
}

double craterVolumeAdded(double radius, double depth) {
  const double rim = kRimFraction * depth;
  const double inner = std::numbers::pi * radius * radius / 2.0 * rim * rim / (depth + rim);
  const double outer = kRimOuter * radius, run = outer - radius;
  return inner + 2.0 * std::numbers::pi * rim * run * (outer / 3.0 - run / 4.0);
}

double distanceToPolyline(const std::vector<std::array<double, 2>>& pts, double x, double z) {
  if (pts.size() == 1) return std::hypot(x - pts[0][0], z - pts[0][1]);
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
    const double ax = pts[k][0], az = pts[k][1];
    const double dx = pts[k + 1][0] - ax, dz = pts[k + 1][1] - az;
    const double len2 = dx * dx + dz * dz;
    double t = len2 > 0 ? ((x - ax) * dx + (z - az) * dz) / len2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    best = std::min(best, std::hypot(x - (ax + t * dx), z - (az + t * dz)));
  }
  return best;
}

bool insidePolygon(const std::vector<std::array<double, 2>>& pts, double x, double z) {
  bool in = false;
  for (std::size_t k = 0, m = pts.size() - 1; k < pts.size(); m = k++) {
    const double xk = pts[k][0], zk = pts[k][1], xm = pts[m][0], zm = pts[m][1];
    if ((zk > z) != (zm > z) && x < (xm - xk) * (z - zk) / (zm - zk) + xk) in = !in;
  }
  return in;
}

Box support(const edit::Edit& e) {
  switch (e.kind) {
    case edit::Kind::crater: return pointsBox(e.points, kRimOuter * e.radius);
    case edit::Kind::berm:
    case edit::Kind::ditch: return pointsBox(e.points, halfBase(e));
    case edit::Kind::flatten: return pointsBox(e.points, 0);
    default: return {};
  }
}

double flattenReach(const edit::Edit& e, double maxGap) { return std::max(0.0, maxGap) / e.sideSlope; }

double newHeight(const edit::Edit& e, double x, double z, double before) {
  switch (e.kind) {
    case edit::Kind::crater: {
      const double r = std::hypot(x - e.points[0][0], z - e.points[0][1]);
      return before + craterDelta(e.radius, e.depth, r);
    }
    case edit::Kind::berm: return before + trapezoid(e, distanceToPolyline(e.points, x, z));
    case edit::Kind::ditch: return before - trapezoid(e, distanceToPolyline(e.points, x, z));
    case edit::Kind::flatten: {
      if (insidePolygon(e.points, x, z)) return e.height;
      // Cut or fill down to the side slope from the polygon's edge.
      const double run = e.sideSlope * distanceToPolygonEdge(e.points, x, z);
      return e.height + std::clamp(before - e.height, -run, run);
    }
    default: return before;
  }
}

std::uint32_t refineCells(const edit::Edit& e, double spacing) {
  double feature = 0;
  switch (e.kind) {
    case edit::Kind::crater: feature = e.radius; break;
    case edit::Kind::berm:
    case edit::Kind::ditch: feature = halfBase(e); break;
    case edit::Kind::flatten: {
      const Box b = pointsBox(e.points, 0);
      feature = 0.5 * std::min(b.x1 - b.x0, b.z1 - b.z0);
      break;
    }
    default: return 0;
  }
  if (!(feature < 2.0 * spacing)) return 0;
  const double target = std::max(kFinestSpacing, feature / 4.0);
  std::uint32_t cells = 2;
  while (cells < kMaxCells && spacing / double(cells) > target) cells *= 2;
  return cells;
}

}  // namespace sandtable::edits
