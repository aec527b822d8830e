#include "sandtable/viewer/x11_window.h"

#include <epoxy/gl.h>

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <X11/XKBlib.h>
#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <X11/keysym.h>
// Xlib defines Status as a macro; ours is sandtable::Status (base/result.h).
#undef Status
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>

#include "sandtable/render/gl_program.h"

namespace sandtable::viewer {

struct ViewerWindow::Gl {
  render::GlProgram program;
  GLuint vao = 0, texture = 0;
  std::uint32_t texW = 0, texH = 0;
};

namespace {

Display* dpyOf(void* p) { return static_cast<Display*>(p); }

std::string eglError(const char* step) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%s failed (eglGetError 0x%04X)", step, unsigned(eglGetError()));
  return buf;
}

bool hasExtension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

/// Whatever EGL had current on this thread; restore() puts it back, so the
/// renderer's headless context is untouched by the window.
class SavedEgl {
 public:
  SavedEgl()
      : api_(eglQueryAPI()),
        display_((eglBindAPI(EGL_OPENGL_API), eglGetCurrentDisplay())),
        draw_(eglGetCurrentSurface(EGL_DRAW)),
        read_(eglGetCurrentSurface(EGL_READ)),
        context_(eglGetCurrentContext()) {}
  SavedEgl(const SavedEgl&) = delete;
  SavedEgl& operator=(const SavedEgl&) = delete;
  /// `ours`: the window's display, to release its context when nothing
  /// was current before.
  void restore(EGLDisplay ours) {
    if (context_ != EGL_NO_CONTEXT) {
      eglMakeCurrent(display_, draw_, read_, context_);
    } else if (ours != EGL_NO_DISPLAY) {
      eglMakeCurrent(ours, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    }
    eglBindAPI(api_);
  }

 private:
  EGLenum api_;
  EGLDisplay display_;
  EGLSurface draw_, read_;
  EGLContext context_;
};

std::optional<world::Key> keyForSym(KeySym s) {
  if (s >= XK_0 && s <= XK_9) return world::Key(int(world::Key::digit0) + int(s - XK_0));
  if (s >= XK_KP_0 && s <= XK_KP_9) return world::Key(int(world::Key::digit0) + int(s - XK_KP_0));
  switch (s) {
    case XK_Up: case XK_KP_Up: return world::Key::up;
    case XK_Down: case XK_KP_Down: return world::Key::down;
    case XK_Left: case XK_KP_Left: return world::Key::left;
    case XK_Right: case XK_KP_Right: return world::Key::right;
    case XK_plus: case XK_equal: case XK_KP_Add: return world::Key::plus;  // '=' is unshifted '+' on US keyboards
    case XK_minus: case XK_KP_Subtract: return world::Key::minus;
    case XK_m: case XK_M: return world::Key::map;
    case XK_bracketleft: return world::Key::mapZoomOut;
    case XK_bracketright: return world::Key::mapZoomIn;
    case XK_Page_Up: case XK_KP_Page_Up: return world::Key::pageUp;
    case XK_Page_Down: case XK_KP_Page_Down: return world::Key::pageDown;
    case XK_f: case XK_F: return world::Key::groundFollow;
    case XK_p: case XK_P: case XK_F12: return world::Key::screenshot;
    case XK_Escape: case XK_q: case XK_Q: return world::Key::quit;
    default: return std::nullopt;
  }
}

/// The entity keys (viewer_keys.h); Shift turns Tab backwards.
std::optional<ViewerKey> viewerKeyForSym(KeySym s, bool shift) {
  switch (s) {
    case XK_Tab: return shift ? ViewerKey::previousEntity : ViewerKey::nextEntity;
    case XK_ISO_Left_Tab: return ViewerKey::previousEntity;
    case XK_e: case XK_E: return ViewerKey::stealth;
    case XK_d: case XK_D: return ViewerKey::drive;
    case XK_space: return ViewerKey::allStop;
    default: return std::nullopt;
  }
}

// Over kFullScreenVertexGlsl; image row 0 is the top.
constexpr const char* kFragment = R"(#version 450 core
in vec2 vNdc;
layout(binding = 0) uniform sampler2D frame;
out vec4 color;
void main() { color = vec4(texture(frame, vec2(vNdc.x * 0.5 + 0.5, 0.5 - vNdc.y * 0.5)).rgb, 1.0); })";

/// Shift and width of a visual's colour mask, for converting XGetImage pixels.
void maskShape(unsigned long mask, int& shift, int& bits) {
  shift = 0;
  bits = 0;
  if (!mask) return;
  while (!(mask & 1)) {
    mask >>= 1;
    ++shift;
  }
  while (mask & 1) {
    mask >>= 1;
    ++bits;
  }
}

std::uint8_t channel(unsigned long pixel, int shift, int bits) {
  if (bits == 0) return 0;
  const unsigned long v = (pixel >> shift) & ((1ul << bits) - 1);
  return std::uint8_t(bits >= 8 ? v >> (bits - 8) : v * 255 / ((1ul << bits) - 1));
}

}  // namespace

bool ViewerWindow::displayConfigured() {
  const char* d = std::getenv("DISPLAY");
  return d && *d;
}

Result<std::unique_ptr<ViewerWindow>> ViewerWindow::open(std::uint32_t width, std::uint32_t height,
                                                         const std::string& title,
                                                         const std::string& display) {
  auto fail = [](const std::string& m) { return Problem{kWindowProblem, 0, "window: " + m}; };
  if (width == 0 || height == 0) return fail("size must not be zero");
  if (display.empty() && !displayConfigured()) {
    return fail("DISPLAY is not set, so there is no X server to open a window on; run in a desktop "
                "session, under Xvfb (xvfb-run), or fly headless to PNG frames");
  }
  const std::string name = display.empty() ? std::getenv("DISPLAY") : display;
  std::unique_ptr<ViewerWindow> w(new ViewerWindow());
  w->display_ = XOpenDisplay(name.c_str());
  if (!w->display_) {
    return fail("cannot open X display \"" + name + "\" (is the X server running, and may this user "
                "connect to it? check DISPLAY and XAUTHORITY)");
  }
  Display* dpy = dpyOf(w->display_);
  const int screen = DefaultScreen(dpy);

  const char* ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  EGLDisplay ed = EGL_NO_DISPLAY;
  if (hasExtension(ext, "EGL_KHR_platform_x11")) {
    const EGLAttrib attrs[] = {EGL_PLATFORM_X11_SCREEN_KHR, screen, EGL_NONE};
    ed = eglGetPlatformDisplay(EGL_PLATFORM_X11_KHR, dpy, attrs);
  } else if (hasExtension(ext, "EGL_EXT_platform_x11")) {
    auto getDisplay = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
    const EGLint attrs[] = {EGL_PLATFORM_X11_SCREEN_EXT, screen, EGL_NONE};
    if (getDisplay) ed = getDisplay(EGL_PLATFORM_X11_EXT, dpy, attrs);
  } else {
    return fail("EGL offers no X11 platform (neither EGL_KHR_platform_x11 nor EGL_EXT_platform_x11); "
                "install Mesa's EGL driver: apt-get install libegl-mesa0");
  }
  if (ed == EGL_NO_DISPLAY) return fail(eglError("eglGetPlatformDisplay(X11)"));
  if (!eglInitialize(ed, nullptr, nullptr)) return fail(eglError("eglInitialize(X11 display)"));
  w->eglDisplay_ = ed;
  if (!eglBindAPI(EGL_OPENGL_API)) return fail(eglError("eglBindAPI(EGL_OPENGL_API)"));

  const EGLint configAttrs[] = {EGL_SURFACE_TYPE, EGL_WINDOW_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                                EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8, EGL_NONE};
  EGLConfig configs[64];
  EGLint count = 0;
  if (!eglChooseConfig(ed, configAttrs, configs, 64, &count) || count < 1) {
    return fail(eglError("eglChooseConfig (an OpenGL-renderable window config)"));
  }
  // The first config whose X visual exists on this screen.
  EGLConfig config = nullptr;
  XVisualInfo* vi = nullptr;
  for (EGLint k = 0; k < count && !vi; ++k) {
    EGLint visualId = 0;
    if (!eglGetConfigAttrib(ed, configs[k], EGL_NATIVE_VISUAL_ID, &visualId) || visualId == 0) continue;
    XVisualInfo tmpl{};
    tmpl.visualid = VisualID(visualId);
    tmpl.screen = screen;
    int n = 0;
    vi = XGetVisualInfo(dpy, VisualIDMask | VisualScreenMask, &tmpl, &n);
    if (vi) config = configs[k];
  }
  if (!vi) return fail("no EGL window config has an X visual on screen " + std::to_string(screen));

  const Window root = RootWindow(dpy, screen);
  w->colormap_ = XCreateColormap(dpy, root, vi->visual, AllocNone);
  XSetWindowAttributes swa{};
  swa.colormap = w->colormap_;
  swa.background_pixel = BlackPixel(dpy, screen);
  swa.border_pixel = 0;
  swa.event_mask = KeyPressMask | KeyReleaseMask | StructureNotifyMask | ExposureMask | FocusChangeMask;
  w->window_ = XCreateWindow(dpy, root, 0, 0, width, height, 0, vi->depth, InputOutput, vi->visual,
                             CWColormap | CWBackPixel | CWBorderPixel | CWEventMask, &swa);
  XFree(vi);
  w->width_ = width;
  w->height_ = height;
  XStoreName(dpy, w->window_, title.c_str());
  Atom wmDelete = XInternAtom(dpy, "WM_DELETE_WINDOW", False);
  w->wmDelete_ = wmDelete;
  XSetWMProtocols(dpy, w->window_, &wmDelete, 1);
  // One press and one release per held key, not a stream of both.
  XkbSetDetectableAutoRepeat(dpy, True, nullptr);
  XMapWindow(dpy, w->window_);
  // Wait for the map (a window manager may take a moment), taking only
  // MapNotify so the other events stay queued for pollEvents().
  XEvent ev;
  bool mapped = false;
  for (int tries = 0; tries < 2500 && !mapped; ++tries) {
    if (XCheckTypedWindowEvent(dpy, w->window_, MapNotify, &ev)) {
      mapped = true;
    } else {
      const timespec pause{0, 2'000'000};
      nanosleep(&pause, nullptr);
    }
  }
  if (!mapped) return fail("the X server did not map the window within 5 s");

  w->eglSurface_ = eglCreateWindowSurface(ed, config, EGLNativeWindowType(w->window_), nullptr);
  if (w->eglSurface_ == EGL_NO_SURFACE) return fail(eglError("eglCreateWindowSurface"));
  const EGLint ctxAttrs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                             EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  SavedEgl saved;
  w->eglContext_ = eglCreateContext(ed, config, EGL_NO_CONTEXT, ctxAttrs);
  if (w->eglContext_ == EGL_NO_CONTEXT) {
    saved.restore(EGL_NO_DISPLAY);
    return fail(eglError("eglCreateContext (OpenGL 4.5 core) for the window"));
  }
  if (!eglMakeCurrent(ed, w->eglSurface_, w->eglSurface_, w->eglContext_)) {
    saved.restore(EGL_NO_DISPLAY);
    return fail(eglError("eglMakeCurrent (window)"));
  }
  w->eglConfig_ = config;
  Status gl = w->makeGl();
  saved.restore(ed);
  if (!gl) return gl.problems();
  return w;
}

Status ViewerWindow::makeGl() {
  if (epoxy_gl_version() < 45) {
    return Problem{kWindowProblem, 0,
                   "window: the window's context offers OpenGL " + std::to_string(epoxy_gl_version()) +
                       ", 4.5 is needed"};
  }
  if (const auto* r = glGetString(GL_RENDERER)) renderer_ = reinterpret_cast<const char*>(r);
  gl_ = std::make_unique<Gl>();
  auto program = render::GlProgram::build("window", render::kFullScreenVertexGlsl, kFragment);
  if (!program) return program.problems();
  gl_->program = std::move(program.value());
  glCreateVertexArrays(1, &gl_->vao);
  return {};
}

render::PresentTarget::EglSurface ViewerWindow::eglSurface() const {
  std::lock_guard lock(mutex_);
  return {eglDisplay_, eglConfig_, eglSurface_};
}

void ViewerWindow::withSurface(const std::function<void(std::uint32_t, std::uint32_t)>& use) {
  std::lock_guard lock(mutex_);
  use(width_, height_);
}

std::uint32_t ViewerWindow::width() const {
  std::lock_guard lock(mutex_);
  return width_;
}

std::uint32_t ViewerWindow::height() const {
  std::lock_guard lock(mutex_);
  return height_;
}

std::vector<world::KeyEvent> ViewerWindow::pollEvents() {
  std::lock_guard lock(mutex_);
  std::vector<world::KeyEvent> out;
  Display* dpy = dpyOf(display_);
  auto emit = [&](world::Key k, bool pressed) {
    const std::uint32_t bit = 1u << unsigned(k);
    if (pressed) downMask_ |= bit;
    else downMask_ &= ~bit;
    out.push_back({k, pressed});
  };
  while (XPending(dpy) > 0) {
    XEvent ev;
    XNextEvent(dpy, &ev);
    switch (ev.type) {
      case KeyPress:
      case KeyRelease: {
        std::optional<world::Key> k = keyForSym(XLookupKeysym(&ev.xkey, 0));
        if (!k) k = keyForSym(XLookupKeysym(&ev.xkey, 1));  // shifted: '+' and keypad digits
        if (k) {
          emit(*k, ev.type == KeyPress);
        } else if (ev.type == KeyPress) {
          if (auto v = viewerKeyForSym(XLookupKeysym(&ev.xkey, 0), (ev.xkey.state & ShiftMask) != 0)) {
            viewerKeys_.push_back(*v);
          }
        }
        break;
      }
      case FocusOut:
        // A key released in another window never reaches us; release
        // everything so no key stays "held" (and repeating) for ever.
        for (std::size_t k = 0; k < world::kKeyCount; ++k) {
          if (downMask_ & (1u << k)) emit(world::Key(k), false);
        }
        break;
      case ConfigureNotify:
        width_ = std::uint32_t(std::max(1, ev.xconfigure.width));
        height_ = std::uint32_t(std::max(1, ev.xconfigure.height));
        break;
      case ClientMessage:
        if (Atom(ev.xclient.data.l[0]) == Atom(wmDelete_)) {
          closeRequested_ = true;
          out.push_back({world::Key::quit, true});
        }
        break;
      default: break;
    }
  }
  return out;
}

std::vector<ViewerKey> ViewerWindow::takeViewerKeys() {
  std::lock_guard lock(mutex_);
  std::vector<ViewerKey> out;
  out.swap(viewerKeys_);
  return out;
}

Status ViewerWindow::present(const render::Image& frame) {
  auto fail = [](const std::string& m) { return Problem{kWindowProblem, 0, "window: " + m}; };
  if (frame.width == 0 || frame.height == 0 || frame.rgba.size() != std::size_t(frame.width) * frame.height * 4) {
    return fail("present() needs a non-empty RGBA frame");
  }
  std::lock_guard lock(mutex_);
  SavedEgl saved;
  if (!eglMakeCurrent(eglDisplay_, eglSurface_, eglSurface_, eglContext_)) {
    saved.restore(EGL_NO_DISPLAY);
    return fail(eglError("eglMakeCurrent (window)"));
  }
  if (gl_->texW != frame.width || gl_->texH != frame.height) {
    if (gl_->texture) glDeleteTextures(1, &gl_->texture);
    glCreateTextures(GL_TEXTURE_2D, 1, &gl_->texture);
    glTextureStorage2D(gl_->texture, 1, GL_RGBA8, GLsizei(frame.width), GLsizei(frame.height));
    glTextureParameteri(gl_->texture, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(gl_->texture, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTextureParameteri(gl_->texture, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(gl_->texture, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    gl_->texW = frame.width;
    gl_->texH = frame.height;
  }
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTextureSubImage2D(gl_->texture, 0, 0, 0, GLsizei(frame.width), GLsizei(frame.height), GL_RGBA,
                      GL_UNSIGNED_BYTE, frame.rgba.data());
  // Fit the frame inside the window, keeping its aspect.
  const double s = std::min(double(width_) / frame.width, double(height_) / frame.height);
  const auto vw = GLsizei(std::lround(frame.width * s)), vh = GLsizei(std::lround(frame.height * s));
  glViewport(0, 0, GLsizei(width_), GLsizei(height_));
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  glViewport((GLint(width_) - vw) / 2, (GLint(height_) - vh) / 2, vw, vh);
  gl_->program.use();
  glBindTextureUnit(0, gl_->texture);
  glBindVertexArray(gl_->vao);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
  const GLenum glErr = glGetError();
  Status st;
  if (glErr != GL_NO_ERROR) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "GL error 0x%04X drawing the frame", unsigned(glErr));
    st = fail(buf);
  }
  if (!eglSwapBuffers(eglDisplay_, eglSurface_) && st) st = fail(eglError("eglSwapBuffers"));
  saved.restore(eglDisplay_);
  return st;
}

Result<render::Image> ViewerWindow::capture() {
  std::lock_guard lock(mutex_);
  Display* dpy = dpyOf(display_);
  XSync(dpy, False);
  XImage* xi = XGetImage(dpy, window_, 0, 0, width_, height_, AllPlanes, ZPixmap);
  if (!xi) return Problem{kWindowProblem, 0, "window: XGetImage failed (is the window mapped and on screen?)"};
  int rs, rb, gs, gb, bs, bb;
  maskShape(xi->red_mask, rs, rb);
  maskShape(xi->green_mask, gs, gb);
  maskShape(xi->blue_mask, bs, bb);
  render::Image img;
  img.width = width_;
  img.height = height_;
  img.rgba.resize(std::size_t(width_) * height_ * 4);
  for (std::uint32_t y = 0; y < height_; ++y) {
    for (std::uint32_t x = 0; x < width_; ++x) {
      const unsigned long p = XGetPixel(xi, int(x), int(y));
      std::uint8_t* d = &img.rgba[(std::size_t(y) * width_ + x) * 4];
      d[0] = channel(p, rs, rb);
      d[1] = channel(p, gs, gb);
      d[2] = channel(p, bs, bb);
      d[3] = 255;
    }
  }
  XDestroyImage(xi);
  return img;
}

void ViewerWindow::releaseEgl() {
  if (!eglDisplay_) return;
  if (gl_ && eglContext_ && eglSurface_) {
    SavedEgl saved;
    if (eglMakeCurrent(eglDisplay_, eglSurface_, eglSurface_, eglContext_)) {
      if (gl_->texture) glDeleteTextures(1, &gl_->texture);
      if (gl_->vao) glDeleteVertexArrays(1, &gl_->vao);
      gl_->program.reset();
    }
    saved.restore(eglDisplay_);
  }
  if (gl_) gl_->program.abandon();  // its context is destroyed next
  if (eglContext_) eglDestroyContext(eglDisplay_, eglContext_);
  if (eglSurface_) eglDestroySurface(eglDisplay_, eglSurface_);
  // A renderer on this display (PresentTarget) is gone by now: it may not
  // outlive the window. A headless renderer's display is another.
  eglTerminate(eglDisplay_);
  eglDisplay_ = nullptr;
  eglContext_ = nullptr;
  eglSurface_ = nullptr;
}

ViewerWindow::~ViewerWindow() {
  std::lock_guard lock(mutex_);
  releaseEgl();
  if (!display_) return;
  Display* dpy = dpyOf(display_);
  if (window_) XDestroyWindow(dpy, window_);
  if (colormap_) XFreeColormap(dpy, colormap_);
  XCloseDisplay(dpy);
}

}  // namespace sandtable::viewer
