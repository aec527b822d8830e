#include "sandtable/viewer/fly_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "sandtable/render/hud.h"
#include "sandtable/scene/camera_math.h"

namespace sandtable::viewer {
namespace {

using world::Pose;

/// The ground clamp of a database: modules' lattices when it has them.
world::GroundClamp groundOf(const paging::World& world) {
  if (!world.modules()) return world::GroundClamp(world.heights());
  const auto& h = world.modules()->header();
  return world::GroundClamp(world.heights(), h.moduleSquares, h.levels);
}

double wallSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string screenshotName(std::uint32_t n) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "screenshot_%04u.png", n);
  return buf;
}

}  // namespace

void FrameControlQueue::push(const FrameControl& c) {
  std::lock_guard lock(m_);
  q_.push_back(c);
}

FrameControl FrameControlQueue::take(std::uint32_t frame) {
  std::lock_guard lock(m_);
  while (!q_.empty() && q_.front().frame <= frame) {
    last_ = q_.front();
    q_.pop_front();
    if (last_.frame == frame) return last_;
  }
  // Not queued (cannot happen while frames stay in order): keep the last
  // state, but never repeat its screenshot.
  FrameControl c = last_;
  c.frame = frame;
  c.screenshot = false;
  return c;
}

std::vector<std::uint8_t> waterMaterials(const Database& db) {
  std::vector<std::uint8_t> out;
  const auto& build = db.manifest.build;
  if (build.is_object() && build.contains("materials") && build["materials"].is_object()) {
    for (const auto& [key, name] : build["materials"].items()) {
      if (!name.is_string() || name.get<std::string>().find("water") == std::string::npos) continue;
      try {
        const int id = std::stoi(key);
        if (id >= 0 && id < 256) out.push_back(std::uint8_t(id));
      } catch (const std::exception&) {
        // A non-numeric key is not a grid material index; ignore it.
      }
    }
  }
  if (out.empty()) out.push_back(1);
  return out;
}

FlySession::FlySession(const paging::World& world, FlySessionSettings settings, const FlightOptions& o,
                       std::unique_ptr<ViewerWindow> window,
                       std::unique_ptr<VideoWriter> video)
    : world_(world),
      settings_(std::move(settings)),
      options_(o),
      ground_(groundOf(world)),
      window_(std::move(window)),
      video_(std::move(video)) {
  ground_.groundEN(o.motion.easting, o.motion.northing);
  // The world's one clock: the simulation's step, which the eye's keys share.
  if (settings_.sim) clock_ = world::FixedStepClock(settings_.sim->stepS());
  if (window_) {
    world::ControllerSettings cs;
    cs.maxFovDeg = 90;  // the view triangle's limit (flight.h): 0 would ask 100
    cs.maxViewDistance = settings_.maxViewDistance;
    cs.minViewDistance = std::min(cs.minViewDistance, o.view.viewDistance);
    auto ground = [this](double e, double n) { return ground_.surfaceEN(e, n, ground_.drawn()); };
    controller_.emplace(initialState(o), ground, cs);
  }
}

world::ViewerState FlySession::initialState(const FlightOptions& o) const {
  world::ViewerState s;
  s.easting = o.motion.easting;
  s.northing = o.motion.northing;
  s.headingDeg = o.motion.headingDeg;
  s.pitchDeg = o.motion.pitchDeg;
  s.speedMs = o.motion.speedKmh / 3.6;
  s.heightAgl = o.motion.heightAgl;
  s.groundFollowing = !settings_.freeFlight;
  s.eyeElevation = settings_.altitude;
  s.hfovDeg = o.view.hfovDeg;
  s.viewDistance = std::min(o.view.viewDistance, settings_.maxViewDistance);
  s.mapVisible = settings_.map;
  s.mapScale = settings_.mapScale;
  return s;
}

bool FlySession::wantsFrame(std::uint32_t) {
  // The window presents on the GPU; only a video or a screenshot needs the
  // frame's pixels back.
  return video_ != nullptr || current_.screenshot;
}

render::PresentTarget* FlySession::window() { return window_.get(); }

void FlySession::frameShown(const FrameStats& s) {
  if (settings_.onFrameDone) settings_.onFrameDone(s.frame);
}

void FlySession::reseedController(const world::Pose& p) {
  world::ViewerState s = controller_->state();
  s.easting = p.easting;
  s.northing = p.northing;
  s.headingDeg = p.headingDeg;
  s.pitchDeg = p.pitchDeg.value_or(s.pitchDeg);
  s.speedMs = 0;  // the stealth eye stops where the tether left it
  s.heightAgl = p.heightAgl;
  s.eyeElevation = p.altitude.value_or(s.eyeElevation);
  const world::ControllerSettings cs = controller_->settings();
  auto ground = [this](double e, double n) { return ground_.surfaceEN(e, n, ground_.drawn()); };
  controller_.emplace(s, ground, cs);
}

double FlySession::pollKeys() {
  SimSession* sim = settings_.sim.get();
  const std::vector<world::KeyEvent> events = window_->pollEvents();
  if (sim) {
    for (const ViewerKey k : window_->takeViewerKeys()) {
      const ViewMode before = sim->mode();
      sim->handle(k);
      if (before != ViewMode::stealth && sim->mode() == ViewMode::stealth) reseedController(lastPose_);
    }
  }
  for (const auto& e : events) {
    // Attached or driving, the arrows and pages steer the tether or the
    // entity; a release always reaches both, so no key stays held.
    if (sim && (sim->steers(e.key) || (!e.pressed && sim->mode() != ViewMode::stealth))) {
      sim->handle(e);
      if (!e.pressed) controller_->handle(e);
      continue;
    }
    controller_->handle(e);
    if (sim && !e.pressed) sim->handle(e);
  }
  if (controller_->quitRequested() || window_->closeRequested()) quitAfterThisFrame_ = true;
  const double now = wallSeconds();
  const double dt = lastWall_ ? std::max(0.0, now - *lastWall_) : 0.0;
  lastWall_ = now;
  return dt;
}

world::Pose FlySession::headlessPose(double t) {
  world::Pose p = settings_.path ? world::samplePath(*settings_.path, t) : poseAt(options_, t);
  if (settings_.freeFlight) {
    // As the Controller does: free flight keeps its altitude but never goes
    // below 1 m above the ground (past the edge: the last ground seen).
    p.altitude = world::GroundClamp::eyeElevation(ground_.groundEN(p.easting, p.northing), 0,
                                           settings_.altitude, 1.0);
  }
  return p;
}

world::Pose FlySession::windowPose(double clock) const {
  const world::ViewerState& s = controller_->state();
  world::Pose p;
  if (settings_.path) {
    // The path drives the eye; the keys still set FOV, view distance and map.
    p = world::samplePath(*settings_.path, clock);
  } else {
    p = controller_->pose();
    if (!s.groundFollowing) p.altitude = s.eyeElevation;
  }
  p.hfovDeg = s.hfovDeg;
  if (settings_.liveViewDistance) p.viewDistance = s.viewDistance;
  return p;
}

std::optional<world::Pose> FlySession::pose(std::uint32_t frame, double t, world::GroundClamp& ground) {
  ground_.setDrawn(ground.drawn());
  // q, Escape or closing the window: the frame with the keys pressed before
  // it is still drawn (so a last change shows), then the flight ends.
  if (failed_.load() || quitting_) return std::nullopt;
  FrameControl fc{frame, settings_.map, settings_.mapScale, false, {}, true};
  SimSession* sim = settings_.sim.get();
  world::Pose p;
  if (window_) {
    // The world advances in fixed steps of the wall clock (world/clock.h),
    // so key repeats, turns and the simulation do not depend on the frame rate.
    for (std::uint32_t n = clock_.advance(pollKeys()); n > 0; --n) {
      controller_->advance(clock_.stepS());
      if (sim) sim->step();
    }
    if (sim) sim->sample();
    p = windowPose(clock_.timeS());
    if (sim && sim->mode() != ViewMode::stealth) {
      // The tether replaces the eye's own motion; FOV and view distance stay the keys'.
      const world::Pose tether = sim->tetherPose(ground);
      const std::optional<double> fov = p.hfovDeg, view = p.viewDistance;
      p = tether;
      p.hfovDeg = fov;
      p.viewDistance = view;
    }
    p.clockS = clock_.timeS();
    fc.map = controller_->state().mapVisible;
    fc.mapScale = controller_->state().mapScale;
    fc.screenshot = controller_->takeScreenshotRequest();
    quitting_ = quitAfterThisFrame_;
  } else {
    if (sim) {
      if (settings_.realTimeHeadless) {
        // On a network the simulation keeps the exercise's time: frame k
        // waits for k / 30 s of the wall clock (a slow frame is caught up).
        if (!paceStart_) paceStart_ = wallSeconds() - t;
        const double wait = *paceStart_ + t - wallSeconds();
        if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
      }
      // Frame k shows the world at k / 30 s: whole steps, so a headless
      // flight replays the same simulation frame for frame.
      sim->advanceToFlightTime(t);
      sim->sample();
    }
    p = sim && sim->mode() != ViewMode::stealth ? sim->tetherPose(ground) : headlessPose(t);
  }
  if (sim) {
    fc.marks = sim->mapMarks();
    fc.viewerMarker = sim->mode() == ViewMode::stealth;
  }
  controls_.push(fc);
  lastPose_ = p;
  return p;
}

namespace {

/// Each label's point on the frame, where it is in front of the eye.
std::vector<FrameStats::ScreenLabel> project(const std::vector<EntityLabel>& labels, const scene::DisplayBuffer& buf,
                                             std::uint32_t width, std::uint32_t height) {
  std::vector<FrameStats::ScreenLabel> out;
  const Eigen::Matrix4d m = scene::viewProjection(buf.camera, buf.originX, buf.originZ);
  for (const EntityLabel& l : labels) {
    const Eigen::Vector4d c = m * Eigen::Vector4d(l.position.x() - buf.originX, l.position.y(),
                                                  l.position.z() - buf.originZ, 1.0);
    if (c.w() <= 1e-6) continue;
    const double x = c.x() / c.w(), y = c.y() / c.w();
    if (std::abs(x) > 1.05 || std::abs(y) > 1.05) continue;  // off the frame
    FrameStats::ScreenLabel s;
    s.x = int(std::lround((x * 0.5 + 0.5) * width));
    s.y = int(std::lround((0.5 - y * 0.5) * height));
    s.text = l.text;
    s.rgb = l.alive ? render::forceColour(l.force) : render::deadColour(l.force);
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace

void FlySession::frameContent(std::uint32_t, scene::DisplayBuffer& buf, FrameStats& stats) {
  if (!settings_.sim) return;
  settings_.sim->setDrawn(std::make_shared<const scene::DrawnLevels>(buf));
  settings_.sim->fill(buf.dynamic);
  stats.panelLines = settings_.sim->panelLines();
  const Eigen::Vector3d eye(buf.camera.x, buf.camera.y, buf.camera.z);
  stats.labels = project(settings_.sim->labels(eye), buf, options_.view.width, options_.view.height);
  stats.extraJson.emplace_back("sim", settings_.sim->frameJson());
}

std::vector<std::pair<std::string, std::string>> FlySession::statsSections() {
  if (!settings_.sim) return {};
  return {{"sim", settings_.sim->summaryJson()}};
}

namespace {

bool overlaps(const render::PixelBox& a, const render::PixelBox& b) {
  return !a.empty() && !b.empty() && a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height &&
         b.y < a.y + a.height;
}

/// The labels, nearest first; one that would cover the panel or a nearer
/// label is left out, so a crowd far away does not turn into a smudge.
void drawLabels(render::Overlay& overlay, const FrameStats& s) {
  const int scale = overlay.layer().width >= 1600 ? 2 : 1;
  constexpr std::size_t kMaxLabelsDrawn = 64;
  std::vector<render::PixelBox> taken{s.hudPanel};
  for (const FrameStats::ScreenLabel& l : s.labels) {
    if (taken.size() > kMaxLabelsDrawn) break;
    const int w = render::textWidth(l.text, scale), h = render::kGlyphHeight * scale;
    const render::PixelBox box{l.x - w / 2 - 1, l.y - h - 1, w + 2, h + 2};
    if (std::any_of(taken.begin(), taken.end(), [&](const render::PixelBox& t) { return overlaps(t, box); })) continue;
    taken.push_back(box);
    // A dark outline under the force's colour reads on sky and ground alike.
    for (const auto& [dx, dy] : {std::pair{-1, 0}, {1, 0}, {0, -1}, {0, 1}}) {
      render::drawText(overlay.layer(), box.x + 1 + dx, box.y + 1 + dy, l.text, scale, {0, 0, 0});
    }
    render::drawText(overlay.layer(), box.x + 1, box.y + 1, l.text, scale, l.rgb);
    overlay.drawn(box);
  }
}

}  // namespace

void FlySession::overlay(render::Overlay& overlay, const FrameStats& s) {
  current_ = controls_.take(s.frame);
  drawLabels(overlay, s);
  if (!current_.map) return;
  if (!map_) {
    // Built here, on the render thread that uses it (MapView caches per thread).
    render::MapOptions mo;
    mo.waterMaterials = settings_.waterMaterials;
    // The red force's arrows would read as the viewer's own: his turns yellow.
    if (settings_.sim) mo.markerFill = {255, 220, 0};
    map_ = std::make_unique<render::MapView>(world_.heights(), mo);
    map_->setVisible(true);
  }
  map_->setScale(current_.mapScale);
  double x = 0, z = 0;
  x = s.easting - world_.heights()->originEasting();
  z = world_.heights()->originNorthing() - s.northing;
  const render::MapLayout box =
      map_->compose(overlay.layer(), x, z, s.headingDeg, current_.marks, current_.viewerMarker);
  // The map, its label and marker inside a one-pixel border.
  if (box.drawn) overlay.drawn({box.x - 1, box.y - 1, box.width + 2, box.height + 2});
}

void FlySession::frameDone(std::uint32_t, const render::Image& img) {
  if (current_.screenshot) saveScreenshot(img);
  if (video_) {
    if (Status st = video_->write(img); !st) fail(st);
  }
}

void FlySession::saveScreenshot(const render::Image& img) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(settings_.screenshotDir, ec);
  if (ec) {
    fail(Problem{"screenshot", 0,
                 "screenshot: cannot create " + settings_.screenshotDir + ": " + ec.message() +
                     " (give a writable FlySessionSettings::screenshotDir)"});
    return;
  }
  // Never overwrite the screenshots of an earlier flight.
  fs::path file;
  do {
    file = fs::path(settings_.screenshotDir) / screenshotName(nextShot_++);
  } while (fs::exists(file, ec));
  if (Status st = render::writePng(file.string(), img); !st) {
    fail(Problem{"screenshot", 0, "screenshot: " + st.problems().front().message});
    return;
  }
  ++screenshots_;
  std::printf("sandtable fly: screenshot %s\n", file.string().c_str());
  std::fflush(stdout);
}

void FlySession::fail(const Status& st) {
  std::lock_guard lock(errorMutex_);
  if (error_.ok()) error_ = st;
  failed_ = true;
}

Status FlySession::finish() {
  if (video_) {
    if (Status st = video_->finish(); !st) fail(st);
  }
  std::lock_guard lock(errorMutex_);
  return error_;
}

}  // namespace sandtable::viewer
