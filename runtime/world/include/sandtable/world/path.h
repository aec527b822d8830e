#pragma once
// Waypoint path files for scripted flights (format in docs/PATH.md) and the
// timing of their legs as in the seed's Table 7 ("Script parameters
// generated from selected path"): the user gives some waypoint times and
// some leg speeds, the rest is computed.
//
// A file holds one waypoint per line:
//   lon lat height_m [speed_kmh] [speed=KMH] [time=S | time=H:MM:SS.s]
// or, after a `frame projected` line, easting northing in the database CRS.
// `speed` is the speed of the leg that starts at the waypoint; `time` is
// when the eye is at the waypoint. The old `lon lat height_m [speed_kmh]`
// files of `sandtable fly --path` read unchanged.
//
// The runtime has no PROJ: lon/lat reach projected coordinates through the
// caller's ToProjectedFn (the CLI passes one built on geodesy).
//
// Thread safety: pure functions on caller-owned values.
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/world/pose.h"

namespace sandtable::world {

/// Problem::file of path problems that are not tied to a file (resolvePath
/// on points built in code).
inline constexpr const char* kPathProblem = "path";

enum class PathFrame { lonLat, projected };

/// (lon, lat) in degrees -> (easting, northing): "" on success, or why not
/// (e.g. "outside the database, which covers ..."); the reason is quoted
/// in the error with the file and line.
using ToProjectedFn =
    std::function<std::string(double lon, double lat, double& easting, double& northing)>;

/// One waypoint as written: the times and speeds the user gave.
struct PathPoint {
  double easting = 0, northing = 0;
  double heightAgl = 300;
  std::optional<double> speedKmh;  ///< speed of the leg that starts here
  std::optional<double> timeS;     ///< when the eye is here
  int line = 0;                    ///< source line, 0 when built in code
};

/// One waypoint with every time and leg speed filled in.
struct PathWaypoint {
  double easting = 0, northing = 0;
  double heightAgl = 300;
  double timeS = 0;       ///< arrival time
  double legSpeedMs = 0;  ///< mean ground speed of the leg that starts here; 0 on the last
  bool timeGiven = false, speedGiven = false;  ///< Table 7's underlined values
  int line = 0;
};

struct Path {
  PathFrame frame = PathFrame::lonLat;
  std::vector<PathWaypoint> waypoints;  ///< two or more, times non-decreasing
  /// The heading turns from one leg's to the next at this rate, the turn
  /// centred on the waypoint (the eye still passes through it). A turn
  /// that would take longer than half of either leg is made faster to fit.
  double turnRateDegS = 45;
  double durationS() const { return waypoints.empty() ? 0 : waypoints.back().timeS - waypoints.front().timeS; }
};

struct PathOptions {
  /// Leg speed where neither a speed nor a later time is given
  /// (`sandtable fly --speed`); without one such a leg is an error.
  std::optional<double> defaultSpeedKmh;
  /// Needed for lon/lat files; a lon/lat file without it is an error.
  ToProjectedFn toProjected;
  /// A leg given both a speed and an end time must agree within this
  /// fraction of its duration (or 0.05 s); the given time then wins.
  double overdeterminedTolerance = 0.01;
};

/// Reads and resolves a path file. Problems carry the file in
/// Problem::file and "line N: ..." with how to fix it in the message.
Result<Path> readPathFile(const std::string& file, const PathOptions& options);
/// The same on text already in memory; `name` stands for the file.
Result<Path> parsePath(std::string_view text, const std::string& name, const PathOptions& options);

/// A path problem as "FILE:LINE: what, how to fix" (compiler style), or
/// "FILE: what" for a problem of several lines (e.g. a run of legs).
std::string pathProblemText(const Problem& p);

/// Fills in missing times and leg speeds (seed Table 7):
///  - the first waypoint's time defaults to 0;
///  - a leg with a speed and no end time ends at start + length / speed;
///  - a leg with an end time and no speed gets length / (end - start);
///  - a run of legs without speeds between two given times shares one
///    speed, so the time left over by the run's legs that do have speeds
///    is split in proportion to length;
///  - a leg with neither, after the last given time, takes
///    defaultSpeedKmh, or else the speed of the last leg that moved
///    (the speed holds, seed VI.B.2).
/// Given times must not decrease; a run whose given time is too short
/// for its given speeds is an error. `file` names the source in problems.
Result<Path> resolvePath(const std::vector<PathPoint>& points, const PathOptions& options,
                         const std::string& file = kPathProblem, PathFrame frame = PathFrame::projected);

/// Where the eye is at time t: along the legs at each leg's speed, height
/// interpolated, the heading turning at Path::turnRateDegS round each
/// waypoint; at or before the first time at the first waypoint with the
/// first leg's speed, after the last at the last (speed 0, heading of the
/// last moving leg).
Pose samplePath(const Path& path, double t);

}  // namespace sandtable::world
