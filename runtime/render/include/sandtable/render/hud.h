#pragma once
// The information panel (seed chapter VI: "the information panel"): a few
// lines of text in a darkened box, with a 5 x 7 bitmap font drawn for
// sandtable. The flight loop draws it into the HUD pass's overlay
// (overlay.h), which the GPU blends over the frame; drawHudPanel(Image&)
// draws the same panel straight onto a frame on the CPU. Upper-case letters, digits and
// . , : - / ( ) + % = ° _ and space; lower case prints as upper case, any
// other character as '?'.
//
// Thread safety: pure functions on caller-owned images and overlays.
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "sandtable/render/image.h"
#include "sandtable/render/overlay.h"

namespace sandtable::render {

inline constexpr int kGlyphWidth = 5;
inline constexpr int kGlyphHeight = 7;
inline constexpr int kGlyphAdvance = kGlyphWidth + 1;  ///< one blank column between glyphs
inline constexpr int kLineAdvance = kGlyphHeight + 3;

/// One glyph: 7 rows, top first; bit 4 is the leftmost of 5 columns.
using Glyph = std::array<std::uint8_t, kGlyphHeight>;

/// The glyph for a character; '?' for one the font lacks. The degree sign
/// is U+00B0 (UTF-8 "\xC2\xB0").
const Glyph& glyphFor(char32_t c);

/// Characters in `text` after UTF-8 decoding of the degree sign.
std::u32string decodeHudText(std::string_view text);

/// Width in pixels of one line at `scale` pixels per font dot.
int textWidth(std::string_view text, int scale);

/// Draws `text` with its top-left corner at (x, y); clipped to the image.
/// Its pixels get alpha 255, so text drawn into an overlay's layer covers.
void drawText(Image& img, int x, int y, std::string_view text, int scale, Rgb color);

/// How much the panel darkens the frame behind its text.
inline constexpr float kHudPanelDarken = 0.55f;

/// The panel's box on a frame `frameWidth` wide (at its top-left corner).
PixelBox hudPanelBox(std::uint32_t frameWidth, const std::vector<std::string>& lines);

/// Draws the lines in a darkened panel at the image's top-left corner.
/// Scale 2 for frames at least 800 pixels wide keeps it legible at HD.
void drawHudPanel(Image& img, const std::vector<std::string>& lines);
/// The same panel into the HUD pass's overlay: the box darkened, the text
/// into the layer. Returns the box.
PixelBox drawHudPanel(Overlay& overlay, const std::vector<std::string>& lines);

}  // namespace sandtable::render
