#pragma once
// Land and sea motion (seed VII.A, VII.B.1, VII.B.2).
//
// Ground following: a land entity stands on the drawn surface at its
// origin; its pitch comes from a point projected ahead to the front of its
// bounding box and its roll from a point projected to its side (the
// projected-point method, Figures 25 and 52). Both points move smoothly
// over triangle edges, so the orientation never jumps there (Figure 51).
//
// Dynamics (VII.B.2.b), along the surface, with g = 9.80665:
//   a = F/m - g sin(pitch) - sign(v) * resist * g cos(pitch)   (moving)
// At rest the entity stays while |F/m - g sin(pitch)| is within the soil's
// grip, g cos(pitch) * max(resist, tan(stick)): on a slope steeper than the
// stick angle it starts to slide. Friction never reverses the motion: a
// speed that would cross zero stops at zero. So under a constant force an
// entity slows uphill, speeds up downhill, holds its speed where F balances
// the resistance, and stops when no force acts.
//  - Tracked (Figure 53): two track forces along the hull, half the width
//    off the centre; their difference is a torque about Y. Yaw damping is
//    set so that the largest torque turns at VehicleParams::turnRateDegS.
//  - Wheeled (Figure 54): one force along the hull and a steerable front
//    axle; the centre turns on rho = sqrt((2d / tan(alpha))^2 + d^2) with d
//    half the entity's length, at v / rho rad/s.
//  - Each force is the control fraction times min(maxForce, power / |v|);
//    braking (against the motion) gets maxForce whatever the speed.
//  - Simple (Table 5): first-order speed (it is set to the command), and
//    the heading turns towards the commanded one at turnRateDegS; or, with
//    Commands::order 2, acceleration and angular acceleration integrated.
// Ships (VII.B.1) move as simple entities on navigable water at pitch and
// roll zero; a step that would put the bow on land is refused (the ship
// stops there, still turning, until its course is clear).
//
// Thread safety: pure functions of their arguments (the world is read only).
#include <optional>

#include "sandtable/sim/entity.h"
#include "sandtable/sim/sim_world.h"

namespace sandtable::sim {

struct Attitude {
  double groundY = 0;
  double pitchDeg = 0, rollDeg = 0;
};

/// The projected-point attitude at (x, z) of an entity of the given half
/// length and width heading `headingDeg`; nullopt off the grid. A point that
/// falls off the grid uses the ground at the origin (level there).
std::optional<Attitude> projectedPointAttitude(const SimWorld& world, double x, double z, double headingDeg,
                                               double halfLength, double halfWidth);

/// Figure 54's turning radius of the centre, metres: d half the length,
/// alpha the steering angle (0: infinite).
double turningRadius(double d, double steerDeg);

/// The force available now: fraction * min(maxForce, power / |v|); a
/// force against the motion (braking) is fraction * maxForce.
double propulsiveForce(const VehicleParams& v, double fraction, double speedMs);

/// One step of a land entity (tracked, wheeled or simple) or a ship; the
/// entity's position, speeds, heading, orientation, attitude and fuel are
/// updated. Returns false when the entity cannot be placed (off the grid:
/// it is held where it was, speed 0).
bool stepSurface(const SimWorld& world, Entity& e, double dt);

/// Sets a land vehicle's controls (tracks or throttle and steer) to reach
/// its commanded speed and heading: the autopilot (VII.D) that the
/// behaviours and scripts drive dynamic entities with.
void landAutopilot(Entity& e);

/// All stop (VII.D): commands zero speed on the current heading, controls
/// released, autopilot on; aircraft are commanded level at their altitude.
void allStop(Entity& e);

}  // namespace sandtable::sim
