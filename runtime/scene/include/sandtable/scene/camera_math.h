#pragma once
// The projection: one definition of the view volume for scene selection
// (frustum culling on the main thread), the renderer, the viewer's fog
// and tests that project a point as the renderer does. Pure functions of
// their arguments: safe from any thread.
//
// Depth is reversed (near = 1, far = 0) with a [0, 1] clip range and a
// float depth buffer: precision is then nearly uniform in relative terms,
// which keeps the decals' polygon offset meaningful out to the fog.
#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <numbers>

#include "sandtable/scene/display_buffer.h"

namespace sandtable::scene {

/// Reversed-Z perspective (eye looks down -Z): depth 1 at the near plane, 0 at the far.
inline Eigen::Matrix4d perspectiveReversed(double vfovDeg, double aspect, double n, double f) {
  const double t = 1.0 / std::tan(vfovDeg * std::numbers::pi / 360.0);
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  m(0, 0) = t / aspect;
  m(1, 1) = t;
  m(2, 2) = n / (f - n);
  m(2, 3) = f * n / (f - n);
  m(3, 2) = -1.0;
  return m;
}

/// World-to-eye for an eye at `eye` turned to heading (clockwise from -Z)
/// and pitched (positive up).
inline Eigen::Matrix4d lookFrom(const Eigen::Vector3d& eye, double headingDeg, double pitchDeg) {
  const double h = headingDeg * std::numbers::pi / 180.0, p = pitchDeg * std::numbers::pi / 180.0;
  const Eigen::Vector3d forward(std::cos(p) * std::sin(h), std::sin(p), -std::cos(p) * std::cos(h));
  const Eigen::Vector3d right(std::cos(h), 0.0, std::sin(h));
  const Eigen::Vector3d up = right.cross(forward);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<1, 3>(0, 0) = right.transpose();
  m.block<1, 3>(1, 0) = up.transpose();
  m.block<1, 3>(2, 0) = -forward.transpose();
  m(0, 3) = -right.dot(eye);
  m(1, 3) = -up.dot(eye);
  m(2, 3) = forward.dot(eye);
  return m;
}

/// View-projection for a camera, positions relative to (originX, 0, originZ).
inline Eigen::Matrix4d viewProjection(const Camera& cam, double originX, double originZ) {
  const Eigen::Vector3d eye(cam.x - originX, cam.y, cam.z - originZ);
  return perspectiveReversed(cam.vfovDeg(), cam.aspect, cam.nearPlane, cam.viewDistance) *
         lookFrom(eye, cam.headingDeg, cam.pitchDeg);
}

/// Fog is clear out to this fraction of the view distance, then thickens.
inline constexpr double kFogClearFraction = 0.25;
/// Fog density tied to the view distance (seed IX.A.3): exp2 fog beyond
/// the clear zone leaves 1/255 of the colour at the view distance, i.e.
/// fully fogged in 8 bits, so nothing past it need be drawn.
inline double fogDensityFor(double viewDistance) {
  return std::sqrt(std::log(255.0)) / ((1.0 - kFogClearFraction) * viewDistance);
}
/// The inverse: the obscuration distance of a fog density (per metre).
inline double viewDistanceForFog(double density) {
  return std::sqrt(std::log(255.0)) / ((1.0 - kFogClearFraction) * density);
}

/// The side and far planes of a reversed-Z clip matrix (a, b, c, d with
/// a x + b y + c z + d >= 0 inside).
inline std::array<Eigen::Vector4d, 5> frustumPlanes(const Eigen::Matrix4d& m) {
  const Eigen::Vector4d r0 = m.row(0), r1 = m.row(1), r2 = m.row(2), r3 = m.row(3);
  return {r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2};
}

/// False when the box lies wholly outside one plane.
inline bool boxInFrustum(const std::array<Eigen::Vector4d, 5>& planes, const Eigen::Vector3d& lo,
                         const Eigen::Vector3d& hi) {
  for (const auto& p : planes) {
    const Eigen::Vector3d v(p.x() >= 0 ? hi.x() : lo.x(), p.y() >= 0 ? hi.y() : lo.y(),
                            p.z() >= 0 ? hi.z() : lo.z());
    if (p.head<3>().dot(v) + p.w() < 0) return false;
  }
  return true;
}

}  // namespace sandtable::scene
