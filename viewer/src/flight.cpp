#include "sandtable/viewer/flight.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <future>
#include <mutex>
#include <thread>

#include <time.h>

#include <nlohmann/json.hpp>

#include "sandtable/base/stats.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/module.h"
#include "sandtable/scene/camera_math.h"
#include "sandtable/scene/display_buffer.h"
#include "sandtable/render/hud.h"
#include "sandtable/scene/module_scene.h"
#include "sandtable/paging/pager.h"
#include "sandtable/world/path.h"
#include "sandtable/render/renderer.h"
#include "sandtable/world/terrain.h"

namespace sandtable::viewer {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
/// Road classes at least this wide (metres) get the texture's markings.
constexpr double kMarkedRoadWidth = 5.0;

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double normalizeHeading(double deg) {
  const double h = std::fmod(deg, 360.0);
  return h < 0 ? h + 360.0 : h;
}

world::Pose straightPose(const FlightOptions& o, double t) {
  const double d = o.motion.speedKmh / 3.6 * t;
  const double h = o.motion.headingDeg * kDegToRad;
  world::Pose p;
  p.easting = o.motion.easting + std::sin(h) * d;
  p.northing = o.motion.northing + std::cos(h) * d;
  p.headingDeg = normalizeHeading(o.motion.headingDeg);
  p.heightAgl = o.motion.heightAgl;
  p.speedKmh = o.motion.speedKmh;
  return p;
}

/// FlightOptions::path flown as a path file would be (path.h): the legs at
/// their speeds, the heading turning at Path::turnRateDegS round each
/// waypoint rather than snapping.
world::Pose pathPose(const std::vector<Waypoint>& path, double t) {
  std::vector<world::PathPoint> points;
  points.reserve(path.size());
  for (const Waypoint& w : path) {
    world::PathPoint q;
    q.easting = w.easting;
    q.northing = w.northing;
    q.heightAgl = w.heightAgl;
    q.speedKmh = w.speedKmh;
    points.push_back(q);
  }
  points.back().speedKmh.reset();  // no leg starts at the last waypoint
  points.front().timeS = 0;
  auto resolved = world::resolvePath(points, {}, "FlightOptions::path");
  if (!resolved.ok()) return {};  // checkFlightOptions refuses such a path before flight
  return world::samplePath(resolved.value(), t);
}

/// CPU time of the calling thread, milliseconds.
double threadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) / 1e6;
}

std::string format(const char* fmt, double a, double b = 0, double c = 0) {
  char buf[128];
  std::snprintf(buf, sizeof buf, fmt, a, b, c);
  return buf;
}

/// An application's JSON text as JSON (a string when it does not parse).
nlohmann::json jsonOrText(const std::string& text) {
  auto j = nlohmann::json::parse(text, nullptr, false);
  return j.is_discarded() ? nlohmann::json(text) : j;
}

nlohmann::json frameJson(const FrameStats& s) {
  nlohmann::json j = {{"frame", s.frame},
                      {"time_s", s.timeS},
                      {"cpu_ms", s.cpuMs},
                      {"render_ms", s.renderMs},
                      {"render_cpu_ms", s.renderCpuMs},
                      {"upload_ms", s.uploadMs},
                      {"frame_ms", s.frameMs},
                      {"png_ms", s.pngMs},
                      {"triangles", s.triangles},
                      {"strips", s.strips},
                      {"easting", s.easting},
                      {"northing", s.northing},
                      {"eye_elevation", s.eyeElevation},
                      {"height_agl", s.heightAgl},
                      {"heading", s.headingDeg},
                      {"fps", s.fps},
                      {"fov", s.hfovDeg},
                      {"view_distance", s.viewDistance},
                      {"speed_kmh", s.speedKmh},
                      {"free_flight", s.freeFlight}};
  if (!s.levelCounts.empty()) {
    j["modules"] = {{"drawn", s.modulesDrawn},     {"missing", s.modulesMissing},
                    {"culled", s.modulesCulled},   {"nodes_drawn", s.nodesDrawn},
                    {"nodes_coarser", s.nodesCoarser},
                    {"nodes_per_level", s.levelCounts}, {"max_error_px", s.maxErrorPx},
                    {"uploads", s.uploads},        {"released", s.released},
                    {"cached_levels", s.cachedLevels},
                    {"gpu_bytes", s.gpuBytes}};
    j["modules"]["nodes_placeholder"] = s.nodesPlaceholder;
    j["objects"] = {{"drawn", s.objectsDrawn},
                    {"instances", s.objectInstances},
                    {"draws", s.objectDraws},
                    {"triangles", s.objectTriangles},
                    {"sprites", s.objectSprites},
                    {"thinned", s.objectsThinned}};
    j["objects"]["removed"] = s.objectsRemoved;
    j["objects"]["changed_drawn"] = s.objectsChanged;
    j["pager"] = {{"resident_in_window", s.residentModules},
                  {"window_modules", s.windowModules},
                  {"queue", s.pagerQueue},
                  {"placeholders", s.pagerPlaceholders},
                  {"budget_refusals", s.pagerBudgetRefusals},
                  {"budget_trimmed_levels", s.pagerTrimmedLevels},
                  {"pool_bytes", s.pagerPoolBytes}};
  }
  j["lon"] = s.lon ? nlohmann::json(*s.lon) : nlohmann::json(nullptr);
  j["lat"] = s.lat ? nlohmann::json(*s.lat) : nlohmann::json(nullptr);
  j["dynamic"] = {{"entities_drawn", s.entitiesDrawn},
                  {"entity_triangles", s.entityTriangles},
                  {"trails_drawn", s.trailsDrawn},
                  {"flashes_drawn", s.flashesDrawn}};
  for (const auto& [key, text] : s.extraJson) j[key] = jsonOrText(text);
  return j;
}

nlohmann::json summaryJson(const FlightSummary& s) {
  return {{"frames", s.frames},
          {"mode", s.mode},
          {"lod", s.lod},
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

std::string writeStats(const std::string& path, const FlightReport& r, const FlightOptions& o,
                       const std::vector<std::pair<std::string, std::string>>& sections) {
  nlohmann::json j;
  j["summary"] = summaryJson(r.summary);
  for (const auto& [key, text] : sections) j[key] = jsonOrText(text);
  j["timing"] = {
      {"simulated_frame_rate", kFramesPerSecond},
      {"note", "time_s is simulated (frame / 30). cpu_ms: main thread, view triangle, "
               "selection and LoD (mesh: vertex build too); render_ms: render thread, upload "
               "and the passes up to the HUD (waits for the GPU); render_cpu_ms: the render thread's "
               "own CPU time over that span; upload_ms: of render_ms, module uploads and LoD; frame_ms: time between frame "
               "completions on the render thread (the threads overlap), frame 0 cpu + render + "
               "panel; png_ms is not in frame_ms or fps"}};
  j["options"] = {{"size", std::to_string(o.view.width) + "x" + std::to_string(o.view.height)},
                  {"height_agl", o.motion.heightAgl},
                  {"pitch", o.motion.pitchDeg},
                  {"speed_kmh", o.motion.speedKmh},
                  {"fov", o.view.hfovDeg},
                  {"view_distance", o.view.viewDistance},
                  {"fog", o.view.fog},
                  {"mode", terrainModeName(o.render.mode)},
                  {"lod", scene::lodModeName(o.render.lod.mode)},
                  {"rings", o.render.lod.rings},
                  {"pixel_error", o.render.lod.pixelError},
                  {"morph", o.render.lod.morph},
                  {"msaa", o.render.samples},
                  {"objects", o.render.objects},
                  {"object_fade", o.render.objectFade},
                  {"object_lod", o.render.objectLod},
                  {"impostor_pixels", o.render.impostorPixels},
                  {"object_thin_pixels", o.render.objectThinPixels},
                  {"hud", o.view.hud},
                  {"path_waypoints", o.motion.path.size()}};
  nlohmann::json frames = nlohmann::json::array();
  for (const auto& f : r.frames) frames.push_back(frameJson(f));
  j["frames"] = frames;
  const std::string text = j.dump(2) + "\n";
  return writeFileAtomic(path, std::as_bytes(std::span(text.data(), text.size()))).message();
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
  s.frameMsP50 = stats::percentile(ms, 0.50);
  s.frameMsP99 = stats::percentile(ms, 0.99);
  s.fpsMean = totalMs > 0 ? 1000.0 * double(frames.size()) / totalMs : 0;
  return s;
}

double effectiveViewDistance(const FlightOptions& o) {
  return o.view.fogDensity > 0 ? scene::viewDistanceForFog(o.view.fogDensity) : o.view.viewDistance;
}

/// The eye's elevation for a pose over `ground`: ground following, or
/// free flight but never below the ground.
double eyeFor(const world::Pose& p, double ground) {
  return world::GroundClamp::eyeElevation(ground, p.heightAgl, p.altitude, 0.0);
}

/// Camera for a pose; the ground under the eye comes from `ground`.
scene::Camera cameraFor(const grid::HeightField& h, const FlightOptions& o, const world::Pose& p, double ground) {
  scene::Camera c;
  c.x = p.easting - h.originEasting();
  c.z = h.originNorthing() - p.northing;
  c.y = eyeFor(p, ground);
  c.headingDeg = p.headingDeg;
  c.pitchDeg = std::clamp(p.pitchDeg.value_or(o.motion.pitchDeg), -89.0, 89.0);
  c.hfovDeg = std::clamp(p.hfovDeg.value_or(o.view.hfovDeg), 10.0, 90.0);
  c.aspect = double(o.view.width) / double(o.view.height);
  c.viewDistance = std::clamp(p.viewDistance.value_or(effectiveViewDistance(o)), 10.0, 1e6);
  return c;
}

/// A display buffer with what the main thread knows about its frame.
struct Slot {
  scene::DisplayBuffer buf;
  FrameStats stats;
};

/// Seed Figure 44: two buffers go round between the main thread, which
/// fills a free one, and the render thread, which draws a full one. Both
/// sides sleep on the condition variable when they have nothing to do.
class Handoff {
 public:
  explicit Handoff(std::array<Slot, 2>& slots) { free_ = {&slots[0], &slots[1]}; }

  /// Main thread: a buffer to fill; null once the render thread failed.
  Slot* takeFree() {
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return failed_ || !free_.empty(); });
    if (failed_) return nullptr;
    Slot* s = free_.front();
    free_.pop_front();
    return s;
  }
  void pushFull(Slot* s) {
    { std::lock_guard lock(m_); full_.push_back(s); }
    cv_.notify_all();
  }
  /// Render thread: a buffer to draw; null when the main thread is done.
  Slot* takeFull() {
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return closed_ || !full_.empty(); });
    if (full_.empty()) return nullptr;
    Slot* s = full_.front();
    full_.pop_front();
    return s;
  }
  void pushFree(Slot* s) {
    { std::lock_guard lock(m_); free_.push_back(s); }
    cv_.notify_all();
  }
  void close() {
    { std::lock_guard lock(m_); closed_ = true; }
    cv_.notify_all();
  }
  void fail() {
    { std::lock_guard lock(m_); failed_ = true; }
    cv_.notify_all();
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<Slot*> free_, full_;
  bool closed_ = false, failed_ = false;
};

/// Everything one flight owns while it runs.
struct FlightRun {
  FlightRun(const FlightOptions& options, FlightApplication& application,
            std::shared_ptr<const grid::HeightField> g, render::RenderSettings rs)
      : o(options), app(application), grid(g), ground(std::move(g)), renderSettings(std::move(rs)) {}

  const FlightOptions& o;
  FlightApplication& app;
  std::shared_ptr<const grid::HeightField> grid;
  /// The one ground clamp: the surface drawn under the eye (module mode:
  /// reset with the pack's module size and levels).
  world::GroundClamp ground;
  render::RenderSettings renderSettings;
  paging::Pager* pager = nullptr;                 ///< module mode
  /// The view distance the pager's window has been filled to: the drawn
  /// distance grows past it only as far as the pager has modules resident.
  double readyViewDistance = 0;
  std::unique_ptr<scene::ModuleScene> scene;     ///< module mode
  std::array<Slot, 2> slots;
  Handoff handoff{slots};
  // Written by the render thread only; read after it is joined.
  FlightReport report;
  std::vector<Problem> renderProblems;
  std::string rendererName, rendererDetail;

  /// Velocity in the world frame (X east, Z south) for the pager's lead
  /// strips: the motion since the previous frame over the time it took, or
  /// on frame 0 (no previous) the pose's own speed along its heading.
  static std::pair<double, double> velocity(const world::Pose& pose, double t, const world::Pose& previous,
                                            double previousT, bool first) {
    if (first || !(t > previousT)) {
      const double v = pose.speedKmh / 3.6, h = pose.headingDeg * kDegToRad;
      return {std::sin(h) * v, -std::cos(h) * v};
    }
    const double dt = t - previousT;
    return {(pose.easting - previous.easting) / dt, -(pose.northing - previous.northing) / dt};
  }

  /// The distance to draw to when `asked` is the pager's view distance now.
  double drawnViewDistance(double asked, double x, double z) {
    if (asked <= readyViewDistance) {
      readyViewDistance = asked;
      return asked;
    }
    const double covered = pager->residentDistance(x, z);
    if (covered >= asked) readyViewDistance = asked;
    return std::max(readyViewDistance, std::min(asked, covered));
  }

  /// Main thread, one frame: motion, paging, selection into a free buffer.
  /// False when the flight ends (the controller said so, or rendering failed).
  bool produce(std::uint32_t k, world::Pose& previous, double& previousT) {
    auto next = app.pose(k, k / kFramesPerSecond, ground);
    if (!next) return false;
    const world::Pose pose = *next;
    const double t = pose.clockS.value_or(k / kFramesPerSecond);
    double groundHere = ground.groundEN(pose.easting, pose.northing);
    scene::Camera cam = cameraFor(*grid, o, pose, groundHere);
    if (pager) {
      // The window follows the view distance asked for (the + and - keys,
      // a path). Growing, the new ring is drawn only as it comes in, so the
      // far edge moves out without a hole; shrinking takes effect at once.
      const double asked = pager->setViewDistance(cam.viewDistance);
      const auto [vx, vz] = velocity(pose, t, previous, previousT, k == 0);
      pager->update(cam.x, cam.z, vx, vz, t);
      if (k == 0 || o.pager.sync) pager->waitIdle(120);
      app.paged(k, *pager);
      cam.viewDistance = drawnViewDistance(asked, cam.x, cam.z);
    }
    previous = pose;
    previousT = t;
    Slot* slot = handoff.takeFree();
    if (!slot) return false;
    slot->buf.dynamic.clear();
    if (scene) {
      scene->fill(cam, k, slot->buf);
      // The eye stands on the surface this frame draws under it, at the
      // level and morph just selected there (seed Figure 23).
      if (auto drawn = scene::drawnLevelAt(slot->buf, cam.x, cam.z)) ground.setDrawn(*drawn);
      groundHere = ground.groundEN(pose.easting, pose.northing);
      cam.y = eyeFor(pose, groundHere);
      slot->buf.camera.y = cam.y;
    } else {
      fillDisplayBuffer(*grid, cam, k, slot->buf, o.render.waterMaterials);
      slot->buf.moduleMode = false;
    }
    FrameStats& s = slot->stats;
    s = FrameStats{};
    s.frame = k;
    s.timeS = t;
    s.cpuMs = slot->buf.cpuMs;
    s.triangles = slot->buf.triangles;
    s.strips = slot->buf.firsts.size();
    s.easting = pose.easting;
    s.northing = pose.northing;
    s.eyeElevation = cam.y;
    s.heightAgl = cam.y - groundHere;
    s.headingDeg = pose.headingDeg;
    s.speedKmh = pose.speedKmh;
    s.hfovDeg = cam.hfovDeg;
    s.viewDistance = cam.viewDistance;
    s.freeFlight = pose.altitude.has_value();
    if (slot->buf.moduleMode) {
      const scene::SceneStats& sc = slot->buf.scene;
      s.modulesDrawn = sc.modulesDrawn;
      s.modulesMissing = sc.modulesMissing;
      s.nodesDrawn = sc.nodesDrawn;
      s.nodesCoarser = sc.nodesCoarser;
      s.modulesCulled = sc.modulesCulled;
      s.levelCounts = sc.levelCounts;
      s.maxErrorPx = sc.maxErrorPx;
      s.residentModules = sc.residentInWindow;
      s.windowModules = sc.windowModules;
      s.pagerQueue = sc.pagerQueue;
      s.nodesPlaceholder = sc.nodesPlaceholder;
      s.pagerPlaceholders = sc.pagerPlaceholders;
      s.pagerBudgetRefusals = sc.pagerBudgetRefusals;
      s.pagerTrimmedLevels = sc.pagerTrimmedLevels;
      s.pagerPoolBytes = sc.pagerPoolBytes;
    }
    if (o.output.toLonLat) {
      if (auto ll = o.output.toLonLat(pose.easting, pose.northing)) {
        s.lon = ll->first;
        s.lat = ll->second;
      }
    }
    app.frameContent(k, slot->buf, s);
    handoff.pushFull(slot);
    return true;
  }

  /// Render thread: the failure that ends the flight.
  void stop(const Status& st) {
    renderProblems = st.problems();
    handoff.fail();
  }

  /// Render thread: runs the renderer's passes, draws the panel and
  /// `composite` into the HUD overlay, reads the frame back only for a
  /// sink that wants its pixels, presents it in the window, and hands out
  /// each frame, then returns the buffer (its pager guards released).
  void consume(render::Renderer& renderer) {
    render::PresentTarget* const window = app.window();
    render::Image image;
    render::Overlay overlay;
    Clock::time_point lastDone{};
    double lastPngMs = 0;
    while (Slot* slot = handoff.takeFull()) {
      FrameStats s = slot->stats;
      const auto t0 = Clock::now();
      const double cpu0 = threadCpuMs();
      const Status drawn = renderer.draw(slot->buf);
      if (drawn) renderer.finish();
      s.renderMs = msSince(t0);
      s.renderCpuMs = threadCpuMs() - cpu0;
      slot->buf.modules.clear();  // release the pager's guards within the frame
      const render::RenderStats& rs = renderer.stats();
      s.uploads = rs.uploads;
      s.uploadMs = rs.uploadMs;
      s.released = rs.released;
      s.cachedLevels = rs.cachedLevels;
      s.gpuBytes = rs.gpuBytes;
      s.uploadBytes = rs.uploadBytes;
      s.uploadsDeferred = rs.uploadsDeferred;
      s.nodesFallback = rs.nodesFallback;
      s.draws = rs.draws;
      s.trianglesDrawn = rs.trianglesDrawn;
      s.objectsDrawn = rs.objectsDrawn;
      s.objectInstances = rs.objectInstances;
      s.objectDraws = rs.objectDraws;
      s.objectTriangles = rs.objectTriangles;
      s.objectSprites = rs.objectSprites;
      s.objectsThinned = rs.objectsThinned;
      s.objectsRemoved = rs.objectsRemoved;
      s.objectsChanged = rs.objectsChangedDrawn;
      s.entitiesDrawn = rs.entitiesDrawn;
      s.entityTriangles = rs.entityTriangles;
      s.trailsDrawn = rs.trailsDrawn;
      s.flashesDrawn = rs.flashesDrawn;
      handoff.pushFree(slot);
      if (!drawn) return stop(drawn);
      const auto now = Clock::now();
      s.frameMs = report.frames.empty()
                      ? s.cpuMs + s.renderMs
                      : std::chrono::duration<double, std::milli>(now - lastDone).count() - lastPngMs;
      s.fps = s.frameMs > 0 ? 1000.0 / s.frameMs : 0;
      // A height frame holds data in its pixels: nothing is drawn over it.
      const bool data = o.render.colour == render::ColourMode::height;
      overlay.begin(o.view.width, o.view.height);
      if (o.view.hud && !data) s.hudPanel = render::drawHudPanel(overlay, hudLines(s, o));
      if (!data) app.overlay(overlay, s);
      Status shown = renderer.drawOverlay(overlay);
      const bool sink = app.wantsFrame(s.frame);
      if (shown && (sink || !o.output.outDir.empty())) shown = renderer.readFrame(image);
      if (shown && window) shown = renderer.present();
      if (!shown) return stop(shown);
      s.frameMs += msSince(now);  // the HUD, a read-back and the present are part of the frame
      lastDone = Clock::now();
      if (sink) app.frameDone(s.frame, image);
      lastPngMs = 0;
      if (!o.output.outDir.empty()) {
        const auto t2 = Clock::now();
        const std::string path = (std::filesystem::path(o.output.outDir) / frameFileName(s.frame)).string();
        if (Status st = render::writePng(path, image); !st) return stop(st);
        s.pngMs = msSince(t2);
      }
      lastPngMs = std::chrono::duration<double, std::milli>(Clock::now() - lastDone).count();
      app.frameShown(s);
      // The panel is drawn: a long window session need not keep its text.
      s.panelLines = {};
      report.frames.push_back(std::move(s));
    }
  }

  /// The render thread's body: the GL context is made, used and destroyed here.
  void renderThread(std::promise<std::vector<Problem>>& ready) {
    auto renderer = render::Renderer::create(renderSettings, app.window());
    if (!renderer) {
      ready.set_value(renderer.problems());
      return;
    }
    rendererName = renderer.value()->glRenderer();
    rendererDetail = renderer.value()->description();
    ready.set_value({});
    consume(*renderer.value());
  }

  Result<FlightReport> run() {
    std::promise<std::vector<Problem>> ready;
    auto readyFuture = ready.get_future();
    std::thread render([&] { renderThread(ready); });
    if (auto problems = readyFuture.get(); !problems.empty()) {
      render.join();
      return problems;
    }
    const world::Pose start = poseAt(o, 0);
    ground.groundEN(start.easting, start.northing);
    world::Pose previous = start;
    double previousT = 0;
    for (std::uint32_t k = 0; k < o.output.frames; ++k) {
      if (!produce(k, previous, previousT)) break;
    }
    handoff.close();
    render.join();
    for (auto& slot : slots) slot.buf.modules.clear();
    if (!renderProblems.empty()) return renderProblems;
    FlightReport& r = report;
    r.summary = summarize(r.frames);
    r.summary.mode = scene ? "modules" : "mesh";
    r.summary.lod = scene ? scene::lodModeName(o.render.lod.mode) : "";
    r.summary.renderer = rendererName;
    r.summary.rendererDetail = rendererDetail;
    r.summary.width = o.view.width;
    r.summary.height = o.view.height;
    if (!o.output.outDir.empty()) {
      const std::string path = (std::filesystem::path(o.output.outDir) / "stats.json").string();
      if (std::string err = writeStats(path, r, o, app.statsSections()); !err.empty()) {
        return Problem{"fly", 0, err};
      }
      r.summary.statsPath = path;
    }
    return std::move(r);
  }
};

render::RenderSettings renderSettingsFor(const FlightOptions& o) {
  render::RenderSettings rs;
  rs.width = o.view.width;
  rs.height = o.view.height;
  rs.background = o.view.background;
  rs.fog = o.view.fog;
  rs.sky = o.view.sky;
  rs.clearColour = o.view.clearColour;
  static_cast<render::DrawChoices&>(rs) = o.render;
  // Synchronous frames are complete frames: nothing waits for a later one.
  rs.uploadBudgetBytes = o.pager.sync ? 0 : o.render.uploadBudgetBytes;
  return rs;
}

std::vector<render::MaterialColour> paletteFor(const materials::Table& t) {
  std::vector<render::MaterialColour> p;
  for (const auto& c : t.classes) {
    if (c.id >= p.size()) p.resize(std::size_t(c.id) + 1);
    const auto rgb = [](std::uint32_t v) {
      return render::Rgb{std::uint8_t(v >> 16), std::uint8_t(v >> 8), std::uint8_t(v)};
    };
    // Roads: the line classes at the road priority; wide ones are marked.
    const bool road = c.kind == materials::Kind::line && c.priority == module::kPriorityRoad;
    p[c.id] = {rgb(c.upperRgb), rgb(c.lowerRgb), road, road && c.width >= kMarkedRoadWidth};
  }
  return p;
}

/// Flies poseAt(options, t): the flight with no application.
class StraightFlight final : public FlightApplication {
 public:
  explicit StraightFlight(const FlightOptions& o) : o_(o) {}
  std::optional<world::Pose> pose(std::uint32_t, double t, world::GroundClamp&) override { return poseAt(o_, t); }

 private:
  const FlightOptions& o_;
};

Result<FlightReport> flyWith(std::shared_ptr<const grid::HeightField> g, const paging::World* world,
                             const FlightOptions& o, FlightApplication* application) {
  const Database* db = world ? &world->database() : nullptr;
  if (!g) return Problem{"fly", 0, "no grid"};
  if (auto problems = checkFlightOptions(g, o, application); !problems.empty()) return problems;
  StraightFlight straight(o);
  FlightApplication& app = application ? *application : straight;
  const bool haveModules = world && world->modules();
  if (o.render.mode == TerrainMode::modules && !haveModules) {
    return Problem{kFlightOptionProblem, 0,
                   "RenderOptions::mode = modules needs load modules (modules.pack), and this database was "
                   "built without them; rebuild it with modules, or fly it with RenderOptions::mode = mesh"};
  }
  const bool modules = haveModules && o.render.mode != TerrainMode::mesh;
  if (!o.output.outDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.output.outDir, ec);
    if (ec) {
      return Problem{kFlightOptionProblem, 0,
                     "cannot create the output directory " + o.output.outDir + ": " + ec.message()};
    }
  }
  render::RenderSettings rs = renderSettingsFor(o);
  rs.grid = g;
  // Icons draw the modules' static objects (unless RenderOptions::objects
  // is off) and the application's entities, in either terrain mode.
  if (db && db->icons) rs.icons = std::make_shared<iconpack::Pack>(*db->icons);
  rs.staticObjects = o.render.objects && modules;
  if (modules && db->materials) {
    rs.palette = paletteFor(*db->materials);
    rs.uncoveredMaterial = db->materials->defaultArea;
  }
  std::unique_ptr<paging::Pager> pager;
  if (modules) {
    paging::PagerOptions po;
    po.viewDistance = effectiveViewDistance(o);
    po.maxViewDistance = std::max(po.viewDistance, o.view.maxViewDistance > 0 ? o.view.maxViewDistance
                                                                        : 3 * po.viewDistance);
    po.loaderThreads = o.pager.loaders;
    po.memoryBudgetBytes = o.pager.budgetBytes;
    // The loaders mesh each level as they publish it (the worker phase);
    // the render thread only copies meshes to the GPU. nodeSquares as
    // ModuleScene derives it.
    const pack::IndexHeader& h = world->modules()->header();
    const auto nodeSquares = std::max<std::uint32_t>(h.moduleSquares >> (std::max<std::uint32_t>(h.levels, 1) - 1), 1);
    po.prepareLevel = render::moduleLevelPreparer(rs, nodeSquares, h.moduleSize);
    auto p = paging::Pager::open(*world, po);
    if (!p) return p.problems();
    pager = std::move(p.value());
  }
  FlightRun run(o, app, g, rs);
  if (pager) {
    scene::ModuleSceneSettings ss;
    ss.lod = o.render.lod;
    ss.imageHeight = o.view.height;
    ss.gridSpacing = g->spacing();
    ss.minElevation = g->elevationBounds().first;
    ss.moduleSquares = world->modules()->header().moduleSquares;
    run.ground = world::GroundClamp(g, ss.moduleSquares, world->modules()->header().levels);
    run.scene = std::make_unique<scene::ModuleScene>(*pager, ss);
    run.pager = pager.get();
    run.readyViewDistance = effectiveViewDistance(o);
  }
  auto result = run.run();
  if (pager) pager->stop();
  return result;
}

}  // namespace

const char* terrainModeName(TerrainMode m) {
  switch (m) {
    case TerrainMode::automatic: return "auto";
    case TerrainMode::mesh: return "mesh";
    case TerrainMode::modules: return "modules";
  }
  return "?";
}

std::vector<std::string> hudLines(const FrameStats& s, const FlightOptions& o) {
  std::vector<std::string> lines;
  lines.push_back("FRAME " + std::to_string(s.frame) + format("  T %.2f S", s.timeS));
  lines.push_back(format("E %.1f  N %.1f", s.easting, s.northing));
  if (s.lon && s.lat) lines.push_back(format("LAT %.5f\xC2\xB0  LON %.5f\xC2\xB0", *s.lat, *s.lon));
  lines.push_back(format("ELEV %.0f M  AGL %.0f M", s.eyeElevation, s.heightAgl) +
                  (s.freeFlight ? "  FREE" : ""));
  lines.push_back(format("HDG %05.1f\xC2\xB0  SPD %.0f KM/H", s.headingDeg, s.speedKmh));
  lines.push_back(format("FOV %.0f\xC2\xB0  VIEW %.0f M", s.hfovDeg > 0 ? s.hfovDeg : o.view.hfovDeg,
                         s.viewDistance > 0 ? s.viewDistance : effectiveViewDistance(o)));
  lines.push_back(format("FPS %.1f  FRAME %.1f MS", s.fps, s.frameMs));
  lines.push_back(format("CPU %.1f MS  DRAW %.1f MS", s.cpuMs, s.renderMs));
  if (s.levelCounts.empty()) {
    lines.push_back("TRIS " + std::to_string(s.triangles) + "  STRIPS " + std::to_string(s.strips));
    lines.insert(lines.end(), s.panelLines.begin(), s.panelLines.end());
    return lines;
  }
  std::string levels;
  for (std::size_t l = 0; l < s.levelCounts.size(); ++l) {
    if (l) levels += '/';
    levels += std::to_string(s.levelCounts[l]);
  }
  lines.push_back("TRIS " + std::to_string(s.triangles));
  lines.push_back(std::string("LOD ") + scene::lodModeName(o.render.lod.mode) + "  LEVELS " + levels);
  lines.push_back("MODULES " + std::to_string(s.modulesDrawn) + "  NODES " +
                  std::to_string(s.nodesDrawn));
  lines.push_back("OBJECTS " + std::to_string(s.objectsDrawn) + "  INST " + std::to_string(s.objectInstances) +
                  "  DRAWS " + std::to_string(s.objectDraws) + "  SPRITES " + std::to_string(s.objectSprites));
  lines.push_back("RESIDENT " +
                  std::to_string(s.residentModules) + "/" + std::to_string(s.windowModules));
  lines.push_back("PAGER QUEUE " + std::to_string(s.pagerQueue));
  lines.insert(lines.end(), s.panelLines.begin(), s.panelLines.end());
  return lines;
}

world::Pose poseAt(const FlightOptions& o, double t) {
  return o.motion.path.size() >= 2 ? pathPose(o.motion.path, t) : straightPose(o, t);
}

std::string frameFileName(std::uint32_t frame) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%05u.png", frame);
  return buf;
}

std::vector<Problem> checkFlightOptions(std::shared_ptr<const grid::GridFile> g,
                                        const FlightOptions& o, const FlightApplication* app) {
  return checkFlightOptions(grid::heightField(std::move(g)), o, app);
}

std::vector<Problem> checkFlightOptions(std::shared_ptr<const grid::HeightField> g,
                                        const FlightOptions& o, const FlightApplication* app) {
  std::vector<Problem> out;
  auto bad = [&](const std::string& msg) { out.push_back({kFlightOptionProblem, 0, msg}); };
  if (o.output.frames == 0) bad("OutputOptions::frames must be at least 1");
  if (o.view.width < 16 || o.view.height < 16 || o.view.width > 16384 || o.view.height > 16384) {
    bad("ViewOptions::width/height must be between 16x16 and 16384x16384");
  }
  if (!(o.view.hfovDeg >= 10 && o.view.hfovDeg <= 90)) bad("ViewOptions::hfovDeg must be between 10 and 90 degrees");
  if (!(o.view.fogDensity >= 0) || !std::isfinite(o.view.fogDensity)) bad("ViewOptions::fogDensity must be >= 0");
  const double vd = effectiveViewDistance(o);
  if (!(vd >= 10 && vd <= 1e6)) {
    bad(o.view.fogDensity > 0 ? "ViewOptions::fogDensity must give a view distance of 10 m .. 1000 km"
                         : "ViewOptions::viewDistance must be 10 m .. 1000 km");
  }
  if (!(o.view.maxViewDistance == 0 || (o.view.maxViewDistance >= vd && o.view.maxViewDistance <= 1e6))) {
    bad("ViewOptions::maxViewDistance must be 0 (3 x ViewOptions::viewDistance) or ViewOptions::viewDistance .. 1000 km");
  }
  if (!(o.motion.pitchDeg >= -89 && o.motion.pitchDeg <= 89)) bad("MotionOptions::pitchDeg must be between -89 and 89 degrees");
  if (!(o.motion.speedKmh >= 0 && o.motion.speedKmh <= 1e5)) bad("MotionOptions::speedKmh must be 0 .. 100000 km/h");
  if (!std::isfinite(o.motion.headingDeg)) bad("MotionOptions::headingDeg must be a number");
  if (!(o.motion.heightAgl >= 0 && o.motion.heightAgl < 1e5)) bad("MotionOptions::heightAgl must be 0 .. 100000 m");
  if (std::string e = scene::checkLodOptions(o.render.lod); !e.empty()) bad(e);
  if (o.pager.loaders < 1 || o.pager.loaders > 4) bad("PagerSettings::loaders must be 1..4");
  if (o.render.samples > 16) bad("RenderOptions::samples must be 0..16 samples");
  if (!(o.render.objectFade >= 0 && o.render.objectFade <= 1)) bad("RenderOptions::objectFade must be 0..1");
  if (!(o.render.impostorPixels >= 0 && o.render.impostorPixels <= 255)) {
    bad("RenderOptions::impostorPixels must be 0..255");
  }
  if (!(o.render.objectThinPixels >= 0 && o.render.objectThinPixels <= 255)) {
    bad("RenderOptions::objectThinPixels must be 0..255");
  }
  const world::Terrain terrain(std::move(g));
  if (o.motion.path.size() == 1) bad("MotionOptions::path needs at least two waypoints");
  if (o.motion.path.size() >= 2) {
    for (std::size_t k = 0; k < o.motion.path.size(); ++k) {
      const Waypoint& w = o.motion.path[k];
      const std::string which = "MotionOptions::path waypoint " + std::to_string(k + 1);
      if (k + 1 < o.motion.path.size() && !(w.speedKmh > 0)) bad(which + ": speed must be positive");
      if (!(w.heightAgl >= 0 && w.heightAgl < 1e5)) bad(which + ": height must be 0 .. 100000 m");
      if (k == 0 && !terrain.sampleEN(w.easting, w.northing)) bad(which + " is outside the database");
    }
  } else if (!app && !terrain.sampleEN(o.motion.easting, o.motion.northing)) {
    bad("the start point is outside the database");
  }
  return out;
}

Result<FlightReport> fly(std::shared_ptr<const grid::HeightField> g, const FlightOptions& o,
                         FlightApplication* app) {
  return flyWith(std::move(g), nullptr, o, app);
}

Result<FlightReport> fly(std::shared_ptr<const grid::GridFile> g, const FlightOptions& o,
                         FlightApplication* app) {
  return flyWith(grid::heightField(std::move(g)), nullptr, o, app);
}

Result<FlightReport> fly(const paging::World& world, const FlightOptions& o, FlightApplication* app) {
  return flyWith(world.heights(), &world, o, app);
}

Result<FlightReport> fly(const Database& db, const FlightOptions& o, FlightApplication* app) {
  const paging::World world(db);
  return fly(world, o, app);
}

std::optional<world::Pose> FlightHooks::pose(std::uint32_t frame, double t, world::GroundClamp& ground) {
  if (onPose) return onPose(frame, t, ground);
  return poseAt(options, t);
}

void FlightHooks::overlay(render::Overlay& overlay, const FrameStats& s) {
  if (onOverlay) onOverlay(overlay, s);
}

bool FlightHooks::wantsFrame(std::uint32_t frame) {
  return onFrame && (!onWantsFrame || onWantsFrame(frame));
}

void FlightHooks::frameDone(std::uint32_t frame, const render::Image& image) {
  if (onFrame) onFrame(frame, image);
}

void FlightHooks::frameContent(std::uint32_t frame, scene::DisplayBuffer& buf, FrameStats& stats) {
  if (onFrameContent) onFrameContent(frame, buf, stats);
}

void FlightHooks::paged(std::uint32_t frame, paging::Pager& pager) {
  if (onPaged) onPaged(frame, pager);
}

}  // namespace sandtable::viewer
