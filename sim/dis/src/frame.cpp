#include "sandtable/sim_dis/frame.h"

#include <cmath>

#include <Eigen/LU>

#include "sandtable/sim/entity.h"
#include "sandtable/sim/units.h"

namespace sandtable::sim_dis {
namespace {

Eigen::Vector3d vec(const dis::Vec3d& v) { return {v.x, v.y, v.z}; }
dis::Vec3d vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d vec(const geodesy::FramePoint& p) { return {p.x, p.y, p.z}; }
dis::Vec3d vec(const geodesy::Ecef& e) { return {e.x, e.y, e.z}; }

/// Central differences over +-10 m: the curvature term cancels, and what
/// is left (about 1e-12 relative) is far below PROJ's own round-off.
constexpr double kStepM = 10;

}  // namespace

Eigen::Vector3d frameOf(const Anchor& a, const dis::Vec3d& ecef) {
  return a.frame + a.toFrame * (vec(ecef) - vec(a.ecef));
}
dis::Vec3d ecefOf(const Anchor& a, const Eigen::Vector3d& frame) {
  return vec(vec(a.ecef) + a.toEcef * (frame - a.frame));
}
Eigen::Vector3d frameVector(const Anchor& a, const dis::Vec3d& v) { return a.toFrame * vec(v); }
dis::Vec3d ecefVector(const Anchor& a, const Eigen::Vector3d& v) { return vec(a.toEcef * v); }
double distanceFrom(const Anchor& a, const dis::Vec3d& ecef) { return (vec(ecef) - vec(a.ecef)).norm(); }

dis::Vec3d disBody(const Eigen::Vector3d& s) { return {-s.z(), s.x(), -s.y()}; }
Eigen::Vector3d simBody(const dis::Vec3d& d) { return {d.y, -d.z, -d.x}; }

FramePose framePose(const Anchor& a, const dis::Vec3d& ecef, const dis::Euler& e) {
  return framePose(a, ecef, dis::rotationMatrix(e.psi, e.theta, e.phi));
}

FramePose framePose(const Anchor& a, const dis::Vec3d& ecef, const dis::Matrix3& bodyToEcef) {
  const dis::Attitude att = dis::attitudeOf(a.axes, bodyToEcef);
  FramePose p;
  p.position = frameOf(a, ecef);
  p.headingDeg = sim::wrapDeg(att.heading * sim::kRadToDeg);
  p.pitchDeg = att.pitch * sim::kRadToDeg;
  p.rollDeg = att.roll * sim::kRadToDeg;
  return p;
}

dis::Euler disOrientation(const Anchor& a, double headingDeg, double pitchDeg, double rollDeg) {
  return dis::toEuler(a.axes, {headingDeg * sim::kDegToRad, pitchDeg * sim::kDegToRad, rollDeg * sim::kDegToRad});
}

Result<Anchor> DisFrame::anchorAtEcef(const dis::Vec3d& ecef) const {
  auto f = frame_.fromEcef({ecef.x, ecef.y, ecef.z});
  if (!f) return f.problems();
  Anchor a;
  a.ecef = ecef;
  a.frame = vec(f.value());
  return complete(a);
}

Result<Anchor> DisFrame::anchorAtFrame(const Eigen::Vector3d& frame) const {
  auto e = frame_.toEcef({frame.x(), frame.y(), frame.z()});
  if (!e) return e.problems();
  Anchor a;
  a.ecef = vec(e.value());
  a.frame = frame;
  return complete(a);
}

Result<Anchor> DisFrame::complete(Anchor a) const {
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[axis] = kStepM;
    const Eigen::Vector3d e = vec(a.ecef);
    auto plus = frame_.fromEcef({e.x() + d.x(), e.y() + d.y(), e.z() + d.z()});
    auto minus = frame_.fromEcef({e.x() - d.x(), e.y() - d.y(), e.z() - d.z()});
    if (!plus) return plus.problems();
    if (!minus) return minus.problems();
    a.toFrame.col(axis) = (vec(plus.value()) - vec(minus.value())) / (2 * kStepM);
  }
  a.toEcef = a.toFrame.inverse();
  auto axes = frame_.localAxes({a.frame.x(), a.frame.y(), a.frame.z()});
  if (!axes) return axes.problems();
  a.axes = {vec(axes->north), vec(axes->east), vec(axes->down)};
  return a;
}

}  // namespace sandtable::sim_dis
