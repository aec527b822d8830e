// `sandtable fly`: a flight over a database, headless to PNG frames and
// stats.json, or in a window driven by the keyboard when there is an X
// display (docs/VIEWER.md). Converts lon/lat to the database's projected
// frame here, because the runtime links no PROJ. The hooks it plugs into
// the flight loop (keys, path, map, window, screenshots, video) live in
// fly_session.cpp.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "commands.h"
#include "flags.h"
#include "progress.h"
#include "sandtable/viewer/fly_session.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/formats/database.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/world/path.h"
#include "sandtable/render/renderer.h"
#include "sandtable/world/terrain.h"
#include "sandtable/viewer/sim_session.h"
#include "sandtable/viewer/video.h"
#include "sandtable/viewer/x11_window.h"
#include "dis_link.h"
#include "journal_util.h"
#include "terrain_link.h"
#include "sim_setup.h"

namespace sandtable::cli {
namespace {

using viewer::FlightOptions;
using viewer::FlySession;
using viewer::FlySessionSettings;
using viewer::waterMaterials;

constexpr const char* kName = "fly";

struct FlyArgs {
  std::string database;
  std::string journal;  ///< --journal (journal_util.h)
  std::string pngDir;
  std::uint32_t frames = 30;
  std::string size = "1280x720";
  std::vector<double> at;  ///< lon, lat
  double height = 300;
  double heading = 0;
  double pitch = -10;
  double speed = 300;
  std::string pathFile;
  double viewDistance = 20000;
  double maxViewDistance = 0;
  double fov = 60;
  std::string background = "87CEEB";
  bool noHud = false;
  bool noFog = false;
  std::string mode = "auto";
  std::string lod = "rings";
  std::string rings;
  double pixelError = 2.0;
  bool noMorph = false;
  bool nodeMorph = false;
  double fogDensity = 0;
  bool pagerSync = false;
  double memoryBudgetMb = 1024;
  bool noSky = false;
  std::uint32_t msaa = 0;
  bool noObjects = false;
  bool noObjectLod = false;
  double impostorPixels = render::kDefaultImpostorPixels;
  double objectThinPixels = render::kDefaultObjectThinPixels;
  double objectFade = render::kDefaultObjectFade;
  std::string shading = "smooth";
  std::string colour = "natural";
  // the stealth viewer: window, map, free flight, outputs
  bool window = false, headless = false;
  bool map = false;
  std::string mapScale = "full";
  bool freeFlight = false;
  std::optional<double> altitude;
  std::string videoFile;
  std::string screenshotDir;
  // a scenario's entities (docs/VIEWER.md, "Entities (fly --scenario)")
  std::string scenario;
  std::optional<std::uint64_t> seed;
  std::string attach;
  bool drive = false;
  double simStart = 0;
  DisArgs dis;  ///< --dis: the stealth viewer on a DIS exercise (watches, publishes nothing)
  CLI::Option* framesOption = nullptr;  ///< to tell an explicit --frames from the default
  CLI::Option* headingOption = nullptr;
  CLI::Option* atOption = nullptr;
};

const char* kFooter = R"(Window or headless: with DISPLAY set the flight opens a window and is flown
from the keyboard until q, Escape or closing the window (or --frames N frames
if given); without a display it runs headless and writes --png frames.
--window insists on a window (exit 2 without a display), --headless on none.
Keys (docs/PATH.md): Up/Down speed +/-5 m/s (the speed holds), Left/Right
turn, PageUp/PageDown height, 1..9 FOV x10 deg, +/- view distance, m map,
[ ] map scale, f ground-following/free flight, p or F12 screenshot
(--screenshot-dir, default the --png directory or .), q/Escape quit.

Time: headless, frame k shows the eye at k/30 s of simulated time, whatever the
real frame rate, so --speed 300 moves the eye 2.78 m per frame. In a window the
flight follows the wall clock (slowing down below 10 fps rather than jumping).
The eye keeps --height metres above the ground under it (ground following);
--free-flight keeps --altitude metres above the datum instead (default: the
ground at the start plus --height), never less than 1 m above the ground.

--path FILE flies scripted waypoints (format: docs/PATH.md). One per line:
    lon lat height_m [speed_kmh] [speed=KMH] [time=S or H:MM:SS]
or easting northing after a "frame projected" line. Missing times and speeds
are computed as in the seed's Table 7; a leg with neither takes --speed.
Without --frames the flight lasts until the last waypoint. Example:
    # up the valley, then climb over the ridge
    8.10 46.60 200 time=0
    8.20 46.65 200 150
    8.30 46.70 800 time=0:03:00

--scenario FILE (docs/SCRIPTS.md) runs the simulator's entities (docs/SIM.md)
on the flight's clock (headless: 1/30 s a frame, 60 Hz steps) and draws them:
icons turned by their full orientation, turrets, wrecks, munition trails,
detonation flashes, knocked-over trees and ruins; the map shows them in their
force's colour and the panel the entity count and the driven one's state.
--sim-start S runs the simulation S seconds before the first frame. The
stealth eye starts 1200 m behind the driven (else first) entity unless --at
or --path is given. --attach NAME tethers the eye behind and above an
entity; --drive drives the scenario's driven entity (or --attach NAME's).
Entity keys: Tab / Shift+Tab attach to the next / previous entity, e back to
the stealth eye, d drive the attached one (again: stop), Space all stop.
Attached, the arrows bring the eye nearer / farther and orbit it, PageUp /
PageDown raise / lower it; driving, Up/Down step the commanded speed
(2.5 m/s), Left/Right turn the commanded heading, PageUp/PageDown an
aircraft's altitude. stats.json gains `sim` (the summary, as `sandtable sim`).

--dis [ADDR:]PORT makes the viewer a stealth watcher of a DIS exercise
(docs/DIS.md §11, §13): it publishes nothing; networked entities are drawn with
their icons (the icon file's dis patterns), turrets, markings over them,
munition trails and detonation flashes; the map shows them by force and the
panel PDUs per second, entities tracked, dead-reckoning corrections and
dropped PDUs. --attach MARKING (or SITE:APP:ENTITY) tethers the eye to a
networked entity when it appears. Headless, frames keep to the wall clock.
With --scenario too, the scenario's entities run beside the networked ones.

--map shows the 2-D map (seed Figures 40, 41) in the top-right corner, at
--map-scale full, half, quarter, eighth or sixteenth of the database.
--video FILE.mp4 encodes the frames with ffmpeg (when it is installed).

Terrain (docs/VIEWER.md): with load modules (modules.pack, from `sandtable build
--culture`) the stealth viewer draws them through the predictive pager, one level
of detail per module, with skirts over the seams, material colours and road and
area decals over the skin; --mode mesh draws the full-resolution grid instead.
--lod rings chooses levels by range rings (seed Figure 84; default: Table 8's four
equal bins scaled to --view-distance, or --rings M,M,... as the outer edges of
each level's bin, finest first); --lod sse by projected error (--pixel-error PX);
--lod full always draws the finest level. Levels geomorph unless --no-morph.
Colours (docs/VIEWER.md): culture class colours, water where the grid says
water, else an elevation tint, in both modes; --shading flat shows the seed's
per-triangle look. --colour height writes heights instead: metres =
(R*65536 + G*256 + B) / 256 - 1000, black where there is no terrain.
--fog-density D (per metre) sets the view distance to the fog's obscuration
distance sqrt(ln 255)/D (seed IX.A.3); otherwise the density follows it.
The pager keeps the window of the starting view distance, so in a window the
+ key cannot see further than --view-distance over load modules.

Writes OUT_DIR/frame_00000.png ... and OUT_DIR/stats.json (per-frame timing,
position, speed, heading, FOV, view distance and triangle counts; summary with
fps and the GL renderer). Needs OpenGL 4.5 core through EGL (Mesa llvmpipe
works without a GPU).
Exit status: 0 done, 1 failed while flying, 2 bad input, no GL context or no
window/ffmpeg where one was asked for.)";

bool parseSize(const std::string& s, std::uint32_t& w, std::uint32_t& h) {
  unsigned a = 0, b = 0;
  char x = 0, extra = 0;
  if (std::sscanf(s.c_str(), "%u%c%u%c", &a, &x, &b, &extra) != 3 || (x != 'x' && x != 'X')) return false;
  w = a;
  h = b;
  return true;
}

bool parseColor(std::string s, render::Rgb& c) {
  if (!s.empty() && s[0] == '#') s.erase(0, 1);
  if (s.size() != 6 || !std::all_of(s.begin(), s.end(), [](char ch) { return std::isxdigit(static_cast<unsigned char>(ch)); })) {
    return false;
  }
  const auto v = std::stoul(s, nullptr, 16);
  c = {static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)};
  return true;
}

std::optional<int> parseMapScale(const std::string& s) {
  static constexpr const char* names[] = {"full", "half", "quarter", "eighth", "sixteenth"};
  for (int k = 0; k < 5; ++k) {
    if (s == names[k]) return k;
  }
  return std::nullopt;
}

std::string boundsText(const manifest::Manifest& m) {
  double lonMin = 1e9, lonMax = -1e9, latMin = 1e9, latMax = -1e9;
  for (const auto& c : m.cornersLonLat) {
    lonMin = std::min(lonMin, c[0]);
    lonMax = std::max(lonMax, c[0]);
    latMin = std::min(latMin, c[1]);
    latMax = std::max(latMax, c[1]);
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "lon %.5f .. %.5f, lat %.5f .. %.5f", lonMin, lonMax, latMin, latMax);
  return buf;
}

std::string projectedBoundsText(const manifest::Manifest& m) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "easting %.1f .. %.1f, northing %.1f .. %.1f", m.originEasting,
                m.eastEasting(), m.southNorthing(), m.originNorthing);
  return buf;
}

/// Converts lon/lat and checks it lies on the grid; "" or the reason not.
std::string project(const geodesy::Projection& geo, const world::Terrain& terrain,
                    const manifest::Manifest& m, double lon, double lat, double& e, double& n) {
  char where[64];
  std::snprintf(where, sizeof where, "%.6f %.6f", lon, lat);
  const auto en = geo.toProjected({lon, lat});
  if (!en) return std::string(where) + " cannot be projected into " + m.crsName;
  e = en->easting, n = en->northing;
  if (!terrain.sampleEN(e, n)) {
    return std::string(where) + " is outside the database, which covers " + boundsText(m) +
           " (the grid is a rectangle in " + m.crsName + ", so its lon/lat corners are not square)";
  }
  return {};
}

/// Reads a --path file through path.h (lon/lat via geodesy, checked
/// against the grid); every error names the file and line.
Result<world::Path> readPath(const FlyArgs& a, const geodesy::Projection& geo,
                               const world::Terrain& terrain, const manifest::Manifest& m) {
  world::PathOptions po;
  po.defaultSpeedKmh = a.speed;
  po.toProjected = [&](double lon, double lat, double& e, double& n) {
    return project(geo, terrain, m, lon, lat, e, n);
  };
  auto path = world::readPathFile(a.pathFile, po);
  if (!path) return path;
  // Projected waypoints bypass toProjected, so check them here.
  for (const auto& w : path->waypoints) {
    if (terrain.sampleEN(w.easting, w.northing)) continue;
    char where[96];
    std::snprintf(where, sizeof where, "%.1f %.1f", w.easting, w.northing);
    return Problem{a.pathFile, 0,
                   "line " + std::to_string(w.line) + ": " + where + " is outside the database, which covers " +
                       projectedBoundsText(m) + " in " + m.crsName};
  }
  return path;
}

/// Fills the runtime options from the command line; "" or a usage error.
std::string buildOptions(const FlyArgs& a, const Database& db, const geodesy::Projection& geo,
                         FlightOptions& o) {
  const world::Terrain terrain(db.grid);
  const auto& m = db.manifest;
  o.output.outDir = a.pngDir;
  o.output.frames = a.frames;
  if (!parseSize(a.size, o.view.width, o.view.height)) return "--size must look like 1280x720, not \"" + a.size + "\"";
  if (!parseColor(a.background, o.view.background)) return "--background must be 6 hex digits RRGGBB, e.g. 87CEEB";
  o.motion.heightAgl = a.height;
  o.motion.headingDeg = a.heading;
  o.motion.pitchDeg = a.pitch;
  o.motion.speedKmh = a.speed;
  o.view.viewDistance = a.viewDistance;
  o.view.maxViewDistance = a.maxViewDistance;
  o.view.hfovDeg = a.fov;
  o.view.hud = !a.noHud;
  o.view.fog = !a.noFog;
  if (a.mode == "auto") o.render.mode = viewer::TerrainMode::automatic;
  else if (a.mode == "mesh") o.render.mode = viewer::TerrainMode::mesh;
  else if (a.mode == "modules") o.render.mode = viewer::TerrainMode::modules;
  else return "--mode must be auto, mesh or modules, not \"" + a.mode + "\"";
  if (a.lod == "rings") o.render.lod.mode = scene::LodMode::rings;
  else if (a.lod == "sse") o.render.lod.mode = scene::LodMode::sse;
  else if (a.lod == "full") o.render.lod.mode = scene::LodMode::full;
  else return "--lod must be rings, sse or full, not \"" + a.lod + "\"";
  if (!a.rings.empty()) {
    std::stringstream in(a.rings);
    std::string item;
    while (std::getline(in, item, ',')) {
      try {
        std::size_t used = 0;
        o.render.lod.rings.push_back(std::stod(item, &used));
        if (used != item.size()) throw std::invalid_argument(item);
      } catch (const std::exception&) {
        return "--rings must be metres separated by commas, e.g. 1500,3000,4500";
      }
    }
  }
  o.render.lod.pixelError = a.pixelError;
  o.render.lod.morph = !a.noMorph;
  o.render.lod.shareMorph = !a.nodeMorph;
  o.view.fogDensity = a.fogDensity;
  o.pager.sync = a.pagerSync;
  o.pager.budgetBytes = std::uint64_t(a.memoryBudgetMb * 1024 * 1024);
  o.view.sky = !a.noSky;
  o.render.samples = a.msaa;
  o.render.objects = !a.noObjects;
  o.render.objectFade = a.objectFade;
  o.render.objectLod = !a.noObjectLod;
  o.render.impostorPixels = a.impostorPixels;
  o.render.objectThinPixels = a.objectThinPixels;
  if (a.shading == "smooth") o.render.shading = render::Shading::smooth;
  else if (a.shading == "flat") o.render.shading = render::Shading::flat;
  else return "--shading must be smooth or flat, not \"" + a.shading + "\"";
  if (a.colour == "natural") o.render.colour = render::ColourMode::natural;
  else if (a.colour == "height") o.render.colour = render::ColourMode::height;
  else return "--colour must be natural or height, not \"" + a.colour + "\"";
  o.render.waterMaterials = waterMaterials(db);
  const auto& h = db.grid->header();
  o.motion.easting = h.originEasting + h.spacing * (h.postsX - 1) / 2.0;
  o.motion.northing = h.originNorthing - h.spacing * (h.postsZ - 1) / 2.0;
  if (a.at.size() == 2) {
    if (std::string err = project(geo, terrain, m, a.at[0], a.at[1], o.motion.easting, o.motion.northing); !err.empty()) {
      return "--at " + err;
    }
  }
  // Called from the viewer's frame loop: geodesy is safe from any thread.
  o.output.toLonLat = [geo](double e, double n) -> std::optional<std::pair<double, double>> {
    const auto ll = geo.toLonLat({e, n});
    if (!ll) return std::nullopt;
    return std::pair{ll->lon, ll->lat};
  };
  return {};
}

/// Frames of a headless path flight without --frames: until the eye is at
/// the last waypoint (frame k is at k / 30 s).
std::uint32_t framesForPath(const world::Path& p) {
  const double end = p.waypoints.back().timeS;
  const double frames = std::ceil(end * viewer::kFramesPerSecond - 1e-9) + 1;
  return std::uint32_t(std::clamp(frames, 1.0, 1e6));
}

/// The session's settings from the arguments and the built options.
std::string sessionSettings(const FlyArgs& a, const Database& db, const FlightOptions& o,
                            FlySessionSettings& s) {
  s.freeFlight = a.freeFlight;
  if (auto g = world::Terrain(db.grid).sampleEN(o.motion.easting, o.motion.northing)) {
    s.altitude = a.altitude.value_or(g->elevation + a.height);
  } else {
    s.altitude = a.altitude.value_or(a.height);
  }
  s.map = a.map;
  const auto scale = parseMapScale(a.mapScale);
  if (!scale) return "--map-scale must be full, half, quarter, eighth or sixteenth, not \"" + a.mapScale + "\"";
  s.mapScale = *scale;
  s.waterMaterials = waterMaterials(db);
  s.screenshotDir = !a.screenshotDir.empty() ? a.screenshotDir : !a.pngDir.empty() ? a.pngDir : ".";
  const bool modules = db.modules && o.render.mode != viewer::TerrainMode::mesh;
  // Over load modules the pager's ring is sized for the most the keys may
  // ask for; the grid mesh has no such limit.
  s.maxViewDistance = modules ? std::max(o.view.viewDistance, o.view.maxViewDistance > 0 ? o.view.maxViewDistance
                                                                             : 3 * o.view.viewDistance)
                              : std::max(s.maxViewDistance, o.view.viewDistance);
  s.liveViewDistance = !(o.view.fogDensity > 0);
  return {};
}

/// Decides window or headless; opens the window. "" or a usage error; a
/// null window with "" means headless.
std::string openWindow(const FlyArgs& a, const Database& db, const FlightOptions& o,
                       std::unique_ptr<viewer::ViewerWindow>& window) {
  if (a.headless) return {};
  if (a.window && !viewer::ViewerWindow::displayConfigured()) {
    return "--window needs an X display, and DISPLAY is not set; run it in a desktop session or "
           "under Xvfb (xvfb-run sandtable fly ...), or fly headless with --png DIR";
  }
  if (!viewer::ViewerWindow::displayConfigured()) return {};
  const std::string title = "sandtable fly " + std::filesystem::path(db.directory).filename().string();
  auto w = viewer::ViewerWindow::open(o.view.width, o.view.height, title);
  if (w) {
    window = std::move(w.value());
    return {};
  }
  // DISPLAY is set but no window opens: --window fails; otherwise fall
  // back to the headless flight if it has somewhere to write.
  const std::string why = w.problems().front().message;  // "window: ..."
  if (a.window || (a.pngDir.empty() && a.videoFile.empty())) {
    return why + (a.window ? "" : "; or fly headless with --headless --png DIR");
  }
  std::fprintf(stderr, "sandtable fly: warning: no %s; flying headless\n", why.c_str());
  return {};
}

std::string openVideo(const FlyArgs& a, const FlightOptions& o, std::unique_ptr<viewer::VideoWriter>& video) {
  if (a.videoFile.empty()) return {};
  if (!viewer::VideoWriter::available()) return "--video: " + viewer::VideoWriter::notInstalledMessage();
  viewer::VideoOptions vo;
  vo.fps = viewer::kFramesPerSecond;
  auto v = viewer::VideoWriter::open(a.videoFile, o.view.width, o.view.height, vo);
  if (!v) return "--video " + a.videoFile + ": " + v.problems().front().message;
  video = std::move(v.value());
  return {};
}

void printSummary(const FlightOptions& o, const viewer::FlightReport& r, const FlySession& session,
                  const FlyArgs& a) {
  const auto& s = r.summary;
  std::printf("sandtable fly: %u frame%s at %ux%u%s", s.frames, s.frames == 1 ? "" : "s", s.width, s.height,
              session.windowed() ? " in a window" : "");
  if (!o.output.outDir.empty() && s.frames > 0) {
    std::printf(" in %s/ (%s .. %s)", o.output.outDir.c_str(), viewer::frameFileName(0).c_str(),
                viewer::frameFileName(s.frames - 1).c_str());
  }
  std::printf("\n");
  if (!s.statsPath.empty()) std::printf("  stats:    %s\n", s.statsPath.c_str());
  if (!a.videoFile.empty()) std::printf("  video:    %s\n", a.videoFile.c_str());
  if (session.screenshotsTaken() > 0) std::printf("  screenshots: %u\n", session.screenshotsTaken());
  // In a window the renderer's context is on the window's EGL surface: the
  // frame is drawn offscreen and blitted into the window on the GPU.
  std::printf("  renderer: %s%s\n", s.rendererDetail.c_str(),
              session.windowed() ? " (offscreen target, blitted into the window on the GPU)" : "");
  std::printf("  terrain:  %s%s%s\n", s.mode.c_str(), s.lod.empty() ? "" : ", lod ", s.lod.c_str());
  std::printf("  speed:    %.1f fps mean, frame %.1f ms p50 / %.1f ms p99 (selection + draw + HUD,"
              " read-back for --png / --video, present; PNG writing excluded), %.0f triangles per frame\n",
              s.fpsMean, s.frameMsP50, s.frameMsP99, s.trianglesMean);
  if (const viewer::SimSession* sim = session.sim()) std::printf("  sim:      %s\n", sim->summaryLine().c_str());
}

/// Checks the combinations CLI11 cannot; "" or a usage error.
std::string checkArgs(const FlyArgs& a) {
  if (a.window && a.headless) return "--window and --headless exclude each other";
  if (a.altitude && !a.freeFlight) return "--altitude needs --free-flight (ground following keeps --height)";
  if (a.freeFlight && !a.pathFile.empty()) {
    return "--free-flight with --path: a path's heights are above the ground; leave out --free-flight";
  }
  if (a.scenario.empty()) {
    if (!a.attach.empty() && a.dis.endpoint.empty()) {
      return "--attach needs --scenario FILE or --dis PORT (the entities come from a scenario or the network)";
    }
    if (a.drive) return "--drive needs --scenario FILE (the entities come from a scenario)";
    if (a.seed) return "--seed needs --scenario FILE (it seeds the scenario's simulation)";
    if (a.simStart != 0) return "--sim-start needs --scenario FILE";
  }
  if ((!a.attach.empty() || a.drive) && !a.pathFile.empty()) {
    return "--path with --attach or --drive: the eye follows the entity; leave out --path";
  }
  return {};
}

/// The session's side of --dis: remote entities attached to by marking or
/// DIS id, labelled with their markings, and the network's panel line.
void watchNetwork(DisLink& link, viewer::SimSessionOptions& so) {
  so.attachWhenSeen = true;
  so.labels = true;
  sim_dis::Gateway* g = link.gateway.get();
  so.findEntity = [g](const std::string& text) -> std::optional<std::uint32_t> {
    unsigned site = 0, app = 0, entity = 0;
    char tail = 0;
    if (std::sscanf(text.c_str(), "%u:%u:%u%c", &site, &app, &entity, &tail) != 3) return std::nullopt;
    if (site > 65535 || app > 65535 || entity > 65535) return std::nullopt;
    const std::uint32_t id = g->simIdOf({std::uint16_t(site), std::uint16_t(app), std::uint16_t(entity)});
    if (id == UINT32_MAX) return std::nullopt;
    return id;
  };
  so.extraPanel = [&link, last = std::make_shared<std::pair<double, std::uint64_t>>(-1.0, 0)]() {
    return std::vector<std::string>{disPanelLine(link, *last)};
  };
}

/// The scenario's simulation for the session, and the stealth eye's start
/// near its entities; "" or a usage error (kUsage with the problem printed
/// when the text is "-").
/// The terrain edits on the map (the newest kMaxEditMarks): a ring at each
/// crater, a berm's or a ditch's line, a flattened polygon's outline.
std::vector<render::MapMark> editMarks(const edits::Editor& editor) {
  constexpr std::size_t kMaxEditMarks = 4096;
  std::vector<render::MapMark> marks;
  const auto& all = editor.edits();
  for (std::size_t k = all.size() > kMaxEditMarks ? all.size() - kMaxEditMarks : 0; k < all.size(); ++k) {
    const edit::Edit& e = all[k];
    if (!edit::changesHeights(e.kind) || e.points.empty()) continue;
    render::MapMark m;
    m.edit = true;
    m.x = e.points[0][0], m.z = e.points[0][1];
    if (e.points.size() == 1) {
      marks.push_back(m);
      continue;
    }
    const bool closed = e.kind == edit::Kind::flatten;
    const std::size_t segments = closed ? e.points.size() : e.points.size() - 1;
    for (std::size_t s = 0; s < segments; ++s) {
      const auto& a = e.points[s];
      const auto& b = e.points[(s + 1) % e.points.size()];
      m.x = a[0], m.z = a[1];
      m.to = std::array<double, 2>{b[0], b[1]};
      marks.push_back(m);
    }
  }
  return marks;
}

std::string setUpScenario(const FlyArgs& a, const paging::World& shared, FlightOptions& o, FlySessionSettings& ss,
                          std::unique_ptr<DisLink>& link, edits::Editor& editor,
                          std::unique_ptr<sim::TerrainEditing>& terrain) {
  sim::SimOptions options;
  if (!a.dis.endpoint.empty()) options.editOrigin = edit::Origin(a.dis.site << 16 | a.dis.application);
  auto setup = setUpSimulation(kName, shared, a.scenario, a.seed, options);
  if (!setup) return "-";
  viewer::SimSessionOptions so;
  so.attach = a.attach;
  so.drive = a.drive;
  so.scenario = a.scenario;
  so.startS = a.simStart;
  if (!a.dis.endpoint.empty()) {
    DisArgs watch = a.dis;
    watch.publish = false;
    link = openDisLink(kName, shared.manifest(), *setup->sim, watch);
    if (!link) return "-";
    watchNetwork(*link, so);
    ss.realTimeHeadless = true;
  }
  // The panel counts the terrain edits, the map marks them.
  so.extraPanel = [network = so.extraPanel, &editor] {
    std::vector<std::string> lines = network ? network() : std::vector<std::string>{};
    lines.push_back(terrainPanelLine(editor));
    return lines;
  };
  so.extraMarks = [&editor] { return editMarks(editor); };
  const std::shared_ptr<sim::SimWorld> world = setup->world;
  const std::vector<edit::Edit> preplaced = std::move(setup->terrainEdits);
  auto session = viewer::SimSession::create(std::move(setup->sim), so);
  if (!session) return session.problems().front().message;
  if (link) link->gateway->attach(session.value()->stepHost());
  terrain = linkTerrain(session.value()->simulation(), editor, link.get(), preplaced);
  terrain->attach(session.value()->stepHost());
  const sim::Simulation& s = session.value()->simulation();
  // Unless told where, the stealth eye starts behind the scenario's focus.
  std::optional<std::uint32_t> focus = session.value()->focus();
  for (const sim::Entity& e : s.entities()) {
    if (!focus && e.domain != sim::Domain::munition) focus = e.id;
  }
  const bool placed = (a.atOption && a.atOption->count() > 0) || !a.pathFile.empty();
  if (focus && !placed) {
    const sim::Entity& e = s.entity(*focus);
    const double heading = a.headingOption && a.headingOption->count() > 0 ? a.heading : e.headingDeg;
    Eigen::Vector3d eye = e.position - sim::headingVector(heading) * 1200.0;
    if (!world->onGrid(eye.x(), eye.z())) eye = e.position;
    o.motion.easting = world->originEasting() + eye.x();
    o.motion.northing = world->originNorthing() - eye.z();
    o.motion.headingDeg = heading;
  }
  ss.sim = std::move(session.value());
  return {};
}

/// "frame 120/900  31.2 fps  25 s left" after each frame (render thread).
std::function<void(std::uint32_t)> flightProgress(Progress& progress, std::uint32_t total) {
  const auto start = std::chrono::steady_clock::now();
  return [&progress, total, start](std::uint32_t frame) {
    const std::uint32_t done = frame + 1;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double fps = s > 0 ? done / s : 0;
    char detail[96];
    std::snprintf(detail, sizeof detail, "frame %u/%u  %.1f fps  %.0f s left", done, total, fps,
                  fps > 0 ? (total - done) / fps : 0.0);
    progress.update(double(done) / total, "fly", detail);
  };
}

int reportFailure(const Result<viewer::FlightReport>& report) {
  // Bad options and a missing GL context are the caller's to fix (2);
  // anything else went wrong while flying (1).
  const auto& first = report.problems().front();
  const bool usage = first.file == viewer::kFlightOptionProblem || first.file == render::kGlContextProblem;
  for (const auto& q : report.problems()) {
    std::fprintf(stderr, "sandtable fly: error: %s\n", withFlags(q.message).c_str());
  }
  return usage ? kUsage : kProblems;
}

int run(FlyArgs& a) {
  if (std::string err = checkArgs(a); !err.empty()) return usageError(kName, err);
  // The run's one database open: the flight, the map and the simulation
  // share this World.
  // The ground the journal left (the database's own edits.journal when
  // there is one); a scenario's edits are appended to a --journal given.
  const bool append = !a.journal.empty() && a.journal != "none" && !a.scenario.empty();
  auto ew = openEditedWorld(kName, a.database, a.journal, append, editorOptions(true, true));
  if (!ew) return kUsage;
  ew->editor->wait();  // the journal's ground, re-meshed, from the first frame
  const std::shared_ptr<const paging::World> world = ew->world();
  const Database* db = &world->database();
  auto geo = geodesy::Projection::create(db->manifest.crsWkt);
  if (!geo) return usageError(kName, geo.error());
  FlightOptions o;
  if (std::string err = buildOptions(a, *db, geo.value(), o); !err.empty()) {
    return usageError(kName, err);
  }
  FlySessionSettings ss;
  std::unique_ptr<DisLink> link;  // outlives the flight: the session's hooks call its gateway
  std::unique_ptr<sim::TerrainEditing> terrain;  // likewise
  // A journal alone also gets a (still) simulation: its panel counts the
  // edits and its map marks them.
  if (!a.scenario.empty() || !a.dis.endpoint.empty() || !ew->editor->edits().empty()) {
    const std::string err = setUpScenario(a, *world, o, ss, link, *ew->editor, terrain);
    if (err == "-") return kUsage;  // setUpSimulation printed the problems
    if (!err.empty()) return usageError(kName, err);
  }
  if (std::string err = sessionSettings(a, *db, o, ss); !err.empty()) return usageError(kName, err);
  if (!a.pathFile.empty()) {
    auto path = readPath(a, geo.value(), world::Terrain(db->grid), db->manifest);
    if (!path) {
      // "--path FILE:N: what, how to fix" (the Problem's offset is always 0 here).
      return usageError(kName, withFlags("--path " + world::pathProblemText(path.problems().front())));
    }
    const auto& first = path->waypoints.front();
    o.motion.easting = first.easting;
    o.motion.northing = first.northing;
    o.motion.heightAgl = first.heightAgl;
    ss.path = std::move(path.value());
  }
  std::unique_ptr<viewer::VideoWriter> video;
  if (std::string err = openVideo(a, o, video); !err.empty()) return usageError(kName, err);
  std::unique_ptr<viewer::ViewerWindow> window;
  if (std::string err = openWindow(a, *db, o, window); !err.empty()) return usageError(kName, err);
  const bool framesGiven = a.framesOption && a.framesOption->count() > 0;
  if (window) {
    // In a window the flight runs until q, Escape or the window closes.
    if (!framesGiven) o.output.frames = std::numeric_limits<std::uint32_t>::max();
  } else {
    if (a.pngDir.empty() && a.videoFile.empty()) {
      return usageError(kName, "a headless flight needs --png DIR (or --video FILE) for its frames; "
                               "for a window, set DISPLAY (or use --window)");
    }
    if (ss.path && !framesGiven) o.output.frames = framesForPath(*ss.path);
  }
  // A headless flight of many frames takes minutes: frames done, frame
  // rate and time left (a bar on a TTY, plain lines in a log).
  Progress progress(window != nullptr);
  if (!window) ss.onFrameDone = flightProgress(progress, o.output.frames);
  FlySession session(*world, std::move(ss), o, std::move(window), std::move(video));
  auto report = viewer::fly(*world, o, &session);
  progress.done();
  const Status sessionStatus = session.finish();
  if (!report) return reportFailure(report);
  if (!sessionStatus) {
    std::fprintf(stderr, "sandtable fly: error: %s\n", withFlags(sessionStatus.problems().front().message).c_str());
    return kProblems;
  }
  ew->editor->wait();
  if (Status st = ew->editor->flush(); !st) return reportProblems(kName, st.problems());
  printSummary(o, report.value(), session, a);
  if (link) std::printf("  %s", disSummary(*link).c_str());
  if (terrain && !ew->editor->edits().empty()) {
    std::printf("  %s", terrainSummary(*terrain, *ew->editor, append ? ew->journal : std::string()).c_str());
  }
  return kOk;
}

}  // namespace

void registerFly(CLI::App& root, Commands& c) {
  auto args = std::make_shared<FlyArgs>();
  auto* sub = root.add_subcommand(kName, "Fly over a database: in a window with a display, else headless to PNG frames");
  sub->footer(kFooter);
  sub->add_option("DB", args->database, "Database directory (from `sandtable build`)")->required();
  sub->add_option("--png", args->pngDir,
                  "Output directory for frames and stats.json (created); needed headless, optional in a window");
  args->framesOption =
      sub->add_option("--frames", args->frames,
                      "Number of frames (headless: 1/30 s of flight each; window: stop after N, default until q)")
          ->capture_default_str()->check(CLI::Range(1u, 1000000u));
  sub->add_option("--size", args->size, "Frame (and window) size WxH")->capture_default_str();
  auto* at = sub->add_option("--at", args->at, "Start over LON LAT, degrees (default: database centre)")
                 ->expected(2);
  args->atOption = at;
  sub->add_option("--height", args->height, "Eye height above the ground, metres")->capture_default_str();
  auto* heading = sub->add_option("--heading", args->heading, "Degrees clockwise from grid north")
                      ->capture_default_str();
  args->headingOption = heading;
  sub->add_option("--pitch", args->pitch, "Degrees, negative looks down (-89..89)")->capture_default_str();
  sub->add_option("--speed", args->speed, "Ground speed, km/h (also the --path default)")->capture_default_str();
  sub->add_option("--path", args->pathFile, "Waypoint file to fly (docs/PATH.md; format below)")
      ->excludes(at)->excludes(heading);
  sub->add_option("--view-distance", args->viewDistance, "Far plane and full fog, metres")
      ->capture_default_str();
  sub->add_option("--max-view-distance", args->maxViewDistance,
                  "Most the + key may grow the view to, metres (default 3 x --view-distance; "
                  "the pager's window follows the view distance up to it)");
  sub->add_option("--fov", args->fov, "Horizontal field of view, degrees (10..90)")
      ->capture_default_str()->check(CLI::Range(10.0, 90.0));
  sub->add_option("--background", args->background, "Sky and fog colour RRGGBB")->capture_default_str();
  sub->add_flag("--no-hud", args->noHud, "Leave out the information panel");
  sub->add_flag("--no-fog", args->noFog, "No fog");
  sub->add_option("--mode", args->mode, "Terrain: auto (modules when the database has them), mesh, modules")
      ->capture_default_str();
  sub->add_option("--lod", args->lod, "Module level of detail: rings, sse or full")->capture_default_str();
  sub->add_option("--rings", args->rings, "Outer edge of each level's range bin, metres, finest first (M,M,...)");
  sub->add_option("--pixel-error", args->pixelError, "--lod sse: largest projected error, pixels")
      ->capture_default_str()->check(CLI::PositiveNumber);
  sub->add_flag("--no-morph", args->noMorph, "Switch levels without geomorphing");
  sub->add_flag("--node-morph", args->nodeMorph,
                "--lod sse: each node keeps its own morph factor (no pop at a level switch; "
                "more draws and skirts than one factor per module and level)");
  sub->add_option("--fog-density", args->fogDensity,
                  "Fog density per metre; sets the view distance to the fog's obscuration distance")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--msaa", args->msaa, "Samples per pixel (0 off; 4 steadies thin far decals)")
      ->capture_default_str()->check(CLI::Range(0u, 16u));
  sub->add_flag("--no-objects", args->noObjects, "Do not draw the modules' static objects (trees, placed icons)");
  sub->add_option("--object-fade", args->objectFade,
                  "Fraction of each icon's far range over which its objects fade in (0 pops them in)")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  sub->add_flag("--no-object-lod", args->noObjectLod,
                "Draw every object in the view distance, and every entity, at its icon's full detail (no ranges, no sprites)");
  sub->add_option("--impostor-pixels", args->impostorPixels,
                  "Objects drawn smaller than this many pixels become impostor sprites (0: always meshes)")
      ->capture_default_str()->check(CLI::Range(0.0, 255.0));
  sub->add_option("--object-thin-pixels", args->objectThinPixels,
                  "Sprites under this many pixels are thinned, the kept ones drawn larger (0: all drawn)")
      ->capture_default_str()->check(CLI::Range(0.0, 255.0));
  sub->add_option("--shading", args->shading,
                  "smooth (per-post normals, elevation tint) or flat (the seed's per-triangle look)")
      ->capture_default_str();
  sub->add_option("--colour", args->colour,
                  "natural, or height: each pixel's world height as 24-bit RGB (docs/VIEWER.md)")
      ->capture_default_str();
  sub->add_flag("--no-sky", args->noSky, "Clear to magenta instead of drawing the sky (shows cracks)");
  sub->add_flag("--pager-sync", args->pagerSync, "Wait for the pager before every frame (reproducible frames)");
  sub->add_option("--memory-budget-mb", args->memoryBudgetMb,
                  "Most memory for paged modules, MiB (the pager's pool; modules beyond it stand in coarse)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1048576.0));
  sub->add_flag("--window", args->window, "Fly in a window from the keyboard (needs DISPLAY; default when set)");
  sub->add_flag("--headless", args->headless, "Fly without a window even when DISPLAY is set");
  sub->add_flag("--map", args->map, "Show the 2-D map in the top-right corner (m toggles it in a window)");
  sub->add_option("--map-scale", args->mapScale, "Map scale: full, half, quarter, eighth, sixteenth")
      ->capture_default_str();
  sub->add_flag("--free-flight", args->freeFlight, "Keep an altitude instead of a height above the ground");
  sub->add_option("--altitude", args->altitude,
                  "--free-flight: eye above the datum, metres (default: ground at the start + --height)");
  sub->add_option("--video", args->videoFile, "Also encode the frames into FILE (e.g. flight.mp4) with ffmpeg");
  sub->add_option("--screenshot-dir", args->screenshotDir,
                  "Where p / F12 write screenshot_NNNN.png (default: the --png directory, else .)");
  sub->add_option("--journal", args->journal,
                  "Terrain edits: start from FILE (default: DB/edits.journal when present; none: the ground as "
                  "built); with --scenario the run's edits are appended to it");
  sub->add_option("--scenario", args->scenario,
                  "Run this scenario's entities (docs/SCRIPTS.md) and draw them (docs/VIEWER.md, Entities)");
  sub->add_option("--seed", args->seed, "--scenario: random seed (default: the scenario's seed line, else 1)");
  sub->add_option("--attach", args->attach, "--scenario: tether the eye behind and above this entity");
  sub->add_option("--sim-start", args->simStart,
                  "--scenario: simulated seconds run before the first frame (default 0)")
      ->check(CLI::Range(0.0, 1e6));
  sub->add_flag("--drive", args->drive,
                "--scenario: drive the scenario's driven entity (or --attach NAME's) from the keys");
  addDisOptions(sub, args->dis);
  c.add(sub, [args] { return run(*args); });
}

}  // namespace sandtable::cli
