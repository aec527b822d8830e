#include "sandtable/world/controls.h"

#include "sandtable/world/ground.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace sandtable::world {
namespace {

constexpr double kMsToKmh = 3.6;

bool isStepped(Key k) { return k == Key::up || k == Key::down; }
bool isContinuous(Key k) {
  return k == Key::left || k == Key::right || k == Key::pageUp || k == Key::pageDown;
}

}  // namespace

const char* keyName(Key k) {
  static constexpr std::array<const char*, kKeyCount> names = {
      "Up",     "Down",   "Left",   "Right",  "Digit0",     "Digit1",    "Digit2",
      "Digit3", "Digit4", "Digit5", "Digit6", "Digit7",     "Digit8",    "Digit9",
      "Plus",   "Minus",  "Map",    "MapZoomOut", "MapZoomIn", "PageUp", "PageDown",
      "GroundFollow", "Screenshot", "Quit"};
  return names[std::size_t(k)];
}

std::optional<double> fovForKey(Key k) {
  const int d = int(k) - int(Key::digit0);
  if (d < 0 || d > 9) return std::nullopt;
  return d == 0 ? 100.0 : 10.0 * d;
}

Controller::Controller(ViewerState initial, GroundElevationFn ground, ControllerSettings settings)
    : state_(initial), ground_(std::move(ground)), settings_(settings) {
  state_.speedMs = std::clamp(state_.speedMs, settings_.minSpeedMs, settings_.maxSpeedMs);
  state_.viewDistance =
      std::clamp(state_.viewDistance, settings_.minViewDistance, settings_.maxViewDistance);
  state_.mapScale = std::clamp(state_.mapScale, 0, kMapScaleCount - 1);
  setHeading(state_.headingDeg);
  state_.groundElevation = groundAt(state_.easting, state_.northing);
  followGround();
}

double Controller::groundAt(double e, double n) {
  if (!ground_) return 0;
  // Off the database the eye keeps the last ground it saw, as flight.h does,
  // so flying past the edge neither drops nor lifts it.
  if (auto g = ground_(e, n)) return *g;
  return state_.groundElevation;
}

void Controller::followGround() {
  // Free flight keeps its altitude, but the ground pushes the eye up
  // rather than letting it fly inside a hill (ground.h: the one clamp).
  const std::optional<double> altitude =
      state_.groundFollowing ? std::nullopt : std::optional<double>(state_.eyeElevation);
  state_.eyeElevation = GroundClamp::eyeElevation(state_.groundElevation, state_.heightAgl, altitude,
                                                  settings_.minHeightAglM);
  state_.heightAgl = state_.eyeElevation - state_.groundElevation;
}

void Controller::setHeading(double deg) {
  deg = std::fmod(deg, 360.0);
  if (deg < 0) deg += 360.0;
  state_.headingDeg = deg;
}

void Controller::stepSpeed(double sign) {
  state_.speedMs = std::clamp(state_.speedMs + sign * settings_.speedStepMs, settings_.minSpeedMs,
                              settings_.maxSpeedMs);
}

void Controller::stepHeight(double metres) {
  if (state_.groundFollowing) {
    state_.heightAgl += metres;
  } else {
    state_.eyeElevation += metres;
  }
  followGround();
}

void Controller::handle(const std::vector<KeyEvent>& events) {
  for (const auto& e : events) handle(e);
}

void Controller::handle(const KeyEvent& e) {
  Hold& h = held_[std::size_t(e.key)];
  if (!e.pressed) {
    h = Hold{};
    return;
  }
  if (h.down) return;  // auto-repeat: advance() does the repeating
  h = Hold{true, 0, settings_.repeatDelayS};
  press(e.key);
}

void Controller::press(Key k) {
  if (auto fov = fovForKey(k)) {
    state_.hfovDeg = std::clamp(*fov, settings_.minFovDeg, settings_.maxFovDeg);
    return;
  }
  switch (k) {
    case Key::up: stepSpeed(+1); break;
    case Key::down: stepSpeed(-1); break;
    case Key::left: setHeading(state_.headingDeg - settings_.turnStepDeg); break;
    case Key::right: setHeading(state_.headingDeg + settings_.turnStepDeg); break;
    case Key::pageUp: stepHeight(+settings_.climbStepM); break;
    case Key::pageDown: stepHeight(-settings_.climbStepM); break;
    case Key::plus:
      state_.viewDistance = std::min(state_.viewDistance * settings_.viewDistanceFactor,
                                     settings_.maxViewDistance);
      break;
    case Key::minus:
      state_.viewDistance = std::max(state_.viewDistance / settings_.viewDistanceFactor,
                                     settings_.minViewDistance);
      break;
    case Key::map: state_.mapVisible = !state_.mapVisible; break;
    case Key::mapZoomIn: state_.mapScale = std::min(state_.mapScale + 1, kMapScaleCount - 1); break;
    case Key::mapZoomOut: state_.mapScale = std::max(state_.mapScale - 1, 0); break;
    case Key::groundFollow:
      // Keep the eye where it is; only what is held constant changes.
      state_.groundFollowing = !state_.groundFollowing;
      state_.heightAgl = state_.eyeElevation - state_.groundElevation;
      followGround();
      break;
    case Key::screenshot: ++screenshots_; break;
    case Key::quit: quit_ = true; break;
    default: break;
  }
}

void Controller::advanceHeld(double dt) {
  for (std::size_t i = 0; i < kKeyCount; ++i) {
    Hold& h = held_[i];
    if (!h.down) continue;
    const Key k = Key(i);
    const double before = h.heldS;
    h.heldS += dt;
    if (isStepped(k)) {
      while (h.heldS >= h.nextRepeatS) {
        stepSpeed(k == Key::up ? +1 : -1);
        h.nextRepeatS += settings_.repeatIntervalS;
      }
    } else if (isContinuous(k)) {
      const double moving = std::max(0.0, h.heldS - std::max(before, settings_.repeatDelayS));
      if (moving <= 0) continue;
      if (k == Key::left) setHeading(state_.headingDeg - settings_.turnRateDegS * moving);
      if (k == Key::right) setHeading(state_.headingDeg + settings_.turnRateDegS * moving);
      if (k == Key::pageUp) stepHeight(+settings_.climbRateMS * moving);
      if (k == Key::pageDown) stepHeight(-settings_.climbRateMS * moving);
    }
  }
}

void Controller::advance(double dt) {
  if (!(dt > 0)) return;
  advanceHeld(dt);
  const double h = state_.headingDeg * std::numbers::pi / 180.0;
  state_.easting += std::sin(h) * state_.speedMs * dt;
  state_.northing += std::cos(h) * state_.speedMs * dt;
  state_.groundElevation = groundAt(state_.easting, state_.northing);
  followGround();
}

Pose Controller::pose() const {
  Pose p;
  p.easting = state_.easting;
  p.northing = state_.northing;
  p.headingDeg = state_.headingDeg;
  p.heightAgl = state_.heightAgl;
  p.speedKmh = state_.speedMs * kMsToKmh;
  return p;
}

std::vector<std::string> controllerPanelLines(const ViewerState& s) {
  char buf[4][96];
  std::snprintf(buf[0], sizeof buf[0], "SPEED %.1f M/S (%.0f KM/H)", s.speedMs, s.speedMs * kMsToKmh);
  // Rounded first so 359.7 reads 000, not 360.
  std::snprintf(buf[1], sizeof buf[1], "HEADING %03ld\xC2\xB0", std::lround(s.headingDeg) % 360);
  if (s.groundFollowing) {
    std::snprintf(buf[2], sizeof buf[2], "GROUND-FOLLOW %.0f M ABOVE GROUND", s.heightAgl);
  } else {
    std::snprintf(buf[2], sizeof buf[2], "FREE FLIGHT %.0f M (%.0f M ABOVE GROUND)", s.eyeElevation,
                  s.heightAgl);
  }
  std::snprintf(buf[3], sizeof buf[3], "FOV %.0f\xC2\xB0 VIEW %.0f M", s.hfovDeg, s.viewDistance);
  return {buf[0], buf[1], buf[2], buf[3]};
}

}  // namespace sandtable::world
