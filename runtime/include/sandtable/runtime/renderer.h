#pragma once
// The renderer: draws a DisplayBuffer into an offscreen frame with OpenGL
// 4.5 core through headless EGL and reads it back.
//
// Each frame: the sky (a full-screen triangle shaded from the background
// colour at the horizon to a deeper tone at the zenith), then the selected
// terrain strips from a streamed vertex buffer with one glMultiDrawArrays,
// tinted by elevation, lit by a fixed sun from the stored normals and fogged
// towards the background colour, full fog at the view distance.
//
// Thread safety: a Renderer owns a GL context that is current on the thread
// that created it. Create, use and destroy it on that one thread (the render
// thread); it reads DisplayBuffers that other threads filled.
#include <cstdint>
#include <memory>
#include <string>

#include "sandtable/formats/result.h"
#include "sandtable/runtime/display_buffer.h"
#include "sandtable/runtime/image.h"

namespace sandtable::runtime {

/// Problem::file of every failure to open the headless context, so callers
/// can tell "no GL here" from other errors.
inline constexpr const char* kGlContextProblem = "EGL";

struct RenderSettings {
  std::uint32_t width = 1280, height = 720;
  Rgb background{0x87, 0xCE, 0xEB};  ///< sky at the horizon and fog colour
  bool fog = true;
  float minElevation = 0, maxElevation = 1000;  ///< scales the tint
};

class Renderer {
 public:
  static Result<std::unique_ptr<Renderer>> create(const RenderSettings& s);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Draws `buf` and reads the frame into `out` (top row first). Returns ""
  /// or a GL error.
  std::string draw(const DisplayBuffer& buf, Image& out);

  /// GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  const std::string& glRenderer() const;
  /// GL_VERSION and the EGL platform used.
  std::string description() const;

 private:
  struct Impl;
  explicit Renderer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Whether a headless GL 4.5 core context can be opened here; `why` gets
/// the reason when not. Opens and closes one context.
bool headlessGlAvailable(std::string& why);

}  // namespace sandtable::runtime
