#pragma once
// Helpers shared by the viewer's integration tests.
#include <cstdint>

#include "sandtable/runtime/image.h"

namespace sandtable::test {

/// The clear colour the crack and hole tests draw against (FlightOptions::clearColour).
inline bool isMagenta(const runtime::Image& img, std::uint32_t x, std::uint32_t y) {
  const auto c = img.at(x, y);
  return c.r > 240 && c.g < 16 && c.b > 240;
}

/// Magenta pixels below the terrain's silhouette: in each column, those
/// under the first pixel from the top that is not the clear colour. With
/// the sky off, each one is a crack or a hole in the terrain.
inline std::uint64_t holesBelowTheSilhouette(const runtime::Image& img) {
  std::uint64_t n = 0;
  for (std::uint32_t x = 0; x < img.width; ++x) {
    std::uint32_t y = 0;
    while (y < img.height && isMagenta(img, x, y)) ++y;
    for (; y < img.height; ++y) n += isMagenta(img, x, y);
  }
  return n;
}

}  // namespace sandtable::test
