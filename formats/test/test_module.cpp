// Load module v1: golden bytes, round trips, index width, truncation,
// hostile counts (with an allocation watch) and flipped bytes.
#include <gtest/gtest.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <atomic>
#include <thread>
#include <tuple>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <cmath>
#include <functional>
#include <limits>
#include <new>

#include "module_samples.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/scatter.h"

// The largest single allocation since the last reset, for checking that
// hostile counts are refused before anything is sized. Every form of
// operator new and delete of this test binary is replaced (so sanitizers
// see them pair up), out of line (so the compiler does not pair inlined
// malloc and free with new and delete and warn).
namespace {
std::atomic<std::size_t> gLargestAllocation{0};
[[gnu::noinline]] void* tracked(std::size_t n) noexcept {
  std::size_t seen = gLargestAllocation.load(std::memory_order_relaxed);
  while (n > seen && !gLargestAllocation.compare_exchange_weak(seen, n)) {
  }
  return std::malloc(n ? n : 1);
}
[[gnu::noinline]] void* trackedOrThrow(std::size_t n) {
  if (void* p = tracked(n)) return p;
  throw std::bad_alloc();
}
}  // namespace
void* operator new(std::size_t n) { return trackedOrThrow(n); }
void* operator new[](std::size_t n) { return trackedOrThrow(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return tracked(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return tracked(n); }
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { ::operator delete(p); }
void operator delete(void* p, std::size_t) noexcept { ::operator delete(p); }
void operator delete[](void* p, std::size_t) noexcept { ::operator delete(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { ::operator delete(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { ::operator delete(p); }

namespace sandtable::module {
namespace {

/// The version 1 bytes these tests pin (encode defaults to version 2).
std::vector<std::byte> encodeV1(const Module& m) { return encode(m, EncodeOptions{.version = kVersion}); }

std::string hex(std::span<const std::byte> b) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (std::byte x : b) {
    s += d[std::to_integer<int>(x) >> 4];
    s += d[std::to_integer<int>(x) & 15];
  }
  return s;
}

/// Recomputes both CRCs so that a hand-made field change reaches the
/// structural checks.
void reseal(std::vector<std::byte>& b) {
  storeLE<std::uint32_t>(b.data() + field::payloadCrc, crc32(std::span(b).subspan(kHeaderBytes)));
  storeLE<std::uint32_t>(b.data() + field::headerCrc, crc32(std::span(b).first(field::headerCrc)));
}

bool sameBits(float a, float b) {
  return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b);
}

void expectEqual(const Module& a, const Module& b) {
  EXPECT_EQ(a.kx, b.kx);
  EXPECT_EQ(a.kz, b.kz);
  ASSERT_EQ(a.levels.size(), b.levels.size());
  for (std::size_t li = 0; li < a.levels.size(); ++li) {
    const Level& x = a.levels[li];
    const Level& y = b.levels[li];
    EXPECT_EQ(x.spacing, y.spacing);
    EXPECT_EQ(x.squaresX, y.squaresX);
    EXPECT_EQ(x.squaresZ, y.squaresZ);
    EXPECT_TRUE(sameBits(x.skirtDepth, y.skirtDepth));
    ASSERT_EQ(x.vertices.size(), y.vertices.size());
    for (std::size_t k = 0; k < x.vertices.size(); ++k) {
      const Vertex& u = x.vertices[k];
      const Vertex& v = y.vertices[k];
      ASSERT_TRUE(sameBits(u.x, v.x) && sameBits(u.y, v.y) && sameBits(u.z, v.z) &&
                  sameBits(u.s, v.s) && sameBits(u.t, v.t))
          << "level " << li << " vertex " << k;
    }
    EXPECT_EQ(x.indices, y.indices);
    ASSERT_EQ(x.groups.size(), y.groups.size());
    for (std::size_t g = 0; g < x.groups.size(); ++g) {
      const Group& p = x.groups[g];
      const Group& q = y.groups[g];
      ASSERT_TRUE(p.square == q.square && p.half == q.half && p.priority == q.priority &&
                  p.material == q.material && p.firstIndex == q.firstIndex &&
                  p.indexCount == q.indexCount)
          << "level " << li << " group " << g;
    }
    ASSERT_EQ(x.maxHeight.size(), y.maxHeight.size());
    for (std::size_t k = 0; k < x.maxHeight.size(); ++k)
      EXPECT_TRUE(sameBits(x.maxHeight[k], y.maxHeight[k]));
  }
}

/// Offset of level 0's header and its arrays in an encoding.
struct Level0 {
  std::size_t header = kHeaderBytes;
  std::size_t vertices, maxHeight, indices, groupSquare, groupHalf, groupPriority, groupMaterial,
      groupCount, end;
  explicit Level0(const Level& l, unsigned indexWidth = 2) {
    const std::size_t nv = l.vertices.size(), ng = l.groups.size();
    vertices = header + kLevelHeaderBytes;
    maxHeight = vertices + kVertexBytes * nv;
    indices = maxHeight + 4 * l.maxHeight.size();
    groupSquare = indices + indexWidth * l.indices.size();
    groupHalf = groupSquare + 4 * ng;
    groupPriority = groupHalf + ng;
    groupMaterial = groupPriority + ng;
    groupCount = groupMaterial + 2 * ng;
    end = groupCount + 4 * ng;
  }
};

TEST(Module, layoutConstantsArePinned) {
  EXPECT_EQ(kHeaderBytes, 48u);
  EXPECT_EQ(kLevelHeaderBytes, 36u);
  EXPECT_EQ(field::kx, 16u);
  EXPECT_EQ(field::levelCount, 24u);
  EXPECT_EQ(field::totalBytes, 32u);
  EXPECT_EQ(field::payloadCrc, 40u);
  EXPECT_EQ(field::headerCrc, 44u);
  EXPECT_EQ(levelField::squaresX, 8u);
  EXPECT_EQ(levelField::skirtDepth, 16u);
  EXPECT_EQ(levelField::flags, 20u);
  EXPECT_EQ(levelField::vertexCount, 24u);
  EXPECT_EQ(levelField::groupCount, 32u);
  EXPECT_EQ(kMaxLevels, 16u);
  EXPECT_EQ(kMaxSquaresPerAxis, 65536u);
}

// Golden bytes of version 1. If this fails, the format changed: bump
// kVersion, keep a reader for version 1, and add a new golden test.
TEST(Module, version1GoldenBytes) {
  const auto bytes = encodeV1(samples::tiny());
  ASSERT_EQ(bytes.size(), 48u + 36u + 80u + 4u + 12u + 24u);
  // Header: magic "SANDMOD1", version 1, header 48, kx 1, kz 2, 1 level,
  // flags 0, total 204, payload CRC 0x364fe54f, header CRC 0x64b78655.
  EXPECT_EQ(hex(std::span(bytes).first(48)),
            "53414e444d4f4431"
            "01000000"
            "30000000"
            "01000000"
            "02000000"
            "01000000"
            "00000000"
            "cc00000000000000"
            "4fe54f36"
            "5586b764");
  // Level 0: spacing 30.0, 1 x 1 squares, skirt 5.0, flags 0 (u16 indices),
  // 4 vertices, 6 indices, 2 groups. Then the planes, each float plane as
  // four byte planes: x (0, 30, 0, 30), y (10, 11, 12, 13), z (0, 0, 30, 30),
  // s (0, 1, 0, 1), t (0, 0, 1, 1), maxHeight (13); indices (0 1 2 1 3 2)
  // as zigzag deltas (0 2 2 1 4 1) in two byte planes; group squares (0 0)
  // as deltas, halves (0 1), priorities (1 1), materials (3 4), counts (3 3).
  EXPECT_EQ(hex(std::span(bytes).subspan(48)),
            "0000000000003e40"
            "01000000"
            "01000000"
            "0000a040"
            "00000000"
            "04000000"
            "06000000"
            "02000000"
            "00000000"
            "00000000"
            "00f000f0"
            "00410041"
            "00000000"
            "00000000"
            "20304050"
            "41414141"
            "00000000"
            "00000000"
            "0000f0f0"
            "00004141"
            "00000000"
            "00000000"
            "00800080"
            "003f003f"
            "00000000"
            "00000000"
            "00008080"
            "00003f3f"
            "00005041"
            "000202010401"
            "000000000000"
            "0000"
            "0000"
            "0000"
            "0000"
            "0001"
            "0101"
            "0304"
            "0000"
            "0303"
            "0000"
            "0000"
            "0000");
  // A slightly larger module (8 x 8 squares, 2 levels, skirts, a road).
  EXPECT_EQ(crcHex(crc32(encodeV1(samples::realistic(3, 4, 8, 2)))), "0x49959341");
}

TEST(Module, roundTripsEveryField) {
  Module m = samples::realistic(5, 7);
  // Values a float plane must carry bit for bit.
  m.levels[1].vertices[3].s = -0.0f;
  m.levels[1].vertices[4].t = std::bit_cast<float>(0x7fc01234u);  // NaN with a payload
  m.levels[1].vertices[5].y = std::bit_cast<float>(1u);           // smallest denormal
  m.levels[2].maxHeight[0] = -1e30f;
  m.levels[3].skirtDepth = 0;
  ASSERT_EQ(checkEncodable(m).message(), "");
  const auto bytes = encodeV1(m);
  EXPECT_EQ(bytes.size(), encodedBytes(m));
  auto back = decode(bytes, "m.bin");
  ASSERT_TRUE(back.ok()) << back.error();
  expectEqual(m, back.value());
  EXPECT_EQ(encodeV1(back.value()), bytes);
  // Realistic content: every level decodes with groups in draw order.
  EXPECT_EQ(back->levels.size(), 4u);
  EXPECT_EQ(back->levels[0].squaresX, 32u);
  EXPECT_EQ(back->levels[3].squaresX, 4u);
  EXPECT_EQ(back->levels[0].groups.back().priority, kPriorityRoad);
}

TEST(Module, decodeIntoReusesAModuleAndMatchesDecode) {
  const Module big = samples::realistic(5, 7), small = samples::realistic(2, 3);  // two different modules
  Module reused;
  Status st = decodeInto(encodeV1(big), "big.bin", 0, reused);
  ASSERT_TRUE(st.ok()) << st.error();
  expectEqual(big, reused);
  const std::size_t capacity = reused.levels[0].vertices.capacity();
  // Another module into the same storage: every field replaced.
  st = decodeInto(encodeV1(small), "small.bin", 0, reused);
  ASSERT_TRUE(st.ok()) << st.error();
  expectEqual(small, reused);
  EXPECT_GE(reused.levels[0].vertices.capacity(), capacity);  // never shrinks: no reallocation for smaller
  // Failures set the problem as decode's do.
  auto bytes = encodeV1(small);
  bytes[bytes.size() / 2] ^= std::byte{1};
  st = decodeInto(bytes, "bad.bin", 100, reused);
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.error(), decode(bytes, "bad.bin", 100).error());
}

TEST(Module, decodeRecomputesFirstIndexAsTheRunningSum) {
  const auto bytes = encodeV1(samples::tiny());
  auto m = decode(bytes, "tiny");
  ASSERT_TRUE(m.ok()) << m.error();
  const auto& g = m->levels[0].groups;
  ASSERT_EQ(g.size(), 2u);
  EXPECT_EQ(g[0].firstIndex, 0u);
  EXPECT_EQ(g[1].firstIndex, 3u);
  EXPECT_EQ(g[1].half, Half::lower);
  EXPECT_EQ(g[1].material, 4);
}

/// One level with `vertices` vertices and a single triangle using the last one.
Module wideModule(std::uint32_t vertices) {
  Module m = samples::tiny();
  Level& l = m.levels[0];
  l.vertices.resize(vertices);
  l.indices = {0, 1, vertices - 1};
  l.groups = {{0, Half::upper, kPrioritySkin, 3, 0, 3}};
  return m;
}

TEST(Module, switchesToU32IndicesAbove65536Vertices) {
  for (const std::uint32_t n : {65536u, 65537u}) {
    const Module m = wideModule(n);
    const auto bytes = encodeV1(m);
    const auto flags = loadLE<std::uint32_t>(bytes.data() + kHeaderBytes + levelField::flags);
    const unsigned width = n > kMaxU16Vertices ? 4 : 2;
    EXPECT_EQ(flags, n > kMaxU16Vertices ? kLevelFlagU32Indices : 0u) << n;
    EXPECT_EQ(bytes.size(), Level0(m.levels[0], width).end) << n;
    auto back = decode(bytes, "wide");
    ASSERT_TRUE(back.ok()) << back.error();
    EXPECT_EQ(back->levels[0].indices.back(), n - 1);
  }
  // A reader accepts u32 indices for a small level too (writers never
  // produce them, but they are well-formed).
  Module m = wideModule(5);
  auto bytes = encodeV1(m);
  const Level0 at(m.levels[0]);
  std::vector<std::byte> wide(bytes.begin(),
                              bytes.begin() + static_cast<std::ptrdiff_t>(at.indices));
  storeLE<std::uint32_t>(wide.data() + kHeaderBytes + levelField::flags, kLevelFlagU32Indices);
  // u32 delta planes of (0, 1, 4): zigzag deltas 0, 2, 6 as four byte planes.
  for (const int b : {0, 2, 6, 0, 0, 0, 0, 0, 0, 0, 0, 0})
    wide.push_back(static_cast<std::byte>(b));
  wide.insert(wide.end(), bytes.begin() + static_cast<std::ptrdiff_t>(at.groupSquare), bytes.end());
  storeLE<std::uint64_t>(wide.data() + field::totalBytes, wide.size());
  reseal(wide);
  auto back = decode(wide, "wide");
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back->levels[0].indices, (std::vector<std::uint32_t>{0, 1, 4}));
}

TEST(Module, everyTruncatedPrefixFailsNamingItsOffset) {
  const auto bytes = encodeV1(samples::realistic(1, 1, 4, 2));
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    auto m = decode(std::span(bytes).first(n), "cut.bin", 1000);
    ASSERT_FALSE(m.ok()) << "prefix " << n;
    const Problem& p = m.problems().front();
    EXPECT_EQ(p.file, "cut.bin");
    EXPECT_EQ(p.offset, 1000 + n);
    EXPECT_EQ(p.message.rfind("module: ", 0), 0u) << p.message;
    EXPECT_NE(p.message.find("truncated"), std::string::npos) << p.message;
    EXPECT_NE(p.message.find(std::to_string(n)), std::string::npos) << p.message;
  }
}

TEST(Module, everyFlippedByteIsDetected) {
  auto bytes = encodeV1(samples::realistic(2, 3, 4, 2));
  for (std::size_t off = 0; off < bytes.size(); ++off) {
    bytes[off] ^= std::byte{0x20};
    EXPECT_FALSE(decode(bytes, "flip").ok()) << "flip at " << off << " not caught";
    bytes[off] ^= std::byte{0x20};
  }
}

// Each malformed input with its exact message and offset. Byte-level
// cases re-seal the CRCs so that the structural check itself is exercised;
// the allocation watch shows no hostile count is trusted.
struct Hostile {
  const char* name;
  std::function<void(std::vector<std::byte>&, const Level0&)> mutate;
  std::size_t offset;  ///< 0: compare only the message
  const char* message;
};

TEST(Module, hostileBytesAreRejectedWithTheirMessage) {
  const Module good = samples::tiny();
  const Level0 at(good.levels[0]);
  const std::size_t lh = at.header;
  auto u32 = [](std::size_t off, std::uint32_t v) {
    return [=](std::vector<std::byte>& b, const Level0&) {
      storeLE<std::uint32_t>(b.data() + off, v);
    };
  };
  const Hostile cases[] = {
      {"version", u32(field::version, 2), field::version,
       "module: version 2 does not match the magic's \"SANDMOD1\""},
      {"header size", u32(field::headerBytes, 64), field::headerBytes,
       "module: header size must be 48"},
      {"flags", u32(field::flags, 1), field::flags, "module: flags must be 0 in version 1"},
      {"no levels", u32(field::levelCount, 0), field::levelCount,
       "module: level count 0 is out of range (1 to 16)"},
      {"17 levels", u32(field::levelCount, 17), field::levelCount,
       "module: level count 17 is out of range (1 to 16)"},
      {"2 levels, 1 present", u32(field::levelCount, 2), at.end,
       "module: level 1: truncated: the level header needs 36 bytes, only 0 remain"},
      {"trailing",
       [](auto& b, auto&) {
         b.push_back(std::byte{0});
         storeLE<std::uint64_t>(b.data() + field::totalBytes, b.size());
       },
       at.end, "module: 1 bytes follow the last level"},
      {"spacing NaN", [&](auto& b, auto&) { storeLE<double>(b.data() + lh, std::nan("")); }, lh,
       "module: level 0 spacing nan is not a finite positive number"},
      {"squares 0", u32(lh + levelField::squaresX, 0), lh + levelField::squaresX,
       "module: level 0 squares 0 x 1 are out of range (1 to 65536 each)"},
      {"squares 65537", u32(lh + levelField::squaresZ, 65537), lh + levelField::squaresZ,
       "module: level 0 squares 1 x 65537 are out of range (1 to 65536 each)"},
      {"squares 65536^2",
       [&](auto& b, auto&) {
         storeLE<std::uint32_t>(b.data() + lh + levelField::squaresX, 65536);
         storeLE<std::uint32_t>(b.data() + lh + levelField::squaresZ, 65536);
       },
       lh + levelField::vertexCount,
       "module: level 0: 4 vertices, 6 indices, 2 groups and 4294967296 squares need 17179869300 "
       "bytes after the level header, only 120 remain"},
      {"skirt -1",
       [&](auto& b, auto&) { storeLE<float>(b.data() + lh + levelField::skirtDepth, -1.0f); },
       lh + levelField::skirtDepth,
       "module: level 0 skirt depth -1.000000 is not a finite number >= 0"},
      {"level flags", u32(lh + levelField::flags, 6), lh + levelField::flags,
       "module: level 0 flags 6 has bits other than bit 0 (u32 indices) set"},
      {"vertices 2^32-1", u32(lh + levelField::vertexCount, 0xffffffffu),
       lh + levelField::vertexCount,
       "module: level 0: 4294967295 vertices, 6 indices, 2 groups and 1 squares need 85899345940 "
       "bytes after the level header, only 120 remain"},
      {"indices 2^32-1", u32(lh + levelField::indexCount, 0xffffffffu),
       lh + levelField::vertexCount,
       "module: level 0: 4 vertices, 4294967295 indices, 2 groups and 1 squares need 8589934698 "
       "bytes after the level header, only 120 remain"},
      {"groups 2^32-1", u32(lh + levelField::groupCount, 0xffffffffu), lh + levelField::vertexCount,
       "module: level 0: 4 vertices, 6 indices, 4294967295 groups and 1 squares need 51539607636 "
       "bytes after the level header, only 120 remain"},
  };
  for (const Hostile& c : cases) {
    auto bytes = encodeV1(good);
    c.mutate(bytes, at);
    reseal(bytes);
    gLargestAllocation = 0;
    auto m = decode(bytes, "h.bin", 0);
    ASSERT_FALSE(m.ok()) << c.name;
    EXPECT_LT(gLargestAllocation.load(), std::size_t(1) << 20) << c.name;
    const Problem& p = m.problems().front();
    EXPECT_EQ(p.message, c.message) << c.name;
    EXPECT_EQ(p.offset, c.offset) << c.name << ": " << p.message;
    EXPECT_EQ(p.file, "h.bin");
  }
}

TEST(Module, malformedContentIsRejectedWithItsMessage) {
  struct Case {
    const char* name;
    std::function<void(Level&)> mutate;
    std::function<std::size_t(const Level0&)> offset;
    const char* message;
  };
  const Case cases[] = {
      {"index past the vertices", [](Level& l) { l.indices[4] = 9; },
       [](const Level0& a) { return a.indices + 4; },
       "module: level 0 index 4 is 9, not below the vertex count 4"},
      {"half 3", [](Level& l) { l.groups[1].half = Half(3); },
       [](const Level0& a) { return a.groupHalf + 1; },
       "module: level 0 group 1 half 3 is not 0 (upper), 1 (lower) or 2 (skirt)"},
      {"square past the level", [](Level& l) { l.groups[1].square = 1; },
       [](const Level0& a) { return a.groupSquare + 1; },
       "module: level 0 group 1 square 1 is not below the level's 1 squares"},
      {"skirt square past the level",
       [](Level& l) {
         l.groups[1].half = Half::skirt;
         l.groups[1].square = 7;
       },
       [](const Level0& a) { return a.groupSquare + 1; },
       "module: level 0 group 1 square 7 is not below the level's 1 squares"},
      {"out of order", [](Level& l) { std::swap(l.groups[0].half, l.groups[1].half); },
       [](const Level0& a) { return a.groupSquare + 1; },
       "module: level 0 group 1 (priority 1, square 0, half 0, material 4) does not follow "
       "group 0 in (priority, square, half, material) order"},
      {"priority before square", [](Level& l) { l.groups[0].priority = kPriorityRoad; },
       [](const Level0& a) { return a.groupSquare + 1; },
       "module: level 0 group 1 (priority 1, square 0, half 1, material 4) does not follow "
       "group 0 in (priority, square, half, material) order"},
      {"count not a multiple of 3",
       [](Level& l) {
         l.groups[0].indexCount = 2;
         l.groups[1].firstIndex = 2;
         l.groups[1].indexCount = 4;
       },
       [](const Level0& a) { return a.groupCount; },
       "module: level 0 group 0 index count 2 is not a positive multiple of 3"},
  };
  for (const Case& c : cases) {
    Module m = samples::tiny();
    c.mutate(m.levels[0]);
    ASSERT_EQ(checkEncodable(m).message(), "") << c.name;
    auto r = decode(encodeV1(m), "bad.bin", 7);
    ASSERT_FALSE(r.ok()) << c.name;
    EXPECT_EQ(r.problems().front().message, c.message) << c.name;
    EXPECT_EQ(r.problems().front().offset, 7 + c.offset(Level0(m.levels[0]))) << c.name;
  }
  // Counts that the bytes hold but the groups do not add up to.
  Module m = samples::tiny();
  auto bytes = encodeV1(m);
  const Level0 at(m.levels[0]);
  storeLE<std::uint8_t>(bytes.data() + at.groupCount + 1, 6);  // group 1 (byte plane 0): 6 indices
  reseal(bytes);
  EXPECT_EQ(decode(bytes, "b").problems().front().message,
            "module: level 0 group 1 indices 3..8 run past the level's 6 indices");
  bytes = encodeV1(m);
  storeLE<std::uint32_t>(bytes.data() + kHeaderBytes + levelField::indexCount, 7);
  std::vector<std::byte> longer(bytes.begin(),
                                bytes.begin() + static_cast<std::ptrdiff_t>(at.groupSquare));
  longer.insert(longer.begin() + static_cast<std::ptrdiff_t>(at.indices + 12), std::byte{0});
  longer.insert(longer.begin() + static_cast<std::ptrdiff_t>(at.indices + 6), std::byte{0});
  longer.insert(longer.end(), bytes.begin() + static_cast<std::ptrdiff_t>(at.groupSquare),
                bytes.end());
  storeLE<std::uint64_t>(longer.data() + field::totalBytes, longer.size());
  reseal(longer);
  EXPECT_EQ(decode(longer, "b").problems().front().message,
            "module: level 0 groups cover 6 of the level's 7 indices");
}

TEST(Module, groupsWithEqualKeysMayFollowEachOther) {
  Module m = samples::tiny();
  m.levels[0].groups[1].half = Half::upper;
  m.levels[0].groups[1].material = 3;  // same key as group 0
  auto back = decode(encodeV1(m), "equal");
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back->levels[0].groups[1].firstIndex, 3u);
}

TEST(Module, checksumsAndMagicAreChecked) {
  auto bytes = encodeV1(samples::tiny());
  bytes[0] = std::byte{'X'};
  EXPECT_EQ(decode(bytes, "m").error(),
            "m @0: module: bad magic: not a sandtable load module (expected \"SANDMOD1\" to \"SANDMOD6\")");
  bytes = encodeV1(samples::tiny());
  bytes[field::kx] ^= std::byte{1};
  EXPECT_EQ(decode(bytes, "m").problems().front().offset, field::headerCrc);
  EXPECT_NE(decode(bytes, "m").error().find("module: header checksum mismatch"), std::string::npos);
  bytes = encodeV1(samples::tiny());
  bytes.back() ^= std::byte{1};
  EXPECT_EQ(decode(bytes, "m").problems().front().offset, field::payloadCrc);
  EXPECT_NE(decode(bytes, "m").error().find("payload checksum mismatch"), std::string::npos);
}

TEST(Module, checkEncodableFindsWhatTheBytesCannotSay) {
  Module m = samples::tiny();
  EXPECT_EQ(checkEncodable(m).message(), "");
  m.levels[0].groups[1].firstIndex = 4;
  EXPECT_EQ(checkEncodable(m).message(),
            "module: level 0 group 1 firstIndex 4 is not 3, the sum of the index counts before it "
            "(groups must cover the indices contiguously, in order)");
  m = samples::tiny();
  m.levels[0].indices.push_back(0);
  EXPECT_EQ(checkEncodable(m).message(), "module: level 0 groups cover 6 of its 7 indices");
  m = samples::tiny();
  m.levels[0].maxHeight.clear();
  EXPECT_EQ(checkEncodable(m).message(), "module: level 0 has 0 maxHeight values for 1 squares");
  m = samples::tiny();
  m.levels[0].squaresX = 0;
  EXPECT_EQ(checkEncodable(m).message(), "module: level 0 squares 0 x 1 are out of range (1 to 65536 each)");
  m.levels.clear();
  EXPECT_EQ(checkEncodable(m).message(), "module: 0 levels; a module holds 1 to 16");
  m.levels.assign(17, samples::tiny().levels[0]);
  EXPECT_EQ(checkEncodable(m).message(), "module: 17 levels; a module holds 1 to 16");
}


// ------------------------------------------------------------- version 2

/// The golden version 2 module: one 32 m square whose four vertices are the
/// lattice (skin texture offset 0), 1 cm heights, normals, one group run.
Module tinyV2() {
  Module m;
  m.kx = 1;
  m.kz = 2;
  Level l;
  l.spacing = 32;
  l.squaresX = 1;
  l.squaresZ = 1;
  l.skirtDepth = 5;
  l.vertices = {{0, 10, 0, 0, 0}, {32, 10.25f, 0, 0.5f, 0}, {0, 10.5f, 32, 0, 0.5f}, {32, 11, 32, 0.5f, 0.5f}};
  l.indices = {0, 2, 1, 1, 2, 3};
  l.groups = {{0, Half::upper, kPrioritySkin, 3, 0, 3}, {0, Half::lower, kPrioritySkin, 3, 3, 3}};
  l.maxHeight = {11};
  // u, v as snorm16: (0,0), (64,0), (0,-64), (64,-64).
  l.normals = {0x00000000u, 0x00000040u, 0xffc00000u, 0xffc00040u};
  m.levels.push_back(l);
  return m;
}

/// tinyV2 with the skirt meshing::addSkirts hangs below it (one node of one
/// square, sides north, south, west, east; bottom vertices 5 m down with
/// s = t = 0 and the top's normal), in material 7: version 3 stores none
/// of it.
void hangSkirt(Level& l);

Module tinyV3() {
  Module m = tinyV2();
  hangSkirt(m.levels[0]);
  return m;
}

void hangSkirt(Level& l) {
  const std::uint32_t sides[4][2] = {{0, 1}, {2, 3}, {0, 2}, {1, 3}};
  std::vector<std::uint32_t> skirt;
  for (const auto& side : sides) {
    const auto first = std::uint32_t(l.vertices.size());
    for (const std::uint32_t top : side) {
      Vertex b = l.vertices[top];
      b.y -= l.skirtDepth;
      b.s = b.t = 0;
      l.vertices.push_back(b);
      l.normals.push_back(l.normals[top]);
    }
    skirt.insert(skirt.end(), {side[0], first, side[1], side[1], first, first + 1});
  }
  l.indices.insert(l.indices.end(), skirt.begin(), skirt.end());
  l.groups.push_back({0, Half::skirt, kPrioritySkin, 7, std::uint32_t(l.indices.size() - 24), 24});
}

/// tinyV3 with a decal triangle on the upper grid triangle (priority 2,
/// material 9), on the plane of its posts, with texture on quarters: what
/// version 4 stores as plane offsets and raw integer texture.
Module tinyV4() {
  Module m = tinyV2();
  Level& l = m.levels[0];
  // Upper plane: y = 10 + 0.25 x / 32 + 0.5 z / 32.
  l.vertices.insert(l.vertices.end(), {{8, 10.1875f, 8, 0.5f, 0}, {16, 10.25f, 8, 0.75f, 0}, {8, 10.3125f, 16, 0.5f, 1}});
  l.normals.insert(l.normals.end(), 3, 0u);
  hangSkirt(l);
  l.indices.insert(l.indices.end(), {4, 6, 5});
  l.groups.push_back({0, Half::upper, 2, 9, 30, 3});
  return m;
}

/// |a - b| within half a quantisation step plus float rounding.
bool withinStep(float a, float b, double step) {
  return std::fabs(double(a) - double(b)) <= 0.5 * step + 1e-6 * std::max(1.0, std::fabs(double(b)));
}

/// Decoded v2 against the original: x, z, s, t, indices, groups and normals
/// exact; y and maxHeight within the step.
void expectNear(const Module& a, const Module& b, double step) {
  ASSERT_EQ(a.levels.size(), b.levels.size());
  for (std::size_t li = 0; li < a.levels.size(); ++li) {
    const Level& x = a.levels[li];
    const Level& y = b.levels[li];
    EXPECT_EQ(x.spacing, y.spacing);
    EXPECT_EQ(x.squaresX, y.squaresX);
    EXPECT_EQ(x.squaresZ, y.squaresZ);
    ASSERT_EQ(x.vertices.size(), y.vertices.size());
    for (std::size_t k = 0; k < x.vertices.size(); ++k) {
      const Vertex& u = x.vertices[k];
      const Vertex& v = y.vertices[k];
      ASSERT_TRUE(sameBits(u.x, v.x) && sameBits(u.z, v.z) && sameBits(u.s, v.s) && sameBits(u.t, v.t))
          << "level " << li << " vertex " << k;
      ASSERT_TRUE(withinStep(u.y, v.y, step)) << "level " << li << " vertex " << k << ": " << u.y << " vs " << v.y;
    }
    EXPECT_EQ(x.indices, y.indices);
    EXPECT_EQ(x.normals, y.normals);
    ASSERT_EQ(x.groups.size(), y.groups.size());
    for (std::size_t g = 0; g < x.groups.size(); ++g) {
      const Group& p = x.groups[g];
      const Group& q = y.groups[g];
      ASSERT_TRUE(p.square == q.square && p.half == q.half && p.priority == q.priority &&
                  p.material == q.material && p.firstIndex == q.firstIndex && p.indexCount == q.indexCount)
          << "level " << li << " group " << g;
    }
    ASSERT_EQ(x.maxHeight.size(), y.maxHeight.size());
    for (std::size_t k = 0; k < x.maxHeight.size(); ++k) EXPECT_TRUE(withinStep(x.maxHeight[k], y.maxHeight[k], step));
  }
}

/// The sample with a normal per vertex (a smooth, made-up field).
Module withNormals(Module m) {
  for (Level& l : m.levels) {
    l.normals.clear();
    for (const Vertex& v : l.vertices) {
      l.normals.push_back(octEncode(float(0.1 * std::sin(v.x / 50.0)), 1.0f, float(0.1 * std::cos(v.z / 70.0))));
    }
  }
  return m;
}

TEST(ModuleV2, layoutConstantsArePinned) {
  EXPECT_EQ(kLevelHeaderBytes2, 104u);
  EXPECT_EQ(levelField2::runCount, 36u);
  EXPECT_EQ(levelField2::heightStep, 40u);
  EXPECT_EQ(levelField2::heightBase, 48u);
  EXPECT_EQ(levelField2::skinS0, 72u);
  EXPECT_EQ(levelField2::normalShift, 88u);
  EXPECT_EQ(levelField2::runBytes, 100u);
}

// Golden bytes of version 2, computed by hand (the comments give each
// value); the CRCs come from zlib over the expected bytes.
TEST(ModuleV2, version2GoldenBytes) {
  const auto bytes = encode(tinyV2(), {.version = 2});
  const std::string level =
      "0000000000004040"  // spacing 32.0
      "01000000"          // squaresX 1
      "01000000"          // squaresZ 1
      "0000a040"          // skirt depth 5.0
      "07000000"          // flags: lattice | derived maxHeight | normals
      "04000000"          // 4 vertices
      "06000000"          // 6 indices
      "02000000"          // 2 groups
      "01000000"          // in 1 run
      "7b14ae47e17a843f"  // height step 0.01
      "e803000000000000"  // height base 1000 (10.00 m / 0.01)
      "0000000000004040"  // lastX 32.0
      "0000000000004040"  // lastZ 32.0
      "0000000000000000"  // skin S0 0
      "0000000000000000"  // skin T0 0
      "0600"              // normal shift 6 (every component a multiple of 64)
      "0000"              // x, z exponent: no stream vertices, all zero -> 0
      "00000000"          // no other vertices: empty vertex stream
      "0b000000"          // index stream 11 bytes
      "05000000"          // runs 5 bytes
      // Heights: codes 0, 25, 50, 100; predictions 0, 0 (west), 0 (north),
      // 25 + 50 - 0; residuals 0, 25, 50, 25; zigzag 0, 50, 100, 50; four
      // byte planes.
      "00326432"
      "00000000"
      "00000000"
      "00000000"
      // Normals u >> 6: 0, 1, 0, 1: residuals 0, 1, 0, 0 -> zigzag 0 2 0 0.
      "00020000"
      "00000000"
      // v >> 6: 0, 0, -1, -1: residuals 0, 0, -1, 0 -> zigzag 0 0 1 0.
      "00000100"
      "00000000"
      // meshopt index sequence: header 0xd0 | version, then per index
      // ((zigzag(delta) << 1) | baseline 0): 0, +2, -1, 0, +1, +1, and the
      // 4-byte zero tail.
      "d?00080200040400000000"
      // One run: start slot delta 0, priority 1, material 3, 3 indices, 2 groups.
      "0001030302";
  // The index codec's version nibble is the library's default; read it.
  ASSERT_GT(bytes.size(), 48u + 104u + 32u);
  const int nibble = std::to_integer<int>(bytes[48 + 104 + 32]) & 15;
  std::string want = level;
  want.replace(want.find('?'), 1, 1, "0123456789abcdef"[nibble]);
  ASSERT_EQ(bytes.size(), 48u + want.size() / 2);
  EXPECT_EQ(hex(std::span(bytes).subspan(48)), want);
  EXPECT_LE(nibble, 1);
  // Header: "SANDMOD2", version 2, 48, kx 1, kz 2, 1 level, flags 0, total 200.
  EXPECT_EQ(hex(std::span(bytes).first(40)),
            "53414e444d4f4432"
            "02000000"
            "30000000"
            "01000000"
            "02000000"
            "01000000"
            "00000000"
            "c800000000000000");
  EXPECT_EQ(loadLE<std::uint32_t>(bytes.data() + field::payloadCrc), crc32(std::span(bytes).subspan(48)));
  EXPECT_EQ(loadLE<std::uint32_t>(bytes.data() + field::headerCrc), crc32(std::span(bytes).first(44)));
  auto back = decode(bytes, "golden");
  ASSERT_TRUE(back.ok()) << back.error();
  expectNear(back.value(), tinyV2(), kDefaultHeightStep);
  EXPECT_EQ(back->levels[0].heightStep, kDefaultHeightStep);
  EXPECT_EQ(back->levels[0].maxHeight, std::vector<float>{11.0f});
}

TEST(ModuleV2, roundTripsWithinTheStepAndReencodesIdentically) {
  for (const Module& m : {samples::realistic(3, 4, 8, 2), withNormals(samples::realistic(5, 7)), samples::tiny()}) {
    for (const double step : {0.01, 0.25}) {
      const auto bytes = encode(m, {.version = 2, .heightStep = step});
      EXPECT_EQ(encodedVersion(bytes), 2u);
      auto back = decode(bytes, "v2");
      ASSERT_TRUE(back.ok()) << back.error();
      expectNear(back.value(), m, step);
      // Quantising quantised heights changes nothing.
      EXPECT_EQ(encode(back.value(), {.version = 2, .heightStep = step}), bytes);
      Module reused = samples::realistic(9, 9, 16, 3);
      ASSERT_TRUE(decodeInto(bytes, "v2", 0, reused).ok());
      expectNear(reused, m, step);
    }
  }
}

TEST(ModuleV2, exactHeightsWhenAskedOrWhenAHeightIsNotFinite) {
  Module m = samples::realistic(3, 4, 8, 2);
  auto back = decode(encode(m, {.version = 2, .heightStep = 0}), "exact");
  ASSERT_TRUE(back.ok()) << back.error();
  expectEqual(back.value(), m);  // bit for bit, y included
  EXPECT_EQ(back->levels[0].heightStep, 0.0);
  m.levels[1].vertices[5].y = std::numeric_limits<float>::infinity();
  const auto bytes = encode(m);
  back = decode(bytes, "inf");
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back->levels[1].vertices[5].y, std::numeric_limits<float>::infinity());
  EXPECT_EQ(back->levels[1].heightStep, 0.0);
  EXPECT_EQ(back->levels[0].heightStep, kDefaultHeightStep);
}

TEST(ModuleV2, lossyOnlyInHeightsAndUsesTheLattice) {
  const Module m = samples::realistic(5, 7);
  const auto v2 = encode(m, {.version = 2});
  const auto v1 = encodeV1(m);
  // The lattice and group runs are in use: much smaller than version 1.
  std::uint32_t flags = loadLE<std::uint32_t>(v2.data() + kHeaderBytes + levelField2::flags);
  EXPECT_EQ(flags & (kLevel2Lattice | kLevel2DerivedMaxHeight), kLevel2Lattice | kLevel2DerivedMaxHeight);
  EXPECT_LT(loadLE<std::uint32_t>(v2.data() + kHeaderBytes + levelField2::runCount),
            m.levels[0].groups.size() / 2);
  EXPECT_LT(v2.size() * 2, v1.size());
  // A lattice vertex moved off its post is stored explicitly, exactly.
  Module off = m;
  off.levels[0].vertices[3].x += 0.5f;
  const auto bytes = encode(off);
  flags = loadLE<std::uint32_t>(bytes.data() + kHeaderBytes + levelField2::flags);
  EXPECT_EQ(flags & kLevel2Lattice, 0u);
  auto back = decode(bytes, "off");
  ASSERT_TRUE(back.ok()) << back.error();
  expectNear(back.value(), off, kDefaultHeightStep);
}

TEST(ModuleV2, octahedralNormalsRoundTripAgainstTheUnitVector) {
  std::uint64_t seed = 12345;
  auto next = [&] {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return double(seed >> 11) * 0x1p-53 * 2.0 - 1.0;
  };
  EXPECT_EQ(octEncode(0, 1, 0), 0u);
  EXPECT_EQ(octEncode(0, 0, 0), 0u);
  const auto up = octDecode(0);
  EXPECT_EQ(up[1], 1.0f);
  for (int i = 0; i < 2000; ++i) {
    double x = next(), y = next(), z = next();
    const double n = std::sqrt(x * x + y * y + z * z);
    if (n < 1e-3) continue;
    x /= n, y /= n, z /= n;
    const auto d = octDecode(octEncode(float(x), float(y), float(z)));
    // snorm16 on the octahedron: well under 1e-3 rad anywhere.
    const double dot = d[0] * x + d[1] * y + d[2] * z;
    EXPECT_GT(dot, std::cos(1e-3)) << x << " " << y << " " << z;
    EXPECT_NEAR(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], 1.0, 1e-5);
  }
}

TEST(ModuleV2, version1StillDecodesAndConvertsLosslesslyExceptHeights) {
  const Module m = samples::realistic(2, 3, 8, 3);
  auto one = decode(encodeV1(m), "v1");
  ASSERT_TRUE(one.ok()) << one.error();
  expectEqual(one.value(), m);
  EXPECT_EQ(encodedVersion(encodeV1(m)), 1u);
  auto two = decode(encode(one.value()), "v2");
  ASSERT_TRUE(two.ok()) << two.error();
  expectNear(two.value(), m, kDefaultHeightStep);
}

TEST(ModuleV2, everyTruncatedPrefixFailsNamingItsOffset) {
  const auto bytes = encode(withNormals(samples::realistic(1, 1, 4, 2)));
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    auto m = decode(std::span(bytes).first(n), "cut.bin", 1000);
    ASSERT_FALSE(m.ok()) << "prefix " << n;
    const Problem& p = m.problems().front();
    EXPECT_EQ(p.file, "cut.bin");
    EXPECT_EQ(p.offset, 1000 + n) << p.message;
    EXPECT_EQ(p.message.rfind("module: ", 0), 0u) << p.message;
    EXPECT_NE(p.message.find("truncated"), std::string::npos) << p.message;
  }
}

TEST(ModuleV2, everyFlippedByteIsDetected) {
  auto bytes = encode(samples::realistic(2, 3, 4, 2));
  for (std::size_t off = 0; off < bytes.size(); ++off) {
    bytes[off] ^= std::byte{0x20};
    EXPECT_FALSE(decode(bytes, "flip").ok()) << "flip at " << off << " not caught";
    bytes[off] ^= std::byte{0x20};
  }
}

TEST(ModuleV2, hostileCountsAreRefusedBeforeAllocating) {
  const auto good = encode(withNormals(samples::realistic(1, 2, 4, 1)), {.version = 2});
  const std::size_t lh = kHeaderBytes;
  const std::size_t kXZExponentField = 90;  // i16 beside the u16 normal shift (FORMAT.md §9.7.2)
  struct Case {
    std::size_t field;
    std::uint32_t value;
    std::size_t offset;
    const char* starts;
  };
  const Case cases[] = {
      {levelField2::vertexCount, 0xffffffffu, lh + levelField2::vertexStreamBytes, "module: level 0 vertex stream of"},
      {levelField2::indexCount, 0xffffffffu, lh + levelField2::indexStreamBytes, "module: level 0 index stream of"},
      {levelField2::groupCount, 0xffffffffu, lh + levelField2::groupCount, "module: level 0 4294967295 stored groups in"},
      {levelField2::runCount, 0xffffffffu, lh + levelField2::groupCount, "module: level 0 "},
      {levelField2::vertexStreamBytes, 0xffffff00u, lh + levelField2::vertexStreamBytes, "module: level 0: 25 lattice posts"},
      {levelField2::runBytes, 0x7fffffffu, lh + levelField2::vertexStreamBytes, "module: level 0: 25 lattice posts"},
      {levelField2::squaresX, 65536, lh + levelField2::vertexStreamBytes, "module: level 0: 327685 lattice posts"},
      {levelField2::flags, 16, lh + levelField2::flags, "module: level 0 flags 23 has bits other than 0..3 set"},
      {levelField2::normalShift, 16, lh + levelField2::normalShift, "module: level 0 normal shift 16 is above 15"},
      {kXZExponentField, 0x7ff0, lh + kXZExponentField, "module: level 0 x, z exponent 32752 is neither"},
  };
  for (const Case& c : cases) {
    auto bytes = good;
    if (c.field == levelField2::flags) {
      storeLE<std::uint32_t>(bytes.data() + lh + c.field, loadLE<std::uint32_t>(bytes.data() + lh + c.field) | c.value);
    } else {
      storeLE<std::uint32_t>(bytes.data() + lh + c.field, c.value);
    }
    reseal(bytes);
    gLargestAllocation = 0;
    auto m = decode(bytes, "h.bin", 0);
    ASSERT_FALSE(m.ok()) << c.field;
    EXPECT_LT(gLargestAllocation.load(), std::size_t(1) << 20) << c.field;
    const Problem& p = m.problems().front();
    EXPECT_EQ(p.message.rfind(c.starts, 0), 0u) << p.message;
    EXPECT_EQ(p.offset, c.offset) << p.message;
    EXPECT_EQ(p.file, "h.bin");
  }
}

// Fuzz-style: random byte mutations of valid v2 modules with the CRCs
// re-sealed, so they reach every structural check. Fixed seed; each input
// must decode or fail with a "module: " problem inside the input, never
// crash or allocate beyond a bound (64x the input plus the lattice).
TEST(ModuleV2, randomMutationsNeverCrashOrOverAllocate) {
  const std::vector<std::vector<std::byte>> seeds = {
      encode(tinyV2(), {.version = 2}), encode(withNormals(samples::realistic(1, 2, 8, 2)), {.version = 2}),
      encode(samples::realistic(4, 1, 4, 3), {.version = 2}), encode(tinyV3(), {.version = 3}), encode(tinyV3(), {.heightStep = 0}), encode(tinyV4()),
      encode(withNormals(samples::realistic(1, 2, 8, 2)))};
  std::uint64_t state = 0x5eed;
  auto next = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return std::uint32_t(state >> 33);
  };
  int failures = 0;
  for (int round = 0; round < 3000; ++round) {
    auto bytes = seeds[std::size_t(round) % seeds.size()];
    const int edits = 1 + int(next() % 4);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = kHeaderBytes + next() % (bytes.size() - kHeaderBytes);
      switch (next() % 3) {
        case 0: bytes[at] ^= std::byte(1u << (next() % 8)); break;
        case 1: bytes[at] = std::byte(next()); break;
        default: bytes[at] = std::byte{0xff}; break;
      }
    }
    reseal(bytes);
    gLargestAllocation = 0;
    auto m = decode(bytes, "fuzz.bin", 0);
    EXPECT_LT(gLargestAllocation.load(), 64 * bytes.size() + (std::size_t(1) << 20)) << "round " << round;
    if (!m.ok()) {
      ++failures;
      const Problem& p = m.problems().front();
      EXPECT_EQ(p.message.rfind("module: ", 0), 0u) << p.message;
      EXPECT_LE(p.offset, bytes.size()) << p.message;
    }
  }
  EXPECT_GT(failures, 100);  // the mutations do reach the checks
}

TEST(ModuleV2, checkEncodableRefusesNormalsOfTheWrongCount) {
  Module m = tinyV2();
  m.levels[0].normals.pop_back();
  EXPECT_EQ(checkEncodable(m).message(), "module: level 0 has 3 normals for 4 vertices (one per vertex, or none)");
}

// ------------------------------------------------------------- version 3

TEST(ModuleV3, layoutConstantsArePinned) {
  EXPECT_EQ(kLevelHeaderBytes3, 116u);
  EXPECT_EQ(levelField3::skirtNode, 104u);
  EXPECT_EQ(levelField3::skirtMaterial, 108u);
  EXPECT_EQ(levelField3::reserved, 110u);
  EXPECT_EQ(levelField3::streamIndices, 112u);
  EXPECT_EQ(kLevel3ImplicitSkirts, 16u);
  EXPECT_EQ(kLevel3PlaneHeights, 32u);
}

// Golden bytes of version 3 by hand: tinyV2's level with its skirt, which
// the 8 more header bytes stand for. The payload is the version 2
// golden's but for the height base (no vertex is stored, so the plane
// prediction has nothing to predict).
TEST(ModuleV3, version3GoldenBytes) {
  const auto bytes = encode(tinyV3(), {.version = 3});
  const std::string header =
      "0000000000004040"  // spacing 32.0
      "01000000"          // squaresX 1
      "01000000"          // squaresZ 1
      "0000a040"          // skirt depth 5.0
      "37000000"          // flags: lattice | derived maxHeight | normals | implicit skirts | plane heights
      "0c000000"          // 12 vertices: 4 posts and 8 skirt bottoms
      "1e000000"          // 30 indices: 6 skin, 24 skirt
      "03000000"          // 3 groups: upper, lower, skirt
      "01000000"          // 1 stored run
      "7b14ae47e17a843f"  // height step 0.01
      "f401000000000000"  // height base 500: the lowest vertex is a skirt bottom, 5.00 m
      "0000000000004040"  // lastX 32.0
      "0000000000004040"  // lastZ 32.0
      "0000000000000000"  // skin S0 0
      "0000000000000000"  // skin T0 0
      "0600"              // normal shift 6
      "0000"              // x, z exponent 0 (no stream vertices)
      "00000000"          // empty vertex stream
      "00000000"          // empty index stream: both triangles are the lattice's
      "05000000"          // runs 5 bytes
      "01000000"          // skirt node: 1 square
      "0700"              // skirt material 7
      "0000"              // reserved
      "00000000";         // no index in the stream
  ASSERT_EQ(bytes.size(), 48u + 116u + 37u);
  EXPECT_EQ(hex(std::span(bytes).subspan(48, 116)), header);
  // Codes 500, 525, 550, 600: residuals 500, 25, 50, 25, zigzag 1000 (0x3e8),
  // 50, 100, 50 in four byte planes; then the version 2 golden's normals;
  // then one lattice run: start 0, priority 1, material 3, 3 indices, length
  // 2 << 1 | 1 (lattice).
  const auto v2 = encode(tinyV2(), {.version = 2});
  EXPECT_EQ(hex(std::span(bytes).subspan(48 + 116, 16)), "e8326432030000000000000000000000");
  EXPECT_EQ(hex(std::span(bytes).subspan(48 + 116 + 16, 16)), hex(std::span(v2).subspan(48 + 104 + 16, 16)));
  EXPECT_EQ(hex(std::span(bytes).subspan(48 + 116 + 32)), "0001030305");
  // "SANDMOD3", version 3, 48, kx 1, kz 2, 1 level, flags 0, total 201.
  EXPECT_EQ(hex(std::span(bytes).first(40)),
            "53414e444d4f4433"
            "03000000"
            "30000000"
            "01000000"
            "02000000"
            "01000000"
            "00000000"
            "c900000000000000");
  EXPECT_EQ(loadLE<std::uint32_t>(bytes.data() + field::payloadCrc), crc32(std::span(bytes).subspan(48)));
  EXPECT_EQ(loadLE<std::uint32_t>(bytes.data() + field::headerCrc), crc32(std::span(bytes).first(44)));
  EXPECT_EQ(encodedVersion(bytes), 3u);
  auto back = decode(bytes, "golden");
  ASSERT_TRUE(back.ok()) << back.error();
  expectNear(back.value(), tinyV3(), kDefaultHeightStep);
  // The rebuilt skirt hangs 5 m below the decoded posts.
  const Level& l = back->levels[0];
  EXPECT_EQ(l.vertices[4].y, l.vertices[0].y - 5.0f);
  EXPECT_EQ(l.vertices[11].y, l.vertices[3].y - 5.0f);
}

TEST(ModuleV3, exactHeightsRoundTripBitForBitWithAndWithoutImplicitSkirts) {
  for (const Module& m : {tinyV3(), samples::realistic(3, 4, 8, 2), withNormals(samples::realistic(5, 7)),
                          samples::tiny()}) {
    const auto bytes = encode(m, {.version = 3, .heightStep = 0});
    EXPECT_EQ(encodedVersion(bytes), 3u);
    auto back = decode(bytes, "v3");
    ASSERT_TRUE(back.ok()) << back.error();
    expectEqual(back.value(), m);
    EXPECT_EQ(encode(back.value(), {.version = 3, .heightStep = 0}), bytes);
    Module reused = samples::realistic(9, 9, 16, 3);
    ASSERT_TRUE(decodeInto(bytes, "v3", 0, reused).ok());
    expectEqual(reused, m);
  }
}

TEST(ModuleV3, quantisedHeightsStayWithinTheStepAndReencodeIdentically) {
  for (const Module& m : {tinyV3(), samples::realistic(3, 4, 8, 2), withNormals(samples::realistic(5, 7))}) {
    for (const double step : {0.01, 0.25}) {
      const auto bytes = encode(m, {.version = 3, .heightStep = step});
      auto back = decode(bytes, "v3");
      ASSERT_TRUE(back.ok()) << back.error();
      expectNear(back.value(), m, step);
      EXPECT_EQ(encode(back.value(), {.version = 3, .heightStep = step}), bytes);
    }
  }
}

TEST(ModuleV3, skirtsThatAreNotTheBuildersAreStoredAsTheyAre) {
  // The sample's skirts run per edge square, not per node: stored.
  const auto sample = encode(samples::realistic(5, 7), {.version = 3});
  EXPECT_EQ(loadLE<std::uint32_t>(sample.data() + kHeaderBytes + levelField2::flags) & kLevel3ImplicitSkirts, 0u);
  EXPECT_EQ(loadLE<std::uint32_t>(sample.data() + kHeaderBytes + levelField3::skirtNode), 0u);
  // A bottom vertex off by one ulp, one with a texture coordinate, a
  // changed index: each keeps the skirt explicit, and each decodes exactly.
  std::vector<Module> changed(3, tinyV3());
  changed[0].levels[0].vertices[6].y = std::nextafter(changed[0].levels[0].vertices[6].y, 0.0f);
  changed[1].levels[0].vertices[9].s = 0.5f;
  std::swap(changed[2].levels[0].indices[7], changed[2].levels[0].indices[8]);
  for (const Module& m : changed) {
    const auto bytes = encode(m, {.version = 3, .heightStep = 0});
    const auto flags = loadLE<std::uint32_t>(bytes.data() + kHeaderBytes + levelField2::flags);
    EXPECT_EQ(flags & kLevel3ImplicitSkirts, 0u);
    EXPECT_NE(flags & kLevel3PlaneHeights, 0u);
    auto back = decode(bytes, "explicit");
    ASSERT_TRUE(back.ok()) << back.error();
    expectEqual(back.value(), m);
  }
  // With implicit skirts and a lattice run, the tiny module with its skirt
  // takes one byte more than version 2 without it (12 more header bytes,
  // 11 fewer index stream bytes).
  EXPECT_EQ(encode(tinyV3(), {.version = 3}).size(), encode(tinyV2(), {.version = 2}).size() + 1);
}

TEST(ModuleV3, planeHeightsPredictCultureVerticesOnTheirTriangle) {
  // Vertices scattered over the upper triangle at the plane's height store
  // zero residuals: their stream is smaller than the same vertices off the
  // plane by varying amounts, and both decode exactly.
  auto withVertices = [](bool off) {
    Module m = tinyV2();
    Level& l = m.levels[0];
    l.normals.clear();
    for (int k = 0; k < 64; ++k) {
      const double u = double(k % 8) / 16, v = double(k / 8) / 16;  // u + v < 1
      const float x = float(32 * u), z = float(32 * v);
      const double y = 10 + u * 0.25 + v * 0.5 + (off ? double((k * 37) % 11) * 0.37 : 0.0);
      l.vertices.push_back({x, float(y), z, x / 64, z / 64});
    }
    return m;
  };
  const auto onPlane = encode(withVertices(false), {.version = 3, .heightStep = 0});
  const auto above = encode(withVertices(true), {.version = 3, .heightStep = 0});
  const std::size_t stream = kHeaderBytes + levelField2::vertexStreamBytes;
  EXPECT_LT(loadLE<std::uint32_t>(onPlane.data() + stream), loadLE<std::uint32_t>(above.data() + stream));
  for (const auto& bytes : {onPlane, above}) {
    auto back = decode(bytes, "plane");
    ASSERT_TRUE(back.ok()) << back.error();
  }
  expectEqual(decode(onPlane, "plane").value(), withVertices(false));
  expectEqual(decode(above, "plane").value(), withVertices(true));
}

TEST(ModuleV3, everyTruncatedPrefixFailsNamingItsOffset) {
  for (const auto& bytes : {encode(tinyV3(), {.version = 3}), encode(samples::realistic(1, 1, 4, 2), {.version = 3})}) {
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      auto m = decode(std::span(bytes).first(n), "cut.bin", 1000);
      ASSERT_FALSE(m.ok()) << "prefix " << n;
      const Problem& p = m.problems().front();
      EXPECT_EQ(p.file, "cut.bin");
      EXPECT_EQ(p.offset, 1000 + n) << p.message;
      EXPECT_NE(p.message.find("truncated"), std::string::npos) << p.message;
    }
  }
}

TEST(ModuleV3, everyFlippedByteIsDetected) {
  for (auto bytes : {encode(tinyV3(), {.version = 3}), encode(samples::realistic(2, 3, 4, 2), {.version = 3})}) {
    for (std::size_t off = 0; off < bytes.size(); ++off) {
      bytes[off] ^= std::byte{0x20};
      EXPECT_FALSE(decode(bytes, "flip").ok()) << "flip at " << off << " not caught";
      bytes[off] ^= std::byte{0x20};
    }
  }
}

/// One level header field of the first level set to a hostile value.
struct HostileField {
  std::size_t field;
  unsigned width;
  std::uint32_t value;
  std::size_t offset;
  const char* message;
};

/// good with the field set (CRCs resealed) is refused with the message and
/// offset, before any large allocation.
void expectRefused(const std::vector<std::byte>& good, const HostileField& c) {
  auto bytes = good;
  std::byte* at = bytes.data() + kHeaderBytes + c.field;
  if (c.width == 2) {
    storeLE<std::uint16_t>(at, std::uint16_t(c.value));
  } else {
    storeLE<std::uint32_t>(at, c.value);
  }
  reseal(bytes);
  gLargestAllocation = 0;
  auto m = decode(bytes, "h.bin", 0);
  ASSERT_FALSE(m.ok()) << c.message;
  EXPECT_LT(gLargestAllocation.load(), std::size_t(1) << 20) << c.message;
  EXPECT_EQ(m.problems().front().message, c.message);
  EXPECT_EQ(m.problems().front().offset, c.offset) << c.message;
}

TEST(ModuleV3, hostileSkirtFieldsAreRefusedBeforeAllocating) {
  const auto good = encode(tinyV3(), {.version = 3});
  const std::size_t lh = kHeaderBytes;
  const HostileField cases[] = {
      {levelField3::skirtNode, 4, 0, lh + levelField3::skirtNode,
       "module: level 0 skirt node 0 is out of range (1 to 65536)"},
      {levelField3::skirtNode, 4, 65537, lh + levelField3::skirtNode,
       "module: level 0 skirt node 65537 is out of range (1 to 65536)"},
      {levelField3::reserved, 2, 1, lh + levelField3::skirtMaterial,
       "module: level 0 skirt material and reserved bytes must be 0 (the material without implicit skirts)"},
      {levelField2::vertexCount, 4, 11, lh + levelField2::vertexCount,
       "module: level 0 has 11 vertices, fewer than its 4 lattice posts and 8 skirt vertices"},
      {levelField2::indexCount, 4, 23, lh + levelField2::indexCount,
       "module: level 0 has 23 indices in 3 groups, fewer than its 24 skirt indices in 1 groups"},
      {levelField2::flags, 4, 0x77, lh + levelField2::flags, "module: level 0 flags 119 has bits other than 0..5 set"},
      {levelField3::streamIndices, 4, 7, lh + levelField3::streamIndices,
       "module: level 0 index stream count 7 is above the 6 stored indices, or below them without the lattice "
       "(bit 0)"},
      {levelField3::streamIndices, 4, 3, lh + levelField2::indexStreamBytes,
       "module: level 0 index stream of 0 bytes cannot hold 3 indices"},
      {levelField2::flags, 4, 0x36, lh + levelField2::flags,
       "module: level 0 flags 54: a derived maxHeight (bit 1), implicit skirts (bit 4) and plane heights (bit 5) "
       "need the lattice (bit 0)"},
  };
  for (const HostileField& c : cases) expectRefused(good, c);
  // A node with no implicit skirts, or a material: refused as well.
  auto bytes = encode(samples::realistic(1, 1, 4, 1), {.version = 3});
  storeLE<std::uint32_t>(bytes.data() + lh + levelField3::skirtNode, 4);
  reseal(bytes);
  EXPECT_EQ(decode(bytes, "n").problems().front().message,
            "module: level 0 skirt node 4 must be 0 without implicit skirts");
}

TEST(ModuleV3, versions1And2StillDecodeAndUpgradeToVersion3) {
  const Module m = samples::realistic(2, 3, 8, 3);
  for (const std::uint32_t version : {1u, 2u}) {
    const auto old = encode(m, {.version = version, .heightStep = 0});
    EXPECT_EQ(encodedVersion(old), version);
    auto back = decode(old, "old");
    ASSERT_TRUE(back.ok()) << back.error();
    expectEqual(back.value(), m);
    auto three = decode(encode(back.value(), {.heightStep = 0}), "v3");
    ASSERT_TRUE(three.ok()) << three.error();
    expectEqual(three.value(), m);
  }
}

// ------------------------------------------------------------- version 4

TEST(ModuleV4, layoutConstantsArePinned) {
  EXPECT_EQ(kLevelHeaderBytes4, 124u);
  EXPECT_EQ(levelField4::rawTextureVertices, 116u);
  EXPECT_EQ(levelField4::stExponent, 120u);
  EXPECT_EQ(levelField4::reserved, 122u);
  EXPECT_EQ(kLevel4PlaneOffsets, 64u);
}

// The header by hand; the vertex stream read back with meshopt's own
// decoder and compared with codes worked out by hand.
TEST(ModuleV4, version4GoldenBytes) {
  const auto bytes = encode(tinyV4(), {.version = 4});
  EXPECT_EQ(hex(std::span(bytes).first(16)), "53414e444d4f44340400000030000000");  // "SANDMOD4", 4, 48
  EXPECT_EQ(encodedVersion(bytes), 4u);
  const std::byte* h = bytes.data() + kHeaderBytes;
  EXPECT_EQ(hex(std::span(bytes).subspan(kHeaderBytes + 20, 16)),
            "77000000"   // flags: lattice | derived | normals | skirts | plane | plane offsets
            "0f000000"   // 15 vertices: 4 posts, 3 decal, 8 skirt bottoms
            "21000000"   // 33 indices
            "04000000");  // 4 groups
  EXPECT_EQ(hex(std::span(bytes).subspan(kHeaderBytes + 90, 2)), "0300");  // x, z exponent 3: 8 and 16 are 1 and 2 eights
  EXPECT_EQ(hex(std::span(bytes).subspan(kHeaderBytes + 116, 8)),
            "03000000"  // the 3 decal vertices store raw texture
            "feff"      // s, t exponent -2 (quarters)
            "0000");    // reserved
  const auto vb = loadLE<std::uint32_t>(h + levelField2::vertexStreamBytes);
  // The stream follows the lattice heights (16 bytes) and normals (16).
  std::vector<std::uint32_t> raw(3 * 6);
  ASSERT_EQ(meshopt_decodeVertexBuffer(raw.data(), 3, 24,
                                       reinterpret_cast<const unsigned char*>(h + kLevelHeaderBytes4 + 32), vb),
            0);
  // x, height offset (0: on the plane), z, s, t codes; normal 0.
  const std::vector<std::uint32_t> want = {1, 0, 1, 2, 0, 0, 2, 0, 1, 3, 0, 0, 1, 0, 2, 2, 4, 0};
  EXPECT_EQ(raw, want);
  auto back = decode(bytes, "golden");
  ASSERT_TRUE(back.ok()) << back.error();
  expectNear(back.value(), tinyV4(), kDefaultHeightStep);
}

// Version 3 re-quantised a culture vertex's height; version 4 puts it on
// the plane of the decoded posts, the plane the lattice triangle draws.
TEST(ModuleV4, quantisedCultureHeightsStayOnTheDecodedPlane) {
  const Module m = tinyV4();
  for (const double step : {0.01, 0.25}) {
    auto v4 = decode(encode(m, {.heightStep = step}), "v4");
    auto v3 = decode(encode(m, {.version = 3, .heightStep = step}), "v3");
    ASSERT_TRUE(v4.ok() && v3.ok());
    expectNear(v4.value(), m, step);
    const auto& p = v4->levels[0].vertices;
    const double hnw = p[0].y, hne = p[1].y, hsw = p[2].y;  // decoded posts
    double v3Off = 0;
    for (int k = 4; k < 7; ++k) {
      const Vertex& q = p[std::size_t(k)];
      const double plane = hnw + (q.x / 32.0) * (hne - hnw) + (q.z / 32.0) * (hsw - hnw);
      EXPECT_NEAR(q.y, plane, 1e-5) << "step " << step << " vertex " << k;
      v3Off = std::max(v3Off, std::fabs(v3->levels[0].vertices[std::size_t(k)].y - plane));
    }
    if (step == 0.25) {
      EXPECT_GT(v3Off, 0.01);  // version 3 left them off it
    }
    EXPECT_EQ(encode(v4.value(), {.heightStep = step}), encode(m, {.heightStep = step}));
  }
}

TEST(ModuleV4, textureThatIsNotOnAStepAndExactHeightsRoundTripBitForBit) {
  Module m = tinyV4();
  m.levels[0].vertices[5].t = -0.0f;  // no integer code: float bits
  m.levels[0].vertices[4].y += 0.003f;  // off the plane
  for (const Module& x : {m, samples::realistic(3, 4, 8, 2), withNormals(samples::realistic(5, 7))}) {
    const auto bytes = encode(x, {.heightStep = 0});
    auto back = decode(bytes, "v4");
    ASSERT_TRUE(back.ok()) << back.error();
    expectEqual(back.value(), x);
    EXPECT_EQ(encode(back.value(), {.heightStep = 0}), bytes);
  }
  const auto bytes = encode(m, {.heightStep = 0});
  EXPECT_EQ(loadLE<std::int16_t>(bytes.data() + kHeaderBytes + levelField4::stExponent), 32767);
  EXPECT_EQ(loadLE<std::uint32_t>(bytes.data() + kHeaderBytes + levelField2::flags) & kLevel4PlaneOffsets, 0u);
}

/// Every prefix of `bytes` is refused as truncated at its end, and every
/// single flipped byte is caught.
void expectPrefixesAndFlipsCaught(std::vector<std::byte> bytes) {
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    auto m = decode(std::span(bytes).first(n), "cut.bin", 1000);
    ASSERT_FALSE(m.ok()) << "prefix " << n;
    EXPECT_EQ(m.problems().front().offset, 1000 + n) << m.problems().front().message;
    EXPECT_NE(m.problems().front().message.find("truncated"), std::string::npos);
  }
  for (std::size_t off = 0; off < bytes.size(); ++off) {
    bytes[off] ^= std::byte{0x20};
    EXPECT_FALSE(decode(bytes, "flip").ok()) << "flip at " << off << " not caught";
    bytes[off] ^= std::byte{0x20};
  }
}

TEST(ModuleV4, everyTruncatedPrefixAndFlippedByteIsCaught) {
  expectPrefixesAndFlipsCaught(encode(tinyV4(), {.version = 4}));
  expectPrefixesAndFlipsCaught(encode(samples::realistic(2, 3, 4, 2), {.version = 4}));
}

TEST(ModuleV4, hostileFieldsAreRefusedBeforeAllocating) {
  const auto good = encode(tinyV4());
  const std::size_t lh = kHeaderBytes;
  const HostileField cases[] = {
      {levelField4::rawTextureVertices, 4, 4, lh + levelField4::rawTextureVertices,
       "module: level 0 has 4 raw-texture vertices, more than its 3 stream vertices"},
      {levelField4::rawTextureVertices, 4, 0xffffffffu, lh + levelField4::rawTextureVertices,
       "module: level 0 has 4294967295 raw-texture vertices, more than its 3 stream vertices"},
      {levelField4::reserved, 2, 1, lh + levelField4::rawTextureVertices,
       "module: level 0 raw-texture vertices need the lattice (bit 0), and the reserved bytes must be 0"},
      {levelField4::stExponent, 2, 200, lh + levelField4::stExponent,
       "module: level 0 s, t exponent 200 is neither -149..127 nor 32767 (float bits)"},
      {levelField2::flags, 4, 0xf7, lh + levelField2::flags, "module: level 0 flags 247 has bits other than 0..6 set"},
      {levelField2::flags, 4, 0x57, lh + levelField2::flags,
       "module: level 0 flags 87: plane offsets (bit 6) need plane heights (bit 5) and quantised heights (bit 3 "
       "clear)"},
  };
  for (const HostileField& c : cases) expectRefused(good, c);
}


// ------------------------------------------------------------- version 5

/// tinyV4 with two objects: a tree (icon 1, class 10) and an explicit one.
Module tinyV5() {
  Module m = tinyV4();
  m.objects = {{1, 10, 8.0f, 4.0f, 0, 1.0f, 0.5f, 6.0f}, {3, kObjectClassExplicit, 24.0f, 28.0f, 16384, 2.5f, 1.25f, 15.0f}};
  m.levels[0].objectY = {10.1875f, 10.625f};
  return m;
}

TEST(ModuleV5, layoutConstantsArePinned) {
  EXPECT_EQ(kObjectBytes, 26u);
  EXPECT_EQ(kObjectClassExplicit, 0xffffu);
  EXPECT_EQ(kNewestVersion, 6u);
  EXPECT_EQ(headingCode(headingRadians(16384)), 16384u);
  EXPECT_EQ(headingCode(-1.5707963267948966), 49152u);
  EXPECT_EQ(headingCode(6.283185307179586), 0u);
}

// The objects section by hand (worked out in FORMAT.md §9.10): the count,
// then each field's byte planes; version 4's bytes before it.
TEST(ModuleV5, version5GoldenBytes) {
  const auto bytes = encode(tinyV5(), {.version = 5});
  const auto v4 = encode(tinyV4(), {.version = 4});
  EXPECT_EQ(hex(std::span(bytes).first(16)), "53414e444d4f44350500000030000000");  // "SANDMOD5", 5, 48
  EXPECT_EQ(encodedVersion(bytes), 5u);
  ASSERT_EQ(bytes.size(), v4.size() + 64);
  EXPECT_TRUE(std::equal(bytes.begin() + kHeaderBytes, bytes.end() - 64, v4.begin() + kHeaderBytes));
  EXPECT_EQ(hex(std::span(bytes).last(64)),
            "02000000"                  // 2 objects
            "01030000"                  // icon 1, 3
            "0aff00ff"                  // class 10, 65535 (explicit)
            "0000000000c04141"          // x 8, 24
            "0000000080e04041"          // z 4, 28
            "00000040"                  // heading 0, 16384 (east)
            "0000000080203f40"          // scale 1, 2.5
            "0000000000a03f3f"          // radius 0.5, 1.25
            "00000000c0704041"          // height 6, 15
            "00000000232a4141");        // level 0 y 10.1875, 10.625
  auto back = decode(bytes, "golden");
  ASSERT_TRUE(back.ok()) << back.error();
  ASSERT_EQ(back->objects.size(), 2u);
  EXPECT_EQ(back->objects[1].heading, 16384u);
  EXPECT_EQ(back->objects[1].cls, kObjectClassExplicit);
  EXPECT_EQ(back->levels[0].objectY, (std::vector<float>{10.1875f, 10.625f}));
  EXPECT_EQ(encode(back.value(), {.version = 5}), bytes);
}

TEST(ModuleV5, olderVersionsDropObjectsAndDecodeWithNone) {
  for (const std::uint32_t v : {1u, 2u, 4u}) {
    auto back = decode(encode(tinyV5(), {.version = v}), "old");
    ASSERT_TRUE(back.ok()) << back.error();
    EXPECT_TRUE(back->objects.empty()) << v;
    EXPECT_TRUE(back->levels[0].objectY.empty()) << v;
  }
  auto none = decode(encode(tinyV4(), {.version = 5}), "none");  // version 5 with no objects: 4 bytes of count
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->objects.empty());
}

TEST(ModuleV5, manyObjectsOnManyLevelsRoundTripBitForBit) {
  Module m = samples::realistic(3, 4, 8, 2);
  for (std::uint32_t k = 0; k < 500; ++k) {
    m.objects.push_back({std::uint16_t(k % 7), std::uint16_t(k % 3), float(k % 97) * 0.37f, float(k / 97) * 5.5f,
                         std::uint16_t(k * 977), 0.5f + float(k % 5) * 0.25f, 1.5f, 9.0f});
  }
  for (std::size_t li = 0; li < m.levels.size(); ++li) {
    for (std::uint32_t k = 0; k < 500; ++k) m.levels[li].objectY.push_back(100.0f + float(k) * 0.01f + float(li));
  }
  const auto bytes = encode(m, {.version = 5, .heightStep = 0});
  auto back = decode(bytes, "many");
  ASSERT_TRUE(back.ok()) << back.error();
  ASSERT_EQ(back->objects.size(), 500u);
  for (std::size_t k = 0; k < 500; ++k) {
    const Object& a = m.objects[k];
    const Object& b = back->objects[k];
    ASSERT_TRUE(a.icon == b.icon && a.cls == b.cls && sameBits(a.x, b.x) && sameBits(a.z, b.z) &&
                a.heading == b.heading && sameBits(a.scale, b.scale) && sameBits(a.radius, b.radius) &&
                sameBits(a.height, b.height))
        << k;
  }
  for (std::size_t li = 0; li < m.levels.size(); ++li) EXPECT_EQ(back->levels[li].objectY, m.levels[li].objectY);
  EXPECT_EQ(encode(back.value(), {.version = 5, .heightStep = 0}), bytes);
}

TEST(ModuleV5, everyTruncatedPrefixAndFlippedByteIsCaught) { expectPrefixesAndFlipsCaught(encode(tinyV5(), {.version = 5})); }

/// tinyV5's encoding with the objects section's bytes at `at` (from the
/// section's start) set to `value`, and the checksums resealed.
std::vector<std::byte> withObjectField(std::size_t at, std::uint32_t value, unsigned width = 4) {
  auto bytes = encode(tinyV5(), {.version = 5});
  std::byte* p = bytes.data() + bytes.size() - 64 + at;
  if (width == 2) {
    storeLE<std::uint16_t>(p, std::uint16_t(value));
  } else {
    storeLE<std::uint32_t>(p, value);
  }
  reseal(bytes);
  return bytes;
}

TEST(ModuleV5, hostileObjectFieldsAreRefusedBeforeAllocating) {
  const std::size_t section = encode(tinyV5(), {.version = 5}).size() - 64;
  struct Case {
    std::size_t at;
    std::uint32_t value;
    std::size_t offset;
    const char* message;
  };
  const Case cases[] = {
      {0, 0xffffffffu, section, "module: objects: count 4294967295 is over the limit of 1048576 objects per module"},
      {0, 1u << 20, section + 64, "module: objects: truncated: 1048576 objects need 31457280 bytes, 60 remain"},
      {0, 3, section + 64, "module: objects: truncated: 3 objects need 90 bytes, 60 remain"},
  };
  for (const Case& c : cases) {
    gLargestAllocation = 0;
    auto m = decode(withObjectField(c.at, c.value), "h.bin");
    ASSERT_FALSE(m.ok()) << c.message;
    EXPECT_LT(gLargestAllocation.load(), std::size_t(1) << 20) << c.message;
    EXPECT_EQ(m.problems().front().message, c.message);
    EXPECT_EQ(m.problems().front().offset, c.offset) << c.message;
  }
  // Bytes after the section.
  auto longer = encode(tinyV5(), {.version = 5});
  longer.resize(longer.size() + 3, std::byte{0});
  storeLE<std::uint64_t>(longer.data() + field::totalBytes, longer.size());
  reseal(longer);
  auto trailing = decode(longer, "h.bin");
  ASSERT_FALSE(trailing.ok());
  EXPECT_EQ(trailing.error(), "h.bin @" + std::to_string(section + 64) +
                                  ": module: 3 bytes follow the objects section");
  // Values that would put NaN into a draw or a collision test: object 0's
  // value in a plane of 4-byte values starting at `at`, byte b at at + 2 b.
  const std::pair<std::size_t, const char*> nanFields[] = {
      {12, "module: objects: object 0 position is not finite"},
      {32, "module: objects: object 0 scale, radius or height is not finite and positive"},
      {56, "module: objects: object 0 elevation on level 0 is not finite"},
  };
  for (const auto& [at, message] : nanFields) {
    auto bytes = encode(tinyV5(), {.version = 5});
    std::byte* p = bytes.data() + section + at;
    const auto u = std::bit_cast<std::uint32_t>(std::numeric_limits<float>::quiet_NaN());
    for (unsigned k = 0; k < 4; ++k) p[2 * k] = std::byte((u >> (8 * k)) & 0xff);
    reseal(bytes);
    auto r = decode(bytes, "h.bin");
    ASSERT_FALSE(r.ok()) << message;
    EXPECT_EQ(r.problems().front().message, message);
  }
  const Module negative = [] {
    Module m = tinyV5();
    m.objects[0].scale = 0;
    return m;
  }();
  EXPECT_FALSE(decode(encode(negative, {.version = 5}), "zero").ok());
}

TEST(ModuleV5, checkEncodableWantsOneElevationPerObjectOnEveryLevel) {
  Module m = tinyV5();
  m.levels[0].objectY.pop_back();
  const Status st = checkEncodable(m);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.message(), "module: level 0 has 1 object elevations for 2 objects (one per object on every level)");
}

TEST(ModuleV5, tallestObjectIsFoundPerSquare) {
  Module m = samples::realistic(3, 4, 8, 2);  // level 0 squares of the realistic sample
  const Level& l0 = m.levels[0];
  const float sx = float(l0.spacing);
  // Two in square 0 (the second taller), one in square (1, 1).
  m.objects = {{0, 0, 0.2f * sx, 0.2f * sx, 0, 1, 1, 5}, {0, 0, 0.7f * sx, 0.6f * sx, 0, 1, 1, 8},
               {0, 0, 1.5f * sx, 1.5f * sx, 0, 1, 1, 2}};
  for (Level& l : m.levels) l.objectY = {10.0f, 9.0f, 3.0f};
  const auto t = tallestObjects(m, 0);
  ASSERT_EQ(t.size(), std::size_t(l0.squaresX) * l0.squaresZ);
  EXPECT_EQ(t[0], 1u);                                 // 9 + 8 over 10 + 5
  EXPECT_EQ(t[std::size_t(l0.squaresX) + 1], 2u);
  EXPECT_EQ(t[1], kNoObject);
  m.levels[0].objectY = {20.0f, 9.0f, 3.0f};           // now the first is taller
  EXPECT_EQ(tallestObjects(m, 0)[0], 0u);
}

// ------------------------------------------------------------- version 6

Module forest(std::uint32_t kx, std::uint32_t kz);

constexpr ScatterRule kTinyRule{2, 3, 0, 16.0, 7, 0.8, 1.2, 0.5f, 6.0f};

/// The rule's trees on `m`'s level 0, plus `extra`; sorted, with bases.
void plantTrees(Module& m, std::vector<Object> extra = {}) {
  const Surface surface(m.levels.front(), true);
  m.objects = std::move(extra);
  for (std::size_t r = 0; r < m.scattering.rules.size(); ++r) {
    const auto trees = scatter(m.scattering, r, surface);
    m.objects.insert(m.objects.end(), trees.begin(), trees.end());
  }
  sortObjects(m.objects);
  placeBases(m);
}

/// tinyV4 (one 32 m square of class 3 with a decal of class 9) with a
/// 16 m scatter rule of class 3 and one explicit object.
Module tinyV6() {
  Module m = tinyV4();
  m.scattering = {0, 0, 32, 32, {kTinyRule}};
  plantTrees(m, {{3, kObjectClassExplicit, 24.0f, 28.0f, 16384, 2.5f, 1.25f, 15.0f, 0}});
  return m;
}

bool sameObject(const Object& a, const Object& b) {
  return a.icon == b.icon && a.cls == b.cls && sameBits(a.x, b.x) && sameBits(a.z, b.z) && a.heading == b.heading &&
         sameBits(a.scale, b.scale) && sameBits(a.radius, b.radius) && sameBits(a.height, b.height) && a.id == b.id;
}

void expectSameObjects(const std::vector<Object>& a, const std::vector<Object>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) ASSERT_TRUE(sameObject(a[k], b[k])) << "object " << k;
}

TEST(ModuleV6, layoutConstantsArePinned) {
  EXPECT_EQ(kNewestVersion, 6u);
  EXPECT_EQ(kRuleRegenerate, 0u);
  EXPECT_EQ(kRuleBitmap, 1u);
  EXPECT_EQ(scatteredId(5, -1, 2), 0x8005ffffff000002ull);
  EXPECT_EQ(idRule(scatteredId(5, -1, 2)), 5u);
  EXPECT_EQ(idCellI(scatteredId(5, -1, 2)), -1);
  EXPECT_EQ(idCellJ(scatteredId(5, -1, 2)), 2);
  EXPECT_EQ(idCellI(scatteredId(0, kMaxCellIndex, -kMaxCellIndex - 1)), kMaxCellIndex);
  EXPECT_EQ(idCellJ(scatteredId(0, kMaxCellIndex, -kMaxCellIndex - 1)), -kMaxCellIndex - 1);
}

// The objects section by hand (worked out in FORMAT.md §9.11): header,
// palette, the rule with an empty drop list, the explicit object's planes.
TEST(ModuleV6, version6GoldenBytes) {
  const Module m = tinyV6();
  ASSERT_GE(m.objects.size(), 2u) << "the rule must keep a tree on tinyV4";
  const auto bytes = encode(m);
  const auto v4 = encode(tinyV4(), {.version = 4});
  EXPECT_EQ(hex(std::span(bytes).first(16)), "53414e444d4f44360600000030000000");  // "SANDMOD6", 6, 48
  EXPECT_EQ(encodedVersion(bytes), 6u);
  ASSERT_EQ(bytes.size(), v4.size() + 123);
  EXPECT_TRUE(std::equal(bytes.begin() + kHeaderBytes, bytes.end() - 123, v4.begin() + kHeaderBytes));
  EXPECT_EQ(hex(std::span(bytes).last(123)),
            "01000000"                                  // 1 explicit object
            "0100" "0100"                               // 1 rule, 1 palette entry
            "0000000000000000" "0000000000000000"       // corner x0 0, z0 0
            "0000000000004040" "0000000000004040"       // width 32, depth 32
            "00002040" "00002040"                       // explicit scales 2.5 .. 2.5
            "0300" "ffff" "0000003f" "0000c040"         // palette: icon 3, class 65535, cylinder 0.5 x 6
            "0200" "0300" "0000" "00" "00"              // rule: icon 2, class 3, index 0, regenerate
            "0000000000003040" "0700000000000000"       // cell 16, seed 7
            "9a9999999999e93f" "333333333333f33f"       // scale 0.8 .. 1.2
            "0000003f" "0000c040"                       // cylinder 0.5 x 6
            "00000000" "00000000"                       // drops none; reserved
            "00c0" "00e0"                               // x 24 = 49152 / 65536 * 32, z 28
            "40" "00" "00");                            // heading 64 * 256 (east), scale code 0, palette 0
  auto back = decode(bytes, "golden");
  ASSERT_TRUE(back.ok()) << back.error();
  expectSameObjects(back->objects, m.objects);
  EXPECT_EQ(back->scattering, m.scattering);
  ASSERT_EQ(back->levels[0].objectY.size(), m.objects.size());
  for (std::size_t k = 0; k < m.objects.size(); ++k) {
    EXPECT_TRUE(withinStep(back->levels[0].objectY[k], m.levels[0].objectY[k], kDefaultHeightStep)) << k;
  }
  EXPECT_EQ(encode(back.value()), bytes);
  // Exact heights: the bases come back bit for bit.
  auto exact = decode(encode(m, {.heightStep = 0}), "exact");
  ASSERT_TRUE(exact.ok()) << exact.error();
  EXPECT_EQ(exact->levels[0].objectY, m.levels[0].objectY);
}

TEST(ModuleV6, everyTruncatedPrefixAndFlippedByteIsCaught) {
  expectPrefixesAndFlipsCaught(encode(tinyV6()));
  Module bitmap = tinyV6();
  bitmap.levels[0].groups[0].material = 4;  // the rule cannot regenerate: a bitmap
  expectPrefixesAndFlipsCaught(encode(bitmap));
}

TEST(ModuleV6, aRemovedTreeIsAnExceptionAndStaysRemoved) {
  Module m = forest(2, 3);
  const std::size_t before = encode(m).size();
  const auto tree = std::find_if(m.objects.begin(), m.objects.end(), [](const Object& o) { return isScattered(o.id); });
  ASSERT_NE(tree, m.objects.end());
  const std::uint64_t gone = tree->id;
  m.objects.erase(tree);
  placeBases(m);
  const auto bytes = encode(m);
  EXPECT_EQ(bytes.size(), before + 4);  // one candidate number in its rule's drop list
  auto back = decode(bytes, "edit");
  ASSERT_TRUE(back.ok()) << back.error();
  expectSameObjects(back->objects, m.objects);
  for (const Object& o : back->objects) EXPECT_NE(o.id, gone);
  // On a rule of 9 candidates a 2-byte bitmap is smaller than a drop list.
  Module tiny = tinyV6();
  tiny.objects.erase(std::find_if(tiny.objects.begin(), tiny.objects.end(), [](const Object& o) { return isScattered(o.id); }));
  placeBases(tiny);
  const auto small = encode(tiny);
  EXPECT_EQ(std::to_integer<int>(small[encode(tiny, {.version = 4}).size() + 60 + 6]), kRuleBitmap);
  auto smallBack = decode(small, "edit");
  ASSERT_TRUE(smallBack.ok()) << smallBack.error();
  expectSameObjects(smallBack->objects, tiny.objects);
}

TEST(ModuleV6, aRecordWithoutItsSkinKeepsTreesByBitmap) {
  Module m = tinyV6();
  Module other = m;
  other.levels[0].groups[0].material = 4;  // level 0 no longer says class 3 there
  const auto bytes = encode(other);
  const std::size_t rule = encode(other, {.version = 4}).size() + 60;
  EXPECT_EQ(std::to_integer<int>(bytes[rule + 6]), kRuleBitmap);
  EXPECT_EQ(loadLE<std::uint32_t>(bytes.data() + rule + 48), 2u);  // 9 candidates (3 x 3 cells): 2 bytes
  auto back = decode(bytes, "bitmap");
  ASSERT_TRUE(back.ok()) << back.error();
  expectSameObjects(back->objects, m.objects);
}

TEST(ModuleV6, explicitObjectsAreQuantisedAsDocumented) {
  Module m = tinyV4();
  m.scattering = {0, 0, 32, 32, {}};
  std::vector<Object> objects;
  for (std::uint32_t k = 0; k < 300; ++k) {
    objects.push_back({std::uint16_t(k % 5), kObjectClassExplicit, float(k % 31) + 0.37f, float(k % 29) + 0.61f,
                       std::uint16_t(k * 977), 0.5f + float(k % 7) * 0.5f, 0.0f, 0.0f, k});
    objects.back().radius = 0.25f * objects.back().scale;
    objects.back().height = 3.0f * objects.back().scale;
  }
  plantTrees(m, objects);
  auto back = decode(encode(m), "q");
  ASSERT_TRUE(back.ok()) << back.error();
  ASSERT_EQ(back->objects.size(), m.objects.size());
  const double step = 32.0 / 65536, ratio = std::pow(3.5 / 0.5, 1.0 / 510.0);
  for (const Object& b : back->objects) {
    const Object& a = objects[std::size_t(b.id)];
    EXPECT_EQ(a.icon, b.icon);
    EXPECT_LE(std::fabs(double(a.x) - b.x), step / 2 + 1e-6);
    EXPECT_LE(std::fabs(double(a.z) - b.z), step / 2 + 1e-6);
    const int dh = std::abs(int(std::int16_t(std::uint16_t(a.heading - b.heading))));
    EXPECT_LE(dh, 128);
    EXPECT_LE(std::max(a.scale / b.scale, b.scale / a.scale), ratio * (1 + 1e-6));
    EXPECT_FLOAT_EQ(b.radius, 0.25f * b.scale);
  }
}

struct HostileV6 {
  std::size_t at;  ///< from the section's start
  std::uint64_t value;
  unsigned width;
  std::size_t offset;  ///< expected, from the section's start (SIZE_MAX: the input's end)
  const char* message;
};

TEST(ModuleV6, hostileRulesAndCountsAreRefusedBeforeAllocating) {
  const auto good = encode(tinyV6());
  const std::size_t section = good.size() - 123, rule = 60;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto f64 = [](double d) { return std::bit_cast<std::uint64_t>(d); };
  const HostileV6 cases[] = {
      {0, 0xffffffffu, 4, 0, "explicit count 4294967295 is over the limit of 1048576 objects per module"},
      {0, 1u << 20, 4, rule + 8,
       "rule 0 cell 16.000000 m makes 9 candidates; with the module's other objects over the limit of 1048576"},
      {0, (1u << 20) - 9, 4, SIZE_MAX, "truncated: 1048567 explicit objects needs 7339969 bytes, 7 remain"},
      {4, 0xffff, 2, SIZE_MAX, "truncated: 65535 rules needs 3669960 bytes, 63 remain"},
      {6, 0xffff, 2, SIZE_MAX, "truncated: 65535 palette entries needs 786420 bytes, 75 remain"},
      {24, f64(-32), 8, 8, "the module's corner and extent must be finite, the extent in (0, 1000000] metres"},
      {40, std::bit_cast<std::uint32_t>(0.0f), 4, 40, "the explicit scale range must be finite, positive and in order"},
      {rule + 8, f64(1e-3), 8, rule + 8,
       "rule 0 cell 0.001000 m makes 1024064001 candidates; with the module's other objects over the limit of 1048576"},
      {rule + 8, f64(nan), 8, rule + 8, "rule 0 cell is not finite and positive"},
      {rule + 8, f64(-16), 8, rule + 8, "rule 0 cell is not finite and positive"},
      {rule + 24, f64(0), 8, rule + 24, "rule 0 scale range is not finite, positive and in order"},
      {rule + 32, f64(0.5), 8, rule + 24, "rule 0 scale range is not finite, positive and in order"},
      {rule + 4, 0x8000, 2, rule + 4, "rule 0 index 32768 is over 32767"},
      {rule + 6, 2, 1, rule + 6, "rule 0 mode must be 0 or 1 and its reserved bytes 0"},
      {rule + 48, 10, 4, rule + 48, "rule 0 drops 10 of its 9 candidates"},
      {rule + 48, 2, 4, SIZE_MAX, "truncated: rule 0 list needs 8 bytes, 7 remain"},
      {116 + 6, 1, 1, 116 + 6, "explicit object 0 names palette entry 1 of 1"},
  };
  for (const HostileV6& c : cases) {
    auto bytes = good;
    std::byte* p = bytes.data() + section + c.at;
    if (c.width == 1) *p = std::byte(c.value);
    else if (c.width == 2) storeLE<std::uint16_t>(p, std::uint16_t(c.value));
    else if (c.width == 4) storeLE<std::uint32_t>(p, std::uint32_t(c.value));
    else storeLE<std::uint64_t>(p, c.value);
    reseal(bytes);
    gLargestAllocation = 0;
    auto m = decode(bytes, "h.bin");
    ASSERT_FALSE(m.ok()) << c.message;
    EXPECT_LT(gLargestAllocation.load(), std::size_t(1) << 20) << c.message;
    EXPECT_EQ(m.problems().front().message, std::string("module: objects: ") + c.message);
    EXPECT_EQ(m.problems().front().offset, c.offset == SIZE_MAX ? bytes.size() : section + c.offset) << c.message;
  }
}

// ---- an independent generator: the rule of docs/ICONS.md §8 written from
// the text, brute force over every triangle, no library call.

std::uint64_t bruteMix(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
double bruteUnit(std::uint64_t h) { return double(h >> 11) / 9007199254740992.0; }

/// The smallest barycentric coordinate of (x, z) in the triangle (as the
/// rule computes it), or -inf for a degenerate one.
double bruteInside(const Level& l, std::uint32_t k, double x, double z) {
  const Vertex& a = l.vertices[l.indices[k]];
  const Vertex& b = l.vertices[l.indices[k + 1]];
  const Vertex& c = l.vertices[l.indices[k + 2]];
  const double d = (double(b.z) - c.z) * (double(a.x) - c.x) + (double(c.x) - b.x) * (double(a.z) - c.z);
  if (d == 0) return -std::numeric_limits<double>::infinity();
  const double wa = ((double(b.z) - c.z) * (x - c.x) + (double(c.x) - b.x) * (z - c.z)) / d;
  const double wb = ((double(c.z) - a.z) * (x - c.x) + (double(a.x) - c.x) * (z - c.z)) / d;
  return std::min({wa, wb, 1 - wa - wb});
}

std::vector<Object> bruteTrees(const Level& l0, const Scattering& s) {
  std::vector<Object> out;
  for (const ScatterRule& r : s.rules) {
    for (auto j = std::int64_t(std::floor(s.z0 / r.cell)); j <= std::int64_t(std::floor((s.z0 + s.depth) / r.cell)); ++j) {
      for (auto i = std::int64_t(std::floor(s.x0 / r.cell)); i <= std::int64_t(std::floor((s.x0 + s.width) / r.cell)); ++i) {
        const std::uint64_t key = bruteMix(std::uint64_t(i) * 0x100000001b3ull ^ bruteMix(std::uint64_t(j))) ^
                                  bruteMix(r.seed + r.index);
        const double x = (double(i) + bruteUnit(bruteMix(key))) * r.cell - s.x0;
        const double z = (double(j) + bruteUnit(bruteMix(key + 1))) * r.cell - s.z0;
        if (x < 0 || x >= s.width || z < 0 || z >= s.depth) continue;
        double skin = -std::numeric_limits<double>::infinity();
        std::uint16_t material = 0;
        bool covered = false;
        for (const Group& g : l0.groups) {
          if (g.half == Half::skirt) continue;
          for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; k += 3) {
            const double in = bruteInside(l0, k, x, z);
            if (g.priority == kPrioritySkin && in > skin) skin = in, material = g.material;
            if (g.priority > kPrioritySkin && in >= -1e-6) covered = true;  // a decal or a roof
          }
        }
        if (skin < -1e-6 || material != r.classId || covered) continue;
        const std::uint64_t h = bruteMix(r.seed ^ bruteMix(key));
        Object o{r.icon, r.classId, float(x), float(z), std::uint16_t(bruteMix(h) & 0xffff),
                 float(r.scaleMin + (r.scaleMax - r.scaleMin) * bruteUnit(h)), 0, 0, 0};
        o.radius = r.radius * o.scale;
        o.height = r.height * o.scale;
        o.id = 1ull << 63 | std::uint64_t(r.index) << 48 | (std::uint64_t(i) & 0xffffff) << 24 | (std::uint64_t(j) & 0xffffff);
        out.push_back(o);
      }
    }
  }
  std::sort(out.begin(), out.end(), [](const Object& a, const Object& b) { return a.id < b.id; });
  return out;
}

std::vector<Object> byId(std::vector<Object> v) {
  std::sort(v.begin(), v.end(), [](const Object& a, const Object& b) { return a.id < b.id; });
  return v;
}

/// A realistic module (classes 1..4, a road of class 20) at (kx, kz) of a
/// grid of 240 m modules, with a rule for each class.
Module forest(std::uint32_t kx, std::uint32_t kz) {
  Module m = samples::realistic(kx, kz, 8, 3);
  m.scattering = {kx * 240.0, kz * 240.0, 240, 240, {}};
  for (std::uint16_t c = 1; c <= 4; ++c) {
    m.scattering.rules.push_back({std::uint16_t(10 + c), c, std::uint16_t(c * 3), 3.0 + c, 11u * c, 0.7, 1.3, 1, 8});
  }
  plantTrees(m);
  return m;
}

TEST(ModuleV6, treesMatchAnIndependentGeneratorWhateverTheOrderThreadsAndCut) {
  for (const auto& [kx, kz] : {std::pair{0u, 0u}, std::pair{3u, 1u}, std::pair{7u, 5u}}) {
    const Module m = forest(kx, kz);
    const auto brute = bruteTrees(m.levels[0], m.scattering);
    ASSERT_GT(brute.size(), 100u);
    expectSameObjects(byId(m.objects), brute);
    const auto bytes = encode(m);
    // Decoded on four threads at once, each the same trees as the generator.
    std::vector<Module> decoded(4);
    std::vector<std::thread> threads;
    for (Module& d : decoded) {
      threads.emplace_back([&bytes, &d] { d = decode(bytes, "t").value(); });
    }
    for (std::thread& t : threads) t.join();
    for (const Module& d : decoded) {
      expectSameObjects(byId(d.objects), brute);
      expectSameObjects(d.objects, decoded[0].objects);
    }
    // A coarse record (levels 1 and 2 only) keeps the same trees by bitmap,
    // each on its own levels' triangles.
    Module coarse{m.kx, m.kz, {m.levels[1], m.levels[2]}, m.objects, m.scattering};
    auto c = decode(encode(coarse), "coarse");
    ASSERT_TRUE(c.ok()) << c.error();
    expectSameObjects(c->objects, decoded[0].objects);
    for (std::size_t k = 0; k < c->objects.size(); ++k) {
      ASSERT_EQ(c->levels[1].objectY[k], decoded[0].levels[2].objectY[k]) << k;
    }
    // Cut in two halves, every candidate of the module is a candidate of
    // exactly one half, with the same id, scale and heading.
    for (const ScatterRule& r : m.scattering.rules) {
      const CellRange range = cellRange(r, m.scattering);
      for (std::int64_t j = range.j0; j <= range.j1; ++j) {
        for (std::int64_t i = range.i0; i <= range.i1; ++i) {
          const Candidate full = candidate(r, m.scattering, i, j);
          int owners = 0;
          for (int h = 0; h < 2; ++h) {
            Scattering half = m.scattering;
            half.width = 120;
            half.x0 += 120.0 * h;
            const Candidate part = candidate(r, half, i, j);
            if (!part.inside) continue;
            ++owners;
            EXPECT_EQ(part.object.id, full.object.id);
            EXPECT_EQ(part.object.heading, full.object.heading);
            EXPECT_TRUE(sameBits(part.object.scale, full.object.scale));
            EXPECT_NEAR(part.x + half.x0, full.x + m.scattering.x0, 1e-9);
          }
          EXPECT_EQ(owners, full.inside ? 1 : 0);
        }
      }
    }
  }
}

}  // namespace
}  // namespace sandtable::module

namespace sandtable::module {
namespace {

// sortObjects takes a shortcut for the nearly sorted lists decoding makes
// and falls back past a budget of moves; either way its order must be the
// one a plain sort by (icon, z, x, id) gives.
TEST(SortObjects, givesThePlainSortsOrderForNearlySortedReversedAndShuffledLists) {
  const auto plain = [](std::vector<Object> v) {
    std::sort(v.begin(), v.end(), [](const Object& a, const Object& b) {
      return std::tie(a.icon, a.z, a.x, a.id) < std::tie(b.icon, b.z, b.x, b.id);
    });
    return v;
  };
  std::vector<Object> rows;  // cell order: rows of 40 cells, z jittered within a row
  std::uint64_t h = 12345;
  for (std::uint64_t j = 0; j < 40; ++j) {
    for (std::uint64_t i = 0; i < 40; ++i) {
      h = h * 6364136223846793005ull + 1442695040888963407ull;
      Object o;
      o.icon = std::uint16_t(h >> 62);  // four icons, interleaved
      o.z = float(j * 25 + (h >> 40) % 25);
      o.x = float(i * 25 + (h >> 20) % 25);
      o.id = j * 40 + i;
      rows.push_back(o);
    }
  }
  std::vector<Object> reversed = plain(rows);
  std::reverse(reversed.begin(), reversed.end());
  std::vector<Object> oneIcon = rows;
  for (Object& o : oneIcon) o.icon = 7;
  for (const auto& input : {rows, reversed, oneIcon, std::vector<Object>{}, std::vector<Object>(1)}) {
    std::vector<Object> v = input;
    sortObjects(v);
    const std::vector<Object> want = plain(input);
    ASSERT_EQ(v.size(), want.size());
    for (std::size_t k = 0; k < v.size(); ++k) EXPECT_EQ(v[k].id, want[k].id) << k;
  }
}

}  // namespace
}  // namespace sandtable::module
