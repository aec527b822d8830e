#pragma once
// Morton (Z-order) codes of 2-D cells: x's bits in the even bits of the
// code, y's in the odd bits. The one coder for the pack's record order
// (docs/FORMAT.md §10, `order` 1), the quadtree node order of a module's
// levels and the renderer's node buckets. Pure functions.
#include <cstdint>
#include <utility>

namespace sandtable::morton {

/// The low 16 bits of v moved to the even bits of the result.
constexpr std::uint32_t spread(std::uint32_t v) {
  v &= 0xffffu;
  v = (v | (v << 8)) & 0x00ff00ffu;
  v = (v | (v << 4)) & 0x0f0f0f0fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}

/// The even bits of v gathered into the low 16 bits (spread inverted).
constexpr std::uint32_t compact(std::uint32_t v) {
  v &= 0x55555555u;
  v = (v | (v >> 1)) & 0x33333333u;
  v = (v | (v >> 2)) & 0x0f0f0f0fu;
  v = (v | (v >> 4)) & 0x00ff00ffu;
  v = (v | (v >> 8)) & 0x0000ffffu;
  return v;
}

/// The code of cell (x, y); only the low 16 bits of each are used, so a
/// 65536 x 65536 grid fits in 32 bits without ties.
constexpr std::uint32_t encode(std::uint32_t x, std::uint32_t y) { return spread(x) | (spread(y) << 1); }

/// The cell (x, y) of a code.
constexpr std::pair<std::uint32_t, std::uint32_t> decode(std::uint32_t code) {
  return {compact(code), compact(code >> 1)};
}

}  // namespace sandtable::morton
