#pragma once
// Remote entities (seed X.C, Figures 89-91): entities another simulation
// owns, known from its Entity State PDUs and dead reckoned between them.
//
// Each PDU replaces the entity's motion (dead_reckoning.h: the algorithm
// the PDU names, from the PDU's time). UDP may reorder and duplicate: a
// PDU whose timestamp is older than the one applied (stale), or a copy of
// it (same timestamp, same state: a duplicate), is counted and dropped,
// since applying it would move the entity back to where it was. The
// address that created an entity owns it: another address's PDUs for the
// id are conflicts, counted and dropped, until the entity times out. The jump between where the old
// motion had it and where the new one puts it is a correction: it snaps
// (munitions, jumps past snapBeyondM) or is smoothed back over a blend time
// chosen per domain (Figure 91's smooth-back: the offset shrinks linearly
// to zero). An entity silent for timeoutS (12 s: 2.4 of the standard's
// 5 s heartbeats) is dropped, as is one whose PDU says it is deactivated.
// Positions are dead reckoned in ECEF, exactly as the standard defines
// the algorithms, and brought into the database frame through the
// entity's Anchor (frame.h), re-anchored past reanchorM.
//
// Thread safety: one thread owns a RemoteEntities (the simulation's, at
// its pre-step hook); const methods may be called while no other thread
// changes it.
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include "sandtable/dis/datagram.h"
#include "sandtable/dis/dead_reckoning.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/sim/entity.h"
#include "sandtable/sim_dis/frame.h"

namespace sandtable::sim_dis {

struct RemoteOptions {
  double timeoutS = 12;      ///< silence after which an entity is dropped
  double blendLandS = 1.0;   ///< smooth-back time per domain; 0 snaps
  double blendSeaS = 2.0;
  double blendAirS = 0.5;
  double blendMunitionS = 0;
  double snapBeyondM = 100;  ///< a correction longer than this snaps whatever the domain
  double reanchorM = 500;    ///< see frame.h: the linear map is off by ~2 cm at 500 m
  /// A PDU older than the applied one by more than this is not a late
  /// arrival (no network holds a datagram that long) but a new clock: the
  /// sender restarted, or its clock jumped. It is applied.
  double staleWindowS = 12;
};

/// The simulator's domain of a DIS entity type (kind 1 platform: domain 1
/// land, 2 air, 3 surface and 4 subsurface sea, 5 space air; kind 2
/// munition; anything else land).
sim::Domain domainOf(const dis::EntityType& t);

/// DIS appearance bits (SISO-REF-010 general appearance) the gateway reads and writes.
inline constexpr std::uint32_t kAppearanceDamageMask = 3u << 3;
inline constexpr std::uint32_t kAppearanceDestroyed = 3u << 3;
inline constexpr std::uint32_t kAppearanceDeactivated = 1u << 23;
/// SISO-REF-010 articulated part parameter types (class x 32 + metric): the
/// seed's UPDATEMESS turret direction and gun elevation.
inline constexpr std::uint32_t kTurretAzimuth = 4096 + 11;  ///< primary turret, azimuth (radians from the hull's nose)
inline constexpr std::uint32_t kGunElevation = 4416 + 13;   ///< primary gun, elevation (radians)

struct RemoteEntity {
  dis::EntityId id;
  dis::Address sender;
  dis::EntityState last;   ///< the latest PDU's body
  dis::Motion motion;      ///< its dead reckoning, valid at motionS
  double motionS = 0;
  double heardS = 0;       ///< when the latest PDU arrived
  std::optional<std::uint32_t> timestamp;  ///< the applied PDU's header timestamp, when the caller gave it
  Anchor anchor;
  sim::Domain domain = sim::Domain::land;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  ///< smooth-back: shrinks to zero
  double blendStartS = 0, blendS = 0;
  std::uint32_t simId = UINT32_MAX;  ///< the simulation's entity, when it has one
  bool offDatabase = false;          ///< the simulation refused it; tried again on its next PDU
  std::uint64_t updates = 0;
};

/// Where a remote entity is now.
struct RemoteState {
  FramePose pose;
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< frame axes, m/s
  bool alive = true;
};

struct RemoteCounters {
  std::uint64_t pdus = 0;         ///< Entity State PDUs applied
  std::uint64_t created = 0;
  std::uint64_t corrections = 0;  ///< PDUs for an entity already known
  std::uint64_t snaps = 0, smooths = 0;
  std::uint64_t timedOut = 0, removed = 0;
  std::uint64_t conflicts = 0;    ///< dropped: a PDU for an id another sender address owns
  std::uint64_t stale = 0;        ///< dropped: older than the PDU applied (reordered)
  std::uint64_t duplicates = 0;   ///< dropped: the PDU applied, again
  std::uint64_t unplaceable = 0;  ///< locations PROJ could not bring into the frame
  std::uint64_t nonFinite = 0;    ///< dropped: a NaN or infinite location, velocity, orientation or rate
  double lastCorrectionM = 0, maxCorrectionM = 0;
};

class RemoteEntities {
 public:
  RemoteEntities(DisFrame frame, RemoteOptions options = {}) : frame_(std::move(frame)), options_(options) {}

  /// Applies an Entity State PDU that arrived at `nowS` and describes the
  /// entity at `pduS` (the caller's clock; equal to nowS when the PDU's
  /// timestamp cannot be compared with it). `timestamp` is the PDU
  /// header's: given, a PDU older than the one applied (by up to
  /// staleWindowS) or a duplicate of it is counted and changes nothing.
  /// A PDU from another address than the one that created the entity is a
  /// conflict: counted, and it changes nothing.
  /// A PDU with a non-finite location, orientation, velocity, acceleration
  /// or angular velocity is counted and changes nothing. Returns the entity
  /// (unchanged when the PDU is dropped), or null when the PDU names no
  /// known entity and is dropped, its location cannot be placed (counted)
  /// or it deactivates the entity (removed, counted).
  RemoteEntity* update(const dis::EntityState& s, const dis::Address& sender, double pduS, double nowS,
                       std::optional<std::uint32_t> timestamp = std::nullopt);
  /// Drops an entity (Remove Entity PDU); false when unknown.
  bool remove(const dis::EntityId& id);
  /// Drops every entity silent for timeoutS at `nowS` and returns them.
  std::vector<RemoteEntity> expire(double nowS);
  /// The state at `nowS` (re-anchors when the entity has moved far).
  Result<RemoteState> stateAt(RemoteEntity& e, double nowS);

  RemoteEntity* find(const dis::EntityId& id);
  std::unordered_map<std::uint64_t, RemoteEntity>& all() { return entities_; }
  const std::unordered_map<std::uint64_t, RemoteEntity>& all() const { return entities_; }
  std::size_t size() const { return entities_.size(); }
  const RemoteCounters& counters() const { return counters_; }
  const RemoteOptions& options() const { return options_; }
  const DisFrame& frame() const { return frame_; }

  static std::uint64_t key(const dis::EntityId& id) {
    return (std::uint64_t(id.site) << 32) | (std::uint64_t(id.application) << 16) | id.entity;
  }

 private:
  double blendFor(sim::Domain d) const;
  enum class Order { newer, stale, duplicate };
  /// `s` at `timestamp` against what `e` applied.
  Order orderOf(const RemoteEntity& e, const dis::EntityState& s, std::uint32_t timestamp) const;
  /// The motion's position at `t` in the frame, without smoothing.
  Eigen::Vector3d reckoned(RemoteEntity& e, double t);

  DisFrame frame_;
  RemoteOptions options_;
  std::unordered_map<std::uint64_t, RemoteEntity> entities_;
  RemoteCounters counters_;
};

}  // namespace sandtable::sim_dis
