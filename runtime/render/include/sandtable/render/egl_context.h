#pragma once
// An OpenGL 4.5 core context through EGL, for the renderer: headless
// (Mesa's surfaceless platform or a pbuffer) or on a window's EGL display
// and surface (present.h). It must be created, used and destroyed on the
// render thread; tests use it to check that other code keeps it current.
#include <memory>
#include <string>

#include "sandtable/base/result.h"
#include "sandtable/render/present.h"

namespace sandtable::render {

class EglContext {
 public:
  /// Tries Mesa's surfaceless platform first (no window system, no GPU
  /// needed with llvmpipe), then the default display with a pbuffer. The
  /// context is current on the calling thread when this returns.
  static Result<std::unique_ptr<EglContext>> create();
  /// A context on `window`'s display and config, current with its surface
  /// on the calling thread. `window` must outlive the context; its display
  /// stays the window's (not terminated here).
  static Result<std::unique_ptr<EglContext>> createOn(PresentTarget& window);
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  /// "surfaceless", "default display + pbuffer" or "X11 window surface".
  const std::string& platform() const { return platform_; }
  /// The window this context presents to; null when headless.
  PresentTarget* window() const { return window_; }
  /// eglSwapBuffers on the window surface; call inside window()->withSurface().
  Status swapBuffers();

 private:
  EglContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
  void* surface_ = nullptr;
  PresentTarget* window_ = nullptr;  ///< set: display_ and surface_ are the window's
  std::string platform_;
};

}  // namespace sandtable::render
