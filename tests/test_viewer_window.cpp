// `sandtable fly` as the stealth viewer, through the CLI. In a window under
// Xvfb: an Up key sent with XTest raises the speed in the per-frame stats
// by 5 m/s (18 km/h) and the panel's text reads the new speed, and p saves
// a screenshot of a frame. Headless: --map draws the 2-D map in the
// top-right corner, --path flies a Table 7 file (times only) for the
// duration the table computes, and the errors are clear.
//
// The window test skips when Xvfb is not installed (tools/setup.sh installs
// it); it runs its own Xvfb on a display number Xvfb picks (-displayfd).
// gtest before the X11 headers: Xlib's macros (None, Bool, Status) would
// break gtest's templates.
#include "test_support.h"

#include <fcntl.h>
#include <gdal_priv.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "sandtable/converters/elevation.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/hud.h"
#include "sandtable/render/image.h"
#include "sandtable/render/renderer.h"
#include "sandtable/testing/xvfb.h"

#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <X11/extensions/XTest.h>
#include <X11/keysym.h>
// Xlib defines Status as a macro; ours is sandtable::Status (base/result.h).
#undef Status


namespace sandtable::test {
namespace {

namespace fs = std::filesystem;
using render::Image;

constexpr const char* kSize = "320x180";
constexpr std::uint32_t kWidth = 320, kHeight = 180;
// Start over Monaco looking north, over land and sea.
const std::vector<std::string> kStart = {"--at", "7.425", "43.735", "--heading", "0", "--height", "150",
                                         "--view-distance", "3000", "--size", kSize};

bool onPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    if (::access((dir + "/" + program).c_str(), X_OK) == 0) return true;
  }
  return false;
}

void pause(long ms) {
  const timespec t{ms / 1000, (ms % 1000) * 1'000'000};
  nanosleep(&t, nullptr);
}

using sandtable::testsupport::Xvfb;

/// Sets (or with nullptr unsets) an environment variable for a scope, so
/// the CLI run from the test sees it and later tests do not.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value) ::setenv(name, value, 1);
    else ::unsetenv(name);
  }
  ~ScopedEnv() {
    if (old_) ::setenv(name_.c_str(), old_->c_str(), 1);
    else ::unsetenv(name_.c_str());
  }

 private:
  std::string name_;
  std::optional<std::string> old_;
};

nlohmann::json readStats(const std::string& dir) {
  const std::string text = slurpFile(dir + "/stats.json");
  return text.empty() ? nlohmann::json() : nlohmann::json::parse(text);
}

/// The panel's "HDG ... SPD ..." line for a frame of stats.json, and its
/// index among the panel's lines, as the flight loop writes them.
std::pair<std::string, int> speedLine(const nlohmann::json& f) {
  viewer::FrameStats s;
  s.frame = f["frame"];
  s.headingDeg = f["heading"];
  s.speedKmh = f["speed_kmh"];
  if (!f["lon"].is_null()) {
    s.lon = f["lon"].get<double>();
    s.lat = f["lat"].get<double>();
  }
  const auto lines = viewer::hudLines(s, viewer::FlightOptions{});
  for (std::size_t k = 0; k < lines.size(); ++k) {
    if (lines[k].rfind("HDG ", 0) == 0) return {lines[k], int(k)};
  }
  return {"", -1};
}

bool isWhite(const Image& img, std::uint32_t x, std::uint32_t y) {
  const auto c = img.at(x, y);
  return c.r == 255 && c.g == 255 && c.b == 255;
}

/// Reads panel line `index` back from a frame: the panel's text is opaque
/// white over a darkened background (never white), so its white pixels are
/// exactly the glyphs. "" when they are the glyphs of `text`, else where not.
std::string panelLineReads(const Image& frame, int index, const std::string& text) {
  const int pad = 4;  // drawHudPanel at scale 1 (frames narrower than 800)
  const int y0 = pad + index * render::kLineAdvance;
  Image want;
  want.width = frame.width;
  want.height = frame.height;
  want.rgba.assign(frame.rgba.size(), 0);
  render::drawText(want, pad, y0, text, 1, render::Rgb{255, 255, 255});
  const int x1 = pad + render::textWidth(text, 1) + render::kGlyphAdvance * 4;
  for (int y = y0; y < y0 + render::kGlyphHeight; ++y) {
    for (int x = 0; x < x1 && x < int(frame.width); ++x) {
      if (isWhite(frame, x, y) != isWhite(want, x, y)) {
        return "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") differs from \"" + text + "\"";
      }
    }
  }
  return {};
}

/// The top-level window whose name starts with `prefix`; 0 if none yet.
Window findWindow(Display* dpy, const std::string& prefix) {
  Window root = 0, parent = 0, *children = nullptr;
  unsigned n = 0;
  Window found = 0;
  if (!XQueryTree(dpy, DefaultRootWindow(dpy), &root, &parent, &children, &n)) return 0;
  for (unsigned k = 0; k < n && !found; ++k) {
    char* name = nullptr;
    if (XFetchName(dpy, children[k], &name) && name) {
      if (std::string(name).rfind(prefix, 0) == 0) found = children[k];
      XFree(name);
    }
  }
  if (children) XFree(children);
  return found;
}

void tapKey(Display* dpy, KeySym sym) {
  const KeyCode code = XKeysymToKeycode(dpy, sym);
  XTestFakeKeyEvent(dpy, code, True, CurrentTime);
  XTestFakeKeyEvent(dpy, code, False, CurrentTime);
  XSync(dpy, False);
}

class ViewerCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    std::string why;
    if (!render::headlessGlAvailable(why)) {
      noGl_ = why;
      return;
    }
    tmp_ = new TempDir("viewerwin");
    convert::ElevationOptions o;
    o.sources = {data("elevation/srtm/N43E007.hgt.zip")};
    o.extent = {7.40, 43.71, 7.45, 43.75};  // Monaco: hills, town and sea, about 4 x 4.4 km
    o.spacing = 30;
    o.output = *tmp_ / "monaco";
    auto r = convert::buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    db_ = o.output;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override {
    SANDTABLE_REQUIRE_DATA();
    SANDTABLE_REQUIRE(noGl_.empty(), "headless GL (EGL, Mesa): " << noGl_);
    ASSERT_FALSE(db_.empty());
  }
  static std::vector<std::string> flyArgs(std::vector<std::string> extra) {
    std::vector<std::string> a = {"fly", db_};
    a.insert(a.end(), kStart.begin(), kStart.end());
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
  static inline TempDir* tmp_ = nullptr;
  static inline std::string db_, noGl_;
};

TEST_F(ViewerCli, WindowUpKeyRaisesTheSpeedInStatsAndPanel) {
  SANDTABLE_REQUIRE(onPath("Xvfb"), "Xvfb (apt-get install xvfb)");
  auto xvfb = Xvfb::start();
  ASSERT_TRUE(xvfb) << "Xvfb is installed but did not start";
  Display* keys = XOpenDisplay(xvfb->display.c_str());  // the user's keyboard
  ASSERT_NE(keys, nullptr);
  int ev = 0, err = 0, major = 0, minor = 0;
  ASSERT_TRUE(XTestQueryExtension(keys, &ev, &err, &major, &minor)) << "Xvfb lacks XTEST";

  TempDir out("flywin");
  const std::string frames = out / "frames";
  CommandResult result;
  std::atomic<bool> done{false};
  // --frames is only a safety stop: the test ends the flight with q.
  const auto args = flyArgs({"--window", "--frames", "600", "--png", frames, "--speed", "36"});
  std::thread flight;
  {
    ScopedEnv display("DISPLAY", xvfb->display.c_str());
    flight = std::thread([&] {
      result = runCli(args);
      done = true;
    });
    // Keys are sent once frame 0 is on disk, so frame 0 (at least) was
    // flown before them; a hang guard, not a timing requirement.
    for (int k = 0; k < 1200 && !done && !fs::exists(frames + "/frame_00000.png"); ++k) pause(50);
    Window w = 0;
    for (int k = 0; k < 200 && !done && !(w = findWindow(keys, "sandtable fly")); ++k) pause(50);
    if (w) {
      XSetInputFocus(keys, w, RevertToPointerRoot, CurrentTime);
      tapKey(keys, XK_Up);
      tapKey(keys, XK_p);
      tapKey(keys, XK_q);
    }
    flight.join();
  }
  XCloseDisplay(keys);
  ASSERT_EQ(result.exitCode, 0) << result.err;
  EXPECT_NE(result.out.find("in a window"), std::string::npos) << result.out;

  const auto stats = readStats(frames);
  ASSERT_TRUE(stats.contains("frames")) << "no stats.json in " << frames;
  const auto& f = stats["frames"];
  ASSERT_GE(f.size(), 2u);
  ASSERT_LT(f.size(), 600u) << "the flight ran to --frames: q never arrived";
  const double before = f[0]["speed_kmh"];
  EXPECT_NEAR(before, 36.0, 1e-9);
  std::size_t k = 1;
  while (k < f.size() && f[k]["speed_kmh"].get<double>() == before) ++k;
  ASSERT_LT(k, f.size()) << "the speed never changed";
  for (std::size_t j = k; j < f.size(); ++j) {
    EXPECT_NEAR(f[j]["speed_kmh"].get<double>(), before + 18.0, 1e-9) << "frame " << j << ": one press is 5 m/s, and it holds";
  }
  EXPECT_NEAR(f[k]["heading"].get<double>(), 0.0, 1e-9);

  // The panel of the last frame before the key reads the old speed, the
  // first after it the new one.
  const auto [oldLine, oldIndex] = speedLine(f[k - 1]);
  const auto [newLine, newIndex] = speedLine(f[k]);
  ASSERT_GE(oldIndex, 0);
  ASSERT_NE(oldLine, newLine);
  EXPECT_NE(newLine.find("SPD 54 KM/H"), std::string::npos) << newLine;
  const Image a = readPng(frames + "/" + viewer::frameFileName(std::uint32_t(k - 1)));
  const Image b = readPng(frames + "/" + viewer::frameFileName(std::uint32_t(k)));
  ASSERT_EQ(a.width, kWidth);
  ASSERT_EQ(b.width, kWidth);
  EXPECT_EQ(panelLineReads(a, oldIndex, oldLine), "");
  EXPECT_EQ(panelLineReads(b, newIndex, newLine), "");
  EXPECT_NE(panelLineReads(b, oldIndex, oldLine), "") << "the new frame must not still read the old speed";

  // p saved a screenshot: one of the frames flown at the new speed.
  const Image shot = readPng(frames + "/screenshot_0000.png");
  ASSERT_EQ(shot.width, kWidth) << result.out;
  bool matches = false;
  for (std::size_t j = k; j < f.size() && !matches; ++j) {
    matches = readPng(frames + "/" + viewer::frameFileName(std::uint32_t(j))).rgba == shot.rgba;
  }
  EXPECT_TRUE(matches) << "screenshot_0000.png is none of the frames after the Up key";
}

TEST_F(ViewerCli, WindowWithoutADisplayFailsClearly) {
  ScopedEnv display("DISPLAY", nullptr);
  TempDir out("flynodisp");
  const auto r = runCli(flyArgs({"--window", "--frames", "2", "--png", out / "f"}));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("--window needs an X display, and DISPLAY is not set"), std::string::npos) << r.err;
  const auto h = runCli(flyArgs({"--frames", "2"}));
  EXPECT_EQ(h.exitCode, 2);
  EXPECT_NE(h.err.find("a headless flight needs --png DIR"), std::string::npos) << h.err;
}

bool isSeaBlue(render::Rgb c) { return c.r == 0 && c.g == 46 && c.b == 113; }

TEST_F(ViewerCli, MapDrawsInTheTopRightCorner) {
  TempDir out("flymap");
  // No panel: its timings differ from run to run.
  const auto plain = runCli(flyArgs({"--headless", "--frames", "1", "--png", out / "plain", "--no-hud"}));
  ASSERT_EQ(plain.exitCode, 0) << plain.err;
  const auto map = runCli(flyArgs({"--headless", "--frames", "1", "--png", out / "map", "--no-hud", "--map"}));
  ASSERT_EQ(map.exitCode, 0) << map.err;
  const Image a = readPng(out / "plain/frame_00000.png");
  const Image b = readPng(out / "map/frame_00000.png");
  ASSERT_EQ(a.width, kWidth);
  ASSERT_EQ(b.width, kWidth);
  std::uint64_t changedTopRight = 0, changedElsewhere = 0, seaOnMap = 0, seaWithout = 0;
  for (std::uint32_t y = 0; y < kHeight; ++y) {
    for (std::uint32_t x = 0; x < kWidth; ++x) {
      const auto ca = a.at(x, y), cb = b.at(x, y);
      const bool changed = ca.r != cb.r || ca.g != cb.g || ca.b != cb.b;
      const bool topRight = x >= kWidth / 2 && y < kHeight / 2;
      (topRight ? changedTopRight : changedElsewhere) += changed;
      if (topRight) {
        seaOnMap += isSeaBlue(cb);
        seaWithout += isSeaBlue(ca);
      }
    }
  }
  EXPECT_GT(changedTopRight, 1000u) << "the map should cover a box in the top-right corner";
  EXPECT_EQ(changedElsewhere, 0u) << "the map must leave the rest of the frame alone";
  EXPECT_GT(seaOnMap, 0u) << "Monaco's sea should show in the map's blue";
  EXPECT_EQ(seaWithout, 0u);
  const auto bad = runCli(flyArgs({"--headless", "--frames", "1", "--png", out / "bad", "--map-scale", "tenth"}));
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.err.find("--map-scale must be full, half, quarter, eighth or sixteenth"), std::string::npos)
      << bad.err;
}

std::vector<std::string> pathArgs(const std::string& db, const std::string& file, const std::string& png,
                                  std::vector<std::string> extra = {}) {
  std::vector<std::string> a = {"fly", db, "--headless", "--path", file, "--png", png, "--size", kSize,
                                "--view-distance", "3000"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

TEST_F(ViewerCli, PathWithTimesOnlyFliesTheTable7Duration) {
  TempDir out("flypath");
  // Times only (no speed anywhere): each leg's speed is length / time (Table 7).
  spit(out / "times.path",
       "# times only\n"
       "7.415 43.730 120 time=0\n"
       "7.425 43.735 120 time=1.5\n"
       "7.430 43.740 150 time=0:00:03\n");
  const auto r = runCli(pathArgs(db_, out / "times.path", out / "f"));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto stats = readStats(out / "f");
  const auto& f = stats["frames"];
  ASSERT_EQ(f.size(), 91u) << "3 s at 30 frames a second, frame 0 at 0 s and frame 90 at the last waypoint";
  EXPECT_NEAR(f[90]["time_s"].get<double>(), 3.0, 1e-9);
  EXPECT_EQ(f[90]["speed_kmh"].get<double>(), 0.0) << "at the last waypoint the eye stops";
  EXPECT_NEAR(f[0]["height_agl"].get<double>(), 120.0, 1e-3);
  EXPECT_NEAR(f[90]["height_agl"].get<double>(), 150.0, 1e-3);
  // Frame 45 (1.5 s) is at the second waypoint; the first leg is flown at
  // its length over 1.5 s.
  const double leg = std::hypot(f[45]["easting"].get<double>() - f[0]["easting"].get<double>(),
                                f[45]["northing"].get<double>() - f[0]["northing"].get<double>());
  EXPECT_GT(leg, 500.0);
  EXPECT_NEAR(f[10]["speed_kmh"].get<double>(), leg / 1.5 * 3.6, 1e-6);

  // The old `lon lat height_m [speed_kmh]` form still reads; its legs take
  // the given speed or --speed.
  spit(out / "old.path", "7.415 43.730 120 360\n7.425 43.735 120\n7.430 43.740 150\n");
  const auto old = runCli(pathArgs(db_, out / "old.path", out / "old", {"--frames", "3", "--speed", "720"}));
  ASSERT_EQ(old.exitCode, 0) << old.err;
  const auto oldStats = readStats(out / "old");
  EXPECT_NEAR(oldStats["frames"][1]["speed_kmh"].get<double>(), 360.0, 1e-9);
}

TEST_F(ViewerCli, PathErrorsNameTheFileAndLine) {
  TempDir out("flypatherr");
  spit(out / "outside.path", "7.415 43.730 120 time=0\n7.425 43.735 120\n\n8.5 44.5 120 time=9\n");
  const auto r = runCli(pathArgs(db_, out / "outside.path", out / "f"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("outside.path"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("outside.path:4:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("outside the database"), std::string::npos) << r.err;
  spit(out / "proj.path", "frame projected\n0 0 100 time=0\n10 10 100 time=5\n");
  const auto p = runCli(pathArgs(db_, out / "proj.path", out / "p"));
  EXPECT_EQ(p.exitCode, 2);
  EXPECT_NE(p.err.find("proj.path:2:"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find("outside the database"), std::string::npos) << p.err;
}

TEST_F(ViewerCli, FreeFlightKeepsTheAltitude) {
  TempDir out("flyfree");
  const auto r = runCli(flyArgs({"--headless", "--frames", "20", "--png", out / "f", "--free-flight",
                                 "--altitude", "900", "--speed", "720"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto stats = readStats(out / "f");
  for (const auto& f : stats["frames"]) {
    EXPECT_NEAR(f["eye_elevation"].get<double>(), 900.0, 1e-6);
    EXPECT_TRUE(f["free_flight"].get<bool>());
  }
  const auto bad = runCli(flyArgs({"--headless", "--frames", "1", "--png", out / "g", "--altitude", "900"}));
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.err.find("--altitude needs --free-flight"), std::string::npos) << bad.err;
}

TEST_F(ViewerCli, MemoryBudgetBoundsThePagersPool) {
  // Item 7: the pager's pool is most of a flight's memory; the flag bounds it.
  TempDir out("flybudget");
  for (const char* mb : {"1024", "2"}) {
    const auto r = runCli(flyArgs({"--headless", "--frames", "2", "--png", out / mb, "--memory-budget-mb", mb}));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto stats = readStats(out / mb);
    const auto& pager = stats["frames"].back()["pager"];
    EXPECT_LE(pager["pool_bytes"].get<double>(), std::stod(mb) * 1024 * 1024) << mb;
    if (std::string(mb) == "2") {
      EXPECT_GT(pager["budget_refusals"].get<double>() + pager["budget_trimmed_levels"].get<double>(), 0);
    }
  }
  const auto bad = runCli(flyArgs({"--headless", "--frames", "1", "--memory-budget-mb", "0"}));
  EXPECT_EQ(bad.exitCode, 2);
}

TEST_F(ViewerCli, VideoThroughFfmpegOrAClearMessage) {
  TempDir out("flyvideo");
  const auto r = runCli(flyArgs({"--headless", "--frames", "6", "--video", out / "flight.mp4"}));
  if (!onPath("ffmpeg")) {
    EXPECT_EQ(r.exitCode, 2);
    EXPECT_NE(r.err.find("ffmpeg"), std::string::npos) << r.err;
    return;
  }
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_GT(fs::file_size(out / "flight.mp4"), 0u);
  EXPECT_FALSE(fs::exists(out / "frame_00000.png"));
}

}  // namespace
}  // namespace sandtable::test
