// The viewer window under Xvfb: a key sent through XTest comes back from
// pollEvents(), a Controller fed with it changes the speed, and the panel
// that shows the speed reaches the screen (read back with XGetImage). The
// renderer's headless context stays current across present(). A renderer
// opened on the window presents its frames there on the GPU: the window
// shows exactly the pixels a read-back gives, with no read-back needed.
//
// Skips when Xvfb is not installed (tools/setup.sh installs it).
#include <gtest/gtest.h>

#include <EGL/egl.h>
#include <X11/Xlib.h>
#include <X11/extensions/XTest.h>
#include <X11/keysym.h>
// Xlib defines Status as a macro; ours is sandtable::Status (base/result.h).
#undef Status
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cstdlib>
#include <optional>
#include <sstream>
#include <thread>

#include "sandtable/render/egl_context.h"
#include "sandtable/render/hud.h"
#include "sandtable/render/renderer.h"
#include "sandtable/viewer/x11_window.h"
#include "sandtable/testing/xvfb.h"
#include "sandtable/testing/require.h"


namespace sandtable::viewer {
namespace {

bool onPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const std::string p = dir + "/" + program;
    if (::access(p.c_str(), X_OK) == 0) return true;
  }
  return false;
}

using sandtable::testsupport::Xvfb;

render::Image filled(std::uint32_t w, std::uint32_t h, render::Rgb c) {
  render::Image img;
  img.width = w;
  img.height = h;
  img.rgba.resize(std::size_t(w) * h * 4);
  for (std::size_t k = 0; k < img.rgba.size(); k += 4) {
    img.rgba[k] = c.r;
    img.rgba[k + 1] = c.g;
    img.rgba[k + 2] = c.b;
    img.rgba[k + 3] = 255;
  }
  return img;
}

/// "" when the window shows exactly `want`, else the first difference.
std::string differs(const render::Image& got, const render::Image& want) {
  if (got.width != want.width || got.height != want.height) return "size differs";
  for (std::uint32_t y = 0; y < want.height; ++y) {
    for (std::uint32_t x = 0; x < want.width; ++x) {
      const render::Rgb a = got.at(x, y), b = want.at(x, y);
      if (a.r != b.r || a.g != b.g || a.b != b.b) {
        return "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is " + std::to_string(a.r) + "," +
               std::to_string(a.g) + "," + std::to_string(a.b) + ", wanted " + std::to_string(b.r) + "," +
               std::to_string(b.g) + "," + std::to_string(b.b);
      }
    }
  }
  return {};
}

/// The panel as a flight loop would draw it over a frame.
render::Image panelFrame(const world::ViewerState& s) {
  render::Image f = filled(320, 240, {0x87, 0xCE, 0xEB});
  render::drawHudPanel(f, world::controllerPanelLines(s));
  return f;
}

/// Reads events until `want` have arrived; the X server delivers them
/// asynchronously, so this polls (up to 5 s) rather than assume a delay.
std::vector<world::KeyEvent> waitForEvents(ViewerWindow& w, std::size_t want) {
  std::vector<world::KeyEvent> got;
  for (int tries = 0; tries < 1000 && got.size() < want; ++tries) {
    for (const auto& e : w.pollEvents()) got.push_back(e);
    if (got.size() < want) {
      const timespec pause{0, 5'000'000};
      nanosleep(&pause, nullptr);
    }
  }
  return got;
}

void sendKey(Display* dpy, KeySym sym, bool press) {
  XTestFakeKeyEvent(dpy, XKeysymToKeycode(dpy, sym), press ? True : False, CurrentTime);
  XSync(dpy, False);
}

class WindowTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SANDTABLE_REQUIRE(onPath("Xvfb"), "Xvfb (apt-get install xvfb)");
    xvfb_ = Xvfb::start();
    ASSERT_TRUE(xvfb_) << "Xvfb is installed but did not start";
    keys_ = XOpenDisplay(xvfb_->display.c_str());
    ASSERT_NE(keys_, nullptr);
    int ev = 0, err = 0, major = 0, minor = 0;
    ASSERT_TRUE(XTestQueryExtension(keys_, &ev, &err, &major, &minor)) << "Xvfb lacks XTEST";
  }
  void TearDown() override {
    if (keys_) XCloseDisplay(keys_);
    xvfb_.reset();
  }
  std::unique_ptr<Xvfb> xvfb_;
  Display* keys_ = nullptr;  // a second client, like the user's keyboard
};

TEST_F(WindowTest, OpenFailsClearlyWithoutAServer) {
  auto w = ViewerWindow::open(64, 64, "nowhere", ":4093");
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.error().find("cannot open X display \":4093\""), std::string::npos) << w.error();
}

TEST_F(WindowTest, KeypressChangesTheSpeedShownInThePanel) {
  auto opened = ViewerWindow::open(320, 240, "sandtable stealth viewer test", xvfb_->display);
  ASSERT_TRUE(opened.ok()) << opened.error();
  ViewerWindow& win = *opened.value();
  EXPECT_EQ(win.width(), 320u);
  EXPECT_EQ(win.height(), 240u);
  XSetInputFocus(keys_, Window(win.xWindow()), RevertToPointerRoot, CurrentTime);
  XSync(keys_, False);

  world::Controller c(world::ViewerState{}, {});
  const render::Image before = panelFrame(c.state());
  ASSERT_TRUE(win.present(before).ok());
  auto shown = win.capture();
  ASSERT_TRUE(shown.ok()) << shown.error();
  EXPECT_EQ(differs(shown.value(), before), "");

  sendKey(keys_, XK_Up, true);
  sendKey(keys_, XK_Up, false);
  const auto events = waitForEvents(win, 2);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0], (world::KeyEvent{world::Key::up, true}));
  EXPECT_EQ(events[1], (world::KeyEvent{world::Key::up, false}));
  c.handle(events);
  EXPECT_DOUBLE_EQ(c.state().speedMs, 5);

  const render::Image after = panelFrame(c.state());
  ASSERT_NE(differs(after, before), "") << "the panel must show the new speed";
  ASSERT_TRUE(win.present(after).ok());
  shown = win.capture();
  ASSERT_TRUE(shown.ok()) << shown.error();
  EXPECT_EQ(differs(shown.value(), after), "");
}

TEST_F(WindowTest, KeysTranslate) {
  auto opened = ViewerWindow::open(64, 64, "keys", xvfb_->display);
  ASSERT_TRUE(opened.ok()) << opened.error();
  ViewerWindow& win = *opened.value();
  XSetInputFocus(keys_, Window(win.xWindow()), RevertToPointerRoot, CurrentTime);
  XSync(keys_, False);
  const std::vector<std::pair<KeySym, world::Key>> keys = {
      {XK_Down, world::Key::down}, {XK_Left, world::Key::left}, {XK_Right, world::Key::right}, {XK_7, world::Key::digit7},
      {XK_0, world::Key::digit0},  {XK_minus, world::Key::minus}, {XK_equal, world::Key::plus}, {XK_m, world::Key::map},
      {XK_Page_Up, world::Key::pageUp}, {XK_f, world::Key::groundFollow}, {XK_p, world::Key::screenshot},
      {XK_F12, world::Key::screenshot}, {XK_Escape, world::Key::quit}};
  for (const auto& [sym, key] : keys) {
    sendKey(keys_, sym, true);
    sendKey(keys_, sym, false);
    const auto ev = waitForEvents(win, 2);
    ASSERT_EQ(ev.size(), 2u) << world::keyName(key);
    EXPECT_EQ(ev[0], (world::KeyEvent{key, true})) << world::keyName(key);
    EXPECT_EQ(ev[1], (world::KeyEvent{key, false})) << world::keyName(key);
  }
}

TEST_F(WindowTest, EntityKeysWaitForTakeViewerKeys) {
  auto opened = ViewerWindow::open(64, 64, "entity keys", xvfb_->display);
  ASSERT_TRUE(opened.ok()) << opened.error();
  ViewerWindow& win = *opened.value();
  XSetInputFocus(keys_, Window(win.xWindow()), RevertToPointerRoot, CurrentTime);
  XSync(keys_, False);
  const std::vector<std::pair<KeySym, ViewerKey>> keys = {{XK_Tab, ViewerKey::nextEntity},
                                                          {XK_e, ViewerKey::stealth},
                                                          {XK_d, ViewerKey::drive},
                                                          {XK_space, ViewerKey::allStop}};
  for (const auto& [sym, key] : keys) {
    sendKey(keys_, sym, true);
    sendKey(keys_, sym, false);
    std::vector<ViewerKey> got;
    for (int tries = 0; tries < 1000 && got.empty(); ++tries) {
      // The eye's keys see nothing of them.
      EXPECT_TRUE(win.pollEvents().empty()) << viewerKeyName(key);
      got = win.takeViewerKeys();
      if (got.empty()) {
        const timespec pause{0, 5'000'000};
        nanosleep(&pause, nullptr);
      }
    }
    ASSERT_EQ(got.size(), 1u) << viewerKeyName(key);  // a press, not its release
    EXPECT_EQ(got[0], key) << viewerKeyName(key);
  }
  // Shift+Tab goes back.
  sendKey(keys_, XK_Shift_L, true);
  sendKey(keys_, XK_Tab, true);
  sendKey(keys_, XK_Tab, false);
  sendKey(keys_, XK_Shift_L, false);
  std::vector<ViewerKey> got;
  for (int tries = 0; tries < 1000 && got.empty(); ++tries) {
    (void)win.pollEvents();
    got = win.takeViewerKeys();
    if (got.empty()) {
      const timespec pause{0, 5'000'000};
      nanosleep(&pause, nullptr);
    }
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], ViewerKey::previousEntity);
}

TEST_F(WindowTest, PresentKeepsTheRenderersContextCurrent) {
  auto headless = render::EglContext::create();
  SANDTABLE_REQUIRE(headless.ok(), "headless GL (EGL, Mesa): " << headless.error());
  const EGLContext renderer = eglGetCurrentContext();
  const EGLSurface draw = eglGetCurrentSurface(EGL_DRAW);
  ASSERT_NE(renderer, EGL_NO_CONTEXT);
  auto opened = ViewerWindow::open(64, 48, "contexts", xvfb_->display);
  ASSERT_TRUE(opened.ok()) << opened.error();
  EXPECT_EQ(eglGetCurrentContext(), renderer);
  const render::Image frame = filled(64, 48, {200, 30, 90});
  ASSERT_TRUE(opened.value()->present(frame).ok());
  EXPECT_EQ(eglGetCurrentContext(), renderer);
  EXPECT_EQ(eglGetCurrentSurface(EGL_DRAW), draw);
  auto shown = opened.value()->capture();
  ASSERT_TRUE(shown.ok()) << shown.error();
  EXPECT_EQ(differs(shown.value(), frame), "");
  opened.value().reset();
  EXPECT_EQ(eglGetCurrentContext(), renderer);
}

TEST_F(WindowTest, RenderThreadPresentsWhileTheMainThreadPolls) {
  // fly()'s layout: the controller polls keys on the main thread, frames
  // are presented from the render thread.
  auto opened = ViewerWindow::open(96, 64, "threads", xvfb_->display);
  ASSERT_TRUE(opened.ok()) << opened.error();
  ViewerWindow& win = *opened.value();
  XSetInputFocus(keys_, Window(win.xWindow()), RevertToPointerRoot, CurrentTime);
  XSync(keys_, False);
  const render::Image last = filled(96, 64, {20, 40, 60});
  std::string renderError;
  std::thread render([&] {
    auto headless = render::EglContext::create();  // a headless renderer's own context
    for (int k = 0; k < 30 && renderError.empty(); ++k) {
      renderError = win.present(filled(96, 64, {std::uint8_t(k * 8), 0, 0})).error();
    }
    if (renderError.empty()) renderError = win.present(last).error();
  });
  sendKey(keys_, XK_Right, true);
  sendKey(keys_, XK_Right, false);
  const auto ev = waitForEvents(win, 2);
  render.join();
  EXPECT_EQ(renderError, "");
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0], (world::KeyEvent{world::Key::right, true}));
  auto shown = win.capture();
  ASSERT_TRUE(shown.ok()) << shown.error();
  EXPECT_EQ(differs(shown.value(), last), "");
}

/// Ground ahead of an eye 30 m up (no grid needed: a hand-made strip).
scene::DisplayBuffer groundAhead(std::uint32_t w, std::uint32_t h) {
  scene::DisplayBuffer b;
  b.camera.y = 30;
  b.camera.pitchDeg = -8;
  b.camera.aspect = double(w) / double(h);
  b.camera.viewDistance = 3000;
  b.vertices = {{-1000, 0, -2000, 0, 1, 0, 0}, {-1000, 0, 0, 0, 1, 0, 0}, {1000, 0, -2000, 0, 1, 0, 0},
                {1000, 0, 0, 0, 1, 0, 0}};
  b.firsts = {0};
  b.counts = {4};
  return b;
}

TEST_F(WindowTest, RendererPresentsIntoTheWindowWithoutReadBack) {
  auto opened = ViewerWindow::open(160, 120, "present", xvfb_->display);
  ASSERT_TRUE(opened.ok()) << opened.error();
  ViewerWindow& win = *opened.value();
  render::RenderSettings rs;
  rs.width = 160;
  rs.height = 120;
  render::Image shownFirst, readBack, cpuPanel;
  std::string error;
  std::uint64_t readBeforeAsking = 99;
  // On its own thread, as fly()'s render thread does it.
  std::thread render([&] {
    auto r = render::Renderer::create(rs, &win);
    if (!r) {
      error = r.error();
      return;
    }
    render::Overlay overlay;
    for (std::uint32_t k = 0; k < 3 && error.empty(); ++k) {
      error = r.value()->draw(groundAhead(160, 120)).error();
      overlay.begin(160, 120);
      render::drawHudPanel(overlay, {"FRAME " + std::to_string(k)});
      if (error.empty()) error = r.value()->drawOverlay(overlay).error();
      if (error.empty()) error = r.value()->present().error();
    }
    readBeforeAsking = r.value()->framesReadBack();
    auto shown = win.capture();
    if (shown) shownFirst = shown.value();
    if (error.empty()) error = r.value()->readFrame(readBack).error();
    // The same frame without the HUD pass, given the panel on the CPU.
    if (error.empty()) error = r.value()->draw(groundAhead(160, 120)).error();
    if (error.empty()) error = r.value()->readFrame(cpuPanel).error();
    render::drawHudPanel(cpuPanel, {"FRAME 2"});
  });
  render.join();
  ASSERT_EQ(error, "");
  EXPECT_EQ(readBeforeAsking, 0u) << "presenting must not read the frame back";
  EXPECT_EQ(differs(shownFirst, readBack), "") << "the window shows the frame the renderer drew";
  EXPECT_EQ(differs(readBack, cpuPanel), "") << "the HUD pass draws the CPU panel's pixels";
}

TEST_F(WindowTest, SmallerFrameIsLetterboxed) {
  auto opened = ViewerWindow::open(200, 100, "letterbox", xvfb_->display);
  ASSERT_TRUE(opened.ok()) << opened.error();
  ASSERT_TRUE(opened.value()->present(filled(100, 100, {255, 255, 255})).ok());
  auto shown = opened.value()->capture();
  ASSERT_TRUE(shown.ok()) << shown.error();
  const render::Rgb side = shown->at(10, 50), middle = shown->at(100, 50);
  EXPECT_EQ(side.r + side.g + side.b, 0);
  EXPECT_EQ(middle.r + middle.g + middle.b, 3 * 255);
}

}  // namespace
}  // namespace sandtable::viewer
