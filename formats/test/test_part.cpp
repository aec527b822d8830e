// Build parts v1 (part.h; docs/FORMAT.md §15): golden bytes, a round trip,
// every truncated prefix, flipped bytes, hostile headers and trailers, and
// the writer's refusals, poisoning and temporaries.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/part.h"

namespace sandtable::part {
namespace {

namespace fs = std::filesystem;

/// A fresh, empty directory under the temp directory.
std::string tempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("sandtable-part-" + name + "." + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
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

/// zlib's crc32 called directly: expected CRCs that do not come from the
/// code under test.
std::uint32_t zlibCrc(std::span<const std::byte> b) {
  return static_cast<std::uint32_t>(::crc32(0L, reinterpret_cast<const Bytef*>(b.data()), static_cast<uInt>(b.size())));
}

std::vector<std::byte> bytesOf(std::string_view s) {
  const auto b = std::as_bytes(std::span(s.data(), s.size()));
  return {b.begin(), b.end()};
}

/// Made-up block bytes: byte k is (k * 7 + seed) % 251.
std::vector<std::byte> blockBytes(std::uint32_t seed) {
  std::vector<std::byte> b(grid::kBlockBytes);
  for (std::size_t k = 0; k < b.size(); ++k) b[k] = std::byte((k * 7 + seed) % 251);
  return b;
}

grid::BlockEntry blockEntry(std::span<const std::byte> bytes, float mn, float mx) {
  return {zlibCrc(bytes), mn, mx, 0};
}

/// Made-up records: n bytes, byte k is (k * 13 + seed) % 256.
std::vector<std::byte> recordBytes(std::size_t n, std::uint32_t seed) {
  std::vector<std::byte> b(n);
  for (std::size_t k = 0; k < n; ++k) b[k] = std::byte((k * 13 + seed) % 256);
  return b;
}

struct TestModule {
  pack::Entry entry;
  std::vector<std::byte> coarse, fine;
};

TestModule makeModule(std::uint32_t kx, std::uint32_t kz, std::size_t coarseBytes, std::size_t fineBytes,
                      std::uint32_t seed) {
  TestModule m;
  m.coarse = recordBytes(coarseBytes, seed);
  m.fine = recordBytes(fineBytes, seed + 1);
  m.entry.kx = kx;
  m.entry.kz = kz;
  m.entry.offset = 12345;  // ignored: the part stores 0
  m.entry.compressedBytes = static_cast<std::uint32_t>(coarseBytes);
  m.entry.rawBytes = static_cast<std::uint32_t>(3 * coarseBytes + 1);
  m.entry.compressedCrc = zlibCrc(m.coarse);
  m.entry.rawCrc = 0x10000000u + seed;
  if (fineBytes > 0) {
    m.entry.fine.offset = 999;  // ignored
    m.entry.fine.compressedBytes = static_cast<std::uint32_t>(fineBytes);
    m.entry.fine.rawBytes = static_cast<std::uint32_t>(5 * fineBytes);
    m.entry.fine.compressedCrc = zlibCrc(m.fine);
    m.entry.fine.rawCrc = 0x20000000u + seed;
  }
  return m;
}

/// A part with `h`'s blocks (seeded by their index) and modules (sizes
/// from `sizes`, cycled), and `report`. Returns what was added.
struct Written {
  std::vector<std::vector<std::byte>> blocks;
  std::vector<grid::BlockEntry> entries;
  std::vector<TestModule> modules;
  std::uint32_t crc = 0;
};

Written writePart(const std::string& path, const Header& h, std::string_view report,
                  const std::vector<std::pair<std::size_t, std::size_t>>& sizes) {
  Written out;
  auto w = PartWriter::create(path, h);
  EXPECT_TRUE(w.ok()) << w.error();
  if (!w.ok()) return out;
  for (std::uint64_t k = 0; k < h.blockCount(); ++k) {
    out.blocks.push_back(blockBytes(static_cast<std::uint32_t>(k + 1)));
    out.entries.push_back(blockEntry(out.blocks.back(), -float(k), float(k) + 0.5f));
    EXPECT_EQ(w.value()->addBlock(out.entries.back(), out.blocks.back()).message(), "");
  }
  for (std::uint64_t k = 0; k < h.moduleCount(); ++k) {
    const auto [c, f] = sizes[k % sizes.size()];
    out.modules.push_back(makeModule(static_cast<std::uint32_t>(k % h.modulesX),
                                     static_cast<std::uint32_t>(h.moduleRow0 + k / h.modulesX), c, f,
                                     static_cast<std::uint32_t>(k * 31)));
    const TestModule& m = out.modules.back();
    EXPECT_EQ(w.value()->addModule(m.entry, m.coarse, m.fine).message(), "");
  }
  EXPECT_EQ(w.value()->finish(report).message(), "");
  out.crc = w.value()->crc();
  return out;
}

Header header(std::uint32_t blockRows, std::uint32_t blocksX, std::uint32_t moduleRows, std::uint32_t modulesX) {
  Header h;
  h.planCrc = 0xdeadbeef;
  h.task = 3;
  h.blockRow0 = 4;
  h.blockRows = blockRows;
  h.blocksX = blocksX;
  h.moduleRow0 = 2;
  h.moduleRows = moduleRows;
  h.modulesX = modulesX;
  h.levels = 4;
  return h;
}

/// Opens and verifies; the first problem, or none.
std::optional<Problem> firstProblem(const std::string& path) {
  auto r = PartReader::open(path);
  if (!r.ok()) return r.problems().front();
  const Status v = r.value()->verify();
  if (!v.ok()) return v.problems().front();
  return std::nullopt;
}

/// Reads every block and module, as the merge does; true if all came back.
bool readEverything(PartReader& r) {
  std::vector<std::byte> block(grid::kBlockBytes);
  for (std::uint64_t k = 0; k < r.header().blockCount(); ++k) {
    if (!r.nextBlock(block).ok()) return false;
  }
  for (std::uint64_t k = 0; k < r.header().moduleCount(); ++k) {
    if (!r.nextModule().ok()) return false;
  }
  return true;
}

/// A header and a trailer with nothing between but `middle`: a hostile
/// part with CRCs sealed, so only the size checks can refuse it.
std::vector<std::byte> sealedPart(const std::array<std::byte, kHeaderBytes>& head, std::span<const std::byte> middle,
                                  std::uint64_t reportBytes) {
  std::vector<std::byte> b(head.begin(), head.end());
  b.insert(b.end(), middle.begin(), middle.end());
  std::array<std::byte, 16> t{};
  storeLE<std::uint64_t>(t.data(), reportBytes);
  std::memcpy(t.data() + 8, kEndMagic.data(), 8);
  b.insert(b.end(), t.begin(), t.end());
  const std::uint32_t crc = zlibCrc(b);
  b.resize(b.size() + 4);
  storeLE<std::uint32_t>(b.data() + b.size() - 4, crc);
  return b;
}

/// The header bytes of `h` with field `off` set to `v` and the CRC resealed.
std::array<std::byte, kHeaderBytes> withField(const Header& h, std::size_t off, std::uint32_t v) {
  auto b = encodeHeader(h);
  storeLE<std::uint32_t>(b.data() + off, v);
  storeLE<std::uint32_t>(b.data() + field::headerCrc, zlibCrc(std::span(b).first(field::headerCrc)));
  return b;
}

TEST(Part, layoutConstantsArePinned) {
  EXPECT_EQ(kHeaderBytes, 64u);
  EXPECT_EQ(kTrailerBytes, 20u);
  EXPECT_EQ(kBlockEntryBytes, 16u);
  EXPECT_EQ(kModuleEntryBytes, 64u);
  EXPECT_EQ(field::levels, 48u);
  EXPECT_EQ(field::reserved, 52u);
  EXPECT_EQ(field::headerCrc, 60u);
}

// Golden bytes of version 1, worked out by hand from docs/FORMAT.md §15. If
// this fails, the format changed: bump kVersion and add a new golden test.
TEST(Part, version1GoldenBytes) {
  Header h;
  h.planCrc = 0x11223344;
  h.task = 7;
  h.blockRow0 = 2;
  h.blockRows = 1;
  h.blocksX = 1;
  h.moduleRow0 = 3;
  h.moduleRows = 1;
  h.modulesX = 1;
  h.levels = 4;
  // magic, version 1, header 64 bytes, plan CRC, task 7, block rows 2 + 1 of
  // 1 block, module rows 3 + 1 of 1 module, 4 levels, 8 reserved zero bytes.
  const std::string fields =
      "53414e4450415254" "01000000" "40000000" "44332211" "07000000" "02000000" "01000000"
      "01000000" "03000000" "01000000" "01000000" "04000000" "0000000000000000";
  const auto head = encodeHeader(h);
  EXPECT_EQ(hex(std::span(head).first(60)), fields);
  // The header CRC, from zlib over the first 60 bytes: 0x656d7557.
  EXPECT_EQ(loadLE<std::uint32_t>(head.data() + 60), zlibCrc(std::span(head).first(60)));
  EXPECT_EQ(hex(std::span(head).subspan(60)), "57756d65");
  auto back = decodeHeader(head, "golden");
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back.value().planCrc, 0x11223344u);
  EXPECT_EQ(back.value().moduleRow0, 3u);
  EXPECT_EQ(back.value().levels, 4u);

  // The whole file: one block (byte k = (k*7+1) % 251, min -1.5, max 2.25),
  // one module ("coarse!" and "fine" records), report "{}".
  const std::string dir = tempDir("golden");
  const std::string path = dir + "/task.part";
  const auto block = blockBytes(1);
  const grid::BlockEntry be = blockEntry(block, -1.5f, 2.25f);
  TestModule m;
  m.coarse = bytesOf("coarse!");
  m.fine = bytesOf("fine");
  m.entry = {77, 7, 100, zlibCrc(m.coarse), 0xaabbccdd, 0, 3, {88, 4, 50, zlibCrc(m.fine), 0x01020304}};
  {
    auto w = PartWriter::create(path, h);
    ASSERT_TRUE(w.ok()) << w.error();
    ASSERT_EQ(w.value()->addBlock(be, block).message(), "");
    ASSERT_EQ(w.value()->addModule(m.entry, m.coarse, m.fine).message(), "");
    ASSERT_EQ(w.value()->finish("{}").message(), "");
    EXPECT_EQ(crcHex(w.value()->crc()), "0xd412dfbd");
  }
  const auto bytes = readAll(path);
  ASSERT_EQ(bytes.size(), 64u + 16 + 45056 + 64 + 7 + 4 + 2 + 20);
  EXPECT_EQ(hex(std::span(bytes).first(64)), hex(head));
  // Block entry: CRC of the block's bytes, -1.5f, 2.25f, 0.
  EXPECT_EQ(hex(std::span(bytes).subspan(64, 16)), "3c3ed20d" "0000c0bf" "00001040" "00000000");
  EXPECT_EQ(loadLE<std::uint32_t>(bytes.data() + 64), zlibCrc(block));
  EXPECT_TRUE(std::equal(block.begin(), block.end(), bytes.begin() + 80));
  // Module entry (pack v2 layout): offset 0, 7 coarse bytes, raw 100, CRC,
  // raw CRC, fine offset 0, 4 fine bytes, raw 50, CRC, raw CRC, kx 0, kz 3,
  // 8 reserved zero bytes; then the records and the report.
  const std::size_t me = 64 + 16 + 45056;
  EXPECT_EQ(hex(std::span(bytes).subspan(me, 64)),
            "0000000000000000" "07000000" "64000000" "d65ba0b9" "ddccbbaa"
            "0000000000000000" "04000000" "32000000" "9254a9be" "04030201"
            "00000000" "03000000" "0000000000000000");
  EXPECT_EQ(hex(std::span(bytes).subspan(me + 64, 13)), hex(bytesOf("coarse!fine{}")));
  // Trailer: reportBytes 2, "SANDPEND", CRC-32 (zlib) of every byte before it.
  const auto trailer = std::span(bytes).last(20);
  EXPECT_EQ(hex(trailer.first(16)), "0200000000000000" "53414e4450454e44");
  EXPECT_EQ(loadLE<std::uint32_t>(trailer.data() + 16), zlibCrc(std::span(bytes).first(bytes.size() - 4)));
  EXPECT_EQ(hex(trailer.subspan(16)), "bddf12d4");
  // Any bytes followed by their own CRC: zlib's residue.
  EXPECT_EQ(crcHex(zlibCrc(bytes)), "0x2144df1c");

  auto r = PartReader::open(path);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value()->report(), "{}");
  EXPECT_EQ(r.value()->storedCrc(), 0xd412dfbdu);
  EXPECT_EQ(r.value()->verify().message(), "");
  fs::remove_all(dir);
}

TEST(Part, roundTrip) {
  const std::string dir = tempDir("rt");
  const std::string path = dir + "/task.part";
  const Header h = header(1, 2, 1, 3);
  const std::string report = R"({"task":3,"modules":3})";
  // A fine record on the first and the last, none on the middle one.
  const Written w = writePart(path, h, report, {{100, 50}, {70, 0}, {1, 300}});
  ASSERT_EQ(w.modules.size(), 3u);
  EXPECT_FALSE(fs::exists(path + ".tmp." + std::to_string(::getpid())));
  const auto bytes = readAll(path);
  EXPECT_EQ(w.crc, zlibCrc(std::span(bytes).first(bytes.size() - 4)));

  auto opened = PartReader::open(path);
  ASSERT_TRUE(opened.ok()) << opened.error();
  PartReader& r = *opened.value();
  EXPECT_EQ(r.path(), path);
  EXPECT_EQ(r.fileBytes(), bytes.size());
  EXPECT_EQ(r.storedCrc(), w.crc);
  EXPECT_EQ(r.report(), report);
  EXPECT_EQ(r.header().planCrc, 0xdeadbeefu);
  EXPECT_EQ(r.header().task, 3u);
  EXPECT_EQ(r.header().blockRow0, 4u);
  EXPECT_EQ(r.header().blockCount(), 2u);
  EXPECT_EQ(r.header().moduleCount(), 3u);
  EXPECT_EQ(r.verify().message(), "");

  // Modules only after every block.
  auto early = r.nextModule();
  ASSERT_FALSE(early.ok());
  EXPECT_NE(early.problems().front().message.find("before every block was read (0 of 2)"), std::string::npos);
  std::vector<std::byte> block(grid::kBlockBytes);
  for (std::size_t k = 0; k < 2; ++k) {
    auto e = r.nextBlock(block);
    ASSERT_TRUE(e.ok()) << e.error();
    EXPECT_EQ(e.value().crc, w.entries[k].crc);
    EXPECT_EQ(e.value().minElevation, w.entries[k].minElevation);
    EXPECT_EQ(e.value().maxElevation, w.entries[k].maxElevation);
    EXPECT_EQ(block, w.blocks[k]);
  }
  EXPECT_FALSE(r.nextBlock(block).ok());
  for (std::size_t k = 0; k < 3; ++k) {
    auto m = r.nextModule();
    ASSERT_TRUE(m.ok()) << m.error();
    const pack::Entry& want = w.modules[k].entry;
    const pack::Entry& got = m.value().entry;
    EXPECT_EQ(got.offset, 0u);
    EXPECT_EQ(got.fine.offset, 0u);
    EXPECT_EQ(got.kx, k);
    EXPECT_EQ(got.kz, 2u);
    EXPECT_EQ(got.compressedBytes, want.compressedBytes);
    EXPECT_EQ(got.rawBytes, want.rawBytes);
    EXPECT_EQ(got.compressedCrc, want.compressedCrc);
    EXPECT_EQ(got.rawCrc, want.rawCrc);
    EXPECT_EQ(got.fine.compressedBytes, want.fine.compressedBytes);
    EXPECT_EQ(got.fine.rawBytes, want.fine.rawBytes);
    EXPECT_EQ(got.fine.compressedCrc, want.fine.compressedCrc);
    EXPECT_EQ(got.fine.rawCrc, want.fine.rawCrc);
    EXPECT_EQ(m.value().coarse, w.modules[k].coarse);
    EXPECT_EQ(m.value().fine, w.modules[k].fine);
  }
  auto past = r.nextModule();
  ASSERT_FALSE(past.ok());
  EXPECT_EQ(past.problems().front().file, path);
  EXPECT_NE(past.problems().front().message.find("after the last of the 3 modules"), std::string::npos);
  fs::remove_all(dir);
}

TEST(Part, emptyPartRoundTrips) {
  const std::string dir = tempDir("empty");
  const std::string path = dir + "/task.part";
  writePart(path, header(0, 7, 0, 5), "", {{1, 0}});
  auto r = PartReader::open(path);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value()->fileBytes(), 84u);
  EXPECT_EQ(r.value()->report(), "");
  EXPECT_EQ(r.value()->verify().message(), "");
  EXPECT_FALSE(r.value()->nextModule().ok());
  fs::remove_all(dir);
}

TEST(Part, everyTruncatedPrefixIsRefused) {
  const std::string dir = tempDir("trunc");
  const std::string path = dir + "/task.part";
  writePart(path, header(0, 5, 2, 2), R"({"a":1})", {{9, 4}, {5, 0}, {3, 11}});
  const auto bytes = readAll(path);
  ASSERT_GT(bytes.size(), 84u + 4 * 64);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    writeAll(path, std::span(bytes).first(n));
    const auto p = firstProblem(path);
    ASSERT_TRUE(p.has_value()) << "prefix " << n;
    EXPECT_EQ(p->file, path) << "prefix " << n;
    EXPECT_LE(p->offset, bytes.size()) << "prefix " << n;
    EXPECT_EQ(p->message.rfind("part: ", 0), 0u) << p->message;
    if (n < 84) {
      EXPECT_NE(p->message.find("truncated"), std::string::npos) << "prefix " << n << ": " << p->message;
    }
    // The records must never be handed out from a torn part either.
    if (auto r = PartReader::open(path); r.ok()) {
      EXPECT_FALSE(readEverything(*r.value())) << "prefix " << n;
    }
  }
  writeAll(path, bytes);
  EXPECT_FALSE(firstProblem(path).has_value());
  fs::remove_all(dir);
}

TEST(Part, flippedBytesAreRefused) {
  const std::string dir = tempDir("flips");
  const std::string path = dir + "/task.part";
  writePart(path, header(1, 1, 1, 3), R"({"flips":true})", {{40, 20}, {30, 0}, {8, 16}});
  auto bytes = readAll(path);
  // Every header, entry, record, report and trailer byte, and a sample of
  // the block's bytes.
  std::set<std::size_t> offsets;
  const std::size_t modulesAt = 64 + 16 + grid::kBlockBytes;
  for (std::size_t k = 0; k < 80; ++k) offsets.insert(k);
  for (std::size_t k = modulesAt; k < bytes.size(); ++k) offsets.insert(k);
  std::uint64_t seed = 12345;
  while (offsets.size() < 600) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    offsets.insert(80 + (seed >> 33) % grid::kBlockBytes);
  }
  for (const std::size_t off : offsets) {
    const auto mask = static_cast<std::byte>(1u << (off % 8));
    bytes[off] ^= mask;
    writeAll(path, bytes);
    const auto p = firstProblem(path);
    ASSERT_TRUE(p.has_value()) << "flip at " << off << " not caught";
    EXPECT_EQ(p->file, path);
    EXPECT_EQ(p->message.rfind("part: ", 0), 0u) << p->message;
    if (auto r = PartReader::open(path); r.ok()) (void)readEverything(*r.value());  // never crashes
    bytes[off] ^= mask;
  }
  writeAll(path, bytes);
  EXPECT_FALSE(firstProblem(path).has_value());
  fs::remove_all(dir);
}

TEST(Part, verifyNamesTheChecksumMismatch) {
  const std::string dir = tempDir("crc");
  const std::string path = dir + "/task.part";
  writePart(path, header(0, 0, 1, 2), "{}", {{10, 10}});
  auto bytes = readAll(path);
  bytes[64 + 64 + 3] ^= std::byte{1};  // a coarse record byte
  writeAll(path, bytes);
  auto r = PartReader::open(path);
  ASSERT_TRUE(r.ok()) << r.error();
  const Status v = r.value()->verify();
  ASSERT_FALSE(v.ok());
  EXPECT_EQ(v.problems().front().file, path);
  EXPECT_EQ(v.problems().front().offset, bytes.size() - 4);
  EXPECT_NE(v.problems().front().message.find("part: checksum mismatch (stored 0x"), std::string::npos)
      << v.error();
  // The record's own CRC catches it too, at the record.
  auto m = r.value()->nextModule();
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.problems().front().offset, 64u + 64);
  EXPECT_NE(m.error().find("module 0 (0,2)'s coarse record does not match its CRC"), std::string::npos) << m.error();
  fs::remove_all(dir);
}

TEST(Part, blockCrcIsCheckedWhenRead) {
  const std::string dir = tempDir("blockcrc");
  const std::string path = dir + "/task.part";
  writePart(path, header(1, 2, 0, 0), "{}", {{1, 0}});
  auto bytes = readAll(path);
  const std::size_t second = 64 + 16 + grid::kBlockBytes + 16;
  bytes[second + 100] ^= std::byte{0x40};
  // Reseal the file CRC, so only the block's own CRC can tell.
  storeLE<std::uint32_t>(bytes.data() + bytes.size() - 4, zlibCrc(std::span(bytes).first(bytes.size() - 4)));
  writeAll(path, bytes);
  auto r = PartReader::open(path);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value()->verify().message(), "");
  std::vector<std::byte> block(grid::kBlockBytes);
  ASSERT_TRUE(r.value()->nextBlock(block).ok());
  auto e = r.value()->nextBlock(block);
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.problems().front().file, path);
  EXPECT_EQ(e.problems().front().offset, second);
  EXPECT_NE(e.error().find("part: block 1 (1,4)'s bytes do not match its CRC"), std::string::npos) << e.error();
  fs::remove_all(dir);
}

TEST(Part, structuralFaultsWithSealedCrcs) {
  const std::string dir = tempDir("structure");
  const std::string path = dir + "/task.part";
  writePart(path, header(0, 0, 1, 1), "{}", {{10, 6}});
  const auto good = readAll(path);
  auto sealedWith = [&](std::size_t off, std::uint32_t v) {
    auto b = good;
    storeLE<std::uint32_t>(b.data() + off, v);
    storeLE<std::uint32_t>(b.data() + b.size() - 4, zlibCrc(std::span(b).first(b.size() - 4)));
    writeAll(path, b);
  };
  const std::size_t e0 = 64;  // module 0's entry
  struct Case {
    std::size_t off;
    std::uint32_t value;
    std::size_t wantOffset;
    const char* message;
  };
  const Case cases[] = {
      {e0 + 8, 11, e0 + 8, "module 0 (0,2)'s records (bytes 128..145) run past the report at byte 144"},
      {e0 + 8, 9, 64 + 64 + 9 + 6, "the modules end at byte 143, but the report starts at byte 144"},
      {e0 + 8, kMaxRecordBytes + 1, e0 + 8, "are over the cap of 268435456 bytes"},
      {e0 + 32, kMaxRecordBytes + 1, e0 + 32, "are over the cap of 268435456 bytes"},
      {e0 + 48, 1, e0 + 48, "module 0 (0,2)'s entry names module (1,2): the modules are out of order"},
      {e0 + 0, 64, e0 + 0, "has a record offset that is not 0"},
      {e0 + 24, 64, e0 + 24, "has a fine record offset that is not 0"},
      {e0 + 60, 1, e0 + 56, "reserved bytes 56..63 that are not zero"},
  };
  for (const Case& c : cases) {
    sealedWith(c.off, c.value);
    auto r = PartReader::open(path);
    ASSERT_TRUE(r.ok()) << r.error();
    const Status v = r.value()->verify();
    ASSERT_FALSE(v.ok()) << c.message;
    const Problem& p = v.problems().front();
    EXPECT_EQ(p.file, path);
    EXPECT_EQ(p.offset, c.wantOffset) << c.message << ": " << p.message;
    EXPECT_NE(p.message.find(c.message), std::string::npos) << p.message;
    auto m = r.value()->nextModule();
    ASSERT_FALSE(m.ok()) << c.message;
    EXPECT_EQ(m.problems().front().offset, c.wantOffset) << m.error();
  }
  fs::remove_all(dir);
}

TEST(Part, hostileHeadersAreRefusedBeforeAllocation) {
  const std::string dir = tempDir("hostile");
  const std::string path = dir + "/task.part";
  const Header h = header(0, 0, 1, 0);  // one module row of no modules
  struct Case {
    std::size_t off;
    std::uint32_t value;
    std::uint64_t wantOffset;  ///< ~0: the file's size
    const char* message;
  };
  const std::uint64_t kSize = ~std::uint64_t(0);
  // One field changed at a time, the header CRC resealed.
  const Case cases[] = {
      {field::version, 2, field::version, "version 2 is not supported"},
      {field::headerBytes, 128, field::headerBytes, "header size must be 64"},
      {field::reserved + 3, 1, field::reserved + 3, "header reserved bytes 52..59 are not zero"},
      {field::blocksX, kMaxPerAxis + 1, field::blocksX, "blocksX 4194305 is out of range"},
      {field::modulesX, 0xffffffffu, field::modulesX, "modulesX 4294967295 is out of range"},
      {field::blockRows, 0xffffffffu, field::blockRows, "block rows 4 + 4294967295 end past row 4194304"},
      {field::moduleRows, kMaxPerAxis, field::moduleRows, "module rows 2 + 4194304 end past row 4194304"},
      {field::levels, 0, field::levels, "level count 0 is out of range (1 to 16)"},
      {field::levels, 17, field::levels, "level count 17 is out of range (1 to 16)"},
      // Counts within their caps, but more than the file holds.
      {field::modulesX, 1000, kSize, "truncated: the header's 0 blocks and 1000 modules"},
  };
  for (const Case& c : cases) {
    const auto b = sealedPart(withField(h, c.off, c.value), {}, 0);
    writeAll(path, b);
    auto r = PartReader::open(path);
    ASSERT_FALSE(r.ok()) << c.message;
    const Problem& p = r.problems().front();
    EXPECT_EQ(p.file, path);
    EXPECT_EQ(p.offset, c.wantOffset == kSize ? b.size() : c.wantOffset) << p.message;
    EXPECT_NE(p.message.find(c.message), std::string::npos) << p.message;
  }
  // Block rows x blocksX and module rows x modulesX of 2^22 x 2^22 (2^44
  // each): refused from the sizes alone, nothing allocated.
  {
    Header big = h;
    big.blockRow0 = 0;
    big.blockRows = kMaxPerAxis;
    big.blocksX = kMaxPerAxis;
    big.moduleRow0 = 0;
    big.moduleRows = kMaxPerAxis;
    big.modulesX = kMaxPerAxis;
    const auto b = sealedPart(encodeHeader(big), {}, 0);
    writeAll(path, b);
    auto r = PartReader::open(path);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.problems().front().offset, b.size());
    EXPECT_NE(r.error().find("17592186044416 blocks and 17592186044416 modules"), std::string::npos) << r.error();
  }
  // Modules alone: 2^22 x 1 needs 256 MiB of entries.
  {
    Header many = h;
    many.moduleRow0 = 0;
    many.moduleRows = kMaxPerAxis;
    many.modulesX = 1;
    const auto b = sealedPart(encodeHeader(many), std::vector<std::byte>(4096), 0);
    writeAll(path, b);
    auto r = PartReader::open(path);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().find("4194304 modules"), std::string::npos) << r.error();
  }
  fs::remove_all(dir);
}

TEST(Part, hostileTrailersAreRefused) {
  const std::string dir = tempDir("trailer");
  const std::string path = dir + "/task.part";
  const auto head = encodeHeader(header(0, 0, 0, 0));
  const std::vector<std::byte> report(100, std::byte{'x'});
  // Report sizes: huge, just over the cap, one more than the file holds.
  for (const std::uint64_t n : {~std::uint64_t(0), std::uint64_t(1) << 63, kMaxReportBytes + 1, std::uint64_t(101)}) {
    const auto b = sealedPart(head, report, n);
    writeAll(path, b);
    auto r = PartReader::open(path);
    ASSERT_FALSE(r.ok()) << n;
    EXPECT_EQ(r.problems().front().file, path);
    EXPECT_EQ(r.problems().front().offset, b.size() - 20) << r.error();
    EXPECT_NE(r.error().find("the report size " + std::to_string(n)), std::string::npos) << r.error();
  }
  // Less than the file holds: the bytes before the report are then
  // modules that the header does not have.
  {
    const auto b = sealedPart(head, report, 99);
    writeAll(path, b);
    auto r = PartReader::open(path);
    ASSERT_TRUE(r.ok()) << r.error();
    EXPECT_EQ(r.value()->report().size(), 99u);
    const Status v = r.value()->verify();
    ASSERT_FALSE(v.ok());
    EXPECT_EQ(v.problems().front().offset, 64u);
    EXPECT_NE(v.error().find("the modules end at byte 64, but the report starts at byte 65"), std::string::npos)
        << v.error();
  }
  // A wrong end magic.
  {
    auto b = sealedPart(head, report, 100);
    b[b.size() - 10] = std::byte{'X'};
    writeAll(path, b);
    auto r = PartReader::open(path);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.problems().front().offset, b.size() - 12);
    EXPECT_NE(r.error().find("bad end magic"), std::string::npos) << r.error();
  }
  // Not a part at all, and no file.
  {
    std::vector<std::byte> b(200, std::byte{0});
    writeAll(path, b);
    auto r = PartReader::open(path);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.problems().front().offset, 0u);
    EXPECT_NE(r.error().find("bad magic: not a sandtable build part"), std::string::npos) << r.error();
    auto none = PartReader::open(dir + "/missing.part");
    ASSERT_FALSE(none.ok());
    EXPECT_EQ(none.problems().front().file, dir + "/missing.part");
    EXPECT_NE(none.error().find("part: cannot open"), std::string::npos);
    EXPECT_FALSE(PartReader::open(dir).ok());  // a directory
  }
  fs::remove_all(dir);
}

TEST(Part, finishWithAMissingModuleFails) {
  const std::string dir = tempDir("missing");
  const std::string path = dir + "/task.part";
  const Header h = header(0, 0, 2, 2);
  {
    auto w = PartWriter::create(path, h);
    ASSERT_TRUE(w.ok()) << w.error();
    for (std::uint32_t k = 0; k < 3; ++k) {
      const TestModule m = makeModule(k % 2, 2 + k / 2, 5, 0, k);
      ASSERT_EQ(w.value()->addModule(m.entry, m.coarse, m.fine).message(), "");
    }
    const Status s = w.value()->finish("{}");
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.problems().front().file, path);
    EXPECT_EQ(s.message(), "part writer: finish() before every module was added: 3 of 4 modules added");
    EXPECT_FALSE(fs::exists(path));
    EXPECT_TRUE(fs::exists(path + ".tmp." + std::to_string(::getpid())));
  }
  // The destroyed writer left nothing behind.
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

TEST(Part, writerRefusesCallerMistakes) {
  const std::string dir = tempDir("mistakes");
  const std::string path = dir + "/task.part";
  {
    auto bad = PartWriter::create(path, header(1, 1, 1, 1) /* levels 4 */);
    ASSERT_TRUE(bad.ok());
    Header h = header(1, 1, 1, 1);
    h.levels = 0;
    auto refused = PartWriter::create(dir + "/other.part", h);
    ASSERT_FALSE(refused.ok());
    EXPECT_NE(refused.error().find("part writer: header: level count 0"), std::string::npos) << refused.error();
  }
  auto w = PartWriter::create(path, header(1, 2, 1, 2));
  ASSERT_TRUE(w.ok()) << w.error();
  PartWriter& pw = *w.value();
  auto block = blockBytes(3);
  const TestModule m = makeModule(0, 2, 5, 5, 1);
  auto expectRefusal = [&](const Status& s, const std::string& want) {
    ASSERT_FALSE(s.ok()) << want;
    EXPECT_EQ(s.problems().front().file, path);
    EXPECT_NE(s.message().find(want), std::string::npos) << s.message();
    EXPECT_EQ(s.message().rfind("part writer: ", 0), 0u);
  };
  expectRefusal(pw.addModule(m.entry, m.coarse, m.fine), "addModule() before every block was added (0 of 2)");
  expectRefusal(pw.addBlock(blockEntry(block, 0, 1), std::span(block).first(100)), "has 100 bytes, not 45056");
  grid::BlockEntry wrong = blockEntry(block, 0, 1);
  wrong.crc ^= 1;
  expectRefusal(pw.addBlock(wrong, block), "block 0 (0,4)'s bytes do not match its entry's CRC");
  grid::BlockEntry reserved = blockEntry(block, 0, 1);
  reserved.reserved = 7;
  expectRefusal(pw.addBlock(reserved, block), "reserved field");
  ASSERT_EQ(pw.addBlock(blockEntry(block, 0, 1), block).message(), "");
  ASSERT_EQ(pw.addBlock(blockEntry(block, 0, 1), block).message(), "");
  expectRefusal(pw.addBlock(blockEntry(block, 0, 1), block), "all 2 blocks were already added");
  // Modules: order, sizes, CRCs.
  const TestModule second = makeModule(1, 2, 5, 0, 2);
  expectRefusal(pw.addModule(second.entry, second.coarse, second.fine), "module 0 (0,2) was expected");
  expectRefusal(pw.addModule(m.entry, std::span(m.coarse).first(4), m.fine), "records are 4 and 5 bytes");
  expectRefusal(pw.addModule(m.entry, m.coarse, {}), "records are 5 and 0 bytes");
  pack::Entry badCrc = m.entry;
  badCrc.fine.compressedCrc ^= 1;
  expectRefusal(pw.addModule(badCrc, m.coarse, m.fine), "fine record does not match its entry's CRC");
  expectRefusal(pw.finish("{}"), "0 of 2 modules added");
  ASSERT_EQ(pw.addModule(m.entry, m.coarse, m.fine).message(), "");
  ASSERT_EQ(pw.addModule(second.entry, second.coarse, second.fine).message(), "");
  expectRefusal(pw.addModule(second.entry, second.coarse, second.fine), "all 2 modules were already added");
  ASSERT_EQ(pw.finish("{}").message(), "");
  expectRefusal(pw.finish("{}"), "finish() was already called");
  expectRefusal(pw.addBlock(blockEntry(block, 0, 1), block), "addBlock() after finish()");
  EXPECT_FALSE(firstProblem(path).has_value());
  w.value().reset();
  EXPECT_TRUE(fs::exists(path));  // a finished part stays
  fs::remove_all(dir);
}

TEST(Part, aFailedWritePoisonsTheWriter) {
  const std::string dir = tempDir("poison");
  const std::string path = dir + "/task.part";
  auto w = PartWriter::create(path, header(1, 1, 1, 1));
  ASSERT_TRUE(w.ok()) << w.error();
  // A file size limit below one block: the block's write fails with EFBIG
  // (SIGXFSZ ignored for the while).
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  auto* const oldHandler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit small = old;
  small.rlim_cur = 4096;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  const auto block = blockBytes(1);
  const Status s = w.value()->addBlock(blockEntry(block, 0, 1), block);
  ::setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, oldHandler);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.problems().front().file, path);
  EXPECT_NE(s.message().find("part writer: cannot write " + path + ".tmp."), std::string::npos) << s.message();
  // Every later call repeats it, even ones that would now succeed.
  EXPECT_EQ(w.value()->addBlock(blockEntry(block, 0, 1), block).message(), s.message());
  const TestModule m = makeModule(0, 2, 5, 0, 1);
  EXPECT_EQ(w.value()->addModule(m.entry, m.coarse, m.fine).message(), s.message());
  EXPECT_EQ(w.value()->finish("{}").message(), s.message());
  w.value().reset();
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::part
