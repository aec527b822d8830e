#pragma once
// The reactive behaviours of the computer-generated forces (seed VIII.A):
// zig-zag paths (Figure 68), environment limits, the edge of the world
// (Figure 69) and fight or flight (Figure 70). Each steers an entity's
// Commands (speed and heading); the entity's own motion model follows them.
//
// Thread safety: pure functions of their arguments.
#include <cstdint>

#include "sandtable/sim/entity.h"
#include "sandtable/sim/sim_world.h"

namespace sandtable::sim {

struct BehaviourOptions {
  /// Zig-zag: Figure 68's LENGTHOFTURNTIME, seconds. A leg lasts T to 2T:
  /// 2T - clamp(u T - speed, 0, T) for a uniform u, so faster entities keep
  /// their legs longer; the turn is uniform in [-maxTurn, +maxTurn].
  double zigzagPeriodS = 10;
  double zigzagMaxTurnDeg = 45;
  double zigzagMinSpeedMs = 1;  ///< Figure 68: only entities at 1 m/s or more zig-zag
  /// Environment limits: how far ahead the ground is checked: this many
  /// seconds at the commanded speed, or the time to turn 90 degrees at the
  /// entity's turn rate if longer, and at least the entity's length.
  double lookAheadS = 3;
  /// Object avoidance (with the environment behaviour): seconds ahead, and
  /// the speed while the path is blocked (under Table 6's slow bin for
  /// tanks, 10 km/h: a touch stops, it does not kill).
  double avoidS = 2;
  double avoidSpeedMs = 2.5;
  /// Edge of the world: the buffer zone's width, metres.
  double edgeBufferM = 250;
  /// Fight or flight: half-sizes of the near-miss and kill boxes, metres.
  double nearMissBoxM = 60;
  double killBoxM = 4;
  /// An armed entity turns this much towards the reverse azimuth each time
  /// it senses a munition, and fires once within this of it.
  double fightTurnDeg = 45;
  /// Engage (beyond the seed): range, metres, and the time between shots,
  /// seconds (each entity's first shot comes at a random time within it).
  /// Fight or flight fires back only at an enemy's munition, and only when
  /// reloaded (the seed's rule alone lets replies to replies grow without end).
  double engageRangeM = 2500;
  double engageReloadS = 30;
};

/// A deterministic random number in [0, 1) for (seed, entity, counter).
double behaviourRandom(std::uint64_t seed, std::uint32_t entity, std::uint64_t counter);

/// Figure 68: when the leg is over (and the entity moves at the minimum
/// speed or faster), turn by a random angle and start a new leg. `counter`
/// is advanced by the draws it makes. Returns the turn made, degrees (0 for
/// none).
double zigzag(Entity& e, double nowS, std::uint64_t seed, std::uint64_t& counter, const BehaviourOptions& o);

/// The leg length of Figure 68 for a draw u in [0, 1) and a speed.
double zigzagLegS(double u, double speedMs, const BehaviourOptions& o);

/// Environment limits: a ship whose look-ahead point is not navigable, or a
/// land entity whose look-ahead point is water (or at or below elevation 0
/// where the soil is unknown), turns back (heading + 180). True when it did.
bool environmentLimit(const SimWorld& world, Entity& e, const BehaviourOptions& o);

/// Beyond the seed, with the environment behaviour: a land entity whose
/// path over the next `avoidS` seconds (and at least two radii) meets a
/// standing object slows to `avoidSpeedMs` and steers to the nearest free
/// heading among +-30, +-60, ... +-180 degrees of its commanded one; once
/// its path is clear it resumes its speed. True when it turned. The
/// seed's noise entities drove into trees and died by Table 6. `stats`,
/// when given, counts the probes' object searches.
bool avoidObjects(const SimWorld& world, Entity& e, const BehaviourOptions& o, SearchStats* stats = nullptr);

/// Edge of the world: an entity in the buffer zone heading further out
/// turns back into the world (the outward component of its heading is
/// reversed). True when it did.
bool edgeOfWorld(const SimWorld& world, Entity& e, const BehaviourOptions& o);

/// Moves an entity that starts inside the buffer zone just outside it,
/// keeping its heading and speed. True when it moved.
bool placeOutsideBuffer(const SimWorld& world, Entity& e, const BehaviourOptions& o);

/// Is point p inside the axis-aligned box of half-size `half` around the
/// entity (x and z in the world frame; y over the entity's height)?
bool inBox(const Entity& e, const Eigen::Vector3d& p, double half);

/// Can a shooter at `from` see a target at `to`: the segment stays above
/// the drawn ground, sampled every `stepM` metres.
bool lineOfSight(const SimWorld& world, const Eigen::Vector3d& from, const Eigen::Vector3d& to, double stepM = 20);

/// What fight or flight decided for one sensed munition.
struct Reaction {
  bool fled = false;
  bool turned = false;
  bool fire = false;          ///< fire back along the reverse azimuth
  double fireAzimuthDeg = 0;
};

/// Figure 70, for a munition moving along `munitionVelocity` in the
/// entity's near-miss box. Unarmed: head along the munition's direction at
/// full speed. Armed: turn fightTurnDeg towards the reverse azimuth; when
/// within one turn of it, fire along it.
Reaction fightOrFlight(Entity& e, const Eigen::Vector3d& munitionVelocity, const BehaviourOptions& o);

}  // namespace sandtable::sim
