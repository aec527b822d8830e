// Morton codes against a bit-by-bit interleave written here.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>

#include "sandtable/base/morton.h"

using namespace sandtable;

namespace {

/// Bit k of x to bit 2k, bit k of y to bit 2k + 1, one bit at a time.
std::uint32_t bruteInterleave(std::uint32_t x, std::uint32_t y) {
  std::uint32_t m = 0;
  for (std::uint32_t k = 0; k < 16; ++k) {
    if (x & (1u << k)) m |= 1u << (2 * k);
    if (y & (1u << k)) m |= 1u << (2 * k + 1);
  }
  return m;
}

}  // namespace

TEST(Morton, encodeIsTheBitInterleave) {
  static_assert(morton::encode(1, 0) == 1 && morton::encode(0, 1) == 2 && morton::encode(3, 3) == 15);
  for (std::uint32_t x = 0; x < 64; ++x) {
    for (std::uint32_t y = 0; y < 64; ++y) ASSERT_EQ(morton::encode(x, y), bruteInterleave(x, y)) << x << " " << y;
  }
  std::mt19937 rng(7);
  for (int k = 0; k < 100000; ++k) {
    const std::uint32_t x = rng() & 0xffffu, y = rng() & 0xffffu;
    ASSERT_EQ(morton::encode(x, y), bruteInterleave(x, y)) << x << " " << y;
  }
  EXPECT_EQ(morton::encode(0xffffu, 0xffffu), 0xffffffffu);
  EXPECT_EQ(morton::encode(0xffffu, 0), 0x55555555u);
  // Bits above 16 are ignored, as the pack's and the quadtree's coders did.
  EXPECT_EQ(morton::encode(0x10001u, 0x20002u), bruteInterleave(1, 2));
}

TEST(Morton, decodeInvertsEncode) {
  std::mt19937 rng(11);
  for (int k = 0; k < 100000; ++k) {
    const std::uint32_t x = rng() & 0xffffu, y = rng() & 0xffffu;
    const auto [dx, dy] = morton::decode(bruteInterleave(x, y));
    ASSERT_EQ(dx, x);
    ASSERT_EQ(dy, y);
  }
  const auto [ax, ay] = morton::decode(0xffffffffu);
  EXPECT_EQ(ax, 0xffffu);
  EXPECT_EQ(ay, 0xffffu);
}
