#pragma once
// Publishing local entities (seed X.C; IEEE 1278.1 §5.3.2): each keeps the
// dead-reckoned copy of itself that receivers hold, and an Entity State
// PDU goes out when the copy's error passes a threshold or a heartbeat is
// due: sim::updateDue, the rule the script recorder uses too.
//
// Land entities are aligned to the ground by their receivers (seed
// "align-to-ground": height, pitch and roll come from the drawn terrain),
// so for them only the horizontal error and the heading count: a tank
// climbing a hill sends no PDUs for its pitch. An armed entity's turret
// and gun, which no algorithm reckons, count against the angle threshold.
//
// Thread safety: one thread owns a Publisher.
#include <cstdint>
#include <optional>
#include <unordered_map>

#include "sandtable/dis/dead_reckoning.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/sim/entity.h"
#include "sandtable/sim/update_rule.h"
#include "sandtable/sim_dis/frame.h"

namespace sandtable::sim_dis {

struct PublishOptions {
  /// Defaults: the 1 m and 3 degrees, the standard's 5 s heartbeat.
  sim::UpdateThresholds thresholds{1.0, 3.0, 5.0};
  /// Dead-reckoning algorithm per domain (IEEE 1278.1 Annex E numbers):
  /// the seed's first-order FPW for surface vehicles, RVW for aircraft,
  /// FVW (gravity) for munitions.
  std::uint8_t landAlgorithm = 2, seaAlgorithm = 2, airAlgorithm = 4, munitionAlgorithm = 5;
  bool alignToGround = true;  ///< land: horizontal error and heading only
};

/// The errors of a dead-reckoned copy against the true state.
struct CopyError {
  double positionM = 0;
  double angleDeg = 0;
};

/// What the publisher knows of an entity besides its simulation state.
struct Identity {
  dis::EntityId id;
  dis::EntityType type;
  std::uint8_t force = 0;
};

class Publisher {
 public:
  Publisher(DisFrame frame, PublishOptions options = {}) : frame_(std::move(frame)), options_(options) {}

  /// Offers entity `e`'s true state at `nowS`; returns the PDU body to
  /// send when the rule says so (or `force`: a first PDU, a change of
  /// alive). nullopt also when its position cannot be converted (counted).
  std::optional<dis::EntityState> offer(const sim::Entity& e, const Identity& who, double nowS, bool force = false);
  /// The body that deactivates `id` (appearance bit 23), and forgets it.
  std::optional<dis::EntityState> retire(std::uint32_t simId, double nowS);
  /// The current copy's error for entity `simId` (tests, Table 9).
  std::optional<CopyError> errorOf(const sim::Entity& e, double nowS) const;

  std::uint64_t sent() const { return sent_; }
  std::uint64_t unplaceable() const { return unplaceable_; }
  std::uint8_t algorithmFor(sim::Domain d) const;

 private:
  struct Copy {
    dis::EntityState sent;
    dis::Motion motion;
    double sentS = 0;
    Anchor anchor;
    bool alive = true;
    double turretDeg = 0, gunDeg = 0;  ///< armed: the turret (from the hull's nose) and gun as sent
  };
  CopyError error(const Copy& c, const sim::Entity& e, double nowS) const;
  std::optional<dis::EntityState> build(const sim::Entity& e, const Identity& who, Anchor& anchor) const;

  DisFrame frame_;
  PublishOptions options_;
  std::unordered_map<std::uint32_t, Copy> copies_;
  std::uint64_t sent_ = 0, unplaceable_ = 0;
};

}  // namespace sandtable::sim_dis
