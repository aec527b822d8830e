#pragma once
// Helpers shared by the version 1 and version 2 module codecs (module.cpp,
// module_v2.cpp): byte-shuffled planes and zigzag deltas (docs/FORMAT.md §9.3).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/module.h"

namespace sandtable::module::detail {

// ---------------------------------------------------------------- planes

/// Writes n values of W bytes (W = 1, 2 or 4; get(i) gives the bits) as W
/// byte planes: byte 0 of every value, then byte 1, ... Returns the end.
template <unsigned W, typename Get>
std::byte* putPlane(std::byte* p, std::size_t n, Get get) {
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t u = get(i);
    for (unsigned b = 0; b < W; ++b) p[b * n + i] = static_cast<std::byte>(u >> (8 * b));
  }
  return p + W * n;
}

/// Reads n values of W bytes from W byte planes: set(i, bits).
template <unsigned W, typename Set>
void getPlane(const std::byte* p, std::size_t n, Set set) {
  const auto* q = reinterpret_cast<const std::uint8_t*>(p);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t u = q[i];
    if constexpr (W >= 2) u |= std::uint32_t(q[n + i]) << 8;
    if constexpr (W == 4) {
      u |= std::uint32_t(q[2 * n + i]) << 16 | std::uint32_t(q[3 * n + i]) << 24;
    }
    set(i, u);
  }
}

template <unsigned W>
constexpr std::uint32_t kMask = W == 4 ? 0xffffffffu : (1u << (8 * W)) - 1;

/// zigzag(v - prev) in W bytes, the difference wrapping modulo 2^(8W).
template <unsigned W>
std::uint32_t zigzagDelta(std::uint32_t v, std::uint32_t prev) {
  const std::uint32_t d = (v - prev) & kMask<W>;
  const std::uint32_t sign = ((d >> (8 * W - 1)) & 1) ? kMask<W> : 0u;
  return ((d << 1) & kMask<W>) ^ sign;
}

/// Inverse of zigzagDelta: the value that follows `prev`.
template <unsigned W>
std::uint32_t unzigzagDelta(std::uint32_t z, std::uint32_t prev) {
  const std::uint32_t d = (z >> 1) ^ ((z & 1) ? kMask<W> : 0u);
  return (prev + d) & kMask<W>;
}

/// Writes a delta-coded plane of W-byte values.
template <unsigned W, typename Get>
std::byte* putDeltaPlane(std::byte* p, std::size_t n, Get get) {
  return putPlane<W>(p, n, [&](std::size_t i) {
    return zigzagDelta<W>(get(i), i == 0 ? 0u : static_cast<std::uint32_t>(get(i - 1)));
  });
}

/// Reads a delta-coded plane of W-byte values into out[0..n).
template <unsigned W>
void getDeltaPlane(const std::byte* p, std::size_t n, std::uint32_t* out) {
  std::uint32_t prev = 0;
  getPlane<W>(p, n,
              [&](std::size_t i, std::uint32_t z) { out[i] = prev = unzigzagDelta<W>(z, prev); });
}

/// Sort key of a group: (priority, square, half, material), half <= 2.
inline std::uint64_t groupKey(std::uint8_t priority, std::uint32_t square, std::uint8_t half,
                              std::uint16_t material) {
  return std::uint64_t(priority) << 50 | std::uint64_t(square) << 18 | std::uint64_t(half) << 16 |
         material;
}

/// Version 2 and 3 codec (module_v2.cpp): the whole module, and one level
/// at `pos` (advanced past it). Problems as decode's.
std::vector<std::byte> encodeV2(const Module& m, const EncodeOptions& options);
Status decodeLevelV2(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base,
                     std::size_t li, std::size_t& pos, Level& l, std::uint32_t version);

/// Version 5's objects section (docs/FORMAT.md §9.10), appended to `out`.
void encodeObjects(const Module& m, std::vector<std::byte>& out);
/// Bytes encodeObjects appends.
std::uint64_t objectsBytes(const Module& m);
/// Reads the objects section at `pos` into m.objects and every level's
/// objectY, and advances `pos` past it. Refuses counts the bytes cannot
/// hold before anything is sized.
Status decodeObjects(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base,
                     std::size_t& pos, Module& m);

/// Version 6's objects section (docs/FORMAT.md §9.11; module_objects_v6.cpp).
inline constexpr std::uint32_t kObjectsHeaderBytes6 = 48;
inline constexpr std::uint32_t kPaletteBytes6 = 12;
inline constexpr std::uint32_t kRuleBytes6 = 56;
inline constexpr std::uint32_t kExplicitBytes6 = 7;  ///< x, z u16; heading, scale, palette index u8
inline constexpr double kMaxExtent6 = 1e6;           ///< metres: a module's width and depth at most
void encodeObjectsV6(const Module& m, bool regenerateRules, std::vector<std::byte>& out);
/// At least the bytes encodeObjectsV6 appends.
std::uint64_t objectsBytesV6Bound(const Module& m);
/// Reads version 6's objects section at `pos`: m.objects (explicit ones,
/// then each rule's trees, sorted), m.scattering and every level's objectY
/// from the levels already decoded; advances `pos`. Refuses counts the
/// bytes or the object limit cannot hold before anything is sized.
Status decodeObjectsV6(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base,
                       std::size_t& pos, Module& m);

}  // namespace sandtable::module::detail
