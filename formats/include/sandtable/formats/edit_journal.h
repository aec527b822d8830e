#pragma once
// The edit journal, version 1 (docs/FORMAT.md §14): every edit applied to a
// database's ground, in the order it was applied, so that a later run (fly,
// sim, `edits bake`) replays it to the same heights. It lies beside the
// database (defaultPath: <db>/edits.journal) or wherever --journal says.
//
// Layout, little-endian: a 24-byte header (magic "SANDJRNL", version,
// header size, flags, header CRC), then records back to back. A record is a
// 20-byte head (payload size, the offset where the write that holds it
// began, the payload's CRC-32, the head's own CRC-32) and a payload holding
// every field of an edit::Edit, its points last.
//
// Durability: JournalWriter appends records in batches, each batch with one
// write and one fdatasync, so a crash (kill -9, power loss) leaves at most
// the last batch incomplete: a torn tail. readJournal cuts a torn tail at the
// last whole record with a warning; damage anywhere before it is a problem,
// never edits silently dropped from the middle. Each record carries the
// offset where its batch's write began (`batchStart`), which is how the
// reader tells the two apart (FORMAT.md §14.4).
//
// Thread safety: the free functions are pure (readJournal reads a file) and
// may run on any thread. A JournalWriter is used by one thread (the editor
// that applies edits in order); it holds an exclusive flock on the file,
// so a second writer, in this process or another, is refused. Readers in
// other processes may read the file at any time and see a prefix of it,
// possibly with a torn tail.
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/edit.h"

namespace sandtable::journal {

/// The journal's name beside a database.
inline constexpr const char* kFileName = "edits.journal";
/// `<databaseDir>/edits.journal`: the journal beside the database.
std::string defaultPath(const std::string& databaseDir);

inline constexpr std::array<char, 8> kMagic = {'S', 'A', 'N', 'D', 'J', 'R', 'N', 'L'};
inline constexpr std::uint32_t kVersion = 1;
inline constexpr std::uint32_t kHeaderBytes = 24;
inline constexpr std::uint32_t kRecordHeadBytes = 20;
/// The payload's fixed fields; the points follow, 16 bytes each.
inline constexpr std::uint32_t kFixedPayloadBytes = 101;
inline constexpr std::uint32_t kPointBytes = 16;
/// Most points of a berm, ditch or flatten polygon; crater and the object
/// kinds hold at most one.
inline constexpr std::uint32_t kMaxLinePoints = 1u << 16;
inline constexpr std::uint32_t kMaxPayloadBytes = kFixedPayloadBytes + kPointBytes * kMaxLinePoints;
/// readJournal refuses a larger file before reading it (about ten million
/// craters).
inline constexpr std::uint64_t kMaxFileBytes = 1ull << 30;

/// Byte offsets of the header fields.
namespace headerField {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, flags = 16, headerCrc = 20;
}
/// Byte offsets of a record head's fields, from the record's start.
namespace headField {
inline constexpr std::size_t payloadBytes = 0, batchStart = 4, payloadCrc = 12, headCrc = 16;
}
/// Byte offsets of the payload's fields, from the payload's start.
namespace payloadField {
inline constexpr std::size_t id = 0, time = 8, origin = 16, kind = 20, radius = 21, depth = 29, width = 37,
                             height = 45, sideSlope = 53, icon = 61, heading = 63, scale = 71, moduleX = 79,
                             moduleZ = 83, object = 87, munition = 95, pointCount = 97, points = 101;
}
static_assert(payloadField::points == kFixedPayloadBytes);

/// The most points an edit of kind `k` may hold: kMaxLinePoints for berm,
/// ditch and flatten, 1 for the rest (0 for a kind out of range).
std::uint32_t maxPoints(edit::Kind k);

/// The 24 header bytes of a version 1 journal.
std::vector<std::byte> encodeHeader();
/// Checks a journal's header (the first bytes of the file): size, magic,
/// version, header size, CRC, flags. Problems name `file` and the field's
/// offset; messages start "journal: ".
Status decodeHeader(std::span<const std::byte> bytes, const std::string& file);

/// Appends the record of `e` to `out`: head, then payload. `batchStart` is
/// the file offset where the write that will hold the record begins
/// (JournalWriter's durable size). Refuses (and appends nothing) an edit
/// that checkEdit refuses or that holds more points than maxPoints(kind),
/// with checkEdit's message or "journal: ...".
Status encodeRecord(const edit::Edit& e, std::uint64_t batchStart, std::vector<std::byte>& out);

/// One record decoded, with where its batch began.
struct Record {
  edit::Edit edit;
  std::uint64_t batchStart = 0;
  std::uint64_t bytes = 0;  ///< head + payload
};
/// Decodes the record at the start of `bytes`, which lies at byte `offset`
/// of `file` (problems name both; messages start "journal: record at byte
/// N: "). Every check a journal reader makes on one record: the head's
/// CRC, the payload size against kMaxPayloadBytes and the bytes there are,
/// the payload's CRC, the kind, the point count against maxPoints and the
/// payload size (both before anything is allocated), batchStart not after
/// the record, then checkEdit. Bytes after the record are ignored.
Result<Record> decodeRecord(std::span<const std::byte> bytes, const std::string& file, std::uint64_t offset);

/// A journal as read: the edits of its whole records, in order.
struct Journal {
  std::vector<edit::Edit> edits;
  /// A torn tail cut (file, the offset of the cut, why); empty otherwise.
  Warnings warnings;
  /// Bytes of header and whole records: where the next record goes. Less
  /// than the file's size when a torn tail was cut.
  std::uint64_t validBytes = 0;
};

/// Decodes a whole journal held in memory (`file` names it in problems).
/// Fails on a bad header, on a whole record that does not decode, and on a
/// damaged record followed by a record of a later batch (damage before the
/// tail, FORMAT.md §14.4). A damaged or partial record followed by nothing
/// of a later batch is a torn tail: cut there, with a warning.
Result<Journal> decodeJournal(std::span<const std::byte> bytes, const std::string& file);
/// Reads and decodes the journal at `path` (at most kMaxFileBytes).
Result<Journal> readJournal(const std::string& path);

/// When JournalWriter makes its batches durable without being asked.
struct WriterOptions {
  /// flush() once this many records are waiting (default 64: about 8 KiB
  /// of craters, one fdatasync per 64 edits).
  std::size_t batchRecords = 64;
  /// flush() once the oldest waiting record has waited this long (default
  /// 50 ms: three frames at 60 Hz). Checked on append() and flushIfDue();
  /// the writer starts no thread, so its owner calls flushIfDue() on a
  /// tick (each simulation step) to bound the wait when no edit comes.
  std::chrono::milliseconds batchDelay{50};
  /// The clock the delay is measured on (tests give their own); empty:
  /// std::chrono::steady_clock::now.
  std::function<std::chrono::steady_clock::time_point()> now;
};

/// Appends edits to a journal file, durable in batches.
///
/// Each record is encoded when appended and waits in memory; flush()
/// writes every waiting record with one pwrite at the end of the durable
/// bytes and one fdatasync. A flush is all or nothing per record on disk:
/// a crash during it leaves a torn tail that readJournal cuts (and open()
/// truncates), a failed write is truncated back at once and its records
/// stay waiting. A failed fdatasync leaves the file's state unknown: the
/// writer refuses every later call (reopen it; open() checks the file).
///
/// Thread contract: one thread calls every method. The destructor flushes
/// what is waiting (its error is lost: call close() to see it).
class JournalWriter {
 public:
  /// Opens `path` for appending: creates it with the header when it does
  /// not exist (atomically: a temp file linked into place, so a journal
  /// never lacks its header), or checks the existing journal (readJournal)
  /// and truncates a torn tail, with a warning on the result. Refuses a
  /// journal with problems, and one another writer holds.
  static Result<std::unique_ptr<JournalWriter>> open(const std::string& path, WriterOptions options = {});
  ~JournalWriter();
  JournalWriter(const JournalWriter&) = delete;
  JournalWriter& operator=(const JournalWriter&) = delete;

  /// Encodes `e` and adds it to the waiting batch; flushes when the batch
  /// is full or due. Refuses an edit encodeRecord refuses (nothing waits
  /// then). The problem of an automatic flush is returned too: `e` is
  /// waiting in that case.
  Status append(const edit::Edit& e);
  /// Writes every waiting record (one write, one fdatasync). No-op when
  /// nothing waits.
  Status flush();
  /// Flushes when the oldest waiting record has waited batchDelay.
  Status flushIfDue();
  /// Flushes and closes the file (releasing the lock); later calls fail.
  Status close();

  const std::string& path() const { return path_; }
  /// Edits the file held when opened (after a torn tail was cut).
  std::size_t editsAtOpen() const { return editsAtOpen_; }
  /// Records waiting for the next flush.
  std::size_t waiting() const { return waiting_; }
  /// Records made durable since open().
  std::size_t flushedRecords() const { return flushed_; }
  /// The file's size up to the last durable record.
  std::uint64_t durableBytes() const { return durable_; }

 private:
  JournalWriter(std::string path, int fd, WriterOptions options, std::uint64_t durable, std::size_t edits);
  std::chrono::steady_clock::time_point now() const;
  Status refuseIfBroken() const;

  std::string path_;
  int fd_ = -1;
  WriterOptions options_;
  std::uint64_t durable_ = 0;
  std::size_t editsAtOpen_ = 0;
  std::vector<std::byte> batch_;
  std::size_t waiting_ = 0;
  std::size_t flushed_ = 0;
  std::chrono::steady_clock::time_point firstWaiting_{};
  std::string broken_;  ///< why the writer refuses every call, or ""
};

}  // namespace sandtable::journal
