// The stealth viewer's key state machine: speed steps that hold (seed
// VI.B.2), held-key repeats, FOV keys, view distance clamps, the map keys,
// ground following and free flight.
#include <gtest/gtest.h>

#include <cmath>

#include "sandtable/world/controls.h"

namespace sandtable::world {
namespace {

KeyEvent press(Key k) { return {k, true}; }
KeyEvent release(Key k) { return {k, false}; }

void tap(Controller& c, Key k) {
  c.handle(press(k));
  c.handle(release(k));
}

ViewerState start() {
  ViewerState s;
  s.easting = 1000;
  s.northing = 2000;
  s.headingDeg = 90;  // east
  s.heightAgl = 100;
  return s;
}

/// A slope rising 1 m per metre east of easting 1000.
std::optional<double> slope(double e, double) { return std::max(0.0, e - 1000); }

TEST(Controls, UpAddsFiveMetresPerSecondAndTheSpeedHolds) {
  Controller c(start(), {});
  EXPECT_EQ(c.state().speedMs, 0);
  tap(c, Key::up);
  EXPECT_DOUBLE_EQ(c.state().speedMs, 5);
  tap(c, Key::up);
  EXPECT_DOUBLE_EQ(c.state().speedMs, 10);
  // No key for ten seconds: still 10 m/s, and the eye moved 100 m east.
  for (int k = 0; k < 100; ++k) c.advance(0.1);
  EXPECT_DOUBLE_EQ(c.state().speedMs, 10);
  EXPECT_NEAR(c.state().easting, 1100, 1e-9);
  EXPECT_NEAR(c.state().northing, 2000, 1e-9);
  tap(c, Key::down);
  EXPECT_DOUBLE_EQ(c.state().speedMs, 5);
}

TEST(Controls, SpeedClampsAtItsLimits) {
  ControllerSettings s;
  s.maxSpeedMs = 12;
  Controller c(start(), {}, s);
  tap(c, Key::down);
  EXPECT_EQ(c.state().speedMs, 0);
  for (int k = 0; k < 5; ++k) tap(c, Key::up);
  EXPECT_EQ(c.state().speedMs, 12);
}

TEST(Controls, HeldUpRepeatsAfterTheDelayAtTheInterval) {
  Controller c(start(), {});  // delay 0.4 s, interval 0.1 s
  c.handle(press(Key::up));
  EXPECT_DOUBLE_EQ(c.state().speedMs, 5);
  c.advance(0.3);
  EXPECT_DOUBLE_EQ(c.state().speedMs, 5);  // before the delay
  c.advance(0.1);                          // at 0.4 s
  EXPECT_DOUBLE_EQ(c.state().speedMs, 10);
  c.advance(0.25);                         // 0.5 and 0.6 s
  EXPECT_DOUBLE_EQ(c.state().speedMs, 20);
  // Auto-repeat presses from the window add nothing.
  c.handle(press(Key::up));
  c.handle(press(Key::up));
  EXPECT_DOUBLE_EQ(c.state().speedMs, 20);
  c.handle(release(Key::up));
  c.advance(1.0);
  EXPECT_DOUBLE_EQ(c.state().speedMs, 20);
  EXPECT_FALSE(c.held(Key::up));
}

TEST(Controls, LeftAndRightTurnAStepThenAtTheTurnRate) {
  Controller c(start(), {});  // step 2 deg, 45 deg/s after 0.4 s
  c.handle(press(Key::right));
  EXPECT_DOUBLE_EQ(c.state().headingDeg, 92);
  c.advance(1.4);  // 1.0 s past the delay
  EXPECT_NEAR(c.state().headingDeg, 92 + 45, 1e-9);
  c.handle(release(Key::right));
  c.advance(1.0);
  EXPECT_NEAR(c.state().headingDeg, 137, 1e-9);
  // Turning left past north wraps to [0, 360).
  ViewerState s = start();
  s.headingDeg = 1;
  Controller d(s, {});
  tap(d, Key::left);
  EXPECT_NEAR(d.state().headingDeg, 359, 1e-9);
}

TEST(Controls, DigitsSetTheFieldOfView) {
  Controller c(start(), {});
  tap(c, Key::digit1);
  EXPECT_EQ(c.state().hfovDeg, 10);
  tap(c, Key::digit9);
  EXPECT_EQ(c.state().hfovDeg, 90);
  tap(c, Key::digit0);
  EXPECT_EQ(c.state().hfovDeg, 100);
  tap(c, Key::digit6);
  EXPECT_EQ(c.state().hfovDeg, 60);
  EXPECT_FALSE(fovForKey(Key::plus).has_value());
  // A viewer whose view triangle stops at 90 degrees clamps the 0 key.
  ControllerSettings narrow;
  narrow.maxFovDeg = 90;
  Controller d(start(), {}, narrow);
  tap(d, Key::digit0);
  EXPECT_EQ(d.state().hfovDeg, 90);
}

TEST(Controls, ScreenshotKeyIsTakenOncePerPress) {
  Controller c(start(), {});
  EXPECT_FALSE(c.takeScreenshotRequest());
  tap(c, Key::screenshot);
  c.advance(1.0);  // held keys repeat, a screenshot does not
  EXPECT_TRUE(c.takeScreenshotRequest());
  EXPECT_FALSE(c.takeScreenshotRequest());
  tap(c, Key::screenshot);
  tap(c, Key::screenshot);
  EXPECT_TRUE(c.takeScreenshotRequest());
  EXPECT_TRUE(c.takeScreenshotRequest());
  EXPECT_FALSE(c.takeScreenshotRequest());
  EXPECT_STREQ(keyName(Key::screenshot), "Screenshot");
  EXPECT_STREQ(keyName(Key::quit), "Quit");
}

TEST(Controls, PlusAndMinusStepTheViewDistanceWithinItsClamps) {
  ViewerState s = start();
  s.viewDistance = 10000;
  Controller c(s, {});
  tap(c, Key::plus);
  tap(c, Key::plus);
  EXPECT_NEAR(c.state().viewDistance, 20000, 1e-6);  // two presses double it
  tap(c, Key::minus);
  tap(c, Key::minus);
  EXPECT_NEAR(c.state().viewDistance, 10000, 1e-6);
  for (int k = 0; k < 40; ++k) tap(c, Key::plus);
  EXPECT_EQ(c.state().viewDistance, c.settings().maxViewDistance);
  for (int k = 0; k < 80; ++k) tap(c, Key::minus);
  EXPECT_EQ(c.state().viewDistance, c.settings().minViewDistance);
}

TEST(Controls, MapKeyTogglesAndBracketsStepTheScale) {
  Controller c(start(), {});
  EXPECT_FALSE(c.state().mapVisible);
  tap(c, Key::map);
  EXPECT_TRUE(c.state().mapVisible);
  tap(c, Key::map);
  EXPECT_FALSE(c.state().mapVisible);
  tap(c, Key::mapZoomOut);
  EXPECT_EQ(c.state().mapScale, 0);
  for (int k = 0; k < 7; ++k) tap(c, Key::mapZoomIn);
  EXPECT_EQ(c.state().mapScale, kMapScaleCount - 1);
  tap(c, Key::mapZoomOut);
  EXPECT_EQ(c.state().mapScale, 3);
}

TEST(Controls, GroundFollowingKeepsTheHeightAboveGround) {
  Controller c(start(), slope);
  EXPECT_DOUBLE_EQ(c.state().eyeElevation, 100);
  tap(c, Key::up);  // 5 m/s east, up the slope
  c.advance(10);
  EXPECT_NEAR(c.state().groundElevation, 50, 1e-9);
  EXPECT_NEAR(c.state().heightAgl, 100, 1e-9);
  EXPECT_NEAR(c.state().eyeElevation, 150, 1e-9);
  tap(c, Key::pageUp);
  EXPECT_NEAR(c.state().heightAgl, 110, 1e-9);
}

TEST(Controls, FreeFlightKeepsTheAltitudeButNotBelowTheGround) {
  Controller c(start(), slope);
  tap(c, Key::groundFollow);
  EXPECT_FALSE(c.state().groundFollowing);
  EXPECT_DOUBLE_EQ(c.state().eyeElevation, 100);  // the toggle does not move the eye
  tap(c, Key::up);
  c.advance(10);  // ground 50 m: the eye stays at 100 m, 50 m above it
  EXPECT_NEAR(c.state().eyeElevation, 100, 1e-9);
  EXPECT_NEAR(c.state().heightAgl, 50, 1e-9);
  c.advance(20);  // ground 150 m: pushed up to the floor
  EXPECT_NEAR(c.state().eyeElevation, 150 + c.settings().minHeightAglM, 1e-9);
  tap(c, Key::pageUp);  // free flight: altitude
  EXPECT_NEAR(c.state().eyeElevation, 161, 1e-9);
  tap(c, Key::groundFollow);
  EXPECT_TRUE(c.state().groundFollowing);
  EXPECT_NEAR(c.state().heightAgl, 11, 1e-9);
}

TEST(Controls, OffTheDatabaseTheLastGroundHolds) {
  auto ground = [](double e, double) -> std::optional<double> {
    if (e > 1100) return std::nullopt;
    return 40.0;
  };
  Controller c(start(), ground);
  for (int k = 0; k < 40; ++k) tap(c, Key::up);  // 200 m/s
  c.advance(2);
  EXPECT_GT(c.state().easting, 1100);
  EXPECT_DOUBLE_EQ(c.state().groundElevation, 40);
  EXPECT_DOUBLE_EQ(c.state().eyeElevation, 140);
}

TEST(Controls, QuitAndPanelLines) {
  Controller c(start(), {});
  tap(c, Key::up);
  tap(c, Key::up);
  tap(c, Key::up);
  const auto lines = controllerPanelLines(c.state());
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0], "SPEED 15.0 M/S (54 KM/H)");
  EXPECT_EQ(lines[1], "HEADING 090\xC2\xB0");
  ViewerState north = c.state();
  north.headingDeg = 359.7;
  EXPECT_EQ(controllerPanelLines(north)[1], "HEADING 000\xC2\xB0");
  EXPECT_FALSE(c.quitRequested());
  tap(c, Key::quit);
  EXPECT_TRUE(c.quitRequested());
  EXPECT_STREQ(keyName(Key::pageDown), "PageDown");
}

TEST(Controls, PoseIsInKilometresPerHour) {
  Controller c(start(), {});
  tap(c, Key::up);
  EXPECT_DOUBLE_EQ(c.pose().speedKmh, 18);
  EXPECT_DOUBLE_EQ(c.pose().headingDeg, 90);
}

}  // namespace
}  // namespace sandtable::world
