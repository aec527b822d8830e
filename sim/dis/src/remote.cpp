#include "sandtable/sim_dis/remote.h"

#include <algorithm>
#include <cmath>

namespace sandtable::sim_dis {
namespace {

dis::Vec3d rotate(const dis::Matrix3& r, const dis::Vec3d& v) {
  return {r[0][0] * v.x + r[0][1] * v.y + r[0][2] * v.z, r[1][0] * v.x + r[1][1] * v.y + r[1][2] * v.z,
          r[2][0] * v.x + r[2][1] * v.y + r[2][2] * v.z};
}

bool bodyAxes(std::uint8_t algorithm) { return algorithm >= 6 && algorithm <= 9; }

bool finite(const dis::Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool finite(const dis::Vec3f& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// Every number dead reckoning reads. The decoder takes any bit pattern (a
/// monitor shows what was sent); a NaN here would become the simulation
/// entity's position, and grid lookups index with it.
bool finiteKinematics(const dis::EntityState& s) {
  return finite(s.location) && finite(s.velocity) && finite(s.deadReckoning.acceleration) &&
         finite(s.deadReckoning.angularVelocity) && std::isfinite(s.orientation.psi) &&
         std::isfinite(s.orientation.theta) && std::isfinite(s.orientation.phi);
}

}  // namespace

sim::Domain domainOf(const dis::EntityType& t) {
  if (t.kind == 2) return sim::Domain::munition;
  if (t.kind == 1) {
    switch (t.domain) {
      case 2:
      case 5: return sim::Domain::air;
      case 3:
      case 4: return sim::Domain::sea;
      default: return sim::Domain::land;
    }
  }
  return sim::Domain::land;
}

double RemoteEntities::blendFor(sim::Domain d) const {
  switch (d) {
    case sim::Domain::land: return options_.blendLandS;
    case sim::Domain::sea: return options_.blendSeaS;
    case sim::Domain::air: return options_.blendAirS;
    case sim::Domain::munition: return options_.blendMunitionS;
  }
  return 0;
}

RemoteEntity* RemoteEntities::find(const dis::EntityId& id) {
  auto it = entities_.find(key(id));
  return it == entities_.end() ? nullptr : &it->second;
}

Eigen::Vector3d RemoteEntities::reckoned(RemoteEntity& e, double t) {
  const dis::Motion m = dis::advance(e.motion, t - e.motionS);
  if (distanceFrom(e.anchor, m.position) > options_.reanchorM) {
    if (auto a = frame_.anchorAtEcef(m.position)) e.anchor = a.value();
  }
  return frameOf(e.anchor, m.position);
}

RemoteEntities::Order RemoteEntities::orderOf(const RemoteEntity& e, const dis::EntityState& s,
                                              std::uint32_t timestamp) const {
  if (!e.timestamp || dis::timestampAbsolute(*e.timestamp) != dis::timestampAbsolute(timestamp)) return Order::newer;
  // Time past the hour in 2^31 units a lap: the signed difference, so the
  // hour turning between two PDUs reads as a step forward.
  std::int64_t ahead = std::int64_t(timestamp >> 1) - std::int64_t(*e.timestamp >> 1);
  constexpr std::int64_t lap = std::int64_t(1) << 31;
  if (ahead >= lap / 2) ahead -= lap;
  if (ahead < -lap / 2) ahead += lap;
  if (ahead > 0) return Order::newer;
  if (ahead == 0) {
    // The same time: a copy, unless the state differs (a sender that does
    // not advance its timestamps still moves its entities).
    const bool same = s.location == e.last.location && s.velocity == e.last.velocity &&
                      s.orientation == e.last.orientation && s.appearance == e.last.appearance;
    return same ? Order::duplicate : Order::newer;
  }
  if (-double(ahead) * (3600.0 / double(lap)) > options_.staleWindowS) return Order::newer;  // a new clock
  return Order::stale;
}

RemoteEntity* RemoteEntities::update(const dis::EntityState& s, const dis::Address& sender, double pduS, double nowS,
                                     std::optional<std::uint32_t> timestamp) {
  const std::uint64_t k = key(s.id);
  if (!finiteKinematics(s)) {
    ++counters_.nonFinite;
    auto it = entities_.find(k);
    return it == entities_.end() ? nullptr : &it->second;
  }
  if (auto it = entities_.find(k); it != entities_.end()) {
    if (!(it->second.sender == sender)) {
      // Another address claims the id (a second simulation given the same
      // site and application, or a spoof). Applying both would make the
      // entity jump between them every PDU: the sender that created it
      // keeps it (the monitor keeps the first owner too) until it falls
      // silent and the entity times out.
      ++counters_.conflicts;
      return &it->second;
    }
    // Timestamps are one sender's clock: compared with that sender's only.
    const Order order = timestamp ? orderOf(it->second, s, *timestamp) : Order::newer;
    if (order == Order::stale) {
      ++counters_.stale;
      return &it->second;
    }
    if (order == Order::duplicate) {
      // A copy proves the sender alive (one that never advances its
      // timestamps heartbeats a parked entity with copies); an older PDU does not.
      ++counters_.duplicates;
      it->second.heardS = nowS;
      return &it->second;
    }
  }
  if ((s.appearance & kAppearanceDeactivated) != 0) {
    if (entities_.erase(k) != 0) ++counters_.removed;
    return nullptr;
  }
  auto it = entities_.find(k);
  const bool known = it != entities_.end();
  const dis::Motion motion = dis::motionOf(s);
  RemoteEntity* e = known ? &it->second : nullptr;
  if (!known || distanceFrom(e->anchor, motion.position) > options_.reanchorM) {
    auto anchor = frame_.anchorAtEcef(motion.position);
    if (!anchor) {
      ++counters_.unplaceable;
      return nullptr;
    }
    if (!known) {
      RemoteEntity fresh;
      fresh.id = s.id;
      fresh.sender = sender;
      fresh.domain = domainOf(s.type);
      fresh.anchor = anchor.value();
      e = &entities_.emplace(k, std::move(fresh)).first->second;
      ++counters_.created;
    } else {
      e->anchor = anchor.value();
    }
  }
  ++counters_.pdus;
  if (known) {
    // Figure 91: where the old motion (and any smoothing still running)
    // shows the entity now, against where the new one puts it.
    Eigen::Vector3d shown = reckoned(*e, nowS);
    if (e->blendS > 0) shown += e->offset * std::max(0.0, 1 - (nowS - e->blendStartS) / e->blendS);
    e->motion = motion;
    e->motionS = pduS;
    const Eigen::Vector3d now = reckoned(*e, nowS);
    const double jump = (shown - now).norm();
    ++counters_.corrections;
    counters_.lastCorrectionM = jump;
    counters_.maxCorrectionM = std::max(counters_.maxCorrectionM, jump);
    const double blend = blendFor(e->domain);
    if (blend > 0 && jump <= options_.snapBeyondM) {
      e->offset = shown - now;
      e->blendStartS = nowS;
      e->blendS = blend;
      ++counters_.smooths;
    } else {
      e->offset.setZero();
      e->blendS = 0;
      ++counters_.snaps;
    }
  } else {
    e->motion = motion;
    e->motionS = pduS;
  }
  e->sender = sender;
  e->last = s;
  e->domain = domainOf(s.type);
  e->heardS = nowS;
  e->timestamp = timestamp;
  e->offDatabase = false;
  ++e->updates;
  return e;
}

bool RemoteEntities::remove(const dis::EntityId& id) {
  if (entities_.erase(key(id)) == 0) return false;
  ++counters_.removed;
  return true;
}

std::vector<RemoteEntity> RemoteEntities::expire(double nowS) {
  std::vector<RemoteEntity> gone;
  for (auto it = entities_.begin(); it != entities_.end();) {
    if (nowS - it->second.heardS >= options_.timeoutS) {
      gone.push_back(std::move(it->second));
      it = entities_.erase(it);
      ++counters_.timedOut;
    } else {
      ++it;
    }
  }
  return gone;
}

Result<RemoteState> RemoteEntities::stateAt(RemoteEntity& e, double nowS) {
  const dis::Motion m = dis::advance(e.motion, nowS - e.motionS);
  if (distanceFrom(e.anchor, m.position) > options_.reanchorM) {
    auto a = frame_.anchorAtEcef(m.position);
    if (!a) return a.problems();
    e.anchor = a.value();
  }
  RemoteState out;
  out.pose = framePose(e.anchor, m.position, m.orientation);
  if (e.blendS > 0) {
    const double left = 1 - (nowS - e.blendStartS) / e.blendS;
    if (left > 0) out.pose.position += e.offset * left;
    else e.blendS = 0;
  }
  const dis::Vec3d v = bodyAxes(m.algorithm) ? rotate(m.orientation, m.velocity) : m.velocity;
  out.velocity = frameVector(e.anchor, v);
  out.alive = (e.last.appearance & kAppearanceDamageMask) != kAppearanceDestroyed;
  return out;
}

}  // namespace sandtable::sim_dis
