// Frames and names of entities.
#include "sandtable/sim/entity.h"

#include <cmath>

namespace sandtable::sim {

Eigen::Vector3d headingVector(double headingDeg) {
  const double h = headingDeg * kDegToRad;
  return {std::sin(h), 0.0, -std::cos(h)};
}

double wrapDeg(double deg) {
  double w = std::fmod(deg, 360.0);
  if (w < 0) w += 360.0;
  return w >= 360.0 ? 0.0 : w;
}

double headingOf(double dx, double dz) { return wrapDeg(std::atan2(dx, -dz) * kRadToDeg); }

double turnBetween(double fromDeg, double toDeg) {
  double d = wrapDeg(toDeg - fromDeg);
  return d > 180.0 ? d - 360.0 : d;
}

Eigen::Quaterniond orientationOf(double headingDeg, double pitchDeg, double rollDeg) {
  // Yaw about +Y by -h turns forward (-Z) to (sin h, 0, -cos h); pitch about
  // the body's +X raises the nose; roll about the body's -Z lowers the right.
  const Eigen::AngleAxisd yaw(-headingDeg * kDegToRad, Eigen::Vector3d::UnitY());
  const Eigen::AngleAxisd pitch(pitchDeg * kDegToRad, Eigen::Vector3d::UnitX());
  const Eigen::AngleAxisd roll(-rollDeg * kDegToRad, Eigen::Vector3d::UnitZ());
  return Eigen::Quaterniond(yaw * pitch * roll).normalized();
}

const char* domainName(Domain d) {
  switch (d) {
    case Domain::land: return "land";
    case Domain::sea: return "sea";
    case Domain::air: return "air";
    case Domain::munition: return "munition";
  }
  return "?";
}

const char* mobilityName(Mobility m) {
  switch (m) {
    case Mobility::simple: return "simple";
    case Mobility::tracked: return "tracked";
    case Mobility::wheeled: return "wheeled";
    case Mobility::ship: return "ship";
    case Mobility::aircraft: return "aircraft";
    case Mobility::ballistic: return "ballistic";
    case Mobility::guided: return "guided";
  }
  return "?";
}

Eigen::Quaterniond Entity::orientation() const { return orientationOf(headingDeg, pitchDeg, rollDeg); }

}  // namespace sandtable::sim
