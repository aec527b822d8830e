#include "sandtable/runtime/flight.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "sandtable/formats/bytes.h"
#include "sandtable/runtime/display_buffer.h"
#include "sandtable/runtime/hud.h"
#include "sandtable/runtime/renderer.h"
#include "sandtable/runtime/terrain.h"

namespace sandtable::runtime {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double normalizeHeading(double deg) {
  const double h = std::fmod(deg, 360.0);
  return h < 0 ? h + 360.0 : h;
}

/// Heading of the leg a -> b, clockwise from grid north.
double legHeading(const Waypoint& a, const Waypoint& b) {
  return normalizeHeading(std::atan2(b.easting - a.easting, b.northing - a.northing) * kRadToDeg);
}

Pose straightPose(const FlightOptions& o, double t) {
  const double d = o.speedKmh / 3.6 * t;
  const double h = o.headingDeg * kDegToRad;
  return {o.easting + std::sin(h) * d, o.northing + std::cos(h) * d, normalizeHeading(o.headingDeg),
          o.heightAgl, o.speedKmh};
}

Pose pathPose(const std::vector<Waypoint>& path, double t) {
  double heading = 0;
  for (std::size_t k = 0; k + 1 < path.size(); ++k) {
    const Waypoint& a = path[k];
    const Waypoint& b = path[k + 1];
    const double length = std::hypot(b.easting - a.easting, b.northing - a.northing);
    if (length <= 0) continue;  // a repeated waypoint has no direction
    heading = legHeading(a, b);
    const double duration = length / (a.speedKmh / 3.6);
    if (t <= duration) {
      const double f = t / duration;
      return {a.easting + f * (b.easting - a.easting), a.northing + f * (b.northing - a.northing),
              heading, a.heightAgl + f * (b.heightAgl - a.heightAgl), a.speedKmh};
    }
    t -= duration;
  }
  // Past the last waypoint the eye hovers there, still facing along the last leg.
  const Waypoint& end = path.back();
  return {end.easting, end.northing, heading, end.heightAgl, 0.0};
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(p * double(v.size())));
  return v[std::clamp<std::size_t>(rank, 1, v.size()) - 1];
}

std::string format(const char* fmt, double a, double b = 0, double c = 0) {
  char buf[128];
  std::snprintf(buf, sizeof buf, fmt, a, b, c);
  return buf;
}

std::vector<std::string> hudLines(const FrameStats& s, const FlightOptions& o, double speedKmh) {
  std::vector<std::string> lines;
  lines.push_back("FRAME " + std::to_string(s.frame) + format("  T %.2f S", s.timeS));
  lines.push_back(format("E %.1f  N %.1f", s.easting, s.northing));
  if (s.lon && s.lat) lines.push_back(format("LAT %.5f\xC2\xB0  LON %.5f\xC2\xB0", *s.lat, *s.lon));
  lines.push_back(format("EYE %.0f M  AGL %.0f M", s.eyeElevation, s.heightAgl));
  lines.push_back(format("HDG %05.1f\xC2\xB0  SPD %.0f KM/H", s.headingDeg, speedKmh));
  lines.push_back(format("FOV %.0f\xC2\xB0  VIEW %.0f M", o.hfovDeg, o.viewDistance));
  lines.push_back("TRIS " + std::to_string(s.triangles) + "  STRIPS " + std::to_string(s.strips));
  lines.push_back(format("CPU %.1f MS  FRAME %.1f MS", s.cpuMs, s.cpuMs + s.renderMs));
  return lines;
}

nlohmann::json frameJson(const FrameStats& s) {
  nlohmann::json j = {{"frame", s.frame},
                      {"time_s", s.timeS},
                      {"cpu_ms", s.cpuMs},
                      {"render_ms", s.renderMs},
                      {"frame_ms", s.frameMs},
                      {"png_ms", s.pngMs},
                      {"triangles", s.triangles},
                      {"strips", s.strips},
                      {"easting", s.easting},
                      {"northing", s.northing},
                      {"eye_elevation", s.eyeElevation},
                      {"height_agl", s.heightAgl},
                      {"heading", s.headingDeg}};
  j["lon"] = s.lon ? nlohmann::json(*s.lon) : nlohmann::json(nullptr);
  j["lat"] = s.lat ? nlohmann::json(*s.lat) : nlohmann::json(nullptr);
  return j;
}

nlohmann::json summaryJson(const FlightSummary& s) {
  return {{"frames", s.frames},
          {"triangles_mean", s.trianglesMean},
          {"frame_ms_p50", s.frameMsP50},
          {"frame_ms_p99", s.frameMsP99},
          {"fps_mean", s.fpsMean},
          {"renderer", s.renderer},
          {"renderer_detail", s.rendererDetail},
          {"size", std::to_string(s.width) + "x" + std::to_string(s.height)},
          {"width", s.width},
          {"height", s.height}};
}

std::string writeStats(const std::string& path, const FlightReport& r, const FlightOptions& o) {
  nlohmann::json j;
  j["summary"] = summaryJson(r.summary);
  j["timing"] = {
      {"simulated_frame_rate", kFramesPerSecond},
      {"note", "time_s is simulated (frame / 30). cpu_ms: view triangle, selection and vertex "
               "build; render_ms: upload, draw and glReadPixels (waits for the GPU); frame_ms: "
               "cpu + render + panel; png_ms is not in frame_ms or fps"}};
  j["options"] = {{"size", std::to_string(o.width) + "x" + std::to_string(o.height)},
                  {"height_agl", o.heightAgl},
                  {"pitch", o.pitchDeg},
                  {"speed_kmh", o.speedKmh},
                  {"fov", o.hfovDeg},
                  {"view_distance", o.viewDistance},
                  {"fog", o.fog},
                  {"hud", o.hud},
                  {"path_waypoints", o.path.size()}};
  nlohmann::json frames = nlohmann::json::array();
  for (const auto& f : r.frames) frames.push_back(frameJson(f));
  j["frames"] = frames;
  const std::string text = j.dump(2) + "\n";
  return writeFileAtomic(path, std::as_bytes(std::span(text.data(), text.size())));
}

FlightSummary summarize(const std::vector<FrameStats>& frames) {
  FlightSummary s;
  s.frames = static_cast<std::uint32_t>(frames.size());
  std::vector<double> ms;
  double triangles = 0, totalMs = 0;
  for (const auto& f : frames) {
    ms.push_back(f.frameMs);
    triangles += double(f.triangles);
    totalMs += f.frameMs;
  }
  if (frames.empty()) return s;
  s.trianglesMean = triangles / double(frames.size());
  s.frameMsP50 = percentile(ms, 0.50);
  s.frameMsP99 = percentile(ms, 0.99);
  s.fpsMean = totalMs > 0 ? 1000.0 * double(frames.size()) / totalMs : 0;
  return s;
}

/// Camera for a pose; the ground under the eye comes from `ground`.
Camera cameraFor(const grid::Header& h, const FlightOptions& o, const Pose& p, double ground) {
  Camera c;
  c.x = p.easting - h.originEasting;
  c.z = h.originNorthing - p.northing;
  c.y = ground + p.heightAgl;
  c.headingDeg = p.headingDeg;
  c.pitchDeg = o.pitchDeg;
  c.hfovDeg = o.hfovDeg;
  c.aspect = double(o.width) / double(o.height);
  c.viewDistance = o.viewDistance;
  return c;
}

/// Everything one flight owns while it runs.
struct FlightRun {
  const FlightOptions& o;
  std::shared_ptr<const grid::GridFile> grid;
  Terrain terrain;
  std::unique_ptr<Renderer> renderer;
  // Seed Figure 44: selection fills one buffer while the renderer draws
  // the other. This loop is sequential, but already alternates.
  std::array<DisplayBuffer, 2> buffers;
  Image image;
  double ground = 0;  ///< last ground elevation seen under the eye
  FlightReport report;

  std::string runFrame(std::uint32_t k) {
    FrameStats s;
    s.frame = k;
    s.timeS = k / kFramesPerSecond;
    const Pose pose = poseAt(o, s.timeS);
    if (auto sample = terrain.sampleEN(pose.easting, pose.northing)) ground = sample->elevation;
    const Camera cam = cameraFor(grid->header(), o, pose, ground);

    const auto t0 = Clock::now();
    DisplayBuffer& buf = buffers[k % 2];
    fillDisplayBuffer(*grid, cam, k, buf);
    const auto t1 = Clock::now();
    if (std::string err = renderer->draw(buf, image); !err.empty()) return err;
    s.cpuMs = buf.cpuMs;
    s.renderMs = msSince(t1);
    s.triangles = buf.triangles;
    s.strips = buf.firsts.size();
    s.easting = pose.easting;
    s.northing = pose.northing;
    s.eyeElevation = cam.y;
    s.heightAgl = pose.heightAgl;
    s.headingDeg = pose.headingDeg;
    if (o.toLonLat) {
      if (auto ll = o.toLonLat(pose.easting, pose.northing)) {
        s.lon = ll->first;
        s.lat = ll->second;
      }
    }
    if (o.hud) drawHudPanel(image, hudLines(s, o, pose.speedKmh));
    s.frameMs = msSince(t0);
    if (o.onFrame) o.onFrame(k, image);
    if (!o.outDir.empty()) {
      const auto t2 = Clock::now();
      const std::string path = (std::filesystem::path(o.outDir) / frameFileName(k)).string();
      if (std::string err = writePng(path, image); !err.empty()) return err;
      s.pngMs = msSince(t2);
    }
    report.frames.push_back(std::move(s));
    return {};
  }
};

}  // namespace

Pose poseAt(const FlightOptions& o, double t) {
  return o.path.size() >= 2 ? pathPose(o.path, t) : straightPose(o, t);
}

std::string frameFileName(std::uint32_t frame) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%05u.png", frame);
  return buf;
}

std::vector<Problem> checkFlightOptions(std::shared_ptr<const grid::GridFile> g,
                                        const FlightOptions& o) {
  std::vector<Problem> out;
  auto bad = [&](const std::string& msg) { out.push_back({kFlightOptionProblem, 0, msg}); };
  if (o.frames == 0) bad("--frames must be at least 1");
  if (o.width < 16 || o.height < 16 || o.width > 16384 || o.height > 16384) {
    bad("--size must be between 16x16 and 16384x16384");
  }
  if (!(o.hfovDeg >= 10 && o.hfovDeg <= 90)) bad("--fov must be between 10 and 90 degrees");
  if (!(o.viewDistance >= 10 && o.viewDistance <= 1e6)) bad("--view-distance must be 10 m .. 1000 km");
  if (!(o.pitchDeg >= -89 && o.pitchDeg <= 89)) bad("--pitch must be between -89 and 89 degrees");
  if (!(o.speedKmh >= 0 && o.speedKmh <= 1e5)) bad("--speed must be 0 .. 100000 km/h");
  if (!std::isfinite(o.headingDeg)) bad("--heading must be a number");
  if (!(o.heightAgl >= 0 && o.heightAgl < 1e5)) bad("--height must be 0 .. 100000 m");
  const Terrain terrain(std::move(g));
  if (o.path.size() == 1) bad("--path needs at least two waypoints");
  if (o.path.size() >= 2) {
    for (std::size_t k = 0; k < o.path.size(); ++k) {
      const Waypoint& w = o.path[k];
      const std::string which = "--path waypoint " + std::to_string(k + 1);
      if (k + 1 < o.path.size() && !(w.speedKmh > 0)) bad(which + ": speed must be positive");
      if (!(w.heightAgl >= 0 && w.heightAgl < 1e5)) bad(which + ": height must be 0 .. 100000 m");
      if (k == 0 && !terrain.sampleEN(w.easting, w.northing)) bad(which + " is outside the database");
    }
  } else if (!terrain.sampleEN(o.easting, o.northing)) {
    bad("the start point is outside the database");
  }
  return out;
}

Result<FlightReport> fly(std::shared_ptr<const grid::GridFile> g, const FlightOptions& o) {
  if (!g) return Problem{"fly", 0, "no grid"};
  if (auto problems = checkFlightOptions(g, o); !problems.empty()) return problems;
  if (!o.outDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.outDir, ec);
    if (ec) {
      return Problem{kFlightOptionProblem, 0,
                     "cannot create the output directory " + o.outDir + ": " + ec.message()};
    }
  }
  RenderSettings rs;
  rs.width = o.width;
  rs.height = o.height;
  rs.background = o.background;
  rs.fog = o.fog;
  rs.minElevation = g->header().minElevation;
  rs.maxElevation = g->header().maxElevation;
  auto renderer = Renderer::create(rs);
  if (!renderer) return renderer.problems();

  FlightRun run{o, g, Terrain(g), std::move(renderer.value()), {}, {}, 0, {}};
  const Pose start = poseAt(o, 0);
  run.ground = run.terrain.sampleEN(start.easting, start.northing)->elevation;
  for (std::uint32_t k = 0; k < o.frames; ++k) {
    if (std::string err = run.runFrame(k); !err.empty()) return Problem{"fly", 0, err};
  }
  FlightReport& r = run.report;
  r.summary = summarize(r.frames);
  r.summary.renderer = run.renderer->glRenderer();
  r.summary.rendererDetail = run.renderer->description();
  r.summary.width = o.width;
  r.summary.height = o.height;
  if (!o.outDir.empty()) {
    const std::string path = (std::filesystem::path(o.outDir) / "stats.json").string();
    if (std::string err = writeStats(path, r, o); !err.empty()) return Problem{"fly", 0, err};
    r.summary.statsPath = path;
  }
  return std::move(r);
}

}  // namespace sandtable::runtime
