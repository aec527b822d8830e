#include <algorithm>

#include "sandtable/render/hud.h"

namespace sandtable::render {
namespace {

void blendPixel(Image& img, int x, int y, Rgb c, float alpha) {
  if (x < 0 || y < 0 || x >= int(img.width) || y >= int(img.height)) return;
  std::uint8_t* p = img.rgba.data() + (std::size_t(y) * img.width + std::size_t(x)) * 4;
  const auto mix = [alpha](std::uint8_t dst, std::uint8_t src) {
    return static_cast<std::uint8_t>(float(dst) + (float(src) - float(dst)) * alpha + 0.5f);
  };
  p[0] = mix(p[0], c.r);
  p[1] = mix(p[1], c.g);
  p[2] = mix(p[2], c.b);
  p[3] = mix(p[3], 255);  // coverage: a frame stays opaque, an overlay's layer gains it
}

void fillRect(Image& img, int x0, int y0, int w, int h, Rgb c, float alpha) {
  for (int y = y0; y < y0 + h; ++y) {
    for (int x = x0; x < x0 + w; ++x) blendPixel(img, x, y, c, alpha);
  }
}

void drawGlyph(Image& img, int x, int y, const Glyph& g, int scale, Rgb color) {
  for (int row = 0; row < kGlyphHeight; ++row) {
    for (int col = 0; col < kGlyphWidth; ++col) {
      if (g[row] & (1u << (kGlyphWidth - 1 - col))) {
        fillRect(img, x + col * scale, y + row * scale, scale, scale, color, 1.0f);
      }
    }
  }
}

}  // namespace

std::u32string decodeHudText(std::string_view text) {
  std::u32string out;
  for (std::size_t k = 0; k < text.size(); ++k) {
    const auto b = static_cast<unsigned char>(text[k]);
    if (b == 0xC2 && k + 1 < text.size() && static_cast<unsigned char>(text[k + 1]) == 0xB0) {
      out.push_back(U'\u00B0');
      ++k;
    } else {
      out.push_back(b < 128 ? char32_t(b) : U'?');
    }
  }
  return out;
}

int textWidth(std::string_view text, int scale) {
  const auto n = static_cast<int>(decodeHudText(text).size());
  return n == 0 ? 0 : (n * kGlyphAdvance - 1) * scale;
}

void drawText(Image& img, int x, int y, std::string_view text, int scale, Rgb color) {
  int cx = x;
  for (const char32_t c : decodeHudText(text)) {
    drawGlyph(img, cx, y, glyphFor(c), scale, color);
    cx += kGlyphAdvance * scale;
  }
}

namespace {

int panelScale(std::uint32_t frameWidth) { return frameWidth >= 800 ? 2 : 1; }

void drawPanelText(Image& img, const std::vector<std::string>& lines) {
  const int scale = panelScale(img.width);
  const int pad = 4 * scale;
  int y = pad;
  for (const auto& l : lines) {
    drawText(img, pad, y, l, scale, Rgb{255, 255, 255});
    y += kLineAdvance * scale;
  }
}

}  // namespace

PixelBox hudPanelBox(std::uint32_t frameWidth, const std::vector<std::string>& lines) {
  if (lines.empty()) return {};
  const int scale = panelScale(frameWidth);
  const int pad = 4 * scale;
  int width = 0;
  for (const auto& l : lines) width = std::max(width, textWidth(l, scale));
  const int height = int(lines.size()) * kLineAdvance * scale - 3 * scale;
  return {0, 0, width + 2 * pad, height + 2 * pad};
}

void drawHudPanel(Image& img, const std::vector<std::string>& lines) {
  if (lines.empty()) return;
  const PixelBox b = hudPanelBox(img.width, lines);
  // Darken rather than cover so the terrain stays visible behind the text.
  fillRect(img, b.x, b.y, b.width, b.height, Rgb{0, 0, 0}, kHudPanelDarken);
  drawPanelText(img, lines);
}

PixelBox drawHudPanel(Overlay& overlay, const std::vector<std::string>& lines) {
  if (lines.empty()) return {};
  const PixelBox b = hudPanelBox(overlay.layer().width, lines);
  overlay.darken(b, kHudPanelDarken);
  drawPanelText(overlay.layer(), lines);
  overlay.drawn(b);
  return b;
}

}  // namespace sandtable::render
