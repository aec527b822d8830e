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
#include <vector>

#include "sandtable/formats/result.h"
#include "sandtable/runtime/display_buffer.h"
#include "sandtable/runtime/image.h"

namespace sandtable::runtime {

/// Problem::file of every failure to open the headless context, so callers
/// can tell "no GL here" from other errors.
inline constexpr const char* kGlContextProblem = "EGL";

/// Colours of one material class (materials.h): upper and lower grid
/// triangle, as the seed shades the two halves of a square differently.
struct MaterialColour {
  Rgb upper{0x6E, 0x8C, 0x46}, lower{0x64, 0x82, 0x40};
};

struct RenderSettings {
  std::uint32_t width = 1280, height = 720;
  Rgb background{0x87, 0xCE, 0xEB};  ///< sky at the horizon and fog colour
  bool fog = true;
  /// Draw the sky; false leaves the clear colour wherever no terrain is
  /// drawn (the crack tests clear to magenta).
  bool sky = true;
  Rgb clearColour{0xFF, 0x00, 0xFF};
  /// Multisampling (0 = off): resolves thin, far decals to their coverage
  /// instead of letting them shimmer from frame to frame.
  std::uint32_t samples = 0;
  float minElevation = 0, maxElevation = 1000;  ///< scales the tint (grid mesh mode)
  /// Module mode: colour of each material id (index); ids beyond it get
  /// the default MaterialColour.
  std::vector<MaterialColour> palette;
};

/// What the render thread did for the last frame (module mode).
struct RenderStats {
  std::uint32_t uploads = 0;        ///< (module, level) buffers built this frame
  std::uint32_t released = 0;       ///< buffers released this frame
  std::uint32_t cachedLevels = 0;   ///< (module, level) buffers held on the GPU
  std::uint64_t gpuBytes = 0;       ///< their vertex bytes
  double uploadMs = 0;              ///< building and uploading them
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

  /// Counters of the last draw.
  const RenderStats& stats() const;

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
