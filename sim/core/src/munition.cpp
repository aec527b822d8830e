// Munition flight and impacts (seed Figures 27 and 59).
#include "sandtable/sim/munition.h"

#include <algorithm>
#include <cmath>

namespace sandtable::sim {

const std::vector<MunitionType>& builtinMunitions() {
  static const std::vector<MunitionType> types = {
      {"missile", true, 250, 40, 24, 0.2, CraterSize::medium},
      {"round", false, 900, 0, 6, 0.1, CraterSize::small},
  };
  return types;
}

const char* craterSizeName(CraterSize s) {
  switch (s) {
    case CraterSize::none: return "none";
    case CraterSize::small: return "small";
    case CraterSize::medium: return "medium";
    case CraterSize::large: return "large";
  }
  return "?";
}

namespace {

/// Height of p over the drawn ground; nullopt off the grid.
std::optional<double> above(const SimWorld& world, const Eigen::Vector3d& p) {
  const auto g = world.groundAt(p.x(), p.z());
  if (!g) return std::nullopt;
  return p.y() - *g;
}

}  // namespace

std::optional<Eigen::Vector3d> terrainImpact(const SimWorld& world, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                             double toleranceM) {
  const auto hb = above(world, b);
  if (!hb || *hb > 0) return std::nullopt;
  Eigen::Vector3d lo = a, hi = b;  // lo above the ground, hi at or below it
  const auto ha = above(world, a);
  if (!ha || *ha <= 0) return a;   // already under: it hit where it stood
  while ((hi - lo).norm() > toleranceM) {
    const Eigen::Vector3d mid = (lo + hi) * 0.5;
    const auto hm = above(world, mid);
    if (hm && *hm > 0) lo = mid;
    else hi = mid;
  }
  Eigen::Vector3d p = (lo + hi) * 0.5;
  if (const auto g = world.groundAt(p.x(), p.z())) p.y() = *g;
  return p;
}

std::optional<double> sweptHitsSphere(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r,
                                      const Eigen::Vector3d& centre) {
  const Eigen::Vector3d d = b - a, m = a - centre;
  const double c = m.squaredNorm() - r * r;
  if (c <= 0) return 0.0;
  const double dd = d.squaredNorm();
  if (dd == 0) return std::nullopt;
  const double bq = m.dot(d);
  const double disc = bq * bq - dd * c;
  if (disc < 0) return std::nullopt;
  const double t = (-bq - std::sqrt(disc)) / dd;
  if (t < 0 || t > 1) return std::nullopt;
  return t;
}

std::optional<double> sweptHitsCylinder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r, double cx,
                                        double cz, double radius, double baseY, double height) {
  // In 2-D the segment against a circle of radius + r; then the height at
  // the entry (or the first point in the vertical range) must lie in it.
  const double R = radius + r;
  const double dx = b.x() - a.x(), dz = b.z() - a.z();
  const double mx = a.x() - cx, mz = a.z() - cz;
  const double dd = dx * dx + dz * dz;
  const double c = mx * mx + mz * mz - R * R;
  double t0 = 0, t1 = 1;
  if (dd == 0) {
    if (c > 0) return std::nullopt;
  } else {
    const double bq = mx * dx + mz * dz;
    const double disc = bq * bq - dd * c;
    if (disc < 0) return std::nullopt;
    const double s = std::sqrt(disc);
    t0 = std::max(0.0, (-bq - s) / dd);
    t1 = std::min(1.0, (-bq + s) / dd);
    if (t0 > t1) return std::nullopt;
  }
  // The part of [t0, t1] where y lies in [baseY - r, baseY + height + r].
  const double lo = baseY - r, hi = baseY + height + r, dy = b.y() - a.y();
  double u0 = t0, u1 = t1;
  if (dy == 0) {
    if (a.y() < lo || a.y() > hi) return std::nullopt;
  } else {
    double ta = (lo - a.y()) / dy, tb = (hi - a.y()) / dy;
    if (ta > tb) std::swap(ta, tb);
    u0 = std::max(u0, ta);
    u1 = std::min(u1, tb);
  }
  if (u0 > u1) return std::nullopt;
  return u0;
}

void stepMunition(Entity& m, const MunitionType& type, const std::optional<Eigen::Vector3d>& target, double dt) {
  if (type.guided && target) {
    const Eigen::Vector3d want = (*target - m.position).normalized();
    Eigen::Vector3d v = m.velocity.normalized();
    const double angle = std::acos(std::clamp(v.dot(want), -1.0, 1.0));
    const double limit = type.turnRateDegS * kDegToRad * dt;
    if (angle > 1e-9) {
      Eigen::Vector3d axis = v.cross(want);
      if (axis.norm() < 1e-12) axis = Eigen::Vector3d::UnitY();
      v = Eigen::AngleAxisd(std::min(angle, limit), axis.normalized()) * v;
    }
    m.velocity = v.normalized() * type.speedMs;
  } else if (!type.guided) {
    m.velocity.y() -= kGravity * dt;
  }
  m.position += m.velocity * dt;
  m.speedMs = m.velocity.norm();
  const Eigen::Vector3d f = m.velocity.normalized();
  m.headingDeg = headingOf(f.x(), f.z());
  m.pitchDeg = std::asin(std::clamp(f.y(), -1.0, 1.0)) * kRadToDeg;
  m.fuseS -= dt;
}

}  // namespace sandtable::sim
