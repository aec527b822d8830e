#include "sandtable/render/egl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <cstring>

namespace sandtable::render {
namespace {

std::string eglErrorText(EGLint code) {
  const char* name = "unknown";
  switch (code) {
    case EGL_SUCCESS: name = "EGL_SUCCESS"; break;
    case EGL_NOT_INITIALIZED: name = "EGL_NOT_INITIALIZED"; break;
    case EGL_BAD_ACCESS: name = "EGL_BAD_ACCESS"; break;
    case EGL_BAD_ALLOC: name = "EGL_BAD_ALLOC"; break;
    case EGL_BAD_ATTRIBUTE: name = "EGL_BAD_ATTRIBUTE"; break;
    case EGL_BAD_CONFIG: name = "EGL_BAD_CONFIG"; break;
    case EGL_BAD_CONTEXT: name = "EGL_BAD_CONTEXT"; break;
    case EGL_BAD_DISPLAY: name = "EGL_BAD_DISPLAY"; break;
    case EGL_BAD_MATCH: name = "EGL_BAD_MATCH"; break;
    case EGL_BAD_PARAMETER: name = "EGL_BAD_PARAMETER"; break;
    case EGL_BAD_SURFACE: name = "EGL_BAD_SURFACE"; break;
    default: break;
  }
  char buf[64];
  std::snprintf(buf, sizeof buf, "eglGetError 0x%04X %s", unsigned(code), name);
  return buf;
}

bool hasExtension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    const bool startOk = p == list || p[-1] == ' ';
    const bool endOk = p[n] == ' ' || p[n] == '\0';
    if (startOk && endOk) return true;
  }
  return false;
}

/// One way of getting a display and a current 4.5 core context; on failure
/// `error` says which step failed and everything it made is released.
struct Attempt {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface surface = EGL_NO_SURFACE;
  std::string error;

  bool fail(const char* step) {
    error = std::string(step) + " failed (" + eglErrorText(eglGetError()) + ")";
    release();
    return false;
  }
  void release() {
    if (display == EGL_NO_DISPLAY) return;
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (surface != EGL_NO_SURFACE) eglDestroySurface(display, surface);
    if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
    eglTerminate(display);
    display = EGL_NO_DISPLAY;
    context = EGL_NO_CONTEXT;
    surface = EGL_NO_SURFACE;
  }

  /// `needPbuffer`: make a small pbuffer current instead of no surface
  /// (the default display may not offer surfaceless contexts).
  bool run(EGLDisplay d, bool needPbuffer) {
    display = d;
    if (display == EGL_NO_DISPLAY) return fail("getting the display");
    if (!eglInitialize(display, nullptr, nullptr)) {
      display = EGL_NO_DISPLAY;  // nothing to terminate
      return fail("eglInitialize");
    }
    if (!eglBindAPI(EGL_OPENGL_API)) return fail("eglBindAPI(EGL_OPENGL_API)");
    const EGLint configAttribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                    EGL_OPENGL_BIT, EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8,
                                    EGL_BLUE_SIZE, 8, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint count = 0;
    if (!eglChooseConfig(display, configAttribs, &config, 1, &count) || count < 1) {
      return fail("eglChooseConfig (an OpenGL-renderable pbuffer config)");
    }
    const EGLint contextAttribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                     EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                     EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    context = eglCreateContext(display, config, EGL_NO_CONTEXT, contextAttribs);
    if (context == EGL_NO_CONTEXT) return fail("eglCreateContext (OpenGL 4.5 core)");
    if (needPbuffer) {
      const EGLint pbufferAttribs[] = {EGL_WIDTH, 16, EGL_HEIGHT, 16, EGL_NONE};
      surface = eglCreatePbufferSurface(display, config, pbufferAttribs);
      if (surface == EGL_NO_SURFACE) return fail("eglCreatePbufferSurface");
    }
    if (!eglMakeCurrent(display, surface, surface, context)) return fail("eglMakeCurrent");
    return true;
  }
};

}  // namespace

Result<std::unique_ptr<EglContext>> EglContext::create() {
  std::string errors;
  const char* clientExtensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (hasExtension(clientExtensions, "EGL_MESA_platform_surfaceless")) {
    Attempt a;
    if (a.run(eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
              false)) {
      std::unique_ptr<EglContext> c(new EglContext());
      c->display_ = a.display;
      c->context_ = a.context;
      c->platform_ = "surfaceless";
      return c;
    }
    errors = "surfaceless platform: " + a.error + "; ";
  } else {
    errors = "surfaceless platform: EGL_MESA_platform_surfaceless is not offered; ";
  }
  Attempt b;
  if (b.run(eglGetDisplay(EGL_DEFAULT_DISPLAY), true)) {
    std::unique_ptr<EglContext> c(new EglContext());
    c->display_ = b.display;
    c->context_ = b.context;
    c->surface_ = b.surface;
    c->platform_ = "default display + pbuffer";
    return c;
  }
  errors += "default display: " + b.error;
  return Problem{"EGL", 0,
                 "EGL: cannot open a headless OpenGL 4.5 core context: " + errors +
                     ". Hint: install Mesa's EGL driver (apt-get install libegl-mesa0; llvmpipe "
                     "needs no GPU) or set EGL_PLATFORM=surfaceless; EGL_LOG_LEVEL=debug shows why a driver refused"};
}

Result<std::unique_ptr<EglContext>> EglContext::createOn(PresentTarget& window) {
  const PresentTarget::EglSurface w = window.eglSurface();
  auto fail = [](const char* step) {
    return Problem{"EGL", 0, "EGL: cannot open the renderer's OpenGL 4.5 core context on the window: " +
                                 std::string(step) + " failed (" + eglErrorText(eglGetError()) + ")"};
  };
  if (!w.display || !w.config || !w.surface) {
    return Problem{"EGL", 0, "EGL: the window has no EGL surface to present to"};
  }
  if (!eglBindAPI(EGL_OPENGL_API)) return fail("eglBindAPI(EGL_OPENGL_API)");
  const EGLint contextAttribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                   EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                   EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  const EGLContext context = eglCreateContext(w.display, w.config, EGL_NO_CONTEXT, contextAttribs);
  if (context == EGL_NO_CONTEXT) return fail("eglCreateContext (OpenGL 4.5 core)");
  bool current = false;
  window.withSurface([&](std::uint32_t, std::uint32_t) {
    current = eglMakeCurrent(w.display, w.surface, w.surface, context);
  });
  if (!current) {
    auto p = fail("eglMakeCurrent (the window surface)");
    eglDestroyContext(w.display, context);
    return p;
  }
  std::unique_ptr<EglContext> c(new EglContext());
  c->display_ = w.display;
  c->context_ = context;
  c->surface_ = w.surface;
  c->window_ = &window;
  c->platform_ = "X11 window surface";
  return c;
}

Status EglContext::swapBuffers() {
  if (!window_) return Problem{"EGL", 0, "EGL: a headless context has no window to swap"};
  if (!eglSwapBuffers(display_, surface_)) {
    return Problem{"EGL", 0, "EGL: eglSwapBuffers failed (" + eglErrorText(eglGetError()) + ")"};
  }
  return {};
}

EglContext::~EglContext() {
  if (!display_) return;
  if (window_) {
    // The display and surface are the window's: release only our context.
    window_->withSurface([&](std::uint32_t, std::uint32_t) {
      eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    });
    eglDestroyContext(display_, context_);
    return;
  }
  eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (surface_) eglDestroySurface(display_, surface_);
  if (context_) eglDestroyContext(display_, context_);
  eglTerminate(display_);
}

}  // namespace sandtable::render
