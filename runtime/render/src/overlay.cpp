#include "sandtable/render/overlay.h"

#include <algorithm>
#include <atomic>
#include <cstring>

namespace sandtable::render {

Overlay::Overlay() {
  static std::atomic<std::uint64_t> next{1};
  id_ = next.fetch_add(1);
}

PixelBox Overlay::clip(PixelBox b) const {
  const int x0 = std::max(0, b.x), y0 = std::max(0, b.y);
  const int x1 = std::min(int(layer_.width), b.x + b.width);
  const int y1 = std::min(int(layer_.height), b.y + b.height);
  if (x1 <= x0 || y1 <= y0) return {};
  return {x0, y0, x1 - x0, y1 - y0};
}

void Overlay::begin(std::uint32_t width, std::uint32_t height) {
  darken_.clear();
  if (layer_.width != width || layer_.height != height) {
    layer_.width = width;
    layer_.height = height;
    layer_.rgba.assign(std::size_t(width) * height * 4, 0);
    drawn_.clear();
    cleared_ = {PixelBox{0, 0, int(width), int(height)}};
    return;
  }
  cleared_ = std::move(drawn_);
  drawn_.clear();
  const std::size_t row = std::size_t(width) * 4;
  for (const PixelBox& b : cleared_) {
    for (int y = b.y; y < b.y + b.height; ++y) {
      std::memset(layer_.rgba.data() + row * std::size_t(y) + std::size_t(b.x) * 4, 0, std::size_t(b.width) * 4);
    }
  }
}

void Overlay::drawn(PixelBox box) {
  const PixelBox b = clip(box);
  if (!b.empty() && std::find(drawn_.begin(), drawn_.end(), b) == drawn_.end()) drawn_.push_back(b);
}

void Overlay::darken(PixelBox box, float alpha) {
  const PixelBox b = clip(box);
  if (!b.empty()) darken_.push_back({b, alpha});
}

PixelBox Overlay::drawnBounds() const {
  if (drawn_.empty()) return {};
  int x0 = drawn_[0].x, y0 = drawn_[0].y, x1 = x0 + drawn_[0].width, y1 = y0 + drawn_[0].height;
  for (const PixelBox& b : drawn_) {
    x0 = std::min(x0, b.x);
    y0 = std::min(y0, b.y);
    x1 = std::max(x1, b.x + b.width);
    y1 = std::max(y1, b.y + b.height);
  }
  return {x0, y0, x1 - x0, y1 - y0};
}

std::vector<PixelBox> Overlay::changedBoxes() const {
  std::vector<PixelBox> out = drawn_;
  for (const PixelBox& b : cleared_) {
    if (std::find(out.begin(), out.end(), b) == out.end()) out.push_back(b);
  }
  return out;
}

void Overlay::composeOnto(Image& frame) const {
  if (frame.width != layer_.width || frame.height != layer_.height) return;
  const auto mix = [](std::uint8_t dst, std::uint8_t src, float a) {
    return static_cast<std::uint8_t>(float(dst) + (float(src) - float(dst)) * a + 0.5f);
  };
  for (const Darken& d : darken_) {
    for (int y = d.box.y; y < d.box.y + d.box.height; ++y) {
      for (int x = d.box.x; x < d.box.x + d.box.width; ++x) {
        std::uint8_t* p = frame.rgba.data() + (std::size_t(y) * frame.width + std::size_t(x)) * 4;
        for (int c = 0; c < 3; ++c) p[c] = mix(p[c], 0, d.alpha);
      }
    }
  }
  const PixelBox b = drawnBounds();
  {
    for (int y = b.y; y < b.y + b.height; ++y) {
      for (int x = b.x; x < b.x + b.width; ++x) {
        const std::size_t k = (std::size_t(y) * frame.width + std::size_t(x)) * 4;
        const std::uint8_t* s = layer_.rgba.data() + k;
        std::uint8_t* p = frame.rgba.data() + k;
        const float a = s[3] / 255.0f;
        for (int c = 0; c < 3; ++c) p[c] = mix(p[c], s[c], a);
      }
    }
  }
}

}  // namespace sandtable::render
