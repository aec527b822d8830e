#pragma once
// Dead reckoning (IEEE 1278.1-2012 Annex E; seed X.C): where an entity is
// Δt after its last Entity State PDU, by the algorithm the PDU names.
//
//  1 Static   no motion
//  2 FPW      fixed orientation, constant velocity, world axes
//  3 RPW      rotating, constant velocity, world axes
//  4 RVW      rotating, constant acceleration, world axes
//  5 FVW      fixed orientation, constant acceleration, world axes
//  6 FPB      fixed orientation, constant velocity, body axes
//  7 RPB      rotating, constant velocity, body axes
//  8 RVB      rotating, constant acceleration, body axes
//  9 FVB      fixed orientation, constant acceleration, body axes
//
// For 1-5 the PDU's velocity and acceleration are world (ECEF) vectors; for
// 6-9 they are in the entity's body axes, as the 2012 standard has them.
// The angular velocity is always in body axes. The rotating algorithms turn
// the orientation by the Rodrigues formula; the body-axis ones integrate
// the turning velocity in closed form (the standard's R1 and R2 matrices).
// Every coefficient has a series below |ω|Δt = 1e-3, so nothing divides by
// a small |ω|. Other algorithm numbers (0, 10-255) are treated as Static.
//
// Thread safety: pure functions; call from any thread.
#include "sandtable/dis/orientation.h"
#include "sandtable/dis/pdu.h"

namespace sandtable::dis {

/// What dead reckoning carries from one time to the next.
struct Motion {
  std::uint8_t algorithm = 1;
  Vec3d position;             ///< ECEF metres
  Matrix3 orientation{};      ///< body to ECEF
  Vec3d velocity;             ///< world (1-5) or body (6-9) axes, m/s
  Vec3d acceleration;         ///< world (1-5) or body (6-9) axes, m/s^2
  Vec3d angularVelocity;      ///< body axes, rad/s
};

/// The motion an Entity State PDU describes at its own time.
Motion motionOf(const EntityState& s);

/// The motion `dt` seconds later (dt may be negative): position,
/// orientation, and the velocity the algorithm's acceleration gives.
/// Advancing twice by dt / 2 equals advancing once by dt.
Motion advance(const Motion& m, double dt);

}  // namespace sandtable::dis
