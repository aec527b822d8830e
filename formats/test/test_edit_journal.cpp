// Edit journal v1: golden bytes, every kind round trip, every truncated
// prefix, flipped and hostile bytes, the writer's batches, reopen and torn
// tails, and a writer killed with SIGKILL in the middle of a burst.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/edit_journal.h"

namespace sandtable::journal {
namespace {

namespace fs = std::filesystem;
using edit::Edit;
using edit::Kind;

std::string tempPath(const std::string& name) {
  return (fs::temp_directory_path() / ("st-journal-" + name + "." + std::to_string(::getpid()))).string();
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

std::vector<std::byte> fromHex(const std::string& s) {
  std::vector<std::byte> b;
  for (std::size_t k = 0; k + 1 < s.size(); k += 2) b.push_back(std::byte(std::stoi(s.substr(k, 2), nullptr, 16)));
  return b;
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

Edit goldenCrater() {
  Edit e;
  e.id = 1;
  e.time = 12.5;
  e.origin = 0x00010002;  // DIS site 1, application 2
  e.kind = Kind::crater;
  e.points = {{100.0, 200.0}};
  e.radius = 3.0;
  e.depth = 1.5;
  e.munition = 2;
  return e;
}

Edit goldenBerm() {
  Edit e;
  e.id = 2;
  e.time = 13.0;
  e.kind = Kind::berm;
  e.points = {{-8.0, 4.0}, {24.0, 4.0}};
  e.width = 2.0;
  e.height = 1.5;
  e.sideSlope = 0.5;
  return e;
}

// The golden journal, worked out field by field (docs/FORMAT.md §14.6):
// the header, then the crater and the berm written in one flush.
const std::string kGoldenHex =
    // header
    "53414e444a524e4c"  // 0 magic "SANDJRNL"
    "01000000"          // 8 version 1
    "18000000"          // 12 header_bytes 24
    "00000000"          // 16 flags 0
    "73647a07"          // 20 header_crc 0x077a6473: CRC-32 of bytes 0..19
    // record 0 at 24: the crater
    "75000000"          // 24 payload_bytes 117 = 101 + 1 point x 16
    "1800000000000000"  // 28 batch_start 24: its write began at byte 24
    "b0f0e440"          // 36 payload_crc 0x40e4f0b0: CRC-32 of bytes 44..160
    "6af4e8a7"          // 40 head_crc 0xa7e8f46a: CRC-32 of bytes 24..39
    "0100000000000000"  // 44 id 1
    "0000000000002940"  // 52 time 12.5
    "02000100"          // 60 origin 0x00010002
    "01"                // 64 kind 1, crater
    "0000000000000840"  // 65 radius 3.0
    "000000000000f83f"  // 73 depth 1.5
    "0000000000000000"  // 81 width 0
    "0000000000000000"  // 89 height 0
    "0000000000000000"  // 97 sideSlope 0
    "0000"              // 105 icon 0
    "0000000000000000"  // 107 heading 0
    "000000000000f03f"  // 115 scale 1.0
    "00000000"          // 123 moduleX 0
    "00000000"          // 127 moduleZ 0
    "0000000000000000"  // 131 object 0
    "0200"              // 139 munition 2
    "01000000"          // 141 point_count 1
    "0000000000005940"  // 145 points[0] x 100.0
    "0000000000006940"  // 153 points[0] z 200.0
    // record 1 at 161: the berm
    "85000000"          // 161 payload_bytes 133 = 101 + 2 points x 16
    "1800000000000000"  // 165 batch_start 24: the same write as the crater
    "73624020"          // 173 payload_crc 0x20406273: CRC-32 of bytes 181..313
    "449fc539"          // 177 head_crc 0x39c59f44: CRC-32 of bytes 161..176
    "0200000000000000"  // 181 id 2
    "0000000000002a40"  // 189 time 13.0
    "00000000"          // 197 origin 0, this process
    "02"                // 201 kind 2, berm
    "0000000000000000"  // 202 radius 0
    "0000000000000000"  // 210 depth 0
    "0000000000000040"  // 218 width 2.0, the crest
    "000000000000f83f"  // 226 height 1.5
    "000000000000e03f"  // 234 sideSlope 0.5
    "0000"              // 242 icon 0
    "0000000000000000"  // 244 heading 0
    "000000000000f03f"  // 252 scale 1.0
    "00000000"          // 260 moduleX 0
    "00000000"          // 264 moduleZ 0
    "0000000000000000"  // 268 object 0
    "0000"              // 276 munition 0
    "02000000"          // 278 point_count 2
    "00000000000020c0"  // 282 points[0] x -8.0
    "0000000000001040"  // 290 points[0] z 4.0
    "0000000000003840"  // 298 points[1] x 24.0
    "0000000000001040"; // 306 points[1] z 4.0; the file ends at 314

constexpr std::uint64_t kCraterAt = 24, kBermAt = 161, kGoldenEnd = 314;

/// One edit of every kind, with every field that kind uses set.
std::vector<Edit> everyKind() {
  std::vector<Edit> v;
  v.push_back(goldenCrater());
  v.push_back(goldenBerm());
  Edit ditch = goldenBerm();
  ditch.id = 3;
  ditch.kind = Kind::ditch;
  ditch.points = {{0.5, 0.25}, {10.125, -3.0}, {20.0, 7.75}};
  ditch.width = 0.0;  // a V ditch: no floor
  ditch.height = 2.5;
  ditch.sideSlope = 1.0;
  v.push_back(ditch);
  Edit flatten;
  flatten.id = 4;
  flatten.kind = Kind::flatten;
  flatten.points = {{0, 0}, {30, 0}, {30, 20}, {0, 20}};
  flatten.height = -12.375;
  flatten.sideSlope = 0.2;
  v.push_back(flatten);
  Edit add;
  add.id = 5;
  add.kind = Kind::addObject;
  add.points = {{1234.5, 678.25}};
  add.icon = 17;
  add.heading = 1.25;
  add.scale = 2.0;
  v.push_back(add);
  Edit remove;
  remove.id = 6;
  remove.kind = Kind::removeObject;
  remove.moduleX = 3;
  remove.moduleZ = 4;
  remove.object = 0x0123456789abcdefull;
  v.push_back(remove);
  Edit sw = remove;
  sw.id = 7;
  sw.kind = Kind::switchObject;
  sw.icon = 65535;
  v.push_back(sw);
  Edit scale = remove;
  scale.id = 8;
  scale.kind = Kind::scaleObject;
  scale.scale = 0.5;
  v.push_back(scale);
  // Extremes of every field's range; -0.0 and a denormal come back bit for bit.
  Edit far = goldenCrater();
  far.id = std::numeric_limits<std::uint64_t>::max();
  far.time = -0.0;
  far.origin = 0xffffffffu;
  far.points = {{std::numeric_limits<double>::denorm_min(), -1e300}};
  far.radius = std::numeric_limits<double>::max();
  far.depth = std::numeric_limits<double>::min();
  far.munition = 65535;
  v.push_back(far);
  return v;
}

std::vector<std::byte> encoded(const std::vector<Edit>& edits, std::uint64_t batchStart = kHeaderBytes) {
  std::vector<std::byte> b = encodeHeader();
  for (const Edit& e : edits) {
    EXPECT_EQ(encodeRecord(e, batchStart, b).message(), "");
  }
  return b;
}

/// Writes `edits` through a JournalWriter, one flush per `perFlush` edits.
void writeJournal(const std::string& path, const std::vector<Edit>& edits, std::size_t perFlush) {
  fs::remove(path);
  auto w = JournalWriter::open(path);
  ASSERT_TRUE(w.ok()) << w.error();
  for (std::size_t k = 0; k < edits.size(); ++k) {
    ASSERT_EQ(w.value()->append(edits[k]).message(), "");
    if ((k + 1) % perFlush == 0) {
      ASSERT_EQ(w.value()->flush().message(), "");
    }
  }
  ASSERT_EQ(w.value()->close().message(), "");
}

/// Record offsets of a journal of whole records (from their payload sizes).
std::vector<std::uint64_t> recordOffsets(std::span<const std::byte> b) {
  std::vector<std::uint64_t> at;
  for (std::uint64_t off = kHeaderBytes; off + kRecordHeadBytes <= b.size();
       off += kRecordHeadBytes + loadLE<std::uint32_t>(b.data() + off)) {
    at.push_back(off);
  }
  return at;
}

/// Recomputes the payload and head CRCs of the record at `off`, whose
/// payload size field is trusted where the bytes allow.
void reseal(std::vector<std::byte>& b, std::uint64_t off) {
  std::byte* r = b.data() + off;
  const std::uint64_t n = loadLE<std::uint32_t>(r + headField::payloadBytes);
  if (off + kRecordHeadBytes + n <= b.size()) {
    storeLE<std::uint32_t>(r + headField::payloadCrc, crc32(std::span(r + kRecordHeadBytes, n)));
  }
  storeLE<std::uint32_t>(r + headField::headCrc, crc32(std::span(r, headField::headCrc)));
}

TEST(EditJournal, layoutConstantsArePinned) {
  EXPECT_EQ(kHeaderBytes, 24u);
  EXPECT_EQ(kRecordHeadBytes, 20u);
  EXPECT_EQ(kFixedPayloadBytes, 101u);
  EXPECT_EQ(payloadField::munition, 95u);
  EXPECT_EQ(kMaxPayloadBytes, 101u + 16u * 65536u);
  EXPECT_EQ(maxPoints(Kind::crater), 1u);
  EXPECT_EQ(maxPoints(Kind::flatten), 65536u);
  EXPECT_EQ(maxPoints(Kind(0)), 0u);
}

// Golden bytes of version 1. If this fails, the format changed: bump
// kVersion, keep a reader for version 1, and add a new golden test.
TEST(EditJournal, version1GoldenBytes) {
  const auto golden = fromHex(kGoldenHex);
  ASSERT_EQ(golden.size(), kGoldenEnd);
  // The CRCs the comments give, computed here by zlib from the hand-written bytes.
  EXPECT_EQ(crcHex(crc32(std::span(golden).first(20))), "0x077a6473");
  EXPECT_EQ(crcHex(crc32(std::span(golden).subspan(44, 117))), "0x40e4f0b0");
  EXPECT_EQ(crcHex(crc32(std::span(golden).subspan(24, 16))), "0xa7e8f46a");
  EXPECT_EQ(crcHex(crc32(std::span(golden).subspan(181, 133))), "0x20406273");
  EXPECT_EQ(crcHex(crc32(std::span(golden).subspan(161, 16))), "0x39c59f44");
  EXPECT_EQ(crcHex(crc32(golden)), "0xc109bbd5");

  // The encoder writes exactly these bytes...
  EXPECT_EQ(hex(encoded({goldenCrater(), goldenBerm()})), kGoldenHex);
  // ...and so does the writer, the two edits in one flush.
  const std::string path = tempPath("golden");
  writeJournal(path, {goldenCrater(), goldenBerm()}, 2);
  EXPECT_EQ(hex(readAll(path)), kGoldenHex);
  // The reader gives the two edits back.
  auto j = readJournal(path);
  ASSERT_TRUE(j.ok()) << j.error();
  EXPECT_EQ(j->edits, (std::vector<Edit>{goldenCrater(), goldenBerm()}));
  EXPECT_TRUE(j->warnings.empty());
  EXPECT_EQ(j->validBytes, kGoldenEnd);
  auto r = decodeRecord(std::span(golden).subspan(kBermAt), path, kBermAt);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r->edit, goldenBerm());
  EXPECT_EQ(r->batchStart, 24u);
  EXPECT_EQ(r->bytes, kGoldenEnd - kBermAt);
  fs::remove(path);
}

TEST(EditJournal, everyKindRoundTripsBitForBit) {
  const std::string path = tempPath("kinds");
  const auto edits = everyKind();
  writeJournal(path, edits, 3);
  auto j = readJournal(path);
  ASSERT_TRUE(j.ok()) << j.error();
  ASSERT_EQ(j->edits.size(), edits.size());
  for (std::size_t k = 0; k < edits.size(); ++k) EXPECT_EQ(j->edits[k], edits[k]) << "edit " << k;
  EXPECT_TRUE(std::signbit(j->edits.back().time));  // -0.0, not 0.0
  EXPECT_EQ(j->validBytes, fs::file_size(path));
  fs::remove(path);
}

TEST(EditJournal, encoderRefusesWhatTheReaderWouldRefuse) {
  std::vector<std::byte> out;
  Edit bad = goldenCrater();
  bad.radius = -1;
  EXPECT_EQ(encodeRecord(bad, kHeaderBytes, out).message(), "edit: crater: Edit::radius must be > 0 (got -1)");
  Edit two = goldenCrater();
  two.points.push_back({1, 2});
  EXPECT_EQ(encodeRecord(two, kHeaderBytes, out).message(), "edit: crater: Edit::points needs at least 1 (got 2)");
  Edit many = goldenBerm();
  many.points.assign(kMaxLinePoints + 1, {1.0, 2.0});
  EXPECT_EQ(encodeRecord(many, kHeaderBytes, out).message(),
            "journal: a berm holds at most 65536 points, this edit has 65537");
  Edit located;
  located.kind = Kind::removeObject;
  located.points = {{1, 2}, {3, 4}};
  EXPECT_EQ(encodeRecord(located, kHeaderBytes, out).message(),
            "journal: a remove-object holds at most 1 points, this edit has 2");
  EXPECT_TRUE(out.empty());
  // The most points a berm holds fit, and come back.
  many.points.resize(kMaxLinePoints);
  ASSERT_EQ(encodeRecord(many, kHeaderBytes, out).message(), "");
  EXPECT_EQ(out.size(), kRecordHeadBytes + kMaxPayloadBytes);
  auto r = decodeRecord(out, "big", kHeaderBytes);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r->edit, many);
}

// A crash can stop a write anywhere: every prefix of a journal is read as
// its whole records, with a warning where the cut fell inside one.
TEST(EditJournal, everyTruncatedPrefixIsCutAtTheLastWholeRecord) {
  const auto edits = std::vector<Edit>{goldenCrater(), goldenBerm(), everyKind()[3]};
  const auto bytes = encoded(edits);
  const auto ends = [&] {
    auto at = recordOffsets(bytes);
    at.push_back(bytes.size());
    return at;
  }();
  ASSERT_EQ(ends.size(), 4u);
  for (std::size_t n = 0; n <= bytes.size(); ++n) {
    auto j = decodeJournal(std::span(bytes).first(n), "cut.journal");
    if (n < kHeaderBytes) {
      ASSERT_FALSE(j.ok()) << n;
      EXPECT_EQ(j.problems().front().str(), "cut.journal @" + std::to_string(n) +
                                                ": journal: truncated header: the header needs 24 bytes, the file "
                                                "ends at byte " + std::to_string(n));
      continue;
    }
    ASSERT_TRUE(j.ok()) << n << ": " << j.error();
    std::size_t whole = 0;
    while (whole < edits.size() && ends[whole + 1] <= n) ++whole;
    const std::uint64_t cut = ends[whole];
    EXPECT_EQ(j->validBytes, cut) << n;
    ASSERT_EQ(j->edits.size(), whole) << n;
    for (std::size_t k = 0; k < whole; ++k) EXPECT_EQ(j->edits[k], edits[k]);
    if (cut == n) {
      EXPECT_TRUE(j->warnings.empty()) << n;
      continue;
    }
    ASSERT_EQ(j->warnings.size(), 1u) << n;
    const Problem& w = j->warnings.front();
    EXPECT_EQ(w.file, "cut.journal");
    EXPECT_EQ(w.offset, cut);
    EXPECT_EQ(w.message.rfind("journal: torn tail at byte " + std::to_string(cut) + ": ", 0), 0u) << w.message;
    const std::string kept = std::to_string(n - cut) + " bytes dropped, " + std::to_string(whole) + " edits kept)";
    EXPECT_NE(w.message.find(kept), std::string::npos) << w.message;
  }
  // The messages of a cut head and a cut payload.
  auto head = decodeJournal(std::span(bytes).first(kBermAt + 7), "f");
  ASSERT_TRUE(head.ok());
  EXPECT_EQ(head->warnings.front().message,
            "journal: torn tail at byte 161: the record's head needs 20 bytes, the file ends at byte 168; cut at the "
            "last whole record (7 bytes dropped, 1 edits kept): a write that a crash cut short");
  auto payload = decodeJournal(std::span(bytes).first(kBermAt + 30), "f");
  ASSERT_TRUE(payload.ok());
  EXPECT_EQ(payload->warnings.front().message,
            "journal: torn tail at byte 161: the payload needs 133 bytes, the file ends at byte 191 (10 there); cut "
            "at the last whole record (30 bytes dropped, 1 edits kept): a write that a crash cut short");
}

// Three records in three flushes: a flipped byte in the first or the
// second is damage to durable edits, named with its record's offset; in the
// last it may be a write a crash cut short, so it is cut with a warning.
TEST(EditJournal, flippedBytesBeforeTheTailAreAProblemWithTheOffset) {
  const std::string path = tempPath("flip");
  const auto edits = std::vector<Edit>{goldenCrater(), goldenBerm(), everyKind()[2]};
  writeJournal(path, edits, 1);
  const auto good = readAll(path);
  const auto at = recordOffsets(good);
  ASSERT_EQ(at.size(), 3u);
  for (std::uint64_t k = kHeaderBytes; k < good.size(); ++k) {
    auto bad = good;
    bad[k] ^= std::byte{0x20};
    auto j = decodeJournal(bad, path);
    if (k < at[2]) {
      const std::uint64_t record = k < at[1] ? at[0] : at[1];
      ASSERT_FALSE(j.ok()) << "byte " << k;
      const Problem& p = j.problems().front();
      EXPECT_EQ(p.file, path);
      EXPECT_EQ(p.offset, record) << "byte " << k;
      EXPECT_EQ(p.message.rfind("journal: record at byte " + std::to_string(record) + ": ", 0), 0u) << p.message;
      EXPECT_NE(p.message.find("checksum mismatch"), std::string::npos) << p.message;
      EXPECT_NE(p.message.find("the journal is corrupt before its end"), std::string::npos) << p.message;
    } else {
      ASSERT_TRUE(j.ok()) << "byte " << k << ": " << j.error();
      EXPECT_EQ(j->edits.size(), 2u);
      EXPECT_EQ(j->validBytes, at[2]);
      ASSERT_EQ(j->warnings.size(), 1u);
      EXPECT_EQ(j->warnings.front().offset, at[2]);
    }
  }
  // The whole message, for a flipped payload byte of the crater.
  auto bad = good;
  bad[kCraterAt + 30] ^= std::byte{1};
  auto j = decodeJournal(bad, "f");
  ASSERT_FALSE(j.ok());
  EXPECT_EQ(j.problems().front().str(),
            "f @24: journal: record at byte 24: payload checksum mismatch (stored 0x40e4f0b0, computed " +
                crcHex(crc32(std::span(bad).subspan(44, 117))) + "); a record of a later write (it began at byte 161) follows at byte 161, so this is damage to "
                "flushed edits, not a tail a crash cut short: the journal is corrupt before its end");
  fs::remove(path);
}

// Power lost during one write may leave any of its pages unwritten: the
// records of that write after a damaged one were never durable, so the
// journal is cut at the damage with a warning (FORMAT.md §14.4).
TEST(EditJournal, damageInsideTheLastWriteIsATornTail) {
  const auto bytes = encoded({goldenCrater(), goldenBerm(), everyKind()[2]});  // one write from byte 24
  for (std::uint64_t k = kHeaderBytes; k < kBermAt; ++k) {
    auto bad = bytes;
    bad[k] = std::byte{0};  // a page never written reads as zeros
    if (bad[k] == bytes[k]) continue;
    auto j = decodeJournal(bad, "f");
    ASSERT_TRUE(j.ok()) << k << ": " << j.error();
    EXPECT_TRUE(j->edits.empty());
    EXPECT_EQ(j->validBytes, kCraterAt);
    ASSERT_EQ(j->warnings.size(), 1u);
    EXPECT_EQ(j->warnings.front().offset, kCraterAt);
  }
}

struct Hostile {
  const char* name;
  std::uint64_t at;   ///< where the change goes
  std::uint64_t value;
  int width;          ///< bytes
  std::string message;  ///< the whole first problem, "file @offset: message"
};

// Whole records (resealed after the change) whose fields break a rule: a
// writer wrote them, so each is a problem wherever it lies, at its field.
TEST(EditJournal, hostileFieldsGiveTheirMessagesBeforeAllocating) {
  const auto golden = fromHex(kGoldenHex);
  const std::uint64_t crater = kCraterAt + kRecordHeadBytes, berm = kBermAt + kRecordHeadBytes;
  const Hostile cases[] = {
      {"kind 0", crater + payloadField::kind, 0, 1, "h @64: journal: record at byte 24: kind 0 is unknown (1 to 8)"},
      {"kind 9", berm + payloadField::kind, 9, 1, "h @201: journal: record at byte 161: kind 9 is unknown (1 to 8)"},
      {"crater count huge", crater + payloadField::pointCount, 0xffffffffu, 4,
       "h @141: journal: record at byte 24: point count 4294967295 is more than a crater holds (1)"},
      {"berm count huge", berm + payloadField::pointCount, 0xffffffffu, 4,
       "h @278: journal: record at byte 161: point count 4294967295 is more than a berm holds (65536)"},
      {"berm count over the cap", berm + payloadField::pointCount, 65537, 4,
       "h @278: journal: record at byte 161: point count 65537 is more than a berm holds (65536)"},
      {"berm count past its payload", berm + payloadField::pointCount, 3, 4,
       "h @278: journal: record at byte 161: point count 3 needs 48 bytes of points, the payload holds 32"},
      {"berm count short of its payload", berm + payloadField::pointCount, 1, 4,
       "h @278: journal: record at byte 161: point count 1 needs 16 bytes of points, the payload holds 32"},
      {"crater without a point", crater + payloadField::pointCount, 0, 4,
       "h @141: journal: record at byte 24: point count 0 needs 0 bytes of points, the payload holds 16"},
      {"negative radius", crater + payloadField::radius, 0xbff0000000000000ull, 8,
       "h @24: journal: record at byte 24: edit: crater: Edit::radius must be > 0 (got -1)"},
      {"NaN time", berm + payloadField::time, 0x7ff8000000000000ull, 8,
       "h @161: journal: record at byte 161: edit: berm: Edit::time must be finite (got nan)"},
      {"batch start in the header", kCraterAt + headField::batchStart, 23, 8,
       "h @28: journal: record at byte 24: batch start 23 is not between the header's end (24) and the record"},
      {"batch start after the record", kBermAt + headField::batchStart, 162, 8,
       "h @165: journal: record at byte 161: batch start 162 is not between the header's end (24) and the record"},
      {"batch start of no write", kBermAt + headField::batchStart, 100, 8,
       "h @165: journal: record at byte 161: batch start 100 is neither the record's own offset nor the previous "
       "record's batch start (24); the records of one write share its start"},
  };
  for (const Hostile& c : cases) {
    auto b = golden;
    for (int k = 0; k < c.width; ++k) b[c.at + k] = std::byte((c.value >> (8 * k)) & 0xff);
    reseal(b, kCraterAt);
    reseal(b, kBermAt);
    auto j = decodeJournal(b, "h");
    ASSERT_FALSE(j.ok()) << c.name;
    EXPECT_EQ(j.problems().front().str(), c.message) << c.name;
  }
  // The header's fields (resealed but for the checksum case).
  struct HeaderCase {
    std::uint64_t at, value;
    bool seal;
    std::string message;
  };
  const HeaderCase headers[] = {
      {0, 0x58, true, "h @0: journal: bad magic: not a sandtable edit journal (expected \"SANDJRNL\")"},
      {8, 2, true, "h @8: journal: version 2 is not supported (this reader knows version 1); use a matching sandtable"},
      {12, 32, true, "h @12: journal: header size 32 must be 24"},
      {16, 1, true, "h @16: journal: flags 0x00000001 are not zero; version 1 defines none"},
      {16, 1, false,
       "h @20: journal: header checksum mismatch (stored 0x077a6473, computed 0xbfc60316): the header is corrupt"},
  };
  for (const HeaderCase& c : headers) {
    auto b = golden;
    b[c.at] = std::byte(c.value);
    if (c.seal) storeLE<std::uint32_t>(b.data() + 20, crc32(std::span(b).first(20)));
    auto j = decodeJournal(b, "h");
    ASSERT_FALSE(j.ok()) << c.at;
    EXPECT_EQ(j.problems().front().str(), c.message);
  }
}

// Hostile sizes in a head whose own CRC holds: refused before the payload is
// read or anything sized by them, as one record and in a journal.
TEST(EditJournal, hostilePayloadSizesAreRefused) {
  const auto golden = fromHex(kGoldenHex);
  for (const std::uint32_t size : {0u, 100u, kMaxPayloadBytes + 1, 0xffffffffu}) {
    auto b = golden;
    storeLE<std::uint32_t>(b.data() + kBermAt, size);
    reseal(b, kBermAt);
    auto r = decodeRecord(std::span(b).subspan(kBermAt), "h", kBermAt);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.problems().front().str(), "h @161: journal: record at byte 161: payload size " + std::to_string(size) +
                                              " is out of range (101 to 1048677)");
    // The last record: a torn tail (a head whose size is wrong is not whole).
    auto j = decodeJournal(b, "h");
    ASSERT_TRUE(j.ok()) << j.error();
    EXPECT_EQ(j->edits.size(), 1u);
    EXPECT_EQ(j->validBytes, kBermAt);
  }
  // A size in range that runs past the end of the record's bytes.
  auto b = golden;
  storeLE<std::uint32_t>(b.data() + kBermAt, kMaxPayloadBytes);
  reseal(b, kBermAt);
  auto r = decodeRecord(std::span(b).subspan(kBermAt), "h", kBermAt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.problems().front().message,
            "journal: record at byte 161: the payload needs 1048677 bytes, the file ends at byte 314 (133 there)");
}

TEST(EditJournal, readerNamesAMissingOrOversizedFile) {
  const std::string missing = tempPath("missing");
  auto j = readJournal(missing);
  ASSERT_FALSE(j.ok());
  EXPECT_EQ(j.problems().front().file, missing);
  EXPECT_EQ(j.problems().front().message.rfind("journal: cannot open: ", 0), 0u) << j.error();
  // A sparse file one byte over the limit is refused before it is read.
  const std::string big = tempPath("big");
  { std::ofstream(big, std::ios::binary); }
  fs::resize_file(big, kMaxFileBytes + 1);
  auto b = readJournal(big);
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.problems().front().str(), big + " @0: journal: file is 1073741825 bytes, more than the 1073741824 allowed");
  fs::remove(big);
  EXPECT_EQ(defaultPath("/data/db"), "/data/db/edits.journal");
}

// ---------------------------------------------------------------- writer

/// A clock the test moves by hand.
struct FakeClock {
  std::chrono::steady_clock::time_point t{};
  WriterOptions options(std::size_t records, int ms) {
    WriterOptions o;
    o.batchRecords = records;
    o.batchDelay = std::chrono::milliseconds(ms);
    o.now = [this] { return t; };
    return o;
  }
};

TEST(EditJournal, writerFlushesWhenTheBatchIsFullOrDue) {
  const std::string path = tempPath("batch");
  fs::remove(path);
  FakeClock clock;
  auto w = JournalWriter::open(path, clock.options(3, 50));
  ASSERT_TRUE(w.ok()) << w.error();
  JournalWriter& j = *w.value();
  EXPECT_EQ(fs::file_size(path), kHeaderBytes);  // created with its header, durable
  const auto edits = everyKind();
  ASSERT_EQ(j.append(edits[0]).message(), "");
  ASSERT_EQ(j.append(edits[1]).message(), "");
  EXPECT_EQ(j.waiting(), 2u);
  EXPECT_EQ(fs::file_size(path), kHeaderBytes);  // nothing written before a flush
  ASSERT_EQ(j.append(edits[2]).message(), "");  // the third fills the batch
  EXPECT_EQ(j.waiting(), 0u);
  EXPECT_EQ(j.flushedRecords(), 3u);
  EXPECT_EQ(fs::file_size(path), j.durableBytes());
  // By time: 49 ms is not due, 50 ms is.
  ASSERT_EQ(j.append(edits[3]).message(), "");
  clock.t += std::chrono::milliseconds(49);
  ASSERT_EQ(j.flushIfDue().message(), "");
  EXPECT_EQ(j.waiting(), 1u);
  clock.t += std::chrono::milliseconds(1);
  ASSERT_EQ(j.flushIfDue().message(), "");
  EXPECT_EQ(j.waiting(), 0u);
  // An append that finds the oldest waiting record due flushes both.
  ASSERT_EQ(j.append(edits[4]).message(), "");
  clock.t += std::chrono::milliseconds(60);
  ASSERT_EQ(j.append(edits[5]).message(), "");
  EXPECT_EQ(j.waiting(), 0u);
  EXPECT_EQ(j.flushedRecords(), 6u);
  // A refused edit waits nowhere.
  Edit bad = edits[0];
  bad.depth = 0;
  EXPECT_EQ(j.append(bad).error(), path + " @" + std::to_string(j.durableBytes()) +
                                     ": edit: crater: Edit::depth must be > 0 (got 0)");
  EXPECT_EQ(j.waiting(), 0u);
  ASSERT_EQ(j.append(edits[6]).message(), "");
  EXPECT_EQ(j.close().message(), "");  // close flushes
  EXPECT_EQ(j.append(edits[7]).message(), "journal writer: the journal is closed");
  auto read = readJournal(path);
  ASSERT_TRUE(read.ok()) << read.error();
  EXPECT_EQ(read->edits, std::vector<Edit>(edits.begin(), edits.begin() + 7));
  fs::remove(path);
}

TEST(EditJournal, writerAppendsAfterReopen) {
  const std::string path = tempPath("reopen");
  const auto edits = everyKind();
  writeJournal(path, {edits[0], edits[1]}, 2);
  {
    auto w = JournalWriter::open(path);
    ASSERT_TRUE(w.ok()) << w.error();
    EXPECT_TRUE(w.warnings().empty());
    EXPECT_EQ(w.value()->editsAtOpen(), 2u);
    EXPECT_EQ(w.value()->durableBytes(), fs::file_size(path));
    ASSERT_EQ(w.value()->append(edits[2]).message(), "");
    ASSERT_EQ(w.value()->append(edits[3]).message(), "");
  }  // the destructor flushes
  auto j = readJournal(path);
  ASSERT_TRUE(j.ok()) << j.error();
  EXPECT_EQ(j->edits, std::vector<Edit>(edits.begin(), edits.begin() + 4));
  EXPECT_TRUE(j->warnings.empty());
  fs::remove(path);
}

TEST(EditJournal, writerCutsATornTailOnReopen) {
  const std::string path = tempPath("torn");
  const auto edits = everyKind();
  writeJournal(path, {edits[0], edits[1], edits[2]}, 1);
  const auto whole = readAll(path);
  const auto at = recordOffsets(whole);
  // A crash in the middle of the third record's write.
  writeAll(path, std::span(whole).first(at[2] + 25));
  auto w = JournalWriter::open(path);
  ASSERT_TRUE(w.ok()) << w.error();
  ASSERT_EQ(w.warnings().size(), 2u);
  EXPECT_EQ(w.warnings()[0].str(), path + " @" + std::to_string(at[2]) + ": journal: torn tail at byte " +
                                       std::to_string(at[2]) + ": the payload needs 149 bytes, the file ends at byte " +
                                       std::to_string(at[2] + 25) +
                                       " (5 there); cut at the last whole record (25 bytes dropped, 2 edits kept): a "
                                       "write that a crash cut short");
  EXPECT_EQ(w.warnings()[1].str(), path + " @" + std::to_string(at[2]) + ": journal writer: truncated the journal to " +
                                       std::to_string(at[2]) + " bytes (from " + std::to_string(at[2] + 25) +
                                       "); appending after its last whole record");
  EXPECT_EQ(fs::file_size(path), at[2]);
  EXPECT_EQ(w.value()->editsAtOpen(), 2u);
  ASSERT_EQ(w.value()->append(edits[3]).message(), "");
  ASSERT_EQ(w.value()->close().message(), "");
  auto j = readJournal(path);
  ASSERT_TRUE(j.ok()) << j.error();
  EXPECT_TRUE(j->warnings.empty());
  EXPECT_EQ(j->edits, (std::vector<Edit>{edits[0], edits[1], edits[3]}));
  fs::remove(path);
}

TEST(EditJournal, writerRefusesADamagedJournalAndASecondWriter) {
  const std::string path = tempPath("refuse");
  writeJournal(path, {goldenCrater(), goldenBerm()}, 1);
  {
    auto first = JournalWriter::open(path);
    ASSERT_TRUE(first.ok()) << first.error();
    auto second = JournalWriter::open(path);
    ASSERT_FALSE(second.ok());
    EXPECT_EQ(second.problems().front().str(),
              path + " @0: journal writer: another writer holds the journal (one writer at a time)");
  }
  auto bytes = readAll(path);
  bytes[kCraterAt + 50] ^= std::byte{4};
  writeAll(path, bytes);
  auto w = JournalWriter::open(path);
  ASSERT_FALSE(w.ok());
  EXPECT_EQ(w.problems().front().offset, kCraterAt);
  EXPECT_EQ(fs::file_size(path), bytes.size());  // left as it was for a person to look at
  std::vector<std::byte> notAJournal(40, std::byte{'x'});
  writeAll(path, notAJournal);
  auto x = JournalWriter::open(path);
  ASSERT_FALSE(x.ok());
  EXPECT_EQ(x.problems().front().message,
            "journal: bad magic: not a sandtable edit journal (expected \"SANDJRNL\")");
  fs::remove(path);
}

/// The i-th edit of the burst below: a crater or a berm, every field from i.
Edit burstEdit(std::uint64_t i) {
  Edit e = i % 3 == 2 ? goldenBerm() : goldenCrater();
  e.id = i;
  e.time = 0.01 * double(i);
  e.points[0] = {double(i), -double(i) / 7.0};
  if (e.kind == Kind::crater) e.radius = 1.0 + double(i % 13);
  return e;
}

// A writer killed with SIGKILL in the middle of a burst: the journal holds
// at least every record its flushes reported durable, then nothing but a
// prefix of what it appended, and it replays to its last whole record.
TEST(EditJournal, killedWriterLeavesAPrefixOfItsEdits) {
  const std::string path = tempPath("kill");
  fs::remove(path);
  int pipefd[2];
  ASSERT_EQ(::pipe(pipefd), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::close(pipefd[0]);
    // Batches of 7 flushed by the writer, and an explicit flush every 50:
    // after each, the count made durable goes to the parent.
    WriterOptions o;
    o.batchRecords = 7;
    auto w = JournalWriter::open(path, o);
    if (!w) ::_exit(3);
    for (std::uint64_t i = 0;; ++i) {
      if (!w.value()->append(burstEdit(i))) ::_exit(4);
      if (i % 50 == 49 && !w.value()->flush()) ::_exit(5);
      const std::uint64_t durable = w.value()->flushedRecords();
      if (w.value()->waiting() == 0 && ::write(pipefd[1], &durable, sizeof durable) != sizeof durable) ::_exit(6);
    }
  }
  ::close(pipefd[1]);
  // Kill it once it has made 2,000 records durable, in the middle of what follows.
  std::uint64_t reported = 0, n = 0;
  while (reported < 2000 && ::read(pipefd[0], &n, sizeof n) == sizeof n) reported = n;
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the child exited by itself: " << status;
  while (::read(pipefd[0], &n, sizeof n) == sizeof n) reported = n;  // what it sent before it died
  ::close(pipefd[0]);
  auto j = readJournal(path);
  ASSERT_TRUE(j.ok()) << j.error();
  EXPECT_GE(j->edits.size(), reported);
  for (std::size_t k = 0; k < j->edits.size(); ++k) ASSERT_EQ(j->edits[k], burstEdit(k)) << k;
  EXPECT_LE(j->warnings.size(), 1u);
  EXPECT_LE(j->validBytes, fs::file_size(path));
  // Reopened, it continues after the last whole record.
  auto w = JournalWriter::open(path);
  ASSERT_TRUE(w.ok()) << w.error();
  EXPECT_EQ(w.value()->editsAtOpen(), j->edits.size());
  ASSERT_EQ(w.value()->append(burstEdit(j->edits.size())).message(), "");
  ASSERT_EQ(w.value()->close().message(), "");
  auto again = readJournal(path);
  ASSERT_TRUE(again.ok()) << again.error();
  EXPECT_TRUE(again->warnings.empty());
  EXPECT_EQ(again->edits.size(), j->edits.size() + 1);
  fs::remove(path);
}

}  // namespace
}  // namespace sandtable::journal
