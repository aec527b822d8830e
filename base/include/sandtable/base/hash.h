#pragma once
// Deterministic hashing for choices that must come out the same on every
// run, thread count and platform: object scatter at build time, sprite
// thinning at draw time.
//
// Thread safety: pure functions.
#include <cstdint>

namespace sandtable::hash {

/// splitmix64's finaliser: a well-mixed 64-bit value from any 64-bit key.
constexpr std::uint64_t mix(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

/// The top 53 bits of `h` as a double in [0, 1).
constexpr double unit(std::uint64_t h) { return double(h >> 11) * 0x1p-53; }

}  // namespace sandtable::hash
