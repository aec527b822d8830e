#pragma once
// The stealth viewer's controls (seed chapter VI B 2, "User Input
// Management"): a pure state machine fed with key events and advanced by
// simulated time. It knows nothing of windows or GL, so it runs the same
// from an X11 window (x11_window.h), a test, or a scripted replay.
//
// Keys (docs/PATH.md lists them for users too):
//   Up / Down        speed +5 / -5 m/s per press. The speed HOLDS when no
//                    key is pressed (seed VI.B.2: "the entity's speed is
//                    assumed to be constant without user input").
//                    Held: one more step after repeatDelayS, then one
//                    every repeatIntervalS (defaults 0.4 s, 0.1 s: a held
//                    key adds 50 m/s per second).
//   Left / Right     heading -/+ turnStepDeg at once; held past
//                    repeatDelayS the heading turns at turnRateDegS.
//   PageUp/PageDown  height +/- climbStepM at once; held past repeatDelayS
//                    the eye climbs at climbRateMS. Ground-following: the
//                    height above ground; free flight: the altitude.
//   1 .. 9, 0        horizontal field of view: digit d is d * 10 degrees
//                    (1 = 10 deg ... 9 = 90 deg), 0 is 100 deg.
//   + / -            view distance times / divided by viewDistanceFactor
//                    (sqrt 2: two presses double it), clamped to
//                    [minViewDistance, maxViewDistance].
//   M                2-D map on / off.
//   [ / ]            map scale out / in (full, half, ..., sixteenth).
//   F                ground-following <-> free flight; the eye does not
//                    jump: it keeps its current altitude.
//   P / F12          screenshot (takeScreenshotRequest(); the caller saves it).
//   Escape / Q       quit (quitRequested()).
//
// A press of a key that is already held is ignored: X11 key auto-repeat
// (or a stuck event) must not add extra steps; repeats come from advance().
//
// Frame: projected easting / northing of the database CRS (as Pose and
// FlightOptions), heading clockwise from grid north, metres and seconds.
//
// Thread safety: a plain value type; use one Controller from one thread.
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/world/pose.h"

namespace sandtable::world {

enum class Key : std::uint8_t {
  up, down, left, right,
  digit0, digit1, digit2, digit3, digit4, digit5, digit6, digit7, digit8, digit9,
  plus, minus,
  map,         ///< M
  mapZoomOut,  ///< [
  mapZoomIn,   ///< ]
  pageUp, pageDown,
  groundFollow,  ///< F
  screenshot,    ///< P or F12
  quit,          ///< Escape or Q
};
inline constexpr std::size_t kKeyCount = std::size_t(Key::quit) + 1;

/// "Up", "Digit5", "PageUp", ... for logs and test messages.
const char* keyName(Key k);

struct KeyEvent {
  Key key = Key::up;
  bool pressed = true;  ///< false: released
  bool operator==(const KeyEvent&) const = default;
};

/// Map scales (seed VI B: "full, half, quarter, eighth, and sixteenth").
inline constexpr int kMapScaleCount = 5;

struct ControllerSettings {
  double speedStepMs = 5;  ///< seed VI.B.2: "the up arrow key adds five meters per second"
  double minSpeedMs = 0;
  double maxSpeedMs = 1000;
  double repeatDelayS = 0.4;
  double repeatIntervalS = 0.1;
  double minFovDeg = 10;  ///< digit keys are clamped into [minFovDeg, maxFovDeg]
  double maxFovDeg = 100;
  double turnStepDeg = 2;
  double turnRateDegS = 45;
  double climbStepM = 10;
  double climbRateMS = 100;
  double minHeightAglM = 1;  ///< also the free-flight floor above the ground
  double viewDistanceFactor = 1.4142135623730951;
  double minViewDistance = 500;
  double maxViewDistance = 200000;
};

/// Everything the flight loop needs to draw one frame.
struct ViewerState {
  double easting = 0, northing = 0;
  double headingDeg = 0;  ///< [0, 360), clockwise from grid north
  double pitchDeg = -10;
  double speedMs = 0;
  double heightAgl = 300;     ///< eye above the ground under it
  double eyeElevation = 300;  ///< eye above the vertical datum
  double groundElevation = 0; ///< last ground seen under the eye
  double hfovDeg = 60;
  double viewDistance = 10000;
  bool groundFollowing = true;
  bool mapVisible = false;
  int mapScale = 0;  ///< 0 full .. 4 sixteenth (map_view.h)
};

/// Ground elevation at (easting, northing); nullopt off the database.
using GroundElevationFn = std::function<std::optional<double>(double easting, double northing)>;

class Controller {
 public:
  /// `initial.eyeElevation` is recomputed from the ground (ground
  /// following) or kept (free flight). An empty `ground` is flat at 0 m.
  Controller(ViewerState initial, GroundElevationFn ground, ControllerSettings settings = {});

  /// Applies one key event at the current instant.
  void handle(const KeyEvent& e);
  void handle(const std::vector<KeyEvent>& events);
  /// Advances simulated time by dt seconds (dt >= 0): held-key repeats,
  /// turning, climbing, then motion along the heading at the held speed.
  void advance(double dt);

  const ViewerState& state() const { return state_; }
  const ControllerSettings& settings() const { return settings_; }
  bool held(Key k) const { return held_[std::size_t(k)].down; }
  bool quitRequested() const { return quit_; }
  /// True once per press of the screenshot key since the last call.
  bool takeScreenshotRequest() {
    const bool r = screenshots_ > 0;
    if (r) --screenshots_;
    return r;
  }
  /// The state as a flight.h Pose (speed in km/h).
  Pose pose() const;

 private:
  struct Hold {
    bool down = false;
    double heldS = 0;       ///< time since the press
    double nextRepeatS = 0; ///< stepped keys: when the next step is due
  };
  void press(Key k);
  void stepSpeed(double sign);
  void stepHeight(double metres);
  void setHeading(double deg);
  void followGround();
  double groundAt(double e, double n);
  void advanceHeld(double dt);

  ViewerState state_;
  GroundElevationFn ground_;
  ControllerSettings settings_;
  std::array<Hold, kKeyCount> held_{};
  bool quit_ = false;
  int screenshots_ = 0;
};

/// Field of view for a digit key (1 -> 10 deg ... 9 -> 90, 0 -> 100);
/// nullopt for any other key.
std::optional<double> fovForKey(Key k);

/// Panel lines for the viewer's state, e.g. "SPEED 15.0 M/S (54 KM/H)";
/// the flight loop adds them to its drawHudPanel lines.
std::vector<std::string> controllerPanelLines(const ViewerState& s);

}  // namespace sandtable::world
