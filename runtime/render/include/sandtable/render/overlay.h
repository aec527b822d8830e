#pragma once
// What the renderer's HUD pass draws over a frame (docs/VIEWER.md,
// "Passes"): the information panel, the 2-D map and any other overlay,
// drawn on the CPU into a frame-sized RGBA layer, plus boxes of the frame
// to darken under it (the panel's background). The HUD pass uploads only
// the boxes that changed and blends them on the GPU, into the frame's
// target, so the frame never has to come back to the CPU for them.
//
// The layer: row 0 at the top; a pixel with alpha 255 covers the frame,
// alpha 0 leaves it as it is, between blends (colour * a + frame * (1 - a)).
// Drawing code marks what it drew with drawn(), so begin() clears only
// that and the pass uploads only that.
//
// Thread safety: one Overlay per thread (the render thread's).
#include <cstdint>
#include <vector>

#include "sandtable/render/image.h"

namespace sandtable::render {

/// Columns [x, x + width) and rows [y, y + height), row 0 at the top.
struct PixelBox {
  int x = 0, y = 0, width = 0, height = 0;
  bool empty() const { return width <= 0 || height <= 0; }
  bool operator==(const PixelBox&) const = default;
};

/// A box of the frame darkened to (1 - alpha) of its colour.
struct Darken {
  PixelBox box;
  float alpha = 0;
};

class Overlay {
 public:
  Overlay();
  /// Distinct for every Overlay made: the HUD pass uploads the whole layer
  /// when it is handed one it did not see last.
  std::uint64_t id() const { return id_; }

  /// Starts a frame of width x height: the boxes the last frame drew are
  /// cleared (and so count as changed), the darkened boxes are dropped.
  void begin(std::uint32_t width, std::uint32_t height);

  /// The layer to draw into (drawText, MapView::compose, ...).
  Image& layer() { return layer_; }
  const Image& layer() const { return layer_; }
  /// Records that `box` of the layer was drawn this frame (clipped).
  void drawn(PixelBox box);
  /// Darkens `box` of the frame before the layer goes over it (clipped).
  void darken(PixelBox box, float alpha);

  /// The boxes drawn this frame, clipped, in the order they were marked.
  const std::vector<PixelBox>& drawnBoxes() const { return drawn_; }
  /// The smallest box holding every drawn box (empty when none): the HUD
  /// pass blends the layer over it once, so overlapping boxes blend once.
  PixelBox drawnBounds() const;
  /// The boxes whose layer pixels may differ from the last frame's: those
  /// drawn this frame and those cleared by begin().
  std::vector<PixelBox> changedBoxes() const;
  const std::vector<Darken>& darkened() const { return darken_; }

  /// The same composition on the CPU, onto a frame of the layer's size:
  /// what the HUD pass does on the GPU (up to rounding of the darkening).
  void composeOnto(Image& frame) const;

 private:
  PixelBox clip(PixelBox b) const;
  std::uint64_t id_;
  Image layer_;
  std::vector<PixelBox> drawn_, cleared_;
  std::vector<Darken> darken_;
};

}  // namespace sandtable::render
