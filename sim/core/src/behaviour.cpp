// Reactive behaviours of the computer-generated forces (seed VIII.A).
#include "sandtable/sim/behaviour.h"

#include <algorithm>
#include <cmath>

#include "sandtable/base/hash.h"

namespace sandtable::sim {

double behaviourRandom(std::uint64_t seed, std::uint32_t entity, std::uint64_t counter) {
  return hash::unit(hash::mix(hash::mix(seed ^ (std::uint64_t(entity) << 32)) ^ counter));
}

double zigzagLegS(double u, double speedMs, const BehaviourOptions& o) {
  const double t = o.zigzagPeriodS;
  return 2 * t - std::clamp(u * t - speedMs, 0.0, t);
}

double zigzag(Entity& e, double nowS, std::uint64_t seed, std::uint64_t& counter, const BehaviourOptions& o) {
  if (!e.alive || nowS < e.nextTurnS || std::abs(e.commands.speedMs) < o.zigzagMinSpeedMs) return 0;
  const double leg = zigzagLegS(behaviourRandom(seed, e.id, counter++), std::abs(e.commands.speedMs), o);
  e.nextTurnS = nowS + leg;
  const double turn = (2 * behaviourRandom(seed, e.id, counter++) - 1) * o.zigzagMaxTurnDeg;
  e.commands.headingDeg = wrapDeg(e.commands.headingDeg + turn);
  return turn;
}

bool environmentLimit(const SimWorld& world, Entity& e, const BehaviourOptions& o) {
  if (e.domain != Domain::land && e.domain != Domain::sea) return false;
  if (std::abs(e.speedMs) < 0.01 && std::abs(e.commands.speedMs) < 0.01) return false;
  // Far enough to turn away in: a ship at 3 degrees/s needs 30 s for 90.
  const double seconds = std::max(o.lookAheadS, 90.0 / std::max(1.0, e.vehicle.turnRateDegS));
  const double ahead = std::max(2 * e.halfLength, std::abs(e.commands.speedMs) * seconds);
  const Eigen::Vector3d p = e.position + headingVector(e.commands.headingDeg) * ahead;
  if (!world.onGrid(p.x(), p.z())) return false;  // the edge behaviour's business
  bool wrong = false;
  if (e.domain == Domain::sea) {
    wrong = !world.navigable(p.x(), p.z());
  } else {
    const SimWorld::Soil soil = world.soilAt(p.x(), p.z());
    const auto ground = world.groundAt(p.x(), p.z());
    wrong = soil.known ? soil.water : (ground && *ground <= 0);
  }
  if (!wrong) return false;
  e.commands.headingDeg = wrapDeg(e.commands.headingDeg + 180);
  return true;
}

namespace {

/// A standing object on the straight path of `length` from the entity at
/// `headingDeg` (probed at its middle and its end).
bool blocked(const SimWorld& world, const Entity& e, double headingDeg, double length, std::vector<std::uint32_t>& hits,
             SearchStats* stats) {
  const Eigen::Vector3d f = headingVector(headingDeg);
  for (double at : {0.5 * length, length}) {
    hits.clear();
    world.objectsNear(e.position.x() + f.x() * at, e.position.z() + f.z() * at, e.radius, e.position.y(), hits, stats);
    if (!hits.empty()) return true;
  }
  return false;
}

}  // namespace

bool avoidObjects(const SimWorld& world, Entity& e, const BehaviourOptions& o, SearchStats* stats) {
  if (e.domain != Domain::land || world.objects().empty()) return false;
  const double speed = std::max(std::abs(e.commands.speedMs), e.cruiseMs);
  if (speed < 1) return false;
  thread_local std::vector<std::uint32_t> hits;
  const double length = std::max(2 * e.radius, speed * o.avoidS);
  const double want = e.commands.headingDeg;
  // Where it points now matters as much as where it wants to go: a tracked
  // vehicle takes seconds to turn.
  const bool wanted = blocked(world, e, want, length, hits, stats);
  if (!wanted && !blocked(world, e, e.headingDeg, length, hits, stats)) {
    if (e.cruiseMs > 0) {
      e.commands.speedMs = std::copysign(e.cruiseMs, e.commands.speedMs);
      e.cruiseMs = 0;
    }
    return false;
  }
  if (e.cruiseMs == 0 && std::abs(e.commands.speedMs) > o.avoidSpeedMs) {
    e.cruiseMs = std::abs(e.commands.speedMs);
    e.commands.speedMs = std::copysign(o.avoidSpeedMs, e.commands.speedMs);
  }
  if (!wanted) return false;
  for (double turn : {30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 120.0, -120.0, 150.0, -150.0, 180.0}) {
    if (!blocked(world, e, want + turn, length, hits, stats)) {
      e.commands.headingDeg = wrapDeg(want + turn);
      return true;
    }
  }
  return false;
}

namespace {

/// The outward directions of the buffer zones (x, z) the point lies in.
Eigen::Vector2d outward(const SimWorld& world, double x, double z, double buffer) {
  Eigen::Vector2d out(0, 0);
  if (x < buffer) out.x() = -1;
  if (x > world.widthM() - buffer) out.x() = 1;
  if (z < buffer) out.y() = -1;
  if (z > world.depthM() - buffer) out.y() = 1;
  return out;
}

}  // namespace

bool edgeOfWorld(const SimWorld& world, Entity& e, const BehaviourOptions& o) {
  const Eigen::Vector2d out = outward(world, e.position.x(), e.position.z(), o.edgeBufferM);
  if (out.isZero()) return false;
  const Eigen::Vector3d f = headingVector(e.commands.headingDeg) * (e.commands.speedMs < 0 ? -1.0 : 1.0);
  double dx = f.x(), dz = f.z();
  bool turned = false;
  if (out.x() != 0 && dx * out.x() > 0) {
    dx = -dx;
    turned = true;
  }
  if (out.y() != 0 && dz * out.y() > 0) {
    dz = -dz;
    turned = true;
  }
  if (!turned) return false;
  double h = headingOf(dx, dz);
  if (e.commands.speedMs < 0) h = wrapDeg(h + 180);
  e.commands.headingDeg = h;
  return true;
}

bool placeOutsideBuffer(const SimWorld& world, Entity& e, const BehaviourOptions& o) {
  const double b = o.edgeBufferM, margin = 1.0;
  const double x = std::clamp(e.position.x(), b + margin, std::max(b + margin, world.widthM() - b - margin));
  const double z = std::clamp(e.position.z(), b + margin, std::max(b + margin, world.depthM() - b - margin));
  if (x == e.position.x() && z == e.position.z()) return false;
  e.position.x() = x;
  e.position.z() = z;
  return true;
}

bool inBox(const Entity& e, const Eigen::Vector3d& p, double half) {
  return std::abs(p.x() - e.position.x()) <= half && std::abs(p.z() - e.position.z()) <= half &&
         p.y() >= e.position.y() - half && p.y() <= e.position.y() + e.height + half;
}

bool lineOfSight(const SimWorld& world, const Eigen::Vector3d& from, const Eigen::Vector3d& to, double stepM) {
  const double length = (to - from).norm();
  const int n = std::max(1, static_cast<int>(length / stepM));
  for (int k = 1; k < n; ++k) {
    const Eigen::Vector3d p = from + (to - from) * (double(k) / n);
    const auto g = world.groundAt(p.x(), p.z());
    if (!g || *g > p.y()) return false;
  }
  return true;
}

Reaction fightOrFlight(Entity& e, const Eigen::Vector3d& munitionVelocity, const BehaviourOptions& o) {
  Reaction r;
  const double along = headingOf(munitionVelocity.x(), munitionVelocity.z());
  if (!e.armed) {
    e.commands.headingDeg = along;
    e.commands.speedMs = e.vehicle.maxSpeedMs;
    r.fled = true;
    return r;
  }
  const double reverse = wrapDeg(along + 180);
  const double gap = turnBetween(e.commands.headingDeg, reverse);
  if (std::abs(gap) <= o.fightTurnDeg) {
    e.commands.headingDeg = reverse;
    r.fire = true;
    r.fireAzimuthDeg = reverse;
    return r;
  }
  e.commands.headingDeg = wrapDeg(e.commands.headingDeg + std::copysign(o.fightTurnDeg, gap));
  r.turned = true;
  return r;
}

}  // namespace sandtable::sim
