#pragma once
// The icons' textures on the GPU: every texture of icons.pack (PNG or JPEG
// bytes as the models had them) decoded through GDAL, resampled to one
// square size and uploaded as one layer of a mipmapped texture array, so
// that all icons draw from one binding. Private to the renderer; GL calls
// on the thread whose context is current. Design: docs/VIEWER.md, "Objects".
#include <epoxy/gl.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"

namespace sandtable::runtime::detail {

/// Texels a side of each icon texture layer.
inline constexpr std::uint32_t kIconTextureTexels = 256;

/// Decodes an image file's bytes (any format GDAL reads: PNG, JPEG, ...)
/// into `texels` x `texels` RGBA8, bilinearly resampled, rows bottom first
/// (GL's and the icons' texture coordinate origin). Grey images are
/// spread to RGB; alpha is 255 where the image has none. Fails naming
/// `name` when GDAL cannot read the bytes.
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

}  // namespace sandtable::runtime::detail
