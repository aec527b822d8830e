#pragma once
// Where an eye (or, later, an entity) is at one instant: the value the
// application's clock advances and every consumer (viewer, pager
// prediction, stats) reads.
//
// Frame: projected easting / northing of the database CRS, metres;
// heading clockwise from grid north, degrees.
//
// Thread safety: a plain value type.
#include <optional>

namespace sandtable::world {

/// Where the eye is at one instant.
struct Pose {
  double easting = 0, northing = 0;
  double headingDeg = 0;
  double heightAgl = 0;
  double speedKmh = 0;
  // A controller may also steer these; unset, FlightOptions' values hold.
  std::optional<double> altitude;      ///< eye above the datum (free flight); else ground + heightAgl
  std::optional<double> pitchDeg;
  std::optional<double> hfovDeg;       ///< 10..90
  /// Fog and far plane follow it. In module mode the pager's window follows
  /// it too, up to FlightOptions::maxViewDistance; while a larger window
  /// fills, the drawn distance grows only as far as modules are resident.
  std::optional<double> viewDistance;
  /// The time this pose is for, seconds, when the controller keeps its own
  /// clock (a window flies on the wall clock); stats, panel and the pager's
  /// prediction use it. Unset: the frame clock frame / kFramesPerSecond.
  std::optional<double> clockS;
};
}  // namespace sandtable::world
