// `sandtable fly`: a headless flight over a database, written as PNG frames
// and stats.json. Converts lon/lat to the database's projected frame here,
// because the runtime links no PROJ.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "commands.h"
#include "sandtable/converters/crs.h"
#include "sandtable/formats/database.h"
#include "sandtable/runtime/flight.h"
#include "sandtable/runtime/renderer.h"
#include "sandtable/runtime/terrain.h"

namespace sandtable::cli {
namespace {

using runtime::FlightOptions;
using runtime::Waypoint;

constexpr const char* kName = "fly";

struct FlyArgs {
  std::string database;
  std::string pngDir;
  std::uint32_t frames = 30;
  std::string size = "1280x720";
  std::vector<double> at;  ///< lon, lat
  double height = 300;
  double heading = 0;
  double pitch = -10;
  double speed = 300;
  std::string pathFile;
  double viewDistance = 10000;
  double fov = 60;
  std::string background = "87CEEB";
  bool noHud = false;
  bool noFog = false;
  std::string mode = "auto";
  std::string lod = "rings";
  std::string rings;
  double pixelError = 2.0;
  bool noMorph = false;
  double fogDensity = 0;
  bool pagerSync = false;
  bool noSky = false;
  std::uint32_t msaa = 0;
};

const char* kFooter = R"(Time: frame k shows the eye at k/30 s of simulated time, whatever the real
frame rate, so --speed 300 moves the eye 2.78 m per frame. The eye keeps
--height metres above the ground under it (ground following).

--path FILE flies a polyline instead of a straight line. One waypoint per line:
    lon lat height_m [speed_kmh]
lon/lat in degrees (WGS 84), height_m above the ground, speed_kmh for the leg
that starts at this waypoint (default --speed). '#' starts a comment; blank
lines are ignored. The eye heads along each leg and hovers at the last
waypoint once it gets there. Example:
    # up the valley, then climb over the ridge
    8.10 46.60 200
    8.20 46.65 200 150
    8.30 46.70 800

Terrain (docs/VIEWER.md): with load modules (modules.pack, from `sandtable build
--culture`) the stealth viewer draws them through the predictive pager, one level
of detail per module, with skirts over the seams, material colours and road and
area decals over the skin; --mode mesh draws the full-resolution grid instead.
--lod rings chooses levels by range rings (seed Figure 84; default: Table 8's four
equal bins scaled to --view-distance, or --rings M,M,... as the outer edges of
each level's bin, finest first); --lod sse by projected error (--pixel-error PX);
--lod full always draws the finest level. Levels geomorph unless --no-morph.
--fog-density D (per metre) sets the view distance to the fog's obscuration
distance sqrt(ln 255)/D (seed IX.A.3); otherwise the density follows it.

Writes OUT_DIR/frame_00000.png ... and OUT_DIR/stats.json (per-frame timing,
position and triangle counts; summary with fps and the GL renderer).
Needs headless OpenGL 4.5 core through EGL (Mesa llvmpipe works without a GPU).
Exit status: 0 done, 1 failed while flying, 2 bad input or no GL context.)";

bool parseSize(const std::string& s, std::uint32_t& w, std::uint32_t& h) {
  unsigned a = 0, b = 0;
  char x = 0, extra = 0;
  if (std::sscanf(s.c_str(), "%u%c%u%c", &a, &x, &b, &extra) != 3 || (x != 'x' && x != 'X')) return false;
  w = a;
  h = b;
  return true;
}

bool parseColor(std::string s, runtime::Rgb& c) {
  if (!s.empty() && s[0] == '#') s.erase(0, 1);
  if (s.size() != 6 || !std::all_of(s.begin(), s.end(), [](char ch) { return std::isxdigit(static_cast<unsigned char>(ch)); })) {
    return false;
  }
  const auto v = std::stoul(s, nullptr, 16);
  c = {static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)};
  return true;
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

/// Converts lon/lat and checks it lies on the grid; "" or the reason not.
std::string project(const convert::GeoTransformer& geo, const runtime::Terrain& terrain,
                    const manifest::Manifest& m, double lon, double lat, double& e, double& n) {
  char where[64];
  std::snprintf(where, sizeof where, "%.6f %.6f", lon, lat);
  if (!geo.toProjected(lon, lat, e, n)) return std::string(where) + " cannot be projected into " + m.crsName;
  if (!terrain.sampleEN(e, n)) {
    return std::string(where) + " is outside the database, which covers " + boundsText(m) +
           " (the grid is a rectangle in " + m.crsName + ", so its lon/lat corners are not square)";
  }
  return {};
}

/// Reads a --path file; "" or an error naming the line.
std::string readPath(const std::string& file, double defaultSpeed, const convert::GeoTransformer& geo,
                     const runtime::Terrain& terrain, const manifest::Manifest& m,
                     std::vector<Waypoint>& out) {
  std::ifstream in(file);
  if (!in) return "--path " + file + ": cannot open";
  std::string line;
  for (int lineNo = 1; std::getline(in, line); ++lineNo) {
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream fields(line);
    double lon = 0, lat = 0;
    Waypoint w;
    w.speedKmh = defaultSpeed;
    std::string rest;
    if (!(fields >> rest)) continue;  // blank or comment-only line
    fields.clear();
    fields.str(line);
    if (!(fields >> lon >> lat >> w.heightAgl)) {
      return "--path " + file + ":" + std::to_string(lineNo) + ": expected \"lon lat height_m [speed_kmh]\"";
    }
    if (fields >> rest) {
      try {
        std::size_t used = 0;
        w.speedKmh = std::stod(rest, &used);
        if (used != rest.size()) throw std::invalid_argument(rest);
      } catch (const std::exception&) {
        return "--path " + file + ":" + std::to_string(lineNo) + ": speed \"" + rest + "\" is not a number";
      }
      if (fields >> rest) return "--path " + file + ":" + std::to_string(lineNo) + ": too many fields";
    }
    if (!(w.speedKmh > 0)) return "--path " + file + ":" + std::to_string(lineNo) + ": speed must be positive";
    if (std::string err = project(geo, terrain, m, lon, lat, w.easting, w.northing); !err.empty()) {
      return "--path " + file + ":" + std::to_string(lineNo) + ": " + err;
    }
    out.push_back(w);
  }
  if (out.size() < 2) return "--path " + file + ": needs at least two waypoints";
  return {};
}

/// Fills the runtime options from the command line; "" or a usage error.
std::string buildOptions(const FlyArgs& a, const Database& db, const convert::GeoTransformer& geo,
                         FlightOptions& o) {
  const runtime::Terrain terrain(db.grid);
  const auto& m = db.manifest;
  o.outDir = a.pngDir;
  o.frames = a.frames;
  if (!parseSize(a.size, o.width, o.height)) return "--size must look like 1280x720, not \"" + a.size + "\"";
  if (!parseColor(a.background, o.background)) return "--background must be 6 hex digits RRGGBB, e.g. 87CEEB";
  o.heightAgl = a.height;
  o.headingDeg = a.heading;
  o.pitchDeg = a.pitch;
  o.speedKmh = a.speed;
  o.viewDistance = a.viewDistance;
  o.hfovDeg = a.fov;
  o.hud = !a.noHud;
  o.fog = !a.noFog;
  if (a.mode == "auto") o.mode = runtime::TerrainMode::automatic;
  else if (a.mode == "mesh") o.mode = runtime::TerrainMode::mesh;
  else if (a.mode == "modules") o.mode = runtime::TerrainMode::modules;
  else return "--mode must be auto, mesh or modules, not \"" + a.mode + "\"";
  if (a.lod == "rings") o.lod.mode = runtime::LodMode::rings;
  else if (a.lod == "sse") o.lod.mode = runtime::LodMode::sse;
  else if (a.lod == "full") o.lod.mode = runtime::LodMode::full;
  else return "--lod must be rings, sse or full, not \"" + a.lod + "\"";
  if (!a.rings.empty()) {
    std::stringstream in(a.rings);
    std::string item;
    while (std::getline(in, item, ',')) {
      try {
        std::size_t used = 0;
        o.lod.rings.push_back(std::stod(item, &used));
        if (used != item.size()) throw std::invalid_argument(item);
      } catch (const std::exception&) {
        return "--rings must be metres separated by commas, e.g. 1500,3000,4500";
      }
    }
  }
  o.lod.pixelError = a.pixelError;
  o.lod.morph = !a.noMorph;
  o.fogDensity = a.fogDensity;
  o.pagerSync = a.pagerSync;
  o.sky = !a.noSky;
  o.msaa = a.msaa;
  const auto& h = db.grid->header();
  o.easting = h.originEasting + h.spacing * (h.postsX - 1) / 2.0;
  o.northing = h.originNorthing - h.spacing * (h.postsZ - 1) / 2.0;
  if (a.at.size() == 2) {
    if (std::string err = project(geo, terrain, m, a.at[0], a.at[1], o.easting, o.northing); !err.empty()) {
      return "--at " + err;
    }
  }
  if (!a.pathFile.empty()) {
    if (std::string err = readPath(a.pathFile, a.speed, geo, terrain, m, o.path); !err.empty()) return err;
  }
  o.toLonLat = [&geo](double e, double n) -> std::optional<std::pair<double, double>> {
    double lon = 0, lat = 0;
    if (!geo.toLonLat(e, n, lon, lat)) return std::nullopt;
    return std::pair{lon, lat};
  };
  return {};
}

void printSummary(const FlightOptions& o, const runtime::FlightReport& r) {
  const auto& s = r.summary;
  std::printf("sandtable fly: %u frame%s at %ux%u in %s/ (%s .. %s)\n", s.frames,
              s.frames == 1 ? "" : "s", s.width, s.height, o.outDir.c_str(),
              runtime::frameFileName(0).c_str(),
              runtime::frameFileName(s.frames - 1).c_str());
  std::printf("  stats:    %s\n", s.statsPath.c_str());
  std::printf("  renderer: %s\n", s.rendererDetail.c_str());
  std::printf("  terrain:  %s%s%s\n", s.mode.c_str(), s.lod.empty() ? "" : ", lod ", s.lod.c_str());
  std::printf("  speed:    %.1f fps mean, frame %.1f ms p50 / %.1f ms p99 (selection + draw + read-back;"
              " PNG writing excluded), %.0f triangles per frame\n",
              s.fpsMean, s.frameMsP50, s.frameMsP99, s.trianglesMean);
}

int run(const FlyArgs& a) {
  auto db = openDatabase(a.database);
  if (!db) return usageError(kName, db.error());
  auto geo = convert::GeoTransformer::create(db->manifest.crsWkt);
  if (!geo) return usageError(kName, geo.error());
  FlightOptions o;
  if (std::string err = buildOptions(a, db.value(), *geo.value(), o); !err.empty()) {
    return usageError(kName, err);
  }
  auto report = runtime::fly(db.value(), o);
  if (!report) {
    // Bad options and a missing GL context are the caller's to fix (2);
    // anything else went wrong while flying (1).
    const auto& first = report.problems().front();
    const bool usage = first.file == runtime::kFlightOptionProblem ||
                       first.file == runtime::kGlContextProblem;
    for (const auto& q : report.problems()) {
      std::fprintf(stderr, "sandtable fly: error: %s\n", q.message.c_str());
    }
    return usage ? kUsage : kProblems;
  }
  printSummary(o, report.value());
  return kOk;
}

}  // namespace

void registerFly(CLI::App& root, Commands& c) {
  auto args = std::make_shared<FlyArgs>();
  auto* sub = root.add_subcommand(kName, "Fly over a database headlessly and write PNG frames");
  sub->footer(kFooter);
  sub->add_option("DB", args->database, "Database directory (from `sandtable build`)")->required();
  sub->add_option("--png", args->pngDir, "Output directory for frames and stats.json (created)")
      ->required();
  sub->add_option("--frames", args->frames, "Number of frames (1/30 s of flight each)")
      ->capture_default_str()->check(CLI::Range(1u, 1000000u));
  sub->add_option("--size", args->size, "Frame size WxH")->capture_default_str();
  auto* at = sub->add_option("--at", args->at, "Start over LON LAT, degrees (default: database centre)")
                 ->expected(2);
  sub->add_option("--height", args->height, "Eye height above the ground, metres")->capture_default_str();
  auto* heading = sub->add_option("--heading", args->heading, "Degrees clockwise from grid north")
                      ->capture_default_str();
  sub->add_option("--pitch", args->pitch, "Degrees, negative looks down (-89..89)")->capture_default_str();
  sub->add_option("--speed", args->speed, "Ground speed, km/h (also the --path default)")->capture_default_str();
  sub->add_option("--path", args->pathFile, "Waypoint file to fly (format below)")
      ->excludes(at)->excludes(heading);
  sub->add_option("--view-distance", args->viewDistance, "Far plane and full fog, metres")
      ->capture_default_str();
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
  sub->add_option("--fog-density", args->fogDensity,
                  "Fog density per metre; sets the view distance to the fog's obscuration distance")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--msaa", args->msaa, "Samples per pixel (0 off; 4 steadies thin far decals)")
      ->capture_default_str()->check(CLI::Range(0u, 16u));
  sub->add_flag("--no-sky", args->noSky, "Clear to magenta instead of drawing the sky (shows cracks)");
  sub->add_flag("--pager-sync", args->pagerSync, "Wait for the pager before every frame (reproducible frames)");
  c.add(sub, [args] { return run(*args); });
}

}  // namespace sandtable::cli
