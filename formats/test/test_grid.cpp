// Grid format v1: golden bytes, round trips, truncation and hostile headers.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/grid.h"

namespace sandtable::grid {
namespace {

namespace fs = std::filesystem;

std::string tempPath(const std::string& name) {
  return (fs::temp_directory_path() / (name + "." + std::to_string(::getpid()))).string();
}

/// A small grid: elevation = 10 i + j, flat normals, material = (i + j) % 3.
std::string writeSmallGrid(const std::string& path, std::uint32_t nx, std::uint32_t nz) {
  auto w = GridWriter::create(path, makeHeader(nx, nz, 30.0, 500000.0, 4000000.0));
  EXPECT_TRUE(w.ok()) << w.error();
  const Header& h = w.value()->header();
  auto b = std::make_unique<BlockData>();
  for (std::uint32_t bz = 0; bz < h.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < h.blocksX; ++bx) {
      for (std::uint32_t k = 0; k < kPostsPerBlock; ++k) {
        const std::uint32_t i = std::min(nx - 1, bx * kBlockPosts + k % kBlockPosts);
        const std::uint32_t j = std::min(nz - 1, bz * kBlockPosts + k / kBlockPosts);
        b->elevation[k] = float(10 * i + j);
        b->normalX[k] = 0;
        b->normalY[k] = toSnorm(1.0f);
        b->normalZ[k] = 0;
        b->material[k] = std::uint8_t((i + j) % 3);
      }
      EXPECT_EQ(w.value()->writeBlock(bx, bz, *b).message(), "");
    }
  }
  EXPECT_EQ(w.value()->finish().message(), "");
  return path;
}

std::vector<std::byte> readAll(const std::string& path) {
  auto v = readSmallFile(path, 1u << 30);
  EXPECT_TRUE(v.ok()) << v.error();
  return v.ok() ? v.value() : std::vector<std::byte>{};
}

void writeAll(const std::string& path, std::span<const std::byte> bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

std::string hex(std::span<const std::byte> b) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (std::byte x : b) {
    s += d[std::to_integer<int>(x) >> 4];
    s += d[std::to_integer<int>(x) & 15];
  }
  return s;
}

TEST(Grid, inlinedSnormRoundsAsToSnorm) {
  // Every value a normal component can take, in steps finer than a snorm step.
  for (int k = -70000; k <= 70000; ++k) {
    const float v = float(k) / 65534.0f + 1e-7f * float(k % 7);
    ASSERT_EQ(toSnormFinite(v), toSnorm(v)) << v;
  }
  EXPECT_EQ(toSnormFinite(2.0f), 32767);
  EXPECT_EQ(toSnormFinite(-2.0f), -32767);
}

TEST(Grid, postNormalIsTheUnitNormalOfAPlaneAndOneSidedAtTheEdges) {
  // A plane rising 0.5 m per metre east and falling 0.25 per metre south,
  // posts 10 m apart: every post, edges included, has the plane's normal.
  const auto at = [](std::uint32_t i, std::uint32_t j) { return float(100.0 + 5.0 * i - 2.5 * j); };
  const double len = std::sqrt(0.25 + 1.0 + 0.0625);
  const PostNormal want{toSnorm(float(-0.5 / len)), toSnorm(float(1.0 / len)), toSnorm(float(0.25 / len))};
  for (const auto& [i, j] : {std::pair{0u, 0u}, std::pair{3u, 2u}, std::pair{7u, 4u}, std::pair{7u, 0u}}) {
    EXPECT_EQ(postNormal(at, i, j, 8, 5, 10.0), want) << i << " " << j;
  }
  // A single post: flat.
  EXPECT_EQ(postNormal(at, 0, 0, 1, 1, 10.0), (PostNormal{0, 32767, 0}));
}

TEST(Grid, layoutConstantsArePinned) {
  EXPECT_EQ(kBlockBytes, 45056u);
  EXPECT_EQ(kNormalXPlane, 16384u);
  EXPECT_EQ(kNormalYPlane, 24576u);
  EXPECT_EQ(kNormalZPlane, 32768u);
  EXPECT_EQ(kMaterialPlane, 40960u);
  EXPECT_EQ(field::headerCrc, 124u);
}

// Golden bytes of version 1. If this fails, the format changed: bump
// kVersion, keep a reader for version 1, and add a new golden test.
TEST(Grid, version1GoldenBytes) {
  const std::string path = writeSmallGrid(tempPath("golden.stg"), 3, 2);
  const auto bytes = readAll(path);
  ASSERT_EQ(bytes.size(), 4096u + 4096u + 45056u);
  // magic, version 1, header 4096, 3 x 2 posts, 64-post blocks, 1 x 1 blocks,
  // flags 0, spacing 30.0, origin (500000, 4000000), min 0.0, max 21.0,
  // table @4096, data @8192, block 45056 bytes, file 53248 bytes, table CRC,
  // zero padding, header CRC.
  EXPECT_EQ(hex(std::span(bytes).first(128)),
            "53414e4447524944010000000010000003000000020000004000000001000000"
            "01000000000000000000000000003e400000000080841e410000000080844e41"
            "000000000000a8410010000000000000002000000000000000b0000000000000"
            "00d00000000000003ee52c4e00000000000000000000000000000000850baa3d");
  EXPECT_EQ(crcHex(crc32(bytes)), "0xe847c078");
  fs::remove(path);
}

TEST(Grid, roundTripsThroughMmap) {
  const std::string path = writeSmallGrid(tempPath("rt.stg"), 130, 70);
  auto g = GridFile::open(path);
  ASSERT_TRUE(g.ok()) << g.error();
  EXPECT_EQ(g.value()->postsX(), 130u);
  EXPECT_EQ(g.value()->header().blocksX, 3u);
  EXPECT_EQ(g.value()->header().blocksZ, 2u);
  EXPECT_FLOAT_EQ(g.value()->elevation(129, 69), 1359.0f);
  EXPECT_FLOAT_EQ(g.value()->elevation(64, 0), 640.0f);
  EXPECT_EQ(g.value()->material(2, 2), 1);
  EXPECT_NEAR(g.value()->normal(5, 5)[1], 1.0f, 1e-6);
  EXPECT_FLOAT_EQ(g.value()->header().maxElevation, 1359.0f);
  EXPECT_TRUE(validateGrid(path).ok());
  fs::remove(path);
}

TEST(Grid, everyTruncatedPrefixFailsWithFileAndOffset) {
  const std::string path = writeSmallGrid(tempPath("trunc.stg"), 3, 2);
  const auto bytes = readAll(path);
  const std::string cut = tempPath("cut.stg");
  // Every prefix through the header fields, then a stride through the rest.
  for (std::size_t n = 0; n < bytes.size(); n += (n < 160 ? 1 : 61)) {
    writeAll(cut, std::span(bytes).first(n));
    auto g = GridFile::open(cut);
    ASSERT_FALSE(g.ok()) << "prefix " << n;
    const Problem& p = g.problems().front();
    EXPECT_EQ(p.file, cut);
    EXPECT_NE(p.message.find("grid"), std::string::npos) << p.message;
    EXPECT_LE(p.offset, n);
    EXPECT_FALSE(validateGrid(cut).ok());
  }
  fs::remove(cut);
  fs::remove(path);
}

struct HostileCase {
  std::size_t offset;
  std::uint64_t value;
  int width;
  const char* expected;
};

TEST(Grid, hostileHeaderFieldsAreRejectedWithoutAllocating) {
  const std::string path = writeSmallGrid(tempPath("hostile.stg"), 3, 2);
  const auto good = readAll(path);
  const HostileCase cases[] = {
      {field::version, 2, 4, "version 2 is not supported"},
      {field::postsX, 0xffffffffu, 4, "out of range"},
      {field::postsZ, 1, 4, "out of range"},
      {field::blockPosts, 32, 4, "block size must be 64"},
      {field::blocksX, 7, 4, "block counts disagree"},
      {field::fileBytes, 1ull << 60, 8, "offsets or sizes disagree"},
      {field::dataOffset, 4096, 8, "offsets or sizes disagree"},
      {field::spacing, 0x7ff8000000000000ull, 8, "not a finite number"},
  };
  const std::string bad = tempPath("bad.stg");
  for (const auto& c : cases) {
    auto bytes = good;
    std::memcpy(bytes.data() + c.offset, &c.value, static_cast<std::size_t>(c.width));
    // Re-seal the header CRC so the field check itself is exercised.
    storeLE<std::uint32_t>(bytes.data() + field::headerCrc, crc32(std::span(bytes).first(field::headerCrc)));
    writeAll(bad, bytes);
    auto g = GridFile::open(bad);
    ASSERT_FALSE(g.ok()) << c.expected;
    EXPECT_NE(g.error().find(c.expected), std::string::npos) << g.error();
  }
  auto bytes = good;
  bytes[0] = std::byte{'X'};
  writeAll(bad, bytes);
  EXPECT_NE(GridFile::open(bad).error().find("bad magic"), std::string::npos);
  bytes = good;
  bytes[field::postsX] ^= std::byte{1};
  writeAll(bad, bytes);
  EXPECT_NE(GridFile::open(bad).error().find("header checksum mismatch"), std::string::npos);
  fs::remove(bad);
  fs::remove(path);
}

TEST(Grid, validateFindsEveryFlippedByteInASmallFile) {
  const std::string path = writeSmallGrid(tempPath("flip.stg"), 3, 2);
  auto bytes = readAll(path);
  const std::string bad = tempPath("flipped.stg");
  for (std::size_t off = 0; off < bytes.size(); off += 13) {
    bytes[off] ^= std::byte{0x5a};
    writeAll(bad, bytes);
    EXPECT_FALSE(validateGrid(bad).ok()) << "flip at " << off << " not caught";
    bytes[off] ^= std::byte{0x5a};
  }
  fs::remove(bad);
  fs::remove(path);
}

TEST(Grid, validateReportsNanAndBadNormals) {
  BlockData b{};
  b.elevation.fill(1.0f);
  b.normalY.fill(toSnorm(1.0f));
  b.elevation[5] = NAN;
  b.normalY[7] = 0;
  auto w = GridWriter::create(tempPath("nan.stg"), makeHeader(64, 64, 1.0, 0, 0));
  ASSERT_TRUE(w.ok());
  ASSERT_EQ(w.value()->writeBlock(0, 0, b).message(), "");
  ASSERT_EQ(w.value()->finish().message(), "");
  const auto problems = validateGrid(tempPath("nan.stg")).problems();
  bool nan = false, normal = false;
  for (const auto& p : problems) {
    nan = nan || p.message.find("NaN") != std::string::npos;
    normal = normal || p.message.find("not a unit upward vector") != std::string::npos;
  }
  EXPECT_TRUE(nan);
  EXPECT_TRUE(normal);
  fs::remove(tempPath("nan.stg"));
}

}  // namespace
}  // namespace sandtable::grid
