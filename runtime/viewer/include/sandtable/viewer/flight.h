#pragma once
// A headless flight: the eye moves over the database frame by frame, each
// frame is selected into a display buffer, rendered, given an information
// panel, written as a PNG, and timed; stats.json sums it up.
//
// Threads (seed Figures 44 and 47; docs/VIEWER.md): the calling thread is
// the main thread (motion, pager updates, scene selection); it fills one
// of two display buffers while the render thread (which owns the GL
// context) draws the other, handed over with a mutex and condition
// variable, no spinning. The pager's loader threads decode modules beside
// them. On the render thread each frame runs the renderer's passes on the
// GPU (renderer.h); the panel and `composite` (e.g. a 2-D map) are drawn
// on the CPU into the HUD pass's overlay, which the GPU blends over it.
// The frame is read back only for a sink that wants its pixels (`outDir`
// PNGs, `onFrame`); a `window` shows it by a GPU blit and a swap.
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
// Thread safety: fly() starts its own render thread (GL objects live only
// there) and joins it before returning; `composite` and `onFrame` run on
// the render thread, `controller` on the calling thread. Run one flight
// per calling thread.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sandtable/formats/database.h"
#include "sandtable/formats/grid.h"
#include "sandtable/base/result.h"
#include "sandtable/world/pose.h"
#include "sandtable/render/image.h"
#include "sandtable/scene/lod.h"
#include "sandtable/render/renderer.h"

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

/// What the terrain is drawn from.
enum class TerrainMode : std::uint8_t {
  automatic,  ///< modules when the database has modules.pack, else the grid mesh
  mesh,       ///< the full-resolution memory-mapped grid as strips (first flight)
  modules,    ///< paged load modules with LoD, skirts, materials and decals
};
const char* terrainModeName(TerrainMode m);

struct FrameStats;

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
  /// How far the view distance may grow at run time (module mode: the
  /// pager's ring of slots is sized for it); 0: 3 x viewDistance.
  double maxViewDistance = 0;
  double hfovDeg = 60;
  Rgb background{0x87, 0xCE, 0xEB};
  bool hud = true;
  bool fog = true;
  /// (easting, northing) -> (lon, lat); empty or nullopt leaves them out.
  std::function<std::optional<std::pair<double, double>>(double, double)> toLonLat;
  /// Called with each finished frame's pixels (after the panel), e.g. for
  /// tests, a video or a screenshot; each such frame is read back.
  std::function<void(std::uint32_t frame, const Image&)> onFrame;
  /// Which frames onFrame wants (asked on the render thread after
  /// `composite`); empty: every frame.
  std::function<bool(std::uint32_t frame)> wantsFrame;
  /// Shows every frame in this window (present.h) without a read-back;
  /// it must outlive the flight. Null: headless.
  PresentTarget* window = nullptr;

  // ---- the stealth viewer (module mode)
  TerrainMode mode = TerrainMode::automatic;
  LodOptions lod;
  /// Fog density per metre; > 0 sets the view distance to the obscuration
  /// distance (seed IX.A.3); 0 derives the density from the view distance.
  double fogDensity = 0;
  /// Sky behind the terrain; false shows `clearColour` (crack tests).
  bool sky = true;
  Rgb clearColour{0xFF, 0x00, 0xFF};
  std::uint32_t msaa = 0;  ///< samples per pixel, 0 (off) .. 16
  /// Smooth (default) or the seed's flat look (docs/VIEWER.md, "Colours").
  Shading shading = Shading::smooth;
  /// ColourMode::height writes each pixel's world height (renderer.h,
  /// kHeightCode*) with no sky, fog, multisampling, panel or composite.
  ColourMode colour = ColourMode::natural;
  /// Grid material indices drawn as water (docs/FORMAT.md 4.7).
  std::vector<std::uint8_t> waterMaterials{1};
  /// Wait for the pager to finish every queued load before each frame
  /// (reproducible frames: tests, benchmarks). Otherwise only before frame 0.
  bool pagerSync = false;
  std::uint32_t pagerLoaders = 4;  ///< seed: four loaders, one per direction
  std::uint64_t pagerBudgetBytes = 1ull << 30;

  // ---- hooks for a controller, a map and a window (all optional)
  /// Replaces poseAt: the pose of frame `frame` at simulated time `t`;
  /// nullopt ends the flight (e.g. the window closed). Main thread.
  std::function<std::optional<Pose>(std::uint32_t frame, double t)> controller;
  /// Draws into the HUD pass's overlay after the panel (a 2-D map,
  /// overlays), marking what it drew (overlay.h). Render thread.
  std::function<void(Overlay&, const FrameStats&)> composite;
};


/// Pose at simulated time `t` seconds: straight along the heading, or
/// along the path legs at each leg's speed, stopping at the last waypoint.
Pose poseAt(const FlightOptions& o, double t);

struct FrameStats {
  std::uint32_t frame = 0;
  double timeS = 0;
  double cpuMs = 0;     ///< main thread: selection (+ vertex build in mesh mode)
  double renderMs = 0;  ///< render thread: upload and draw up to the HUD (waits for the GPU)
  /// Time between this frame's completion and the previous one's on the
  /// render thread, PNG writing excluded (frame 0: cpu + render + panel).
  /// With the two threads overlapping, this is what limits the frame rate.
  double frameMs = 0;
  double fps = 0;       ///< 1000 / frameMs
  double pngMs = 0;     ///< PNG encoding and writing, not part of frameMs
  std::uint64_t triangles = 0;
  std::uint64_t strips = 0;
  double speedKmh = 0;
  double hfovDeg = 0, viewDistance = 0;  ///< what the frame was drawn with
  // module mode
  std::uint32_t modulesDrawn = 0, modulesMissing = 0, modulesCulled = 0;
  std::uint32_t nodesDrawn = 0;    ///< quadtree nodes drawn (lod.h)
  std::uint32_t nodesCoarser = 0;  ///< drawn coarser than wanted (finer level not resident yet)
  std::vector<std::uint32_t> levelCounts;  ///< quadtree nodes drawn per level
  double maxErrorPx = 0;                   ///< largest projected error bound drawn
  std::uint32_t residentModules = 0, windowModules = 0, pagerQueue = 0;
  std::uint32_t nodesPlaceholder = 0;  ///< drawn from placeholder modules
  std::uint64_t pagerPlaceholders = 0, pagerBudgetRefusals = 0, pagerTrimmedLevels = 0;
  std::uint64_t pagerPoolBytes = 0;
  std::uint32_t uploads = 0, released = 0, cachedLevels = 0;  ///< GPU (module, level) buffers
  std::uint64_t gpuBytes = 0;
  double easting = 0, northing = 0;
  std::optional<double> lon, lat;
  double eyeElevation = 0, heightAgl = 0, headingDeg = 0;
  bool freeFlight = false;  ///< the pose set an altitude (else ground following)
};

struct FlightSummary {
  std::uint32_t frames = 0;
  std::string mode;  ///< "mesh" or "modules"
  std::string lod;   ///< "rings", "sse", "full" (modules)
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

/// Flies over the grid mesh (TerrainMode::modules is refused: no pack).
/// Fails with Problem::file == kGlContextProblem (renderer.h) when no
/// headless GL context can be opened.
Result<FlightReport> fly(std::shared_ptr<const grid::GridFile> g, const FlightOptions& o);
/// Flies over a database: load modules through the pager when it has them
/// (or TerrainMode::modules asks), else the grid mesh. Module colours come
/// from its material table.
Result<FlightReport> fly(const Database& db, const FlightOptions& o);

/// The lines of the information panel for a frame.
std::vector<std::string> hudLines(const FrameStats& s, const FlightOptions& o);

/// Frame file name: "frame_00042.png".
std::string frameFileName(std::uint32_t frame);

}  // namespace sandtable::runtime
