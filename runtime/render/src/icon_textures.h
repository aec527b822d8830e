#pragma once
// The icons' textures on the GPU: every texture of icons.pack (PNG or JPEG
// bytes as the models had them) decoded with libpng or libjpeg (not GDAL:
// the runtime links no GDAL), resampled to one square size and uploaded as
// one layer of a mipmapped texture array, so that all icons draw from one
// binding. Private to the renderer. The decoders are pure functions, safe
// on any thread; GL calls on the thread whose context is current. Design:
// docs/VIEWER.md, "Objects".
#include <epoxy/gl.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"

namespace sandtable::render::detail {

/// Texels a side of each icon texture layer.
inline constexpr std::uint32_t kIconTextureTexels = 256;

/// The largest image side and texel count decoded; checked from the
/// header before any allocation (a texture is drawn 256 texels a side).
inline constexpr std::uint32_t kMaxImageSide = 16384;
inline constexpr std::uint64_t kMaxImageTexels = std::uint64_t(1) << 24;

/// An image as its file holds it: RGBA8, top row first.
struct DecodedImage {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  ///< width * height * 4
};

/// Decodes PNG (libpng: palettes and transparency expanded, 16-bit
/// reduced, the file's gamma honoured) or JPEG (libjpeg, grey or YCbCr)
/// bytes at their own size. Grey is spread to RGB; alpha is 255 where the
/// image has none. Fails naming `name` for other formats, damaged bytes or
/// images past the limits above.
Result<DecodedImage> decodeImage(std::span<const std::byte> bytes, const std::string& name);

/// `img` resampled to `texels` x `texels` with GDAL's bilinear kernel (a
/// tent one texel wide, widened to the scale when shrinking, weights
/// renormalised at the edges), each channel alone, rows bottom first
/// (GL's and the icons' texture coordinate origin).
std::vector<std::uint8_t> resampleSquare(const DecodedImage& img, std::uint32_t texels);

/// decodeImage, then resampleSquare.
Result<std::vector<std::uint8_t>> decodeIconTexture(std::span<const std::byte> bytes, const std::string& name,
                                                    std::uint32_t texels = kIconTextureTexels);

/// An RGBA8 GL_TEXTURE_2D_ARRAY of `layers` layers of `texels` square with
/// every mipmap level, sampled trilinearly, wrapping as `wrap` says.
GLuint createTextureArray(std::uint32_t texels, std::uint32_t layers, GLenum wrap);

/// One GL_TEXTURE_2D_ARRAY with a layer per pack texture (layer k = pack
/// texture k), mipmapped, repeating; 0 when the pack has no textures. A
/// texture that does not decode becomes a white layer (its materials show
/// their base colour) and a line in `warnings`.
GLuint uploadIconTextures(const iconpack::Pack& pack, std::vector<std::string>& warnings);

}  // namespace sandtable::render::detail
