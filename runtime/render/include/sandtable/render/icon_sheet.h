#pragma once
// The icon contact sheet (`sandtable icons ... -o DIR`): one image with
// every icon of a pack at every level of detail, each in its own cell,
// with the icon's name, size and cylinder in a header line and each cell's
// level, triangle count and switch range under it. Design: docs/ICONS.md,
// "The contact sheet".
//
// Each icon is seen from the same direction in all its cells (from the
// south-east, `elevationDegrees` above the horizon), framed on the bounding
// sphere of its alive state, so that the levels compare pixel for pixel.
// Shading is the material's base colour times its texture (decoded
// through GDAL, as the viewer does), lit by one sun from behind the eye's
// left shoulder plus an ambient term.
//
// Thread safety: renderIconSheet creates its own headless EGL context and
// makes it current on the calling thread; it releases it before it
// returns, so call it where no other context must stay current.
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/render/image.h"

namespace sandtable::render {

struct IconSheetOptions {
  std::uint32_t cell = 200;          ///< pixels, square, per level
  float fovDegrees = 30.0f;          ///< vertical field of view of each cell
  float azimuthDegrees = 135.0f;     ///< the eye's bearing from the icon, clockwise from north
  float elevationDegrees = 20.0f;    ///< the eye's height above the horizon
  Rgb background{214, 222, 230};
  Rgb label{28, 32, 36};
};

/// Where each cell of a sheet lies, for callers and tests.
struct IconSheetCell {
  std::uint32_t icon = 0, level = 0;
  std::uint32_t x = 0, y = 0;        ///< top-left corner of the cell's picture
  std::uint64_t triangles = 0;
};

struct IconSheet {
  Image image;
  std::vector<IconSheetCell> cells;
  std::vector<std::string> warnings;  ///< textures that did not decode (drawn in their base colour)
};

/// Header band above each icon's row and label band under its cells.
inline constexpr std::uint32_t kIconSheetHeader = 24;
inline constexpr std::uint32_t kIconSheetFooter = 44;
inline constexpr std::uint32_t kIconSheetMargin = 8;

/// Renders icons [first, first + count) of `pack` (clamped to the pack),
/// one row per icon. Fails with an EGL or shader problem when no context
/// can be made; an empty range gives an empty sheet.
Result<IconSheet> renderIconSheet(const iconpack::Pack& pack, std::size_t first, std::size_t count,
                                  const IconSheetOptions& o = {});

}  // namespace sandtable::render
