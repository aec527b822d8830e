#pragma once
// A headless flight: the eye moves over the database frame by frame, each
// frame is selected into a display buffer, rendered, given an information
// panel, written as a PNG, and timed; stats.json sums it up.
//
// Time: frame k shows the eye at simulated time k / kFramesPerSecond
// seconds, whatever the real frame rate, so a flight is reproducible.
// The eye keeps its height above the ground under it (ground following);
// past the grid's edge it holds the last ground elevation it saw.
//
// All positions are projected coordinates of the database's CRS (easting,
// northing, metres). The runtime cannot convert to lon/lat itself (no
// PROJ here), so the caller passes a converter for the panel and stats.
//
// Thread safety: fly() creates and uses its GL context on the calling
// thread; run one flight per thread.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/result.h"
#include "sandtable/runtime/image.h"

namespace sandtable::runtime {

inline constexpr double kFramesPerSecond = 30.0;

/// Problem::file of a problem with the options (bad input, including an
/// output directory that cannot be made), as opposed to a failure while
/// flying (Problem::file "fly") or no GL (kGlContextProblem, renderer.h).
inline constexpr const char* kFlightOptionProblem = "fly options";

/// A point of a --path flight.
struct Waypoint {
  double easting = 0, northing = 0;
  double heightAgl = 300;  ///< metres above the ground
  double speedKmh = 300;   ///< speed on the leg that starts here
};

struct FlightOptions {
  std::string outDir;  ///< frames and stats.json go here; "" writes nothing
  std::uint32_t frames = 30;
  std::uint32_t width = 1280, height = 720;
  double easting = 0, northing = 0;  ///< start (ignored with a path)
  double heightAgl = 300;
  double headingDeg = 0;  ///< clockwise from grid north (ignored with a path)
  double pitchDeg = -10;
  double speedKmh = 300;
  std::vector<Waypoint> path;  ///< two or more: fly this polyline instead
  double viewDistance = 10000;
  double hfovDeg = 60;
  Rgb background{0x87, 0xCE, 0xEB};
  bool hud = true;
  bool fog = true;
  /// (easting, northing) -> (lon, lat); empty or nullopt leaves them out.
  std::function<std::optional<std::pair<double, double>>(double, double)> toLonLat;
  /// Called with each finished frame (after the panel), e.g. for tests.
  std::function<void(std::uint32_t frame, const Image&)> onFrame;
};

/// Where the eye is at one instant.
struct Pose {
  double easting = 0, northing = 0;
  double headingDeg = 0;
  double heightAgl = 0;
  double speedKmh = 0;
};

/// Pose at simulated time `t` seconds: straight along the heading, or
/// along the path legs at each leg's speed, stopping at the last waypoint.
Pose poseAt(const FlightOptions& o, double t);

struct FrameStats {
  std::uint32_t frame = 0;
  double timeS = 0;
  double cpuMs = 0;     ///< selection + vertex build
  double renderMs = 0;  ///< upload, draw and read-back (waits for the GPU)
  double frameMs = 0;   ///< cpu + render + panel: what limits the frame rate
  double pngMs = 0;     ///< PNG encoding and writing, not part of frameMs
  std::uint64_t triangles = 0;
  std::uint64_t strips = 0;
  double easting = 0, northing = 0;
  std::optional<double> lon, lat;
  double eyeElevation = 0, heightAgl = 0, headingDeg = 0;
};

struct FlightSummary {
  std::uint32_t frames = 0;
  double trianglesMean = 0;
  double frameMsP50 = 0, frameMsP99 = 0;
  double fpsMean = 0;  ///< frames / sum of frameMs
  std::string renderer;  ///< GL_RENDERER
  std::string rendererDetail;
  std::uint32_t width = 0, height = 0;
  std::string statsPath;  ///< "" when nothing was written
};

struct FlightReport {
  std::vector<FrameStats> frames;
  FlightSummary summary;
};

/// Checks the options against the grid; problems say which option is wrong.
std::vector<Problem> checkFlightOptions(std::shared_ptr<const grid::GridFile> g,
                                        const FlightOptions& o);

/// Flies. Fails with Problem::file == kGlContextProblem (renderer.h) when
/// no headless GL context can be opened.
Result<FlightReport> fly(std::shared_ptr<const grid::GridFile> g, const FlightOptions& o);

/// Frame file name: "frame_00042.png".
std::string frameFileName(std::uint32_t frame);

}  // namespace sandtable::runtime
