#pragma once
// The database frame and DIS's geocentric states (docs/DIS.md §11.1).
//
// A DIS location is WGS-84 geocentric (ECEF) and its orientation is taken
// relative to the geocentric axes; the simulation works in the database
// frame (x east, y up, z south, metres; heading clockwise from grid north,
// pitch nose up, roll right side down). The exact conversions go through
// PROJ (geodesy::DatabaseFrame), a few microseconds each, so an entity
// keeps an Anchor: the exact conversion at one point plus the frame's
// derivative there (a 3 x 3 matrix by central differences), and converts
// the points its dead reckoning visits with one matrix product. Over a
// distance d from the anchor that linear map is off by about d^2 / (2 R)
// (R the earth's radius): 2 cm at 500 m, so callers re-anchor past
// reanchorM (RemoteOptions).
//
// Thread safety: DisFrame is an immutable value (its geodesy frame is
// thread-safe); Anchor functions are pure.
#include <Eigen/Core>

#include "sandtable/base/result.h"
#include "sandtable/dis/orientation.h"
#include "sandtable/geodesy/geodesy.h"

namespace sandtable::sim_dis {

/// A place and an attitude in the database frame.
struct FramePose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double headingDeg = 0, pitchDeg = 0, rollDeg = 0;
};

/// The exact conversion at a point and the linear map around it.
struct Anchor {
  dis::Vec3d ecef;
  Eigen::Vector3d frame = Eigen::Vector3d::Zero();
  Eigen::Matrix3d toFrame = Eigen::Matrix3d::Identity();  ///< d frame / d ecef at the point
  Eigen::Matrix3d toEcef = Eigen::Matrix3d::Identity();   ///< its inverse
  dis::LocalAxes axes;  ///< grid north, east and down in ECEF at the point
};

/// ECEF point or vector near `a` into the frame, and back.
Eigen::Vector3d frameOf(const Anchor& a, const dis::Vec3d& ecef);
dis::Vec3d ecefOf(const Anchor& a, const Eigen::Vector3d& frame);
Eigen::Vector3d frameVector(const Anchor& a, const dis::Vec3d& v);
dis::Vec3d ecefVector(const Anchor& a, const Eigen::Vector3d& v);
/// Distance from the anchor's point, metres.
double distanceFrom(const Anchor& a, const dis::Vec3d& ecef);

/// The simulator's body axes (forward -Z, up +Y, right +X) and DIS's
/// (x forward, y right, z down): a proper rotation, so it maps positions,
/// velocities and angular velocities alike.
dis::Vec3d disBody(const Eigen::Vector3d& simBody);
Eigen::Vector3d simBody(const dis::Vec3d& disBody);

/// A DIS orientation at the anchor as a frame attitude, and back.
FramePose framePose(const Anchor& a, const dis::Vec3d& ecef, const dis::Euler& e);
FramePose framePose(const Anchor& a, const dis::Vec3d& ecef, const dis::Matrix3& bodyToEcef);
dis::Euler disOrientation(const Anchor& a, double headingDeg, double pitchDeg, double rollDeg);

class DisFrame {
 public:
  explicit DisFrame(geodesy::DatabaseFrame frame) : frame_(std::move(frame)) {}
  /// The anchor at a geocentric point, or at a frame point.
  Result<Anchor> anchorAtEcef(const dis::Vec3d& ecef) const;
  Result<Anchor> anchorAtFrame(const Eigen::Vector3d& frame) const;
  const geodesy::DatabaseFrame& frame() const { return frame_; }

 private:
  Result<Anchor> complete(Anchor a) const;
  geodesy::DatabaseFrame frame_;
};

}  // namespace sandtable::sim_dis
