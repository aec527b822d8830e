#pragma once
// The stealth viewer application (`sandtable fly`), a FlightApplication
// (flight.h): the pose source (a path file, the keyboard Controller in a
// window on a fixed-step clock, or the straight line), the 2-D map, the
// window, screenshots and the video; with a scenario (`--scenario`), the
// simulation (sim_session.h) stepped on the same fixed-step clock, its
// entities drawn and shown on the map and the panel, and the eye attached
// to or driving an entity.
//
// Threads: pose() runs on fly()'s main thread (it polls the window's
// keys there); overlay(), frameDone() and frameShown() run on its render
// thread. The window is the renderer's PresentTarget (frames reach it on
// the GPU); frameDone() gets the pixels only of frames a video or a
// screenshot takes. The
// main thread produces a frame or two ahead of the one being drawn, so
// what the render thread needs of the controller's state (map on/off and
// scale, a screenshot request) travels with the frame number through a
// mutex-guarded queue, and each frame is composited with its own state.
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/formats/database.h"
#include "sandtable/world/controls.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/viewer/sim_session.h"
#include "sandtable/render/map_view.h"
#include "sandtable/world/path.h"
#include "sandtable/world/clock.h"
#include "sandtable/world/ground.h"
#include "sandtable/viewer/video.h"
#include "sandtable/viewer/x11_window.h"

namespace sandtable::viewer {

struct FlySessionSettings {
  std::optional<world::Path> path;  ///< fly this instead of a straight line / the keys
  bool freeFlight = false;
  double altitude = 0;                ///< free flight: eye above the datum, metres
  bool map = false;                   ///< map shown at the start
  int mapScale = 0;                   ///< 0 full .. 4 sixteenth
  std::vector<std::uint8_t> waterMaterials{1};
  std::string screenshotDir;          ///< where the screenshot key writes
  /// The largest view distance the keys may ask for (module mode: the one
  /// the pager was opened with, which it cannot grow).
  double maxViewDistance = 200000;
  bool liveViewDistance = true;       ///< false with --fog-density (fog fixes it)
  /// Called on the render thread after each frame is done (e.g. to show
  /// progress); `frame` counts from 0.
  std::function<void(std::uint32_t frame)> onFrameDone;
  /// A scenario's simulation (`--scenario`), or null. Stepped on the
  /// flight's clock: headless, frame k at k / 30 s; in a window, one step
  /// per fixed step of the wall clock.
  std::unique_ptr<SimSession> sim;
  /// Headless frames wait for the wall clock (frame k at k / 30 s after
  /// the first): fly --dis, where remote entities move in real time.
  bool realTimeHeadless = false;
};

/// Per frame, what the render thread needs of the controller's state.
struct FrameControl {
  std::uint32_t frame = 0;
  bool map = false;
  int mapScale = 0;
  bool screenshot = false;
  std::vector<render::MapMark> marks;  ///< the scenario's entities on the map, as of this frame
  bool viewerMarker = true;    ///< false while the eye is attached (its entity's mark is selected)
};

/// Frames go from the main thread to the render thread in order; the
/// render thread takes each frame's entry (and drops older ones).
class FrameControlQueue {
 public:
  void push(const FrameControl& c);
  FrameControl take(std::uint32_t frame);

 private:
  std::mutex m_;
  std::deque<FrameControl> q_;
  FrameControl last_;
};

class FlySession final : public FlightApplication {
 public:
  /// `window` and `video` may be null (headless, no video). `o` must be
  /// the flight's options (start, heading, speed, height, FOV...).
  FlySession(const paging::World& world, FlySessionSettings settings, const FlightOptions& o,
             std::unique_ptr<ViewerWindow> window,
             std::unique_ptr<VideoWriter> video);

  std::optional<world::Pose> pose(std::uint32_t frame, double t, world::GroundClamp& ground) override;
  void overlay(render::Overlay& overlay, const FrameStats& s) override;
  bool wantsFrame(std::uint32_t frame) override;
  void frameDone(std::uint32_t frame, const render::Image& img) override;
  void frameShown(const FrameStats& s) override;
  render::PresentTarget* window() override;
  void frameContent(std::uint32_t frame, scene::DisplayBuffer& buf, FrameStats& stats) override;
  std::vector<std::pair<std::string, std::string>> statsSections() override;
  /// The scenario's simulation, or null.
  const SimSession* sim() const { return settings_.sim.get(); }
  /// After fly(): finishes the video; the first error of the flight's
  /// screenshots or video.
  Status finish();
  std::uint32_t screenshotsTaken() const { return screenshots_.load(); }
  bool windowed() const { return window_ != nullptr; }

 private:
  double pollKeys();  ///< window: handles the keys, returns the wall-clock time since the last poll
  /// The stealth eye's controller again from `p` (after detaching).
  void reseedController(const world::Pose& p);
  world::Pose headlessPose(double t);
  world::Pose windowPose(double clock) const;
  void saveScreenshot(const render::Image& img);
  void fail(const Status& st);
  world::ViewerState initialState(const FlightOptions& o) const;

  const paging::World& world_;
  FlySessionSettings settings_;
  const FlightOptions& options_;
  /// The viewer's own copy of the flight's ground clamp (same surface; the
  /// level drawn under the eye is copied from the flight's each frame).
  world::GroundClamp ground_;
  std::unique_ptr<ViewerWindow> window_;
  std::unique_ptr<VideoWriter> video_;
  // main thread
  std::optional<world::Controller> controller_;
  bool quitAfterThisFrame_ = false, quitting_ = false;
  world::FixedStepClock clock_;  ///< window: flight time, advanced in fixed steps of the wall clock
  std::optional<double> lastWall_;
  std::optional<double> paceStart_;  ///< realTimeHeadless: the wall time of flight time 0
  world::Pose lastPose_;  ///< the pose of the last frame (a detached eye starts there)
  // render thread
  std::unique_ptr<render::MapView> map_;
  FrameControl current_;
  std::uint32_t nextShot_ = 0;
  // shared
  FrameControlQueue controls_;
  std::atomic<bool> failed_{false};
  std::atomic<std::uint32_t> screenshots_{0};
  std::mutex errorMutex_;
  Status error_;
};

/// Water material indices from the database's material table (manifest
/// build.materials names containing "water"); {1} (docs/FORMAT.md 4.7)
/// when it lists none.
std::vector<std::uint8_t> waterMaterials(const Database& db);

}  // namespace sandtable::viewer
