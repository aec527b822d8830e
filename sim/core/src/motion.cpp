// Land and sea motion: projected-point ground following, tracked and
// wheeled dynamics with soil, Table 5 control, ships (seed VII.B).
#include "sandtable/sim/motion.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sandtable::sim {

std::optional<Attitude> projectedPointAttitude(const SimWorld& world, double x, double z, double headingDeg,
                                               double halfLength, double halfWidth) {
  const auto centre = world.groundAt(x, z);
  if (!centre) return std::nullopt;
  const Eigen::Vector3d f = headingVector(headingDeg);
  const Eigen::Vector3d right(-f.z(), 0, f.x());  // forward turned 90 degrees clockwise
  const double front = world.groundAt(x + f.x() * halfLength, z + f.z() * halfLength).value_or(*centre);
  const double side = world.groundAt(x + right.x() * halfWidth, z + right.z() * halfWidth).value_or(*centre);
  Attitude a;
  a.groundY = *centre;
  a.pitchDeg = std::atan2(front - *centre, halfLength) * kRadToDeg;
  a.rollDeg = std::atan2(*centre - side, halfWidth) * kRadToDeg;  // right side lower: positive
  return a;
}

double turningRadius(double d, double steerDeg) {
  const double t = std::tan(std::abs(steerDeg) * kDegToRad);
  if (t <= 0) return std::numeric_limits<double>::infinity();
  const double a = 2 * d / t;
  return std::sqrt(a * a + d * d);
}

double propulsiveForce(const VehicleParams& v, double fraction, double speedMs) {
  const double s = std::abs(speedMs);
  // Braking (the force against the motion) is not limited by engine power.
  const bool braking = fraction * speedMs < 0;
  const double limit = s > 0 && !braking ? std::min(v.maxForceN, v.powerW / s) : v.maxForceN;
  return std::clamp(fraction, -1.0, 1.0) * limit;
}

namespace {

/// The new speed along the surface after dt under net drive `drive`
/// (propulsion per unit mass less gravity along the slope), with the
/// soil's friction (see motion.h).
double alongSurface(double v, double drive, double pitchDeg, const SimWorld::Soil& soil, double dt) {
  const double cosP = std::cos(pitchDeg * kDegToRad);
  const double friction = soil.resist * kGravity * cosP;
  if (v == 0) {
    const double grip = kGravity * cosP * std::max(soil.resist, std::tan(soil.stickDeg * kDegToRad));
    if (std::abs(drive) <= grip) return 0;
    const double a = drive - std::copysign(friction, drive);
    return (a > 0) == (drive > 0) ? a * dt : 0;
  }
  const double next = v + (drive - std::copysign(friction, v)) * dt;
  return (next > 0) == (v > 0) ? next : 0;  // friction stops, never reverses
}

double burn(Entity& e, double fraction, double dt) {
  if (e.vehicle.fuelBurnPerS <= 0) return fraction;
  if (e.fuel <= 0) return 0;
  e.fuel = std::max(0.0, e.fuel - e.vehicle.fuelBurnPerS * std::abs(fraction) * dt);
  return fraction;
}

double turnTowards(double headingDeg, double wantDeg, double rateDegS, double dt) {
  const double turn = std::clamp(turnBetween(headingDeg, wantDeg), -rateDegS * dt, rateDegS * dt);
  return wrapDeg(headingDeg + turn);
}

/// Speed change and heading rate of the dynamics models; `yawRate` is the
/// entity's angular velocity about Y (clockwise positive, rad/s).
void landDynamics(const SimWorld& world, Entity& e, double pitchDeg, double dt) {
  const double m = e.vehicle.massKg;
  const SimWorld::Soil soil = world.soilAt(e.position.x(), e.position.z());
  const double slope = kGravity * std::sin(pitchDeg * kDegToRad);
  if (e.mobility == Mobility::tracked) {
    const double left = burn(e, e.controls.leftTrack, dt * 0.5), right = burn(e, e.controls.rightTrack, dt * 0.5);
    const double fl = propulsiveForce(e.vehicle, left, e.speedMs) * 0.5;
    const double fr = propulsiveForce(e.vehicle, right, e.speedMs) * 0.5;
    e.speedMs = alongSurface(e.speedMs, (fl + fr) / m - slope, pitchDeg, soil, dt);
    // Figure 53: the stronger left track turns the hull right (clockwise).
    const double inertia = m * (4 * e.halfLength * e.halfLength + 4 * e.halfWidth * e.halfWidth) / 12;
    const double torque = (fl - fr) * e.halfWidth;
    const double maxTorque = e.vehicle.maxForceN * e.halfWidth;  // full tracks, opposite
    const double damping = maxTorque / (inertia * e.vehicle.turnRateDegS * kDegToRad);
    double yaw = -e.angularVelocity.y();  // body +Y rate is counter-clockwise seen from above
    yaw += (torque / inertia - damping * yaw) * dt;
    e.angularVelocity = {0, -yaw, 0};
    e.headingDeg = wrapDeg(e.headingDeg + yaw * kRadToDeg * dt);
  } else {  // wheeled
    const double throttle = burn(e, e.controls.throttle, dt);
    e.speedMs = alongSurface(e.speedMs, propulsiveForce(e.vehicle, throttle, e.speedMs) / m - slope, pitchDeg,
                             soil, dt);
    const double steer = std::clamp(e.controls.steer, -1.0, 1.0) * e.vehicle.steerLimitDeg;
    const double rho = turningRadius(e.halfLength, steer);
    const double yaw = std::isfinite(rho) ? std::copysign(e.speedMs / rho, steer) : 0.0;
    e.angularVelocity = {0, -yaw, 0};
    e.headingDeg = wrapDeg(e.headingDeg + yaw * kRadToDeg * dt);
  }
}

/// Table 5, second order: acceleration and angular acceleration.
void secondOrderControl(Entity& e, double dt) {
  const double limit = e.vehicle.turnRateDegS;
  e.speedMs = std::clamp(e.speedMs + e.commands.accelerationMs2 * dt, -e.vehicle.maxSpeedMs, e.vehicle.maxSpeedMs);
  const double rate = std::clamp(-e.angularVelocity.y() * kRadToDeg + e.commands.turnAccelerationDegS2 * dt, -limit,
                                 limit);
  e.headingDeg = wrapDeg(e.headingDeg + rate * dt);
  e.angularVelocity = {0, -rate * kDegToRad, 0};
  e.commands.speedMs = e.speedMs;  // what the behaviours and the recorder read
  e.commands.headingDeg = e.headingDeg;
}

void simpleControl(Entity& e, double dt) {
  if (e.commands.order == 2) {
    secondOrderControl(e, dt);
    return;
  }
  const double before = e.headingDeg;
  e.speedMs = std::clamp(e.commands.speedMs, -e.vehicle.maxSpeedMs, e.vehicle.maxSpeedMs);
  if (e.vehicle.fuelBurnPerS > 0) {
    if (e.fuel <= 0) e.speedMs = 0;
    burn(e, e.speedMs / std::max(1e-9, e.vehicle.maxSpeedMs), dt);
  }
  e.headingDeg = turnTowards(e.headingDeg, e.commands.headingDeg, e.vehicle.turnRateDegS, dt);
  e.angularVelocity = {0, -turnBetween(before, e.headingDeg) * kDegToRad / dt, 0};
}

bool stepShip(const SimWorld& world, Entity& e, double dt) {
  simpleControl(e, dt);
  const Eigen::Vector3d f = headingVector(e.headingDeg);
  const Eigen::Vector3d next = e.position + f * (e.speedMs * dt);
  const Eigen::Vector3d bow = next + f * std::copysign(e.halfLength, e.speedMs);
  if (e.speedMs != 0 && (!world.navigable(next.x(), next.z()) || !world.navigable(bow.x(), bow.z()))) {
    e.speedMs = 0;  // held off the land; it moves again once it has turned clear
    e.velocity.setZero();
    return true;
  }
  const Eigen::Vector3d old = e.position;
  e.position = next;
  e.position.y() = std::max(0.0, world.groundAt(next.x(), next.z()).value_or(0.0));
  e.pitchDeg = e.rollDeg = 0;
  e.velocity = (e.position - old) / dt;
  e.heightAgl = 0;
  return true;
}

}  // namespace

bool stepSurface(const SimWorld& world, Entity& e, double dt) {
  if (e.mobility == Mobility::ship || e.domain == Domain::sea) return stepShip(world, e, dt);
  const Eigen::Vector3d old = e.position;
  const Eigen::Vector3d oldVelocity = e.velocity;
  if (e.mobility == Mobility::simple) {
    simpleControl(e, dt);
  } else {
    landDynamics(world, e, e.pitchDeg, dt);
  }
  // Along the surface: the horizontal step is v cos(pitch) dt.
  const double horizontal = e.speedMs * std::cos(e.pitchDeg * kDegToRad) * dt;
  const Eigen::Vector3d f = headingVector(e.headingDeg);
  const double x = e.position.x() + f.x() * horizontal, z = e.position.z() + f.z() * horizontal;
  const auto a = projectedPointAttitude(world, x, z, e.headingDeg, e.halfLength, e.halfWidth);
  if (!a) {
    e.speedMs = 0;
    e.velocity.setZero();
    return false;
  }
  e.position = {x, a->groundY, z};
  e.pitchDeg = a->pitchDeg;
  e.rollDeg = a->rollDeg;
  e.velocity = (e.position - old) / dt;
  e.acceleration = (e.velocity - oldVelocity) / dt;
  e.heightAgl = 0;
  return true;
}

void landAutopilot(Entity& e) {
  const double speedError = e.commands.speedMs - e.speedMs;
  const double turn = turnBetween(e.headingDeg, e.commands.headingDeg);
  // Proportional control, with the force needed to hold speed against the
  // resistance of firm ground as the feed-forward.
  const double hold = 0.05 * e.vehicle.massKg * kGravity / e.vehicle.maxForceN;
  // Far off the wanted heading, turn first: a tracked vehicle pivots, a
  // wheeled one backs round (cos < 0 reverses it).
  const double align = std::cos(std::clamp(std::abs(turn), 0.0, 180.0) * kDegToRad);
  double drive = std::clamp(hold * (e.commands.speedMs != 0 ? 1 : 0) * (e.commands.speedMs < 0 ? -1 : 1) +
                                speedError * 0.5,
                            -1.0, 1.0);
  if (align < 0.5) drive = e.mobility == Mobility::tracked ? std::min(drive, 0.0) * 0.2 : drive * align;
  if (e.mobility == Mobility::tracked) {
    const double steer = std::clamp(turn / 20.0, -1.0, 1.0);
    e.controls.leftTrack = std::clamp(drive + steer * 0.5, -1.0, 1.0);
    e.controls.rightTrack = std::clamp(drive - steer * 0.5, -1.0, 1.0);
  } else {
    e.controls.throttle = drive;
    e.controls.steer = std::clamp(turn / 15.0, -1.0, 1.0) * (e.speedMs < 0 ? -1 : 1);
  }
}

void allStop(Entity& e) {
  e.commands.speedMs = 0;
  e.commands.headingDeg = e.headingDeg;
  e.commands.altitudeM = e.position.y();
  e.controls = {};
  e.autopilot = true;
}

}  // namespace sandtable::sim
