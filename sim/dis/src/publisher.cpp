#include "sandtable/sim_dis/publisher.h"

#include <algorithm>
#include <cmath>

#include "sandtable/sim/units.h"
#include "sandtable/sim_dis/remote.h"

namespace sandtable::sim_dis {
namespace {

dis::Vec3f toFloat(const dis::Vec3d& v) { return {float(v.x), float(v.y), float(v.z)}; }

double angleBetweenDeg(double a, double b) { return std::abs(sim::turnBetween(a, b)); }

/// The turret's azimuth from the hull's nose, degrees (the PDU's articulated part).
double turretOf(const sim::Entity& e) { return sim::turnBetween(e.headingDeg, e.gunAzimuthDeg); }

}  // namespace

std::uint8_t Publisher::algorithmFor(sim::Domain d) const {
  switch (d) {
    case sim::Domain::land: return options_.landAlgorithm;
    case sim::Domain::sea: return options_.seaAlgorithm;
    case sim::Domain::air: return options_.airAlgorithm;
    case sim::Domain::munition: return options_.munitionAlgorithm;
  }
  return 2;
}

std::optional<dis::EntityState> Publisher::build(const sim::Entity& e, const Identity& who, Anchor& anchor) const {
  auto a = frame_.anchorAtFrame(e.position);
  if (!a) return std::nullopt;
  anchor = a.value();
  dis::EntityState s;
  s.id = who.id;
  s.force = who.force;
  s.type = who.type;
  s.location = anchor.ecef;
  s.orientation = disOrientation(anchor, e.headingDeg, e.pitchDeg, e.rollDeg);
  s.velocity = toFloat(ecefVector(anchor, e.velocity));
  s.deadReckoning.algorithm = algorithmFor(e.domain);
  s.deadReckoning.acceleration = toFloat(ecefVector(anchor, e.acceleration));
  if (e.domain == sim::Domain::munition) s.deadReckoning.acceleration = toFloat(ecefVector(anchor, {0, -9.81, 0}));
  s.deadReckoning.angularVelocity = toFloat(disBody(e.angularVelocity));
  s.appearance = e.alive ? 0 : kAppearanceDestroyed;
  s.marking = dis::Marking::ascii(e.name);
  if (e.armed) {
    const double turret = turretOf(e) * sim::kDegToRad;
    s.parameters.push_back(dis::toParameter(dis::ArticulatedPart{0, 0, kTurretAzimuth, float(turret)}));
    s.parameters.push_back(
        dis::toParameter(dis::ArticulatedPart{0, 0, kGunElevation, float(e.gunElevationDeg * sim::kDegToRad)}));
  }
  return s;
}

CopyError Publisher::error(const Copy& c, const sim::Entity& e, double nowS) const {
  const dis::Motion m = dis::advance(c.motion, nowS - c.sentS);
  const FramePose shown = framePose(c.anchor, m.position, m.orientation);
  CopyError err;
  Eigen::Vector3d d = shown.position - e.position;
  const bool ground = options_.alignToGround && e.domain == sim::Domain::land;
  if (ground) d.y() = 0;
  err.positionM = d.norm();
  err.angleDeg = angleBetweenDeg(shown.headingDeg, e.headingDeg);
  if (!ground) {
    err.angleDeg = std::max({err.angleDeg, std::abs(shown.pitchDeg - e.pitchDeg), angleBetweenDeg(shown.rollDeg, e.rollDeg)});
  }
  if (e.armed) {
    // Articulated parts are not dead reckoned: a turret or gun that turned
    // past the threshold needs a PDU too (IEEE 1278.1 asks it of them).
    err.angleDeg = std::max({err.angleDeg, angleBetweenDeg(c.turretDeg, turretOf(e)),
                             std::abs(c.gunDeg - e.gunElevationDeg)});
  }
  return err;
}

std::optional<CopyError> Publisher::errorOf(const sim::Entity& e, double nowS) const {
  auto it = copies_.find(e.id);
  if (it == copies_.end()) return std::nullopt;
  return error(it->second, e, nowS);
}

std::optional<dis::EntityState> Publisher::offer(const sim::Entity& e, const Identity& who, double nowS, bool force) {
  auto it = copies_.find(e.id);
  if (it != copies_.end() && !force && it->second.alive == e.alive) {
    const CopyError err = error(it->second, e, nowS);
    if (!sim::updateDue(options_.thresholds, err.positionM, err.angleDeg, nowS - it->second.sentS)) return std::nullopt;
  }
  Copy c;
  auto s = build(e, who, c.anchor);
  if (!s) {
    ++unplaceable_;
    return std::nullopt;
  }
  c.sent = *s;
  c.motion = dis::motionOf(*s);
  c.sentS = nowS;
  c.alive = e.alive;
  c.turretDeg = turretOf(e);
  c.gunDeg = e.gunElevationDeg;
  copies_[e.id] = std::move(c);
  ++sent_;
  return s;
}

std::optional<dis::EntityState> Publisher::retire(std::uint32_t simId, double nowS) {
  static_cast<void>(nowS);
  auto it = copies_.find(simId);
  if (it == copies_.end()) return std::nullopt;
  dis::EntityState s = it->second.sent;
  s.appearance |= kAppearanceDeactivated;
  s.velocity = {};
  s.deadReckoning.algorithm = 1;
  copies_.erase(it);
  ++sent_;
  return s;
}

}  // namespace sandtable::sim_dis
