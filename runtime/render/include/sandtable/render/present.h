#pragma once
// A window the renderer presents into (docs/VIEWER.md, "Frame path"). The
// renderer opens its own OpenGL context on the window's EGL display and
// config, current with the window's surface, so a finished frame reaches
// the window by a blit on the GPU and a swap: no read-back, no upload.
// ViewerWindow (viewer/x11_window.h) is the one implementation; render
// knows no window system.
//
// Thread safety: withSurface() may be called from any thread; the
// implementation serialises it with its own use of the window system (the
// X connection the main thread polls for keys).
#include <cstdint>
#include <functional>

namespace sandtable::render {

class PresentTarget {
 public:
  /// EGL handles as void*: EGLDisplay (initialised, OpenGL bound), the
  /// EGLConfig the surface was made with, and the EGLSurface.
  struct EglSurface {
    void* display = nullptr;
    void* config = nullptr;
    void* surface = nullptr;
  };
  virtual ~PresentTarget() = default;
  virtual EglSurface eglSurface() const = 0;
  /// Runs `use` with the window's lock held and its client size now. Every
  /// EGL or GL call that touches the window surface (making it current,
  /// drawing into framebuffer 0, swapping) goes inside.
  virtual void withSurface(const std::function<void(std::uint32_t width, std::uint32_t height)>& use) = 0;
};

}  // namespace sandtable::render
