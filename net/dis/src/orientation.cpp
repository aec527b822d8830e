// DIS Euler angles <-> local attitude (orientation.h): both are the same
// rotation sequence, Rz Ry Rx, relative to different axes, so a conversion
// is one change of basis between the rotation matrices.
#include "sandtable/dis/orientation.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace sandtable::dis {

namespace {

using Mat = Matrix3;

/// The local axes as the columns of a matrix: local coordinates to ECEF.
Mat basis(const LocalAxes& a) {
  return {{{a.north.x, a.east.x, a.down.x}, {a.north.y, a.east.y, a.down.y}, {a.north.z, a.east.z, a.down.z}}};
}

Mat transpose(const Mat& a) {
  Mat t{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) t[i][j] = a[j][i];
  }
  return t;
}

}  // namespace

Matrix3 multiply(const Matrix3& a, const Matrix3& b) {
  Matrix3 c{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
  }
  return c;
}

Matrix3 rotationMatrix(double yaw, double pitch, double roll) {
  const double cy = std::cos(yaw), sy = std::sin(yaw), cp = std::cos(pitch), sp = std::sin(pitch);
  const double cr = std::cos(roll), sr = std::sin(roll);
  return {{{cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy},
           {cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy},
           {-sp, sr * cp, cr * cp}}};
}

std::array<double, 3> rotationAngles(const Matrix3& r) {
  const double sp = std::clamp(-r[2][0], -1.0, 1.0);
  const double pitch = std::asin(sp);
  if (std::abs(sp) > 1.0 - 1e-12) return {std::atan2(-r[0][1], r[1][1]), pitch, 0.0};
  return {std::atan2(r[1][0], r[0][0]), pitch, std::atan2(r[2][1], r[2][2])};
}

Euler toEuler(const LocalAxes& axes, const Attitude& a) {
  const auto e = rotationAngles(multiply(basis(axes), rotationMatrix(a.heading, a.pitch, a.roll)));
  return {float(e[0]), float(e[1]), float(e[2])};
}

Attitude toAttitude(const LocalAxes& axes, const Euler& e) {
  return attitudeOf(axes, rotationMatrix(e.psi, e.theta, e.phi));
}

Attitude attitudeOf(const LocalAxes& axes, const Matrix3& bodyToEcef) {
  const auto a = rotationAngles(multiply(transpose(basis(axes)), bodyToEcef));
  return {a[0], a[1], a[2]};
}

LocalAxes trueAxes(double latitude, double longitude) {
  const double cl = std::cos(latitude), sl = std::sin(latitude), co = std::cos(longitude), so = std::sin(longitude);
  return {{-sl * co, -sl * so, cl}, {-so, co, 0.0}, {-cl * co, -cl * so, -sl}};
}

}  // namespace sandtable::dis
