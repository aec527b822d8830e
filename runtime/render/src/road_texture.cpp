// The road texture: grain, darker shoulders, white edge lines and a
// dashed centre line (docs/CULTURE.md 8), mipmapped and, on a GPU,
// filtered anisotropically.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "module_draw.h"

namespace sandtable::render::detail {
namespace {

/// Road texture: T across (u), S along (v), one repeat per road width.
constexpr int kRoadTextureSize = 128;

/// Road texture texel (u across, v along, both 0..1): rgb multiplies the
/// road's colour (grain, darker shoulders), alpha is marking coverage
/// (white edge lines and a dashed centre line, SurfaceKind::marked).
std::array<std::uint8_t, 4> roadTexel(double u, double v, std::uint32_t hash) {
  const double noise = double(hash % 1000) / 1000.0;  // 0..1, per texel
  double shade = 0.90 + 0.10 * noise;
  const double edge = std::min(u, 1.0 - u);
  if (edge < 0.035) shade *= 0.70;  // worn shoulder
  double mark = 0;
  if (edge >= 0.045 && edge < 0.095) mark = 1;                    // edge line
  if (std::abs(u - 0.5) < 0.02 && v < 0.45) mark = 1;             // centre dash
  const auto byte = [](double x) { return std::uint8_t(std::lround(std::clamp(x, 0.0, 1.0) * 255.0)); };
  return {byte(shade), byte(shade), byte(shade), byte(mark * (0.85 + 0.15 * noise))};
}

}  // namespace

void ModuleRenderer::createRoadTexture() {
  constexpr int n = kRoadTextureSize;
  std::vector<std::uint8_t> texels(std::size_t(n) * n * 4);
  std::uint32_t hash = 0x9E3779B9u;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      hash = hash * 1664525u + 1013904223u;
      const auto t = roadTexel((x + 0.5) / n, (y + 0.5) / n, hash >> 8);
      std::copy(t.begin(), t.end(), texels.begin() + (std::ptrdiff_t(y) * n + x) * 4);
    }
  }
  const auto levels = GLsizei(std::log2(n)) + 1;
  glCreateTextures(GL_TEXTURE_2D, 1, &roadTexture_);
  glTextureStorage2D(roadTexture_, levels, GL_RGBA8, n, n);
  glTextureSubImage2D(roadTexture_, 0, 0, 0, n, n, GL_RGBA, GL_UNSIGNED_BYTE, texels.data());
  glGenerateTextureMipmap(roadTexture_);
  glTextureParameteri(roadTexture_, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);  // across
  glTextureParameteri(roadTexture_, GL_TEXTURE_WRAP_T, GL_REPEAT);         // along
  glTextureParameteri(roadTexture_, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTextureParameteri(roadTexture_, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  // Roads are seen at grazing angles: anisotropic filtering keeps their
  // markings from blurring into the asphalt, where the GPU does it in
  // hardware. llvmpipe filters anisotropically in software at seconds per
  // frame, so there the mipmaps alone must do.
  const std::string renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const bool software = renderer.find("llvmpipe") != std::string::npos ||
                        renderer.find("softpipe") != std::string::npos;
  if (!software && (epoxy_has_gl_extension("GL_EXT_texture_filter_anisotropic") ||
                    epoxy_has_gl_extension("GL_ARB_texture_filter_anisotropic"))) {
    GLfloat most = 1;
    glGetFloatv(GL_MAX_TEXTURE_MAX_ANISOTROPY_EXT, &most);
    glTextureParameterf(roadTexture_, GL_TEXTURE_MAX_ANISOTROPY_EXT, std::min(most, 8.0f));
  }
}

}  // namespace sandtable::render::detail
