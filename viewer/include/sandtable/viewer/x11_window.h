#pragma once
// The stealth viewer's window: an X11 window (Xlib) with an EGL window
// surface. It is a PresentTarget (render/present.h): the flight's renderer
// opens its context on this window's EGL display and surface and shows
// each frame with a GPU blit and a swap (docs/VIEWER.md, "Frame path").
// present(Image) shows a frame that is already in memory instead, through
// the window's own OpenGL 4.5 core context (tests, tools).
//
// Contexts: present(Image) makes the window's context current, draws,
// swaps, and then makes current again whatever EGL display / surfaces /
// context / API were current before, so a renderer's context survives on
// the same thread. open() and the destructor restore it the same way.
//
// Keys: pollEvents() returns presses and releases of the keys controls.h
// knows; presses of the entity keys (viewer_keys.h) wait for
// takeViewerKeys(); others are dropped. X11 auto-repeat is made "detectable", so a
// held key gives one press and one release; the Controller does its own
// repeating. Closing the window (WM_DELETE_WINDOW) reports Key::quit.
//
// Thread safety: every method may be called from any thread and they are
// serialised by one mutex, so pollEvents() can run on the main thread (with
// the Controller) while the render thread presents (withSurface() holds
// the same mutex). This works without XInitThreads() because only this
// object, and EGL inside withSurface(), touch its own X connection.
#include <cstdint>
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/world/controls.h"
#include "sandtable/render/image.h"
#include "sandtable/render/present.h"
#include "sandtable/viewer/viewer_keys.h"

namespace sandtable::viewer {

/// Problem::file of window problems.
inline constexpr const char* kWindowProblem = "window";

class ViewerWindow : public render::PresentTarget {
 public:
  /// True when $DISPLAY is set (not a promise that the server answers).
  static bool displayConfigured();

  /// Opens a width x height window titled `title` on `display` (an X
  /// display name such as ":1"; "" uses $DISPLAY). Fails with a message
  /// saying which step failed (no X server, no EGL X11 platform, no 4.5
  /// core context ...).
  static Result<std::unique_ptr<ViewerWindow>> open(std::uint32_t width, std::uint32_t height,
                                                    const std::string& title,
                                                    const std::string& display = "");
  ~ViewerWindow() override;
  ViewerWindow(const ViewerWindow&) = delete;
  ViewerWindow& operator=(const ViewerWindow&) = delete;

  /// Every key event queued since the last call, oldest first; never blocks.
  std::vector<world::KeyEvent> pollEvents();
  /// Presses of the entity keys (viewer_keys.h: Tab, Shift+Tab, E, D,
  /// Space) that pollEvents() has read since the last call, oldest first.
  std::vector<ViewerKey> takeViewerKeys();
  /// True once the window manager asked the window to close.
  bool closeRequested() const { return closeRequested_.load(); }

  /// Shows the frame scaled to fit the window (letterboxed, nearest
  /// pixels at 1:1) and swaps.
  Status present(const render::Image& frame);

  // PresentTarget: the renderer's way into the window.
  EglSurface eglSurface() const override;
  void withSurface(const std::function<void(std::uint32_t width, std::uint32_t height)>& use) override;

  /// The window's pixels as the X server holds them (XGetImage): what the
  /// user sees; for tests and screenshots.
  Result<render::Image> capture();

  /// Current client size (follows resizes seen by pollEvents()).
  std::uint32_t width() const;
  std::uint32_t height() const;
  /// Xlib handles (Display*, Window) for callers that need X directly,
  /// e.g. tests that send synthetic keys.
  void* xDisplay() const { return display_; }
  unsigned long xWindow() const { return window_; }
  /// GL_RENDERER of the window's context.
  const std::string& renderer() const { return renderer_; }

 private:
  ViewerWindow() = default;
  struct Gl;
  Status makeGl();
  void releaseEgl();

  void* display_ = nullptr;  // Display*
  unsigned long window_ = 0;
  unsigned long colormap_ = 0;
  unsigned long wmDelete_ = 0;
  void* eglDisplay_ = nullptr;
  void* eglSurface_ = nullptr;
  void* eglContext_ = nullptr;
  void* eglConfig_ = nullptr;
  std::unique_ptr<Gl> gl_;
  std::uint32_t width_ = 0, height_ = 0;
  std::atomic<bool> closeRequested_{false};
  mutable std::mutex mutex_;  // guards the X connection, EGL use and the fields below
  std::uint32_t downMask_ = 0;  // keys pressed and not yet released, by Key
  std::vector<ViewerKey> viewerKeys_;  // entity keys read by pollEvents(), not yet taken
  std::string renderer_;
};

}  // namespace sandtable::viewer
