#pragma once
// DIS orientations (IEEE 1278.1 §1.3.2 and 6.2.33): the entity's axes
// (x forward, y right, z down) relative to the geocentric (WGS-84 ECEF)
// frame, as Euler angles psi, theta, phi: rotate about ECEF Z by psi, about
// the new Y by theta, about the new X by phi, so the entity's axes in ECEF
// are the columns of Rz(psi) Ry(theta) Rx(phi). A local heading, pitch and
// roll are the same rotations relative to north, east, down at the point
// (heading clockwise from north, pitch nose up, roll right wing down).
// The caller supplies north, east and down in ECEF (the database frame's
// from geodesy::DatabaseFrame::localAxes, whose north is grid north), so
// this library stays free of geodesy (docs/DIS.md §5).
//
// Thread safety: pure functions; call from any thread.
#include <array>

#include "sandtable/dis/pdu.h"

namespace sandtable::dis {

/// A 3 x 3 matrix, row-major; as an orientation, its columns are the body's
/// x, y, z axes in the reference axes (body to world).
using Matrix3 = std::array<std::array<double, 3>, 3>;

/// Rz(yaw) Ry(pitch) Rx(roll) (radians): a DIS orientation (psi, theta,
/// phi) relative to ECEF, or an attitude relative to north, east, down.
Matrix3 rotationMatrix(double yaw, double pitch, double roll);
/// Its angles back, {yaw, pitch, roll}; past |sin pitch| = 1 - 1e-12
/// (gimbal lock) the roll is 0 and the yaw carries the turn.
std::array<double, 3> rotationAngles(const Matrix3& r);
/// The product a b.
Matrix3 multiply(const Matrix3& a, const Matrix3& b);

/// Unit vectors of local north, east and down in ECEF, right-handed.
struct LocalAxes {
  Vec3d north, east, down;
};

/// Local heading, pitch and roll in radians.
struct Attitude {
  double heading = 0, pitch = 0, roll = 0;
};

/// The DIS orientation of an entity with attitude `a` at a point whose
/// local axes are `axes`.
Euler toEuler(const LocalAxes& axes, const Attitude& a);

/// The attitude of a DIS orientation at a point with local axes `axes`.
/// At pitch +-90 degrees heading and roll turn about the same axis; the
/// roll is then 0 and the heading carries the turn.
Attitude toAttitude(const LocalAxes& axes, const Euler& e);
/// The same for an orientation held as a matrix (body to ECEF), as dead
/// reckoning carries it: no rounding to the PDU's single-precision angles.
Attitude attitudeOf(const LocalAxes& axes, const Matrix3& bodyToEcef);

/// North, east and down at geodetic latitude and longitude (radians) on
/// the WGS-84 ellipsoid, for callers with no database frame (true north).
LocalAxes trueAxes(double latitude, double longitude);

}  // namespace sandtable::dis
