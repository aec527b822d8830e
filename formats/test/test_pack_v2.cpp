// Pack files v2 (a coarse and a fine record per module): golden bytes,
// round trips of both parts with their level numbers, the record order
// against an independent Morton order, determinism, every truncated
// prefix, random flips, and a table of hostile entry and header fields
// each with its message. (Version 1 stays covered by test_pack.cpp.)
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "module_samples.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/pack.h"

namespace sandtable::pack {
namespace {

namespace fs = std::filesystem;
using module::Module;

std::string tempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("sandtable-pack2-" + name + "." + std::to_string(::getpid()));
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

std::vector<std::byte> fromHex(const std::string& h) {
  std::vector<std::byte> b;
  for (std::size_t k = 0; k + 1 < h.size(); k += 2) b.push_back(static_cast<std::byte>(std::stoi(h.substr(k, 2), nullptr, 16)));
  return b;
}

/// zlib's crc32 directly: expected CRCs not from the code under test.
std::uint32_t zlibCrc(std::span<const std::byte> b) {
  return static_cast<std::uint32_t>(::crc32(0L, reinterpret_cast<const Bytef*>(b.data()), static_cast<uInt>(b.size())));
}

std::string leHex(std::uint32_t v) {
  std::vector<std::byte> b(4);
  storeLE(b.data(), v);
  return hex(b);
}

IndexHeader header(std::uint32_t mx, std::uint32_t mz, std::uint32_t levels = 3, std::uint32_t squares = 8) {
  IndexHeader h;
  h.modulesX = mx;
  h.modulesZ = mz;
  h.levels = levels;
  h.moduleSquares = squares;
  h.moduleSize = 30.0 * squares;
  return h;
}

Module sample(std::uint32_t kx, std::uint32_t kz, const IndexHeader& h) {
  return module::samples::realistic(kx, kz, h.moduleSquares, h.levels);
}

/// A module holding levels [from, to) of m (what a v2 record encodes).
Module partOf(const Module& m, std::size_t from, std::size_t to) {
  return {m.kx, m.kz, std::vector<module::Level>(m.levels.begin() + std::ptrdiff_t(from), m.levels.begin() + std::ptrdiff_t(to)), m.objects};
}

void writePack(const std::string& dir, const IndexHeader& h, const PackLayout& layout, bool reverse = false) {
  auto w = PackWriter::create(dir, h, 3, layout);
  ASSERT_TRUE(w.ok()) << w.error();
  const std::uint32_t n = h.modulesX * h.modulesZ;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t k = reverse ? n - 1 - i : i;
    ASSERT_EQ(w.value()->add(sample(k % h.modulesX, k / h.modulesX, h)).message(), "");
  }
  ASSERT_EQ(w.value()->finish().message(), "");
}

std::vector<std::string> messages(const std::vector<Problem>& ps) {
  std::vector<std::string> out;
  for (const Problem& p : ps) out.push_back(p.str());
  return out;
}

bool hasMessage(const std::vector<Problem>& ps, const std::string& part) {
  return std::any_of(ps.begin(), ps.end(), [&](const Problem& p) { return p.message.find(part) != std::string::npos; });
}

std::size_t entryAt(std::uint32_t kx, std::uint32_t kz, std::uint32_t mx) {
  return kIndexHeaderBytes + kEntryBytesV2 * (std::size_t(kz) * mx + kx);
}

void resealIndex(std::vector<std::byte>& idx) {
  const std::uint64_t count = loadLE<std::uint64_t>(idx.data() + indexField::entryCount);
  storeLE<std::uint32_t>(idx.data() + indexField::tableCrc,
                         crc32(std::span(idx).subspan(kIndexHeaderBytes, kEntryBytesV2 * count)));
  storeLE<std::uint32_t>(idx.data() + indexField::headerCrc, crc32(std::span(idx).first(indexField::headerCrc)));
}

TEST(PackV2, layoutConstantsArePinned) {
  EXPECT_EQ(kVersion, 2u);
  EXPECT_EQ(kEntryBytesV2, 64u);
  EXPECT_EQ(entryBytesOf(1), 32u);
  EXPECT_EQ(entryBytesOf(2), 64u);
  EXPECT_EQ(indexField::coarseLevel, 76u);
  EXPECT_EQ(indexField::order, 80u);
  EXPECT_EQ(indexField::reservedV2, 84u);
  EXPECT_EQ(entryFieldV2::fineOffset, 24u);
  EXPECT_EQ(entryFieldV2::fineRawCrc, 44u);
  EXPECT_EQ(entryFieldV2::kx, 48u);
  EXPECT_EQ(entryFieldV2::kz, 52u);
  EXPECT_EQ(entryFieldV2::reserved, 56u);
  // The documented default split: levels 2 and 3 of 4 are coarse.
  EXPECT_EQ(PackLayout::split(4).coarseLevel, 2u);
  EXPECT_EQ(PackLayout::split(4).order, PackOrder::morton);
  EXPECT_EQ(PackLayout::split(1).coarseLevel, 0u);
}

// Golden bytes of version 2, written out by hand (FORMAT.md 10.1, 10.2).
// If this fails, the v2 format changed.
TEST(PackV2, version2GoldenBytes) {
  const std::string packFields = "53414e445041434b"
                                 "02000000"
                                 "40000000"
                                 "00000000"
                                 "01000000"
                                 "000000000000000000000000000000000000000000000000000000000000000000000000";
  const std::vector<std::byte> packHeader = fromHex(packFields + leHex(zlibCrc(fromHex(packFields))));
  ASSERT_EQ(packHeader.size(), kPackHeaderBytes);
  EXPECT_EQ(hex(encodePackHeader(kVersion2)), hex(packHeader));
  EXPECT_EQ(zlibCrc(packHeader), 0x2144df1cu);  // the residue (FORMAT.md 10.2)

  IndexHeader h = header(3, 2, 4, 32);
  h.version = kVersion2;
  h.moduleSize = 960;
  h.packBytes = 123456;
  h.packHeaderCrc = 0x2144df1c;
  h.tableCrc = 0xa0b0c0d0;
  h.coarseLevel = 2;
  h.order = PackOrder::morton;
  const auto page = encodeIndexHeader(h);
  const std::string indexFields = "53414e4449445831"
                                  "02000000"
                                  "00100000"
                                  "03000000"
                                  "02000000"
                                  "04000000"
                                  "20000000"
                                  "0000000000008e40"
                                  "40e2010000000000"
                                  "1cdf4421"
                                  "40000000"            // entry 64 bytes
                                  "0600000000000000"
                                  "0010000000000000"
                                  "d0c0b0a0"
                                  "02000000"            // coarse level 2
                                  "01000000"            // Morton order
                                  "0000000000000000000000000000000000000000"
                                  "0000000000000000000000000000000000000000";
  ASSERT_EQ(fromHex(indexFields).size(), indexField::headerCrc);
  EXPECT_EQ(hex(std::span(page).first(128)), indexFields + leHex(zlibCrc(fromHex(indexFields))));
  auto back = decodeIndexHeader(page, "idx", 4096 + 64 * 6);
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back->coarseLevel, 2u);
  EXPECT_EQ(back->order, PackOrder::morton);
  EXPECT_EQ(back->indexBytes(), 4096u + 64 * 6);

  Entry e{0x1122334455667788ull, 100, 200, 0xdeadbeef, 0xcafef00d, 7, 9, {0x0102030405060708ull, 300, 400, 0x11223344, 0x55667788}};
  std::vector<std::byte> entry(kEntryBytesV2, std::byte{0xff});
  encodeEntry(e, entry, kVersion2);
  EXPECT_EQ(hex(entry),
            "8877665544332211"
            "64000000"
            "c8000000"
            "efbeadde"
            "0df0feca"
            "0807060504030201"
            "2c010000"
            "90010000"
            "44332211"
            "88776655"
            "07000000"
            "09000000"
            "0000000000000000");
  const Entry d = decodeEntry(entry, kVersion2);
  EXPECT_EQ(d.fine.offset, e.fine.offset);
  EXPECT_EQ(d.fine.rawCrc, e.fine.rawCrc);
  EXPECT_EQ(d.kz, 9u);
  EXPECT_EQ(d.storedBytes(), 400u);
}

TEST(PackV2, bothPartsRoundTripWithTheirLevelNumbers) {
  const std::string dir = tempDir("roundtrip");
  const IndexHeader h = header(3, 2, 3);
  writePack(dir, h, PackLayout::split(3));  // coarse: levels 1 and 2
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  const PackReader& reader = *r.value();
  EXPECT_EQ(reader.header().version, 2u);
  EXPECT_EQ(reader.coarseLevel(), 1u);
  EXPECT_EQ(fs::file_size(dir + "/modules.idx"), 4096u + 6 * 64);
  for (std::uint32_t kz = 0; kz < 2; ++kz) {
    for (std::uint32_t kx = 0; kx < 3; ++kx) {
      const Module want = sample(kx, kz, h);
      auto whole = reader.read(kx, kz);
      ASSERT_TRUE(whole.ok()) << whole.error();
      EXPECT_EQ(module::encode(whole.value()), module::encode(want));
      // The coarse record alone: levels 1..2 at their own numbers.
      Module coarse;
      ASSERT_EQ(reader.readCoarseInto(kx, kz, coarse).message(), "");
      ASSERT_EQ(coarse.levels.size(), 3u);
      EXPECT_TRUE(coarse.levels[0].vertices.empty());
      EXPECT_EQ(module::encode(partOf(coarse, 1, 3)), module::encode(partOf(want, 1, 3)));
      auto raw = reader.readRaw(kx, kz);
      ASSERT_TRUE(raw.ok()) << raw.error();
      EXPECT_EQ(raw.value(), module::encode(partOf(want, 1, 3)));
      // Then the fine one fills level 0 and leaves the coarse ones.
      ASSERT_EQ(reader.readFineInto(kx, kz, coarse).message(), "");
      EXPECT_EQ(module::encode(coarse), module::encode(want));
      auto fineRaw = reader.readRaw(kx, kz, Part::fine);
      ASSERT_TRUE(fineRaw.ok()) << fineRaw.error();
      EXPECT_EQ(fineRaw.value(), module::encode(partOf(want, 0, 1)));
      const Entry e = reader.entry(kx, kz);
      EXPECT_EQ(e.rawBytes, module::encode(partOf(want, 1, 3)).size());
      EXPECT_EQ(e.fine.rawCrc, zlibCrc(module::encode(partOf(want, 0, 1))));
      EXPECT_LT(e.compressedBytes, e.fine.compressedBytes);  // the coarse record is the small one
      std::vector<std::byte> record(e.fine.compressedBytes);
      ASSERT_EQ(::pread(reader.packFd(), record.data(), record.size(), off_t(e.fine.offset)), ssize_t(record.size()));
      auto unpacked = reader.unpack(kx, kz, record, Part::fine);
      ASSERT_TRUE(unpacked.ok()) << unpacked.error();
      EXPECT_EQ(unpacked.value(), fineRaw.value());
    }
  }
  EXPECT_TRUE(validatePack(dir).ok()) << ::testing::PrintToString(messages(validatePack(dir).problems()));
  fs::remove_all(dir);
}

// The records lie back to back: every coarse record, then every fine one,
// each group in Morton order, computed here by hand for 3 x 2 modules.
TEST(PackV2, coarseRecordsComeFirstInMortonOrder) {
  const std::string dir = tempDir("morton");
  const IndexHeader h = header(3, 2, 2);
  writePack(dir, h, PackLayout::split(2), true);  // appended in reverse: the order is the layout's
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  // Morton codes (kx in even bits): (0,0)=0 (1,0)=1 (0,1)=2 (1,1)=3 (2,0)=4 (2,1)=6.
  const std::uint32_t morton[][2] = {{0, 0}, {1, 0}, {0, 1}, {1, 1}, {2, 0}, {2, 1}};
  std::uint64_t at = kPackHeaderBytes;
  for (const auto& k : morton) {
    const Entry e = r.value()->entry(k[0], k[1]);
    EXPECT_EQ(e.offset, at) << k[0] << "," << k[1];
    at += e.compressedBytes;
  }
  for (const auto& k : morton) {
    const Entry e = r.value()->entry(k[0], k[1]);
    EXPECT_EQ(e.fine.offset, at) << k[0] << "," << k[1];
    at += e.fine.compressedBytes;
  }
  EXPECT_EQ(at, fs::file_size(dir + "/modules.pack"));
  const std::vector<std::uint32_t> expect = {0, 1, 3, 4, 2, 5};
  EXPECT_EQ(moduleOrder(3, 2, PackOrder::morton), expect);
  // Append order does not change the bytes.
  const std::string other = tempDir("morton-fwd");
  writePack(other, h, PackLayout::split(2), false);
  EXPECT_EQ(readAll(dir + "/modules.pack"), readAll(other + "/modules.pack"));
  EXPECT_EQ(readAll(dir + "/modules.idx"), readAll(other + "/modules.idx"));
  // No spill file is left behind.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2);
  fs::remove_all(dir);
  fs::remove_all(other);
}

TEST(PackV2, rowMajorOrderAndCoarseLevelZero) {
  const std::string dir = tempDir("rowmajor");
  const IndexHeader h = header(3, 2, 2);
  writePack(dir, h, PackLayout{kVersion2, 1, PackOrder::rowMajor}, true);
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  std::uint64_t at = kPackHeaderBytes;
  for (std::uint32_t k = 0; k < 6; ++k) {
    EXPECT_EQ(r.value()->entry(k % 3, k / 3).offset, at);
    at += r.value()->entry(k % 3, k / 3).compressedBytes;
  }
  EXPECT_EQ(r.value()->entry(0, 0).fine.offset, at);
  fs::remove_all(dir);
  fs::create_directories(dir);

  // Coarse level 0: the coarse record is the whole module, no fine record.
  writePack(dir, h, PackLayout{kVersion2, 0, PackOrder::morton});
  auto z = PackReader::open(dir);
  ASSERT_TRUE(z.ok()) << z.error();
  const Entry e = z.value()->entry(1, 1);
  EXPECT_EQ(e.fine.compressedBytes, 0u);
  EXPECT_EQ(e.fine.offset, 0u);
  Module m;
  ASSERT_EQ(z.value()->readCoarseInto(1, 1, m).message(), "");
  EXPECT_EQ(module::encode(m), module::encode(sample(1, 1, h)));
  EXPECT_EQ(z.value()->readFineInto(1, 1, m).message(), "");
  EXPECT_EQ(module::encode(m), module::encode(sample(1, 1, h)));
  EXPECT_NE(z.value()->readRaw(1, 1, Part::fine).error().find("has no fine record"), std::string::npos);
  EXPECT_TRUE(validatePack(dir).ok()) << ::testing::PrintToString(messages(validatePack(dir).problems()));
  fs::remove_all(dir);
}

TEST(PackV2, writerRefusesABadLayout) {
  const std::string dir = tempDir("badlayout");
  EXPECT_NE(PackWriter::create(dir, header(2, 2, 3), 3, {kVersion2, 3, PackOrder::morton}).error().find(
                "coarse level 3 is out of range (0 to 2 for 3 levels)"),
            std::string::npos);
  EXPECT_NE(PackWriter::create(dir, header(2, 2, 3), 3, {3, 1, PackOrder::morton}).error().find(
                "version 3 is not supported"),
            std::string::npos);
  fs::remove_all(dir);
}

TEST(PackV2, everyTruncatedPrefixOfEitherFileFails) {
  const std::string dir = tempDir("trunc");
  writePack(dir, header(2, 2, 2, 4), PackLayout::split(2));
  const std::string idxPath = dir + "/modules.idx", packPath = dir + "/modules.pack";
  const auto idx = readAll(idxPath);
  ASSERT_EQ(idx.size(), 4096u + 4 * 64);
  for (std::size_t n = 0; n < idx.size(); ++n) {
    writeAll(idxPath, std::span(idx).first(n));
    auto r = PackReader::open(dir);
    ASSERT_FALSE(r.ok()) << "prefix " << n;
    EXPECT_EQ(r.problems().front().offset, n);
    EXPECT_NE(r.error().find("truncated"), std::string::npos) << r.error();
    ASSERT_FALSE(validatePack(dir).ok()) << "prefix " << n;
  }
  writeAll(idxPath, idx);
  const auto pack = readAll(packPath);
  for (std::size_t n = 0; n < pack.size(); ++n) {
    writeAll(packPath, std::span(pack).first(n));
    auto r = PackReader::open(dir);
    ASSERT_FALSE(r.ok()) << "prefix " << n;
    EXPECT_NE(r.problems().back().message.find("truncated"), std::string::npos) << r.error();
    ASSERT_FALSE(validatePack(dir).ok()) << "prefix " << n;
  }
  writeAll(packPath, pack);
  EXPECT_TRUE(validatePack(dir).ok());
  fs::remove_all(dir);
}

TEST(PackV2, randomFlipsInEitherFileAreDetected) {
  const std::string dir = tempDir("flips");
  writePack(dir, header(2, 2, 2, 4), PackLayout::split(2));
  for (const char* name : {"modules.idx", "modules.pack"}) {
    const std::string path = dir + "/" + name;
    auto bytes = readAll(path);
    std::uint64_t seed = 777;
    for (int k = 0; k < 400; ++k) {
      seed = module::samples::mix(seed);
      const std::size_t off = seed % bytes.size();
      const auto mask = static_cast<std::byte>(1 + (seed >> 32) % 255);
      bytes[off] ^= mask;
      writeAll(path, bytes);
      EXPECT_FALSE(validatePack(dir).ok()) << name << ": flip at " << off << " not caught";
      bytes[off] ^= mask;
    }
    writeAll(path, bytes);
  }
  EXPECT_TRUE(validatePack(dir).ok());
  fs::remove_all(dir);
}

// Hostile entries and header fields, each re-sealed so only the structure
// is wrong: every one gives its message at its offset, none crashes, and a
// read of the module fails cleanly.
TEST(PackV2, hostileFieldsGiveTheirMessages) {
  const std::string dir = tempDir("hostile");
  const IndexHeader h = header(2, 2, 2, 4);
  writePack(dir, h, PackLayout::split(2));
  const std::string idxPath = dir + "/modules.idx", packPath = dir + "/modules.pack";
  const auto good = readAll(idxPath);
  const std::size_t e10 = entryAt(1, 0, 2);
  const Entry first = decodeEntry(std::span(good).subspan(e10, 64), kVersion2);
  const std::uint64_t packBytes = fs::file_size(packPath);
  struct Case {
    const char* name;
    std::size_t offset;  ///< field to overwrite
    std::uint64_t value;
    int width;
    std::size_t at;  ///< offset of the problem in modules.idx
    std::string expected;
    bool header;  ///< a header field: open fails
  };
  const Case cases[] = {
      {"coarse level", indexField::coarseLevel, 2, 4, indexField::coarseLevel,
       "pack index: coarse level 2 is out of range (0 to 1 for 2 levels)", true},
      {"order", indexField::order, 7, 4, indexField::order, "pack index: record order 7 is not known", true},
      {"entry size", indexField::entryBytes, 32, 4, indexField::entryBytes, "pack index: entry size must be 64 in version 2",
       true},
      {"version", indexField::version, 3, 4, indexField::version, "pack index: version 3 is not supported", true},
      {"no fine", e10 + entryFieldV2::fineCompressedBytes, 0, 4, e10 + entryFieldV2::fineCompressedBytes,
       "pack index: module (1,0) has a coarse record but no fine record (coarse level 1 needs one)", false},
      {"fine huge", e10 + entryFieldV2::fineRawBytes, 0x7fffffff, 4, e10 + entryFieldV2::fineCompressedBytes,
       "pack index: fine module (1,0) sizes", false},
      {"fine beyond", e10 + entryFieldV2::fineOffset, packBytes, 8, e10 + entryFieldV2::fineOffset,
       "pack index: fine module (1,0) record at bytes " + std::to_string(packBytes), false},
      {"fine over coarse", e10 + entryFieldV2::fineOffset, first.offset, 8, e10,  // overlaps: at the entry
       "overlaps the record of", false},
      {"kx", e10 + entryFieldV2::kx, 0, 4, e10 + entryFieldV2::kx, "pack index: the entry of module (1,0) names module (0,0)",
       false},
      {"reserved", e10 + entryFieldV2::reserved, 1, 8, e10 + entryFieldV2::reserved,
       "pack index: the entry of module (1,0) has reserved bytes 56..63 that are not zero", false},
  };
  for (const Case& c : cases) {
    auto bytes = good;
    std::memcpy(bytes.data() + c.offset, &c.value, static_cast<std::size_t>(c.width));
    resealIndex(bytes);
    writeAll(idxPath, bytes);
    const auto problems = validatePack(dir).problems();
    ASSERT_TRUE(hasMessage(problems, c.expected)) << c.name << ": " << ::testing::PrintToString(messages(problems));
    const auto it = std::find_if(problems.begin(), problems.end(),
                                 [&](const Problem& p) { return p.message.find(c.expected) != std::string::npos; });
    EXPECT_EQ(it->offset, c.at) << c.name;
    auto r = PackReader::open(dir);
    if (c.header) {
      ASSERT_FALSE(r.ok()) << c.name;
      EXPECT_NE(r.error().find(c.expected), std::string::npos) << r.error();
      continue;
    }
    ASSERT_TRUE(r.ok()) << c.name << ": " << r.error();
    if (std::string(c.name) == "reserved" || std::string(c.name) == "fine over coarse") continue;  // reads still work
    Module m;
    EXPECT_FALSE(r.value()->readInto(1, 0, m).ok()) << c.name;
  }
  // A fine record whose bytes are wrong: the read of the fine part fails
  // with the fine record's name, the coarse part still reads.
  writeAll(idxPath, good);
  auto pack = readAll(packPath);
  pack[first.fine.offset + 3] ^= std::byte{0x40};
  writeAll(packPath, pack);
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  Module m;
  EXPECT_EQ(r.value()->readCoarseInto(1, 0, m).message(), "");
  const Status fine = r.value()->readFineInto(1, 0, m);
  ASSERT_FALSE(fine.ok());
  EXPECT_NE(fine.message().find("pack: fine module (1,0) record checksum mismatch"), std::string::npos) << fine.message();
  EXPECT_EQ(fine.problems().front().offset, first.fine.offset);
  // A v1 pack header under a v2 index.
  pack[first.fine.offset + 3] ^= std::byte{0x40};
  const auto v1 = encodePackHeader(kVersion1);
  std::copy(v1.begin(), v1.end(), pack.begin());
  writeAll(packPath, pack);
  EXPECT_NE(PackReader::open(dir).error().find("pack: version 1 differs from the index's version 2"), std::string::npos)
      << PackReader::open(dir).error();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::pack
