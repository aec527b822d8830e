// Pack files v1 (the default PackLayout; v2 is in test_pack_v2.cpp): golden headers, round trips, determinism, threads, the
// writer's temporaries, truncation and flipped bytes of either file, and a
// table of structural faults each with its message.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>

#include "module_samples.h"
#include "sandtable/base/range_source.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/pack.h"

namespace sandtable::pack {
namespace {

namespace fs = std::filesystem;
using module::Module;

/// A fresh, empty directory under the temp directory.
std::string tempDir(const std::string& name) {
  const fs::path p =
      fs::temp_directory_path() / ("sandtable-pack-" + name + "." + std::to_string(::getpid()));
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
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
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
/// code under test (formats' crc32 wraps the same function).
std::uint32_t zlibCrc(std::span<const std::byte> b) {
  return static_cast<std::uint32_t>(
      ::crc32(0L, reinterpret_cast<const Bytef*>(b.data()), static_cast<uInt>(b.size())));
}

/// Bytes of a hex string (two digits a byte).
std::vector<std::byte> fromHex(const std::string& h) {
  std::vector<std::byte> b;
  for (std::size_t k = 0; k + 1 < h.size(); k += 2) {
    b.push_back(static_cast<std::byte>(std::stoi(h.substr(k, 2), nullptr, 16)));
  }
  return b;
}

/// A u32 as 8 hex digits, little-endian.
std::string leHex(std::uint32_t v) {
  std::vector<std::byte> b(4);
  storeLE(b.data(), v);
  return hex(b);
}

IndexHeader smallHeader(std::uint32_t mx, std::uint32_t mz, std::uint32_t squares = 4,
                        std::uint32_t levels = 2) {
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

/// Writes a pack of mx x mz realistic modules (row-major add order).
void writePack(const std::string& dir, const IndexHeader& h, int level = kDefaultZstdLevel) {
  auto w = PackWriter::create(dir, h, level);
  ASSERT_TRUE(w.ok()) << w.error();
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      ASSERT_EQ(w.value()->add(sample(kx, kz, h)).message(), "");
    }
  }
  ASSERT_EQ(w.value()->finish().message(), "");
}

std::vector<std::string> messages(const std::vector<Problem>& ps) {
  std::vector<std::string> out;
  for (const Problem& p : ps) out.push_back(p.str());
  return out;
}

bool hasMessage(const std::vector<Problem>& ps, const std::string& part) {
  return std::any_of(ps.begin(), ps.end(),
                     [&](const Problem& p) { return p.message.find(part) != std::string::npos; });
}

/// Recomputes the index's table CRC and header CRC after a hand edit.
void resealIndex(std::vector<std::byte>& idx) {
  const std::uint64_t count = loadLE<std::uint64_t>(idx.data() + indexField::entryCount);
  storeLE<std::uint32_t>(idx.data() + indexField::tableCrc,
                         crc32(std::span(idx).subspan(kIndexHeaderBytes, kEntryBytes * count)));
  storeLE<std::uint32_t>(idx.data() + indexField::headerCrc,
                         crc32(std::span(idx).first(indexField::headerCrc)));
}

std::size_t entryAt(std::uint32_t kx, std::uint32_t kz, std::uint32_t mx) {
  return kIndexHeaderBytes + kEntryBytes * (std::size_t(kz) * mx + kx);
}

TEST(Pack, layoutConstantsArePinned) {
  EXPECT_EQ(kPackHeaderBytes, 64u);
  EXPECT_EQ(packField::codec, 20u);
  EXPECT_EQ(packField::headerCrc, 60u);
  EXPECT_EQ(kIndexHeaderBytes, 4096u);
  EXPECT_EQ(indexField::moduleSize, 32u);
  EXPECT_EQ(indexField::packBytes, 40u);
  EXPECT_EQ(indexField::entryCount, 56u);
  EXPECT_EQ(indexField::tableOffset, 64u);
  EXPECT_EQ(indexField::tableCrc, 72u);
  EXPECT_EQ(indexField::headerCrc, 124u);
  EXPECT_EQ(kEntryBytes, 32u);
  EXPECT_EQ(entryField::rawCrc, 20u);
  EXPECT_EQ(entryField::kz, 28u);
  EXPECT_EQ(kMaxModuleBytes, 64u << 20);
}

// Golden bytes of version 1. If this fails, the format changed: bump
// kVersion, keep a reader for version 1, and add a new golden test. The
// fields are written out by hand; every CRC is computed here with zlib over
// the bytes FORMAT.md says it covers.
TEST(Pack, version1GoldenHeaders) {
  // Pack header: magic "SANDPACK", version 1, header 64, flags 0, codec 1
  // (zstd), 36 reserved zero bytes, then the CRC of bytes 0..59.
  const std::string packFields = "53414e445041434b"
                                 "01000000"
                                 "40000000"
                                 "00000000"
                                 "01000000"
                                 "000000000000000000000000000000000000000000000000000000000000000000000000";
  const std::uint32_t packHeaderCrc = zlibCrc(fromHex(packFields));
  EXPECT_EQ(packHeaderCrc, 0x1af7f5bdu);  // the value FORMAT.md 10.1 quotes
  const std::vector<std::byte> packHeader = fromHex(packFields + leHex(packHeaderCrc));
  ASSERT_EQ(packHeader.size(), kPackHeaderBytes);
  EXPECT_EQ(hex(encodePackHeader()), hex(packHeader));
  // The index's packHeaderCrc: the CRC of all 64 bytes, its headerCrc included
  // (FORMAT.md 10.2), which is not the pack's own headerCrc.
  // CRC-32 over bytes followed by their own CRC is the constant residue
  // 0x2144df1c, so every sound pack header gives this value.
  const std::uint32_t wholePackHeaderCrc = zlibCrc(packHeader);
  EXPECT_NE(wholePackHeaderCrc, packHeaderCrc);
  EXPECT_EQ(wholePackHeaderCrc, 0x2144df1cu);

  IndexHeader h = smallHeader(3, 2, 32, 4);
  h.moduleSize = 960;
  h.packBytes = 123456;
  h.packHeaderCrc = wholePackHeaderCrc;
  h.tableCrc = 0xa0b0c0d0;
  const auto page = encodeIndexHeader(h);
  ASSERT_EQ(page.size(), 4096u);
  // magic "SANDIDX1", version 1, header 4096, 3 x 2 modules, 4 levels, 32
  // squares, 960.0 m, pack 123456 bytes, pack header CRC, entry 32 bytes,
  // 6 entries, table at 4096, table CRC, reserved zeros, then the CRC of
  // bytes 0..123.
  const std::string indexFields = "53414e4449445831"
                                  "01000000"
                                  "00100000"
                                  "03000000"
                                  "02000000"
                                  "04000000"
                                  "20000000"
                                  "0000000000008e40"
                                  "40e2010000000000" +
                                  leHex(wholePackHeaderCrc) +
                                  "20000000"
                                  "0600000000000000"
                                  "0010000000000000"
                                  "d0c0b0a0"
                                  "000000000000000000000000000000000000000000000000"
                                  "000000000000000000000000000000000000000000000000";
  ASSERT_EQ(fromHex(indexFields).size(), indexField::headerCrc);
  EXPECT_EQ(hex(std::span(page).first(128)), indexFields + leHex(zlibCrc(fromHex(indexFields))));
  EXPECT_TRUE(
      std::all_of(page.begin() + 128, page.end(), [](std::byte b) { return b == std::byte{0}; }));
  std::vector<std::byte> entry(kEntryBytes);
  encodeEntry({0x1122334455667788ull, 100, 200, 0xdeadbeef, 0xcafef00d, 7, 9, {}}, entry);
  EXPECT_EQ(hex(entry),
            "8877665544332211"
            "64000000"
            "c8000000"
            "efbeadde"
            "0df0feca"
            "07000000"
            "09000000");

  // The writer writes exactly these headers, and the index it writes holds
  // the CRC of the pack's 64 header bytes.
  const std::string dir = tempDir("golden");
  writePack(dir, smallHeader(2, 1));
  const auto pack = readAll(dir + "/modules.pack");
  const auto idx = readAll(dir + "/modules.idx");
  EXPECT_EQ(hex(std::span(pack).first(64)), hex(packHeader));
  auto back = decodeIndexHeader(idx, "idx", idx.size());
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back->modulesX, 2u);
  EXPECT_EQ(back->levels, 2u);
  EXPECT_EQ(back->moduleSquares, 4u);
  EXPECT_EQ(back->moduleSize, 120.0);
  EXPECT_EQ(back->packBytes, pack.size());
  EXPECT_EQ(back->packHeaderCrc, wholePackHeaderCrc);
  EXPECT_EQ(loadLE<std::uint32_t>(idx.data() + indexField::packHeaderCrc), zlibCrc(std::span(pack).first(64)));
  EXPECT_EQ(loadLE<std::uint32_t>(idx.data() + indexField::headerCrc),
            zlibCrc(std::span(idx).first(indexField::headerCrc)));
  EXPECT_EQ(hex(std::span(idx).first(4096)), hex(encodeIndexHeader(back.value())));
  fs::remove_all(dir);
}

TEST(Pack, roundTripsEveryModule) {
  const std::string dir = tempDir("roundtrip");
  const IndexHeader h = smallHeader(3, 2, 8, 3);
  auto w = PackWriter::create(dir, h);
  ASSERT_TRUE(w.ok()) << w.error();
  for (std::uint32_t kz = 0; kz < 2; ++kz) {
    for (std::uint32_t kx = 0; kx < 3; ++kx) ASSERT_EQ(w.value()->add(sample(kx, kz, h)).message(), "");
  }
  ASSERT_EQ(w.value()->finish().message(), "");
  const PackWriter& writer = *w.value();
  // The writer's CRCs and sizes are those of the files (for the manifest).
  const auto pack = crc32File(dir + "/modules.pack");
  ASSERT_TRUE(pack.ok()) << pack.error();
  EXPECT_EQ(pack->crc, writer.packCrc());
  EXPECT_EQ(pack->bytes, writer.packBytes());
  const auto index = crc32File(dir + "/modules.idx");
  ASSERT_TRUE(index.ok()) << index.error();
  EXPECT_EQ(index->crc, writer.indexCrc());
  EXPECT_EQ(index->bytes, writer.indexBytes());
  EXPECT_EQ(index->bytes, 4096u + 6 * 32);

  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  const PackReader& reader = *r.value();
  EXPECT_EQ(reader.header().modulesX, 3u);
  EXPECT_EQ(reader.header().levels, 3u);
  EXPECT_EQ(reader.packPath(), dir + "/modules.pack");
  EXPECT_EQ(reader.indexPath(), dir + "/modules.idx");
  std::uint64_t expectedOffset = kPackHeaderBytes;
  for (std::uint32_t kz = 0; kz < 2; ++kz) {
    for (std::uint32_t kx = 0; kx < 3; ++kx) {
      const auto raw = module::encode(sample(kx, kz, h));
      const Entry e = reader.entry(kx, kz);
      EXPECT_EQ(e.kx, kx);
      EXPECT_EQ(e.kz, kz);
      EXPECT_EQ(e.offset, expectedOffset);  // added in row-major order
      expectedOffset += e.compressedBytes;
      EXPECT_EQ(e.rawBytes, raw.size());
      EXPECT_EQ(e.rawCrc, crc32(raw));
      auto got = reader.readRaw(kx, kz);
      ASSERT_TRUE(got.ok()) << got.error();
      EXPECT_EQ(got.value(), raw);
      auto m = reader.read(kx, kz);
      ASSERT_TRUE(m.ok()) << m.error();
      EXPECT_EQ(module::encode(m.value()), raw);
      // A record read by the caller itself (e.g. an async pager).
      std::vector<std::byte> record(e.compressedBytes);
      ASSERT_EQ(
          ::pread(reader.packFd(), record.data(), record.size(), static_cast<off_t>(e.offset)),
          static_cast<ssize_t>(record.size()));
      auto unpacked = reader.unpack(kx, kz, record);
      ASSERT_TRUE(unpacked.ok()) << unpacked.error();
      EXPECT_EQ(unpacked.value(), raw);
    }
  }
  EXPECT_EQ(expectedOffset, writer.packBytes());
  EXPECT_TRUE(validatePack(dir).ok()) << ::testing::PrintToString(messages(validatePack(dir).problems()));
  fs::remove_all(dir);
}

TEST(Pack, writerIsDeterministic) {
  const std::string a = tempDir("det-a"), b = tempDir("det-b");
  writePack(a, smallHeader(2, 2));
  writePack(b, smallHeader(2, 2));
  EXPECT_EQ(readAll(a + "/modules.pack"), readAll(b + "/modules.pack"));
  EXPECT_EQ(readAll(a + "/modules.idx"), readAll(b + "/modules.idx"));
  fs::remove_all(a);
  fs::remove_all(b);
}

TEST(Pack, threadsAddConcurrently) {
  const std::string dir = tempDir("threads");
  const IndexHeader h = smallHeader(6, 5);
  auto w = PackWriter::create(dir, h, 3);
  ASSERT_TRUE(w.ok()) << w.error();
  std::vector<std::thread> threads;
  std::vector<std::string> errors(4);
  for (std::uint32_t t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (std::uint32_t k = t; k < 30; k += 4) {
        const std::string e = w.value()->add(sample(k % 6, k / 6, h)).message();
        if (!e.empty()) errors[t] = e;
      }
    });
  }
  for (auto& th : threads) th.join();
  for (const auto& e : errors) EXPECT_EQ(e, "");
  const SizeStats st = w.value()->stats();
  EXPECT_EQ(st.count, 30u);
  ASSERT_EQ(w.value()->finish().message(), "");
  EXPECT_TRUE(validatePack(dir).ok()) << ::testing::PrintToString(messages(validatePack(dir).problems()));
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  for (std::uint32_t k = 0; k < 30; ++k) {
    auto m = r.value()->read(k % 6, k / 6);
    ASSERT_TRUE(m.ok()) << m.error();
    EXPECT_EQ(module::encode(m.value()), module::encode(sample(k % 6, k / 6, h)));
  }
  fs::remove_all(dir);
}

TEST(Pack, recordsLandInAppendOrder) {
  const std::string dir = tempDir("append-order");
  const IndexHeader h = smallHeader(3, 2);
  auto w = PackWriter::create(dir, h, 3);
  ASSERT_TRUE(w.ok()) << w.error();
  // Compressed in row-major order, appended in reverse: the pack follows append().
  std::vector<PackWriter::Record> records;
  for (std::uint32_t k = 0; k < 6; ++k) {
    auto r = w.value()->compress(sample(k % 3, k / 3, h));
    ASSERT_TRUE(r.ok()) << r.error();
    records.push_back(std::move(r.value()));
  }
  PackWriter::Record again = records[5];
  for (std::uint32_t k = 6; k-- > 0;) ASSERT_TRUE(w.value()->append(std::move(records[k])).ok());
  EXPECT_NE(w.value()->append(std::move(again)).error().find("module (2,1) was added twice"), std::string::npos);
  ASSERT_TRUE(w.value()->finish().ok());
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  std::uint64_t offset = kPackHeaderBytes;
  for (std::uint32_t k = 6; k-- > 0;) {
    const Entry e = r.value()->entry(k % 3, k / 3);
    EXPECT_EQ(e.offset, offset) << k;
    offset += e.compressedBytes;
    auto m = r.value()->read(k % 3, k / 3);
    ASSERT_TRUE(m.ok()) << m.error();
    EXPECT_EQ(module::encode(m.value()), module::encode(sample(k % 3, k / 3, h)));
  }
  EXPECT_EQ(offset, fs::file_size(dir + "/modules.pack"));
  fs::remove_all(dir);
}

TEST(Pack, sizeStatsAreNearestRank) {
  const std::string dir = tempDir("stats");
  const IndexHeader h = smallHeader(5, 4, 4, 2);
  auto w = PackWriter::create(dir, h);
  ASSERT_TRUE(w.ok());
  EXPECT_EQ(w.value()->stats().count, 0u);
  std::vector<std::uint32_t> sizes;
  std::uint64_t raw = 0;
  for (std::uint32_t k = 0; k < 20; ++k) {
    // Varied sizes: some modules carry more levels of detail squares.
    const Module m = module::samples::realistic(k % 5, k / 5, 4 + (k % 3) * 4, 2);
    ASSERT_EQ(w.value()->add(m).message(), "");
    raw += module::encode(m).size();
  }
  ASSERT_EQ(w.value()->finish().message(), "");
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok());
  for (std::uint32_t k = 0; k < 20; ++k)
    sizes.push_back(r.value()->entry(k % 5, k / 5).compressedBytes);
  std::sort(sizes.begin(), sizes.end());
  const SizeStats st = w.value()->stats();
  EXPECT_EQ(st.count, 20u);
  EXPECT_EQ(st.totalRaw, raw);
  EXPECT_EQ(st.totalCompressed + kPackHeaderBytes, w.value()->packBytes());
  EXPECT_EQ(st.minCompressed, sizes[0]);
  EXPECT_EQ(st.medianCompressed, sizes[9]);  // ceil(0.5 * 20) = 10th
  EXPECT_EQ(st.p95Compressed, sizes[18]);    // ceil(0.95 * 20) = 19th
  EXPECT_EQ(st.maxCompressed, sizes[19]);
  EXPECT_LT(st.minCompressed, st.maxCompressed);
  fs::remove_all(dir);
}

TEST(Pack, finishFailsWhileAModuleIsMissing) {
  const std::string dir = tempDir("missing");
  const IndexHeader h = smallHeader(2, 2);
  auto w = PackWriter::create(dir, h);
  ASSERT_TRUE(w.ok());
  for (std::uint32_t k = 0; k < 3; ++k) ASSERT_EQ(w.value()->add(sample(k % 2, k / 2, h)).message(), "");
  EXPECT_EQ(w.value()->finish().message(),
            "pack writer: 1 of 4 modules were not added (the first is module (1,1))");
  EXPECT_FALSE(fs::exists(dir + "/modules.pack"));
  EXPECT_FALSE(fs::exists(dir + "/modules.idx"));
  // The writer stays usable: add the last one and finish.
  ASSERT_EQ(w.value()->add(sample(1, 1, h)).message(), "");
  ASSERT_EQ(w.value()->finish().message(), "");
  EXPECT_EQ(w.value()->finish().message(), "pack writer: finish() was already called");
  EXPECT_EQ(w.value()->add(sample(0, 0, h)).message(), "pack writer: add() after finish()");
  EXPECT_TRUE(validatePack(dir).ok());
  // Only the two files: no temporaries left behind.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2);
  fs::remove_all(dir);
}

TEST(Pack, writerDestroyedWithoutFinishLeavesNoFiles) {
  const std::string dir = tempDir("abandon");
  const IndexHeader h = smallHeader(2, 1);
  {
    auto w = PackWriter::create(dir, h);
    ASSERT_TRUE(w.ok());
    ASSERT_EQ(w.value()->add(sample(0, 0, h)).message(), "");
    EXPECT_TRUE(fs::exists(dir + "/modules.pack.tmp." + std::to_string(::getpid())));
  }
  EXPECT_TRUE(fs::is_empty(dir));
  {
    auto w = PackWriter::create(dir, h);  // one of two added: finish fails, then abandoned
    ASSERT_TRUE(w.ok());
    ASSERT_EQ(w.value()->add(sample(0, 0, h)).message(), "");
    EXPECT_NE(w.value()->finish().message(), "");
  }
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

TEST(Pack, writerRefusesBadInput) {
  const std::string dir = tempDir("refuse");
  EXPECT_EQ(PackWriter::create(dir, smallHeader(0, 1)).error(),
            dir + " @0: pack writer: module counts 0 x 1 are out of range (1 to 65536 each)");
  EXPECT_NE(PackWriter::create(dir, smallHeader(1, 1, 4, 17))
                .error()
                .find("level count 17 is out of range"),
            std::string::npos);
  EXPECT_NE(
      PackWriter::create(dir, smallHeader(1, 1), 99).error().find("zstd level 99 is out of range"),
      std::string::npos);
  EXPECT_NE(
      PackWriter::create(dir + "/no/such/dir", smallHeader(1, 1)).error().find("cannot create"),
      std::string::npos);
  const IndexHeader h = smallHeader(2, 2);
  auto w = PackWriter::create(dir, h);
  ASSERT_TRUE(w.ok());
  PackWriter& pw = *w.value();
  EXPECT_EQ(pw.add(sample(2, 0, h)).message(),
            "pack writer: module (2,0) is outside the pack's 2 x 2 modules");
  EXPECT_EQ(pw.add(module::samples::realistic(0, 0, 4, 3)).message(),
            "pack writer: module (0,0) has 3 levels, the pack holds 2");
  Module m = sample(0, 0, h);
  m.levels[1].groups[2].firstIndex += 3;
  EXPECT_EQ(pw.add(m).message().rfind("pack writer: module (0,0): module: level 1 group 2 firstIndex", 0),
            0u);
  m = sample(0, 0, h);
  m.levels[0].indices[5] = 100000;
  EXPECT_EQ(pw.add(m).message().rfind("pack writer: module (0,0) is malformed: module: level 0 index 5 is "
                            "100000, not below the vertex count",
                            0),
            0u)
      << pw.add(m).message();
  m = sample(0, 0, h);
  std::swap(m.levels[0].groups[0], m.levels[0].groups[1]);
  m.levels[0].groups[0].firstIndex = 0;
  m.levels[0].groups[1].firstIndex = m.levels[0].groups[0].indexCount;
  EXPECT_NE(pw.add(m).message().find("in (priority, square, half, material) order"), std::string::npos);
  ASSERT_EQ(pw.add(sample(0, 0, h)).message(), "");
  EXPECT_EQ(pw.add(sample(0, 0, h)).message(), "pack writer: module (0,0) was added twice");
  fs::remove_all(dir);
}

TEST(Pack, everyTruncatedIndexPrefixFails) {
  const std::string dir = tempDir("trunc-idx");
  writePack(dir, smallHeader(2, 2));
  const std::string idxPath = dir + "/modules.idx";
  const auto idx = readAll(idxPath);
  ASSERT_EQ(idx.size(), 4096u + 4 * 32);
  for (std::size_t n = 0; n < idx.size(); ++n) {
    writeAll(idxPath, std::span(idx).first(n));
    auto r = PackReader::open(dir);
    ASSERT_FALSE(r.ok()) << "prefix " << n;
    const Problem& p = r.problems().front();
    EXPECT_EQ(p.file, idxPath);
    EXPECT_EQ(p.offset, n);
    EXPECT_NE(p.message.find("truncated"), std::string::npos) << p.message;
    const auto problems = validatePack(dir).problems();
    ASSERT_FALSE(problems.empty()) << "prefix " << n;
    EXPECT_EQ(problems.front().offset, n);
  }
  writeAll(idxPath, idx);
  EXPECT_TRUE(validatePack(dir).ok());
  fs::remove_all(dir);
}

TEST(Pack, truncatedPacksFail) {
  const std::string dir = tempDir("trunc-pack");
  writePack(dir, smallHeader(2, 2));
  const std::string packPath = dir + "/modules.pack";
  const auto pack = readAll(packPath);
  // Every prefix through the header and the first records' frame headers,
  // then a stride through the rest.
  for (std::size_t n = 0; n < pack.size(); n += (n < 200 ? 1 : 37)) {
    writeAll(packPath, std::span(pack).first(n));
    auto r = PackReader::open(dir);
    ASSERT_FALSE(r.ok()) << "prefix " << n;
    EXPECT_EQ(r.problems().back().file, packPath);
    EXPECT_NE(r.problems().back().message.find("truncated"), std::string::npos) << r.error();
    const auto problems = validatePack(dir).problems();
    ASSERT_FALSE(problems.empty()) << "prefix " << n;
    EXPECT_TRUE(hasMessage(
        problems, "bytes but the index says " + std::to_string(pack.size()) + ": truncated"));
  }
  fs::remove_all(dir);
}

TEST(Pack, randomFlipsInEitherFileAreDetected) {
  const std::string dir = tempDir("flips");
  writePack(dir, smallHeader(2, 2));
  for (const char* name : {"modules.idx", "modules.pack"}) {
    const std::string path = dir + "/" + name;
    auto bytes = readAll(path);
    std::uint64_t seed = 12345;
    for (int k = 0; k < 500; ++k) {
      seed = module::samples::mix(seed);
      const std::size_t off = seed % bytes.size();
      const auto mask = static_cast<std::byte>(1 + (seed >> 32) % 255);
      bytes[off] ^= mask;
      writeAll(path, bytes);
      EXPECT_FALSE(validatePack(dir).ok()) << name << ": flip at " << off << " not caught";
      bytes[off] ^= mask;
    }
    writeAll(path, bytes);
    EXPECT_TRUE(validatePack(dir).ok());
  }
  fs::remove_all(dir);
}

// Structural faults that the CRCs alone do not explain: each hand edit
// re-seals the index CRCs, and must give its own message at its offset.
TEST(Pack, validateReportsEachStructuralFault) {
  const std::string dir = tempDir("faults");
  const IndexHeader h = smallHeader(2, 2);
  writePack(dir, h);
  const std::string idxPath = dir + "/modules.idx", packPath = dir + "/modules.pack";
  const auto goodIdx = readAll(idxPath);
  const auto goodPack = readAll(packPath);
  const std::size_t e10 = entryAt(1, 0, 2), e00 = entryAt(0, 0, 2);
  const Entry first = decodeEntry(std::span(goodIdx).subspan(e00));
  const Entry second = decodeEntry(std::span(goodIdx).subspan(e10));
  struct Case {
    const char* name;
    std::function<void(std::vector<std::byte>&)> edit;
    std::string file;
    std::uint64_t offset;
    std::string message;
  };
  auto u32At = [](std::size_t off, std::uint32_t v) {
    return [=](std::vector<std::byte>& b) { storeLE<std::uint32_t>(b.data() + off, v); };
  };
  const std::string packBytes = std::to_string(goodPack.size());
  const Case cases[] = {
      {"kx", u32At(e10 + entryField::kx, 0), idxPath, e10 + entryField::kx,
       "pack index: the entry of module (1,0) names module (0,0)"},
      {"missing", u32At(e10 + entryField::compressedBytes, 0), idxPath,
       e10 + entryField::compressedBytes,
       "pack index: module (1,0) is missing (its entry has no record)"},
      {"huge", u32At(e10 + entryField::compressedBytes, 0x7fffffff), idxPath,
       e10 + entryField::compressedBytes,
       "pack index: module (1,0) sizes (2147483647 compressed, " + std::to_string(second.rawBytes) +
           " raw) are out of range (1 to 67108864 bytes)"},
      {"in the header", [&](auto& b) { storeLE<std::uint64_t>(b.data() + e10, 10); }, idxPath, e10,
       "pack index: module (1,0) record at bytes 10.." +
           std::to_string(10 + second.compressedBytes - 1) +
           " is not within the records of modules.pack (bytes 64.." +
           std::to_string(goodPack.size() - 1) + ")"},
      {"past the end",
       [&](auto& b) { storeLE<std::uint64_t>(b.data() + e10, goodPack.size() - 5); }, idxPath, e10,
       "pack index: module (1,0) record at bytes "},
      {"overlap", [&](auto& b) { storeLE<std::uint64_t>(b.data() + e10, first.offset + 1); },
       idxPath, e10,
       "pack index: the record of module (1,0) (bytes " + std::to_string(first.offset + 1) + ".." +
           std::to_string(first.offset + second.compressedBytes) +
           ") overlaps the record of module (0,0) (bytes 64.." +
           std::to_string(63 + first.compressedBytes) + ")"},
      {"gap", u32At(e10 + entryField::compressedBytes, second.compressedBytes - 1), packPath,
       second.offset + second.compressedBytes - 1,
       "pack: bytes " + std::to_string(second.offset + second.compressedBytes - 1) + ".." +
           std::to_string(second.offset + second.compressedBytes - 1) +
           " are in no module's record"},
      {"record crc", u32At(e10 + entryField::compressedCrc, second.compressedCrc ^ 1), packPath,
       second.offset, "pack: module (1,0) record checksum mismatch (stored "},
      {"raw size", u32At(e10 + entryField::rawBytes, second.rawBytes + 1), packPath, second.offset,
       "pack: module (1,0) record does not decompress: the frame holds " +
           std::to_string(second.rawBytes) + " bytes, the index says " +
           std::to_string(second.rawBytes + 1)},
      {"raw crc", u32At(e10 + entryField::rawCrc, second.rawCrc ^ 1), packPath, second.offset,
       "pack: module (1,0) decompressed checksum mismatch (stored "},
      {"swapped records",
       [&](auto& b) {
         Entry a = first, c = second;
         std::swap(a.offset, c.offset);
         std::swap(a.compressedBytes, c.compressedBytes);
         std::swap(a.rawBytes, c.rawBytes);
         std::swap(a.compressedCrc, c.compressedCrc);
         std::swap(a.rawCrc, c.rawCrc);
         encodeEntry(a, std::span(b).subspan(e00));
         encodeEntry(c, std::span(b).subspan(e10));
       },
       packPath, second.offset, "pack: the record of module (0,0) holds module (1,0)"},
      {"pack size",
       [&](auto& b) {
         storeLE<std::uint64_t>(b.data() + indexField::packBytes, goodPack.size() + 1);
       },
       packPath, goodPack.size(),
       "pack: file is " + packBytes + " bytes but the index says " +
           std::to_string(goodPack.size() + 1) + ": truncated; rebuild the database"},
      {"pack header crc", u32At(indexField::packHeaderCrc, 7), packPath, packField::headerCrc,
       "pack: header checksum " + crcHex(crc32(std::span(goodPack).first(64))) +
           " differs from the index's 0x00000007: modules.pack and modules.idx are not from the "
           "same build"},
      {"levels", u32At(indexField::levels, 3), packPath, first.offset,
       "pack: module (0,0) has 2 levels, the index says 3"},
      {"padding", [](auto& b) { b[200] = std::byte{1}; }, idxPath, 200,
       "pack index: header padding is not zero"},
  };
  for (const Case& c : cases) {
    auto idx = goodIdx;
    c.edit(idx);
    resealIndex(idx);
    writeAll(idxPath, idx);
    const auto problems = validatePack(dir).problems();
    const bool found = std::any_of(problems.begin(), problems.end(), [&](const Problem& p) {
      return p.file == c.file && p.offset == c.offset && p.message.rfind(c.message, 0) == 0;
    });
    EXPECT_TRUE(found) << c.name << ": expected " << c.file << " @" << c.offset << ": " << c.message
                       << "\ngot " << ::testing::PrintToString(messages(problems));
  }
  writeAll(idxPath, goodIdx);
  ASSERT_TRUE(validatePack(dir).ok());

  // The reader reports the same faults when it reads the module.
  auto idx = goodIdx;
  storeLE<std::uint32_t>(idx.data() + e10 + entryField::compressedCrc, second.compressedCrc ^ 1);
  resealIndex(idx);
  writeAll(idxPath, idx);
  auto r = PackReader::open(dir);
  ASSERT_TRUE(r.ok()) << r.error();
  auto m = r.value()->read(1, 0);
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.problems().front().file, packPath);
  EXPECT_EQ(m.problems().front().offset, second.offset);
  EXPECT_NE(m.error().find("record checksum mismatch"), std::string::npos) << m.error();
  EXPECT_TRUE(r.value()->read(0, 0).ok());
  writeAll(idxPath, goodIdx);

  // A pack header from another codec (its CRC re-sealed): both the header
  // check and the index's copy of its CRC complain.
  auto pack = goodPack;
  storeLE<std::uint32_t>(pack.data() + packField::codec, 2);
  storeLE<std::uint32_t>(pack.data() + packField::headerCrc, crc32(std::span(pack).first(60)));
  writeAll(packPath, pack);
  const auto problems = validatePack(dir).problems();
  EXPECT_TRUE(hasMessage(problems, "pack: codec 2 is not supported (1 = zstd)"))
      << ::testing::PrintToString(messages(problems));
  EXPECT_FALSE(PackReader::open(dir).ok());
  fs::remove_all(dir);
}

TEST(Pack, hostileIndexHeaderFieldsAreRejected) {
  const std::string dir = tempDir("hostile");
  writePack(dir, smallHeader(2, 2));
  const std::string idxPath = dir + "/modules.idx";
  const auto good = readAll(idxPath);
  struct Case {
    std::size_t offset;
    std::uint64_t value;
    int width;
    const char* expected;
  };
  const Case cases[] = {
      {indexField::version, 3, 4, "pack index: version 3 is not supported"},
      {indexField::headerBytes, 128, 4, "pack index: header size must be 4096"},
      {indexField::modulesX, 0, 4, "pack index: module counts 0 x 2 are out of range"},
      {indexField::modulesZ, 70000, 4, "pack index: module counts 2 x 70000 are out of range"},
      {indexField::levels, 17, 4, "pack index: level count 17 is out of range (1 to 16)"},
      {indexField::moduleSquares, 0, 4, "pack index: module squares 0 is out of range"},
      {indexField::moduleSize, 0x7ff0000000000000ull, 8, "pack index: module size is not a finite"},
      {indexField::packBytes, 63, 8, "pack index: pack size 63 is smaller than the pack header"},
      {indexField::entryBytes, 16, 4, "pack index: entry size must be 32"},
      {indexField::entryCount, 1ull << 40, 8, "pack index: entry count 1099511627776 is not 2 x 2"},
      {indexField::tableOffset, 0, 8, "pack index: table offset must be 4096"},
  };
  for (const Case& c : cases) {
    auto bytes = good;
    std::memcpy(bytes.data() + c.offset, &c.value, static_cast<std::size_t>(c.width));
    storeLE<std::uint32_t>(bytes.data() + indexField::headerCrc,
                           crc32(std::span(bytes).first(indexField::headerCrc)));
    writeAll(idxPath, bytes);
    auto r = PackReader::open(dir);
    ASSERT_FALSE(r.ok()) << c.expected;
    EXPECT_NE(r.error().find(c.expected), std::string::npos) << r.error();
    EXPECT_EQ(r.problems().front().offset, c.offset) << r.error();
    EXPECT_TRUE(hasMessage(validatePack(dir).problems(), c.expected));
  }
  auto bytes = good;
  bytes[0] = std::byte{'X'};
  writeAll(idxPath, bytes);
  EXPECT_EQ(
      PackReader::open(dir).error(),
      idxPath + " @0: pack index: bad magic: not a sandtable pack index (expected \"SANDIDX1\")");
  bytes = good;
  bytes[indexField::modulesX] ^= std::byte{1};
  writeAll(idxPath, bytes);
  EXPECT_NE(PackReader::open(dir).error().find("header checksum mismatch"), std::string::npos);
  bytes = good;
  bytes.push_back(std::byte{0});
  writeAll(idxPath, bytes);
  EXPECT_NE(PackReader::open(dir).error().find("trailing bytes"), std::string::npos);
  bytes = good;
  bytes[4096 + 3] ^= std::byte{1};
  writeAll(idxPath, bytes);
  EXPECT_EQ(PackReader::open(dir).problems().front().offset, 4096u);
  EXPECT_NE(PackReader::open(dir).error().find("entry table checksum mismatch"), std::string::npos);
  fs::remove(idxPath);
  EXPECT_NE(PackReader::open(dir).error().find("pack index: cannot open"), std::string::npos);
  EXPECT_FALSE(validatePack(dir).ok());
  fs::remove_all(dir);
}

TEST(Pack, compressRoundTripsAndDecompressRefusesBadFrames) {
  // Version 1: its planes are what zstd is meant to shrink threefold.
  const auto raw = module::encode(module::samples::realistic(1, 2, 8, 2), {.version = module::kVersion});
  const auto packed = compress(raw, 9);
  ASSERT_FALSE(packed.empty());
  EXPECT_LT(packed.size(), raw.size() / 3);
  std::vector<std::byte> out;
  const Status whole = decompress(packed, static_cast<std::uint32_t>(raw.size()), out);
  ASSERT_TRUE(whole.ok()) << whole.error();
  EXPECT_EQ(out, raw);
  EXPECT_EQ(decompress(packed, static_cast<std::uint32_t>(raw.size() - 1), out).message(),
            "the frame holds " + std::to_string(raw.size()) + " bytes, the index says " +
                std::to_string(raw.size() - 1));
  EXPECT_EQ(decompress(std::span(raw).first(100), 100, out).message(), "not a zstd frame");
  const Status cut = decompress(std::span(packed).first(packed.size() - 1), static_cast<std::uint32_t>(raw.size()), out);
  EXPECT_FALSE(cut.ok());
  EXPECT_EQ(cut.message().rfind("zstd: ", 0), 0u) << cut.message();
  EXPECT_FALSE(decompress({}, 10, out).ok());
}

}  // namespace
}  // namespace sandtable::pack

namespace sandtable::pack {
namespace {

/// A pack's bytes served from memory as a web server would: `alter` reads
/// come back with one byte flipped (a damaged response) until refresh().
class MemoryRange final : public RangeSource {
 public:
  MemoryRange(std::vector<std::byte> bytes, int alter) : bytes_(std::move(bytes)), alter_(alter) {}
  const std::string& name() const override { return name_; }
  std::uint64_t size() const override { return bytes_.size(); }
  Status read(std::uint64_t off, std::span<std::byte> out) const override {
    ++reads;
    if (off + out.size() > bytes_.size()) return Problem{"", off, "past the end"};
    std::copy_n(bytes_.begin() + std::ptrdiff_t(off), out.size(), out.begin());
    if (off > 0 && alter_ > 0) out[out.size() / 2] ^= std::byte{0x40};
    return {};
  }
  void refresh(std::uint64_t, std::uint64_t) const override {
    ++refreshes;
    if (alter_ > 0) --alter_;
  }
  mutable int reads = 0, refreshes = 0;

 private:
  std::string name_ = "http://example.org/db/modules.pack";
  std::vector<std::byte> bytes_;
  mutable int alter_ = 0;
};

std::vector<std::byte> fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> b(s.size());
  std::memcpy(b.data(), s.data(), s.size());
  return b;
}

TEST(PackRemote, readsEveryModuleAsFromDiskAndFetchesADamagedRecordOnceMore) {
  const std::string dir = tempDir("remote");
  const IndexHeader h = smallHeader(2, 2);
  writePack(dir, h);
  auto local = PackReader::open(dir);
  ASSERT_TRUE(local.ok()) << local.error();
  const auto idx = fileBytes(dir + "/" + kIndexFileName), pk = fileBytes(dir + "/" + kPackFileName);
  // Sound: every module equals the local read.
  auto sound = std::make_shared<MemoryRange>(pk, 0);
  auto r = PackReader::openRemote(idx, "modules.idx", sound);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value()->packFd(), -1);
  for (std::uint32_t kz = 0; kz < 2; ++kz) {
    for (std::uint32_t kx = 0; kx < 2; ++kx) {
      auto a = local.value()->read(kx, kz), b = r.value()->read(kx, kz);
      ASSERT_TRUE(a.ok() && b.ok()) << b.error();
      EXPECT_EQ(module::encode(a.value()), module::encode(b.value()));
    }
  }
  EXPECT_EQ(sound->refreshes, 0);
  // One damaged response: fetched again after refresh(), then sound.
  auto once = std::make_shared<MemoryRange>(pk, 1);
  auto r1 = PackReader::openRemote(idx, "modules.idx", once);
  ASSERT_TRUE(r1.ok()) << r1.error();
  module::Module m;
  EXPECT_TRUE(r1.value()->readInto(1, 1, m).ok());
  EXPECT_EQ(once->refreshes, 1);
  // Damaged every time: the record's checksum error, naming the URL.
  auto always = std::make_shared<MemoryRange>(pk, 1000);
  auto r2 = PackReader::openRemote(idx, "modules.idx", always);
  ASSERT_TRUE(r2.ok()) << r2.error();
  const Status bad = r2.value()->readInto(1, 0, m);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().find("checksum mismatch"), std::string::npos) << bad.error();
  EXPECT_EQ(bad.problems()[0].file, "http://example.org/db/modules.pack");
  // A pack from another build (its size differs from the index's) is refused at open.
  auto shortPack = std::vector<std::byte>(pk.begin(), pk.end() - 10);
  auto r3 = PackReader::openRemote(idx, "modules.idx", std::make_shared<MemoryRange>(shortPack, 0));
  ASSERT_FALSE(r3.ok());
  EXPECT_NE(r3.error().find("truncated"), std::string::npos) << r3.error();
}

}  // namespace
}  // namespace sandtable::pack
