// DIS Euler angles against local attitudes (orientation.h): hand-derived
// values on the equator and at the pole, and round trips over the sphere,
// pitch +-90 degrees included, compared as rotations.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "sandtable/dis/orientation.h"

namespace sandtable::dis {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

/// The body's x (forward) and y (right) axes in ECEF for an attitude.
std::array<Vec3d, 2> bodyAxes(const LocalAxes& l, const Attitude& a) {
  const double ch = std::cos(a.heading), sh = std::sin(a.heading), cp = std::cos(a.pitch), sp = std::sin(a.pitch);
  const double cr = std::cos(a.roll), sr = std::sin(a.roll);
  // Forward and right in north, east, down, written out from Rz Ry Rx.
  const std::array<double, 3> x{cp * ch, cp * sh, -sp};
  const std::array<double, 3> y{sr * sp * ch - cr * sh, sr * sp * sh + cr * ch, sr * cp};
  auto ecef = [&](const std::array<double, 3>& v) {
    return Vec3d{v[0] * l.north.x + v[1] * l.east.x + v[2] * l.down.x, v[0] * l.north.y + v[1] * l.east.y + v[2] * l.down.y,
                 v[0] * l.north.z + v[1] * l.east.z + v[2] * l.down.z};
  };
  return {ecef(x), ecef(y)};
}

double angleDeg(const Vec3d& a, const Vec3d& b) {
  const double d = a.x * b.x + a.y * b.y + a.z * b.z;
  const double c = std::sqrt((a.x * a.x + a.y * a.y + a.z * a.z) * (b.x * b.x + b.y * b.y + b.z * b.z));
  return std::acos(std::clamp(d / c, -1.0, 1.0)) / kDeg;
}

TEST(DisOrientation, handValuesOnTheEquatorAndAtThePole) {
  // At (0, 0): north is ECEF +Z, east +Y, down -X.
  const LocalAxes eq = trueAxes(0, 0);
  EXPECT_NEAR(eq.north.z, 1, 1e-15);
  EXPECT_NEAR(eq.east.y, 1, 1e-15);
  EXPECT_NEAR(eq.down.x, -1, 1e-15);
  // Level, facing north: forward is +Z, so theta = -90 degrees (gimbal lock: phi 0, psi 0).
  Euler e = toEuler(eq, {0, 0, 0});
  EXPECT_NEAR(e.psi, 0, 1e-6);
  EXPECT_NEAR(e.theta, -kPi / 2, 1e-6);
  EXPECT_NEAR(e.phi, 0, 1e-6);
  // Level, facing east: forward +Y, right -Z, down -X: psi 90, theta 0, phi -90.
  e = toEuler(eq, {kPi / 2, 0, 0});
  EXPECT_NEAR(e.psi, kPi / 2, 1e-6);
  EXPECT_NEAR(e.theta, 0, 1e-6);
  EXPECT_NEAR(e.phi, -kPi / 2, 1e-6);
  // At the north pole on the prime meridian, level facing north: forward -X, down -Z:
  // psi 180, theta 0, phi 180.
  e = toEuler(trueAxes(kPi / 2, 0), {0, 0, 0});
  EXPECT_NEAR(std::abs(e.psi), kPi, 1e-6);
  EXPECT_NEAR(e.theta, 0, 1e-6);
  EXPECT_NEAR(std::abs(e.phi), kPi, 1e-6);
}

TEST(DisOrientation, attitudesComeBackAsTheSameRotationEverywhere) {
  for (double lat : {-90.0, -60.0, -1.0, 0.0, 35.0, 49.95, 89.0, 90.0}) {
    for (double lon : {-180.0, -75.0, 0.0, 11.58, 120.0, 179.0}) {
      const LocalAxes l = trueAxes(lat * kDeg, lon * kDeg);
      for (double pitch : {-90.0, -89.99, -45.0, -3.0, 0.0, 10.0, 60.0, 89.99, 90.0}) {
        for (double heading : {0.0, 37.5, 90.0, 181.0, 359.0}) {
          for (double roll : {-179.0, -20.0, 0.0, 5.0, 90.0}) {
            const Attitude a{heading * kDeg, pitch * kDeg, roll * kDeg};
            const Attitude back = toAttitude(l, toEuler(l, a));
            const auto want = bodyAxes(l, a), got = bodyAxes(l, back);
            ASSERT_LT(angleDeg(want[0], got[0]), 0.01) << lat << " " << lon << " " << heading << " " << pitch << " " << roll;
            ASSERT_LT(angleDeg(want[1], got[1]), 0.01) << lat << " " << lon << " " << heading << " " << pitch << " " << roll;
            if (std::abs(pitch) < 89) {
              EXPECT_NEAR(back.pitch / kDeg, pitch, 0.01);
              EXPECT_NEAR(std::remainder(back.heading / kDeg - heading, 360.0), 0, 0.01);
              EXPECT_NEAR(std::remainder(back.roll / kDeg - roll, 360.0), 0, 0.01);
            }
          }
        }
      }
    }
  }
}

TEST(DisOrientation, trueAxesAreRightHandedUnitVectors) {
  for (double lat : {-90.0, -30.0, 0.0, 45.0, 90.0}) {
    for (double lon : {-170.0, 0.0, 100.0}) {
      const LocalAxes l = trueAxes(lat * kDeg, lon * kDeg);
      EXPECT_NEAR(angleDeg(l.north, l.east), 90, 1e-9);
      EXPECT_NEAR(angleDeg(l.north, l.down), 90, 1e-9);
      // north x east = down
      const Vec3d c{l.north.y * l.east.z - l.north.z * l.east.y, l.north.z * l.east.x - l.north.x * l.east.z,
                    l.north.x * l.east.y - l.north.y * l.east.x};
      EXPECT_LT(angleDeg(c, l.down), 1e-6);
    }
  }
}

}  // namespace
}  // namespace sandtable::dis
