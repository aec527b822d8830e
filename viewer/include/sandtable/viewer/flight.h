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
// GPU (renderer.h); the panel and the application's overlay (e.g. a 2-D
// map) are drawn on the CPU into the HUD pass's overlay, which the GPU
// blends over it. The frame is read back only for a sink that wants its
// pixels (OutputOptions::outDir PNGs, FlightApplication::wantsFrame); the
// application's window shows it by a GPU blit and a swap.
//
// Time: frame k shows the eye at simulated time k / kFramesPerSecond
// seconds, whatever the real frame rate, so a flight is reproducible; an
// application with its own clock (a window flies on the wall clock, in
// fixed steps: world/clock.h) says so in Pose::clockS.
// The eye keeps its height above the surface DRAWN under it (the one
// ground clamp, world/ground.h, at the level and morph selected there);
// past the grid's edge it holds the last ground elevation it saw.
//
// All positions are projected coordinates of the database's CRS (easting,
// northing, metres). The runtime cannot convert to lon/lat itself (no
// PROJ here), so the caller passes a converter for the panel and stats.
//
// Thread safety: fly() starts its own render thread (GL objects live only
// there) and joins it before returning; FlightApplication::overlay and
// frameDone run on the render thread, pose() on the calling thread. Run
// one flight per calling thread.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sandtable/formats/database.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/paging/pager.h"
#include "sandtable/paging/world.h"
#include "sandtable/base/result.h"
#include "sandtable/world/ground.h"
#include "sandtable/world/pose.h"
#include "sandtable/render/image.h"
#include "sandtable/scene/lod.h"
#include "sandtable/render/renderer.h"

namespace sandtable::viewer {

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

/// Where the eye starts and how it moves when no application steers it.
struct MotionOptions {
  double easting = 0, northing = 0;  ///< start (ignored with a path)
  double heightAgl = 300;
  double headingDeg = 0;  ///< clockwise from grid north (ignored with a path)
  double pitchDeg = -10;
  double speedKmh = 300;
  std::vector<Waypoint> path;  ///< two or more: fly this polyline instead
};

/// The frame and what it shows of the world.
struct ViewOptions {
  std::uint32_t width = 1280, height = 720;
  double hfovDeg = 60;
  double viewDistance = 10000;
  /// How far the view distance may grow at run time (module mode: the
  /// pager's ring of slots is sized for it); 0: 3 x viewDistance.
  double maxViewDistance = 0;
  /// Fog density per metre; > 0 sets the view distance to the obscuration
  /// distance (seed IX.A.3); 0 derives the density from the view distance.
  double fogDensity = 0;
  bool fog = true;
  bool hud = true;
  render::Rgb background{0x87, 0xCE, 0xEB};
  /// Sky behind the terrain; false shows `clearColour` (crack tests).
  bool sky = true;
  render::Rgb clearColour{0xFF, 0x00, 0xFF};
};

/// How the terrain is drawn: the renderer's DrawChoices (renderer.h;
/// `samples` is --msaa, and PagerSettings::sync lifts `uploadBudgetBytes`:
/// every frame is then complete), and what the flight adds to them.
struct RenderOptions : render::DrawChoices {
  TerrainMode mode = TerrainMode::automatic;
  scene::LodOptions lod;
  /// Draw the modules' static objects with the database's icons.pack.
  bool objects = true;
};

/// The pager under a module flight (paging/pager.h has the full options).
struct PagerSettings {
  /// Wait for the pager to finish every queued load before each frame
  /// (reproducible frames: tests, benchmarks). Otherwise only before frame 0.
  bool sync = false;
  std::uint32_t loaders = 4;  ///< seed: four loaders, one per direction
  std::uint64_t budgetBytes = 1ull << 30;
};

/// What a flight writes and for how long it runs.
struct OutputOptions {
  std::string outDir;  ///< frames and stats.json go here; "" writes nothing
  std::uint32_t frames = 30;
  /// (easting, northing) -> (lon, lat); empty or nullopt leaves them out.
  std::function<std::optional<std::pair<double, double>>(double, double)> toLonLat;
};

/// A flight's settings, one struct per concern. Plain values: nothing in
/// them points back at the application (that is FlightApplication).
struct FlightOptions {
  MotionOptions motion;
  ViewOptions view;
  RenderOptions render;
  PagerSettings pager;
  OutputOptions output;
};

/// The application a flight serves (the stealth viewer, a test, a
/// benchmark). The application owns its clock and its world and hands
/// fly() one snapshot (a Pose) per frame; fly() selects, draws and times
/// it (seed Figure 44: the producer/consumer with two display buffers).
/// Without one, fly() flies poseAt(options, t).
class FlightApplication {
 public:
  virtual ~FlightApplication() = default;
  /// Main thread: the pose of frame `frame` at frame time `t`
  /// (frame / kFramesPerSecond); nullopt ends the flight. `ground` is the
  /// flight's one ground clamp (world/ground.h), at the level drawn under
  /// the eye in the last frame: steer with it, do not sample the grid.
  virtual std::optional<world::Pose> pose(std::uint32_t frame, double t, world::GroundClamp& ground) = 0;
  /// Main thread, module flights: after the pager took frame `frame`'s eye
  /// and view distance, before the frame is selected. A test waits here for
  /// the loads it needs (pager.waitIdle) instead of sleeping between frames.
  virtual void paged(std::uint32_t /*frame*/, paging::Pager& /*pager*/) {}
  /// Render thread: draws into the HUD pass's overlay after the panel (a
  /// 2-D map), marking what it drew (overlay.h).
  virtual void overlay(render::Overlay&, const FrameStats&) {}
  /// Render thread: whether frameDone wants frame `frame`'s pixels; each
  /// such frame is read back from the GPU (a video, a screenshot, a test).
  virtual bool wantsFrame(std::uint32_t /*frame*/) { return false; }
  /// Render thread: the pixels of each frame wantsFrame asked for, after
  /// the panel and overlay.
  virtual void frameDone(std::uint32_t /*frame*/, const render::Image&) {}
  /// Render thread: every frame, once it is done (e.g. progress).
  virtual void frameShown(const FrameStats&) {}
  /// The window every frame is shown in by a GPU blit (present.h), asked
  /// once before the first frame; it must outlive the flight. Null: headless.
  virtual render::PresentTarget* window() { return nullptr; }
  /// Main thread, after pose() and the scene selection of frame `frame`:
  /// what the application adds to it. `buf.dynamic` (scene/dynamic.h:
  /// entities, trails, flashes, changed static objects; empty on entry) is
  /// drawn by the models pass; `stats.panelLines` are added to the
  /// information panel and `stats.extraJson` to the frame's stats.json
  /// entry. `buf` also tells what is drawn where (drawnLevelAt).
  virtual void frameContent(std::uint32_t /*frame*/, scene::DisplayBuffer& /*buf*/, FrameStats& /*stats*/) {}
  /// Main thread, after the last frame: (key, JSON text) objects added to
  /// stats.json's top level (the stealth viewer's `sim` summary).
  virtual std::vector<std::pair<std::string, std::string>> statsSections() { return {}; }
};

/// An application made of callbacks, for tests and small tools. Unset
/// callbacks do nothing; no onPose flies poseAt(options, t). Thread
/// contract as FlightApplication's: onPose on the main thread, the others
/// on the render thread.
struct FlightHooks final : FlightApplication {
  explicit FlightHooks(const FlightOptions& o) : options(o) {}
  std::function<std::optional<world::Pose>(std::uint32_t frame, double t, world::GroundClamp& ground)> onPose;
  std::function<void(render::Overlay&, const FrameStats&)> onOverlay;
  /// Every frame's pixels, or those onWantsFrame picks when it is set.
  std::function<void(std::uint32_t frame, const render::Image&)> onFrame;
  std::function<bool(std::uint32_t frame)> onWantsFrame;
  /// frameContent (main thread): e.g. entities placed by a test.
  std::function<void(std::uint32_t frame, scene::DisplayBuffer& buf, FrameStats& stats)> onFrameContent;
  std::function<void(std::uint32_t frame, paging::Pager& pager)> onPaged;

  std::optional<world::Pose> pose(std::uint32_t frame, double t, world::GroundClamp& ground) override;
  void overlay(render::Overlay& overlay, const FrameStats& s) override;
  bool wantsFrame(std::uint32_t frame) override;
  void frameDone(std::uint32_t frame, const render::Image& image) override;
  void frameContent(std::uint32_t frame, scene::DisplayBuffer& buf, FrameStats& stats) override;
  void paged(std::uint32_t frame, paging::Pager& pager) override;

  const FlightOptions& options;
};

/// Pose at simulated time `t` seconds: straight along the heading, or
/// along the path legs at each leg's speed, stopping at the last waypoint.
world::Pose poseAt(const FlightOptions& o, double t);

struct FrameStats {
  std::uint32_t frame = 0;
  double timeS = 0;
  double cpuMs = 0;     ///< main thread: selection (+ vertex build in mesh mode)
  double renderMs = 0;  ///< render thread: upload and draw up to the HUD (waits for the GPU)
  /// Render thread: its own CPU time over the same span (the GL driver's
  /// threads and the waits for the GPU are not in it).
  double renderCpuMs = 0;
  /// Render thread: of renderMs, module mode's uploads and LoD resolution
  /// (RenderStats::uploadMs).
  double uploadMs = 0;
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
  std::uint64_t uploadBytes = 0;       ///< uploaded this frame
  std::uint32_t uploadsDeferred = 0;   ///< levels left to later frames by the upload budget
  std::uint32_t nodesFallback = 0;     ///< node runs drawn coarser meanwhile
  std::uint32_t draws = 0;             ///< draw commands (node ranges x blocks)
  std::uint64_t trianglesDrawn = 0;    ///< triangles the GPU was given
  /// Static objects (RenderStats): drawn, instances, instanced draws, triangles,
  /// and of those drawn, the ones drawn as impostor sprites.
  std::uint32_t objectsDrawn = 0, objectInstances = 0, objectDraws = 0;
  std::uint64_t objectTriangles = 0;
  std::uint32_t objectSprites = 0, objectsThinned = 0;
  /// Static objects a simulation destroyed (not drawn) and changed ones drawn.
  std::uint32_t objectsRemoved = 0, objectsChanged = 0;
  /// The dynamic scene (RenderStats): entities, their triangles, trails and flashes drawn.
  std::uint32_t entitiesDrawn = 0;
  std::uint64_t entityTriangles = 0;
  std::uint32_t trailsDrawn = 0, flashesDrawn = 0;
  /// The application's (FlightApplication::frameContent): panel lines
  /// (emptied in FlightReport once the panel is drawn) and (key, JSON text)
  /// objects for the frame's stats.json entry.
  std::vector<std::string> panelLines;
  std::vector<std::pair<std::string, std::string>> extraJson;
  /// Text the application draws over the frame at pixel (x, y) (its
  /// bottom centre), e.g. the markings over networked entities.
  struct ScreenLabel {
    int x = 0, y = 0;
    std::string text;
    render::Rgb rgb{255, 255, 255};
  };
  std::vector<ScreenLabel> labels;
  /// Where the information panel was drawn (set before the application's
  /// overlay, which keeps its labels off it).
  render::PixelBox hudPanel;
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
/// `app`: the application that will steer the flight (its start point is
/// then not checked against the database).
std::vector<Problem> checkFlightOptions(std::shared_ptr<const grid::HeightField> g,
                                        const FlightOptions& o,
                                        const FlightApplication* app = nullptr);
std::vector<Problem> checkFlightOptions(std::shared_ptr<const grid::GridFile> g,
                                        const FlightOptions& o,
                                        const FlightApplication* app = nullptr);

/// Flies over the posts' mesh (TerrainMode::modules is refused: no pack).
/// Fails with Problem::file == kGlContextProblem (renderer.h) when no
/// headless GL context can be opened.
Result<FlightReport> fly(std::shared_ptr<const grid::HeightField> g, const FlightOptions& o,
                         FlightApplication* app = nullptr);
Result<FlightReport> fly(std::shared_ptr<const grid::GridFile> g, const FlightOptions& o,
                         FlightApplication* app = nullptr);
/// Flies over a world opened once (paging/world.h): load modules from its
/// ModuleSource through the pager when it has them (or TerrainMode::modules
/// asks), else the mesh of its posts; ground, map and shading read its
/// HeightField. Module colours come from its material table. Opens nothing.
Result<FlightReport> fly(const paging::World& world, const FlightOptions& o, FlightApplication* app = nullptr);
/// The same over a database already open (a World made from it).
Result<FlightReport> fly(const Database& db, const FlightOptions& o, FlightApplication* app = nullptr);

/// The lines of the information panel for a frame.
std::vector<std::string> hudLines(const FrameStats& s, const FlightOptions& o);

/// Frame file name: "frame_00042.png".
std::string frameFileName(std::uint32_t frame);

}  // namespace sandtable::viewer
