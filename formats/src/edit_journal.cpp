// The edit journal, version 1 (docs/FORMAT.md §14): encode and decode of
// the header and the records, the reader that tells a torn tail from
// damage, and the batching writer.
#include "sandtable/formats/edit_journal.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>

#include "sandtable/formats/bytes.h"

namespace sandtable::journal {
namespace {

std::string num(std::uint64_t v) { return std::to_string(v); }

std::string recordAt(std::uint64_t offset) { return "journal: record at byte " + num(offset) + ": "; }

/// What the seal of the record at some offset says: whole (head CRC, size
/// in range, every payload byte there, payload CRC), or why not. A record
/// that is not whole may be the torn tail a crash left; one that is whole
/// was written by a writer, so anything wrong inside it is damage.
struct Seal {
  bool whole = false;
  std::string why;  ///< when not whole
  std::uint32_t payloadBytes = 0;
  std::uint64_t batchStart = 0;
};

bool headCrcMatches(const std::byte* head) {
  return crc32(std::span(head, headField::headCrc)) == loadLE<std::uint32_t>(head + headField::headCrc);
}

bool payloadSizeInRange(std::uint32_t n) { return n >= kFixedPayloadBytes && n <= kMaxPayloadBytes; }

/// `rest` runs from the record's first byte, at `offset`, to the end of the file.
Seal sealOf(std::span<const std::byte> rest, std::uint64_t offset) {
  Seal s;
  const std::uint64_t end = offset + rest.size();
  if (rest.size() < kRecordHeadBytes) {
    s.why = "the record's head needs " + num(kRecordHeadBytes) + " bytes, the file ends at byte " + num(end);
    return s;
  }
  const std::byte* h = rest.data();
  const std::uint32_t storedHead = loadLE<std::uint32_t>(h + headField::headCrc);
  const std::uint32_t head = crc32(std::span(h, headField::headCrc));
  if (storedHead != head) {
    s.why = "record head checksum mismatch (stored " + crcHex(storedHead) + ", computed " + crcHex(head) + ")";
    return s;
  }
  s.payloadBytes = loadLE<std::uint32_t>(h + headField::payloadBytes);
  s.batchStart = loadLE<std::uint64_t>(h + headField::batchStart);
  if (!payloadSizeInRange(s.payloadBytes)) {
    s.why = "payload size " + num(s.payloadBytes) + " is out of range (" + num(kFixedPayloadBytes) + " to " +
            num(kMaxPayloadBytes) + ")";
    return s;
  }
  if (s.payloadBytes > rest.size() - kRecordHeadBytes) {
    s.why = "the payload needs " + num(s.payloadBytes) + " bytes, the file ends at byte " + num(end) + " (" +
            num(rest.size() - kRecordHeadBytes) + " there)";
    return s;
  }
  const std::uint32_t storedPayload = loadLE<std::uint32_t>(h + headField::payloadCrc);
  const std::uint32_t payload = crc32(rest.subspan(kRecordHeadBytes, s.payloadBytes));
  if (storedPayload != payload) {
    s.why = "payload checksum mismatch (stored " + crcHex(storedPayload) + ", computed " + crcHex(payload) + ")";
    return s;
  }
  s.whole = true;
  return s;
}

/// The fields of a whole record's payload, checked in the order FORMAT.md
/// §14.3 gives: kind, then the point count against the kind's cap and the
/// payload's size (before the points are allocated), then checkEdit.
/// `offset` is the record's first byte in the file.
Result<edit::Edit> decodePayload(std::span<const std::byte> payload, const std::string& file, std::uint64_t offset) {
  using namespace payloadField;
  const std::byte* p = payload.data();
  const std::uint64_t at = offset + kRecordHeadBytes;
  const std::uint8_t kind = loadLE<std::uint8_t>(p + payloadField::kind);
  if (kind < 1 || kind > edit::kMaxKind) {
    return Problem{file, at + payloadField::kind,
                   recordAt(offset) + "kind " + num(kind) + " is unknown (1 to " + num(edit::kMaxKind) + ")"};
  }
  edit::Edit e;
  e.kind = edit::Kind(kind);
  const std::uint32_t count = loadLE<std::uint32_t>(p + pointCount);
  if (count > maxPoints(e.kind)) {
    return Problem{file, at + pointCount,
                   recordAt(offset) + "point count " + num(count) + " is more than a " +
                       std::string(edit::kindName(e.kind)) + " holds (" + num(maxPoints(e.kind)) + ")"};
  }
  const std::uint64_t pointBytes = payload.size() - kFixedPayloadBytes;
  if (std::uint64_t(count) * kPointBytes != pointBytes) {
    return Problem{file, at + pointCount,
                   recordAt(offset) + "point count " + num(count) + " needs " + num(std::uint64_t(count) * kPointBytes) +
                       " bytes of points, the payload holds " + num(pointBytes)};
  }
  e.id = loadLE<std::uint64_t>(p + id);
  e.time = loadLE<double>(p + time);
  e.origin = loadLE<std::uint32_t>(p + origin);
  e.radius = loadLE<double>(p + radius);
  e.depth = loadLE<double>(p + depth);
  e.width = loadLE<double>(p + width);
  e.height = loadLE<double>(p + height);
  e.sideSlope = loadLE<double>(p + sideSlope);
  e.icon = loadLE<std::uint16_t>(p + icon);
  e.heading = loadLE<double>(p + heading);
  e.scale = loadLE<double>(p + scale);
  e.moduleX = loadLE<std::uint32_t>(p + moduleX);
  e.moduleZ = loadLE<std::uint32_t>(p + moduleZ);
  e.object = loadLE<std::uint64_t>(p + object);
  e.munition = loadLE<std::uint16_t>(p + munition);
  e.points.resize(count);
  for (std::uint32_t k = 0; k < count; ++k) {
    e.points[k] = {loadLE<double>(p + points + kPointBytes * k), loadLE<double>(p + points + kPointBytes * k + 8)};
  }
  if (const std::string bad = edit::checkEdit(e); !bad.empty()) return Problem{file, offset, recordAt(offset) + bad};
  return e;
}

/// Everything on one record that needs no neighbour: the seal (as a
/// problem), the payload, and a batch start between the header's end and
/// the record.
Result<Record> decodeSealed(std::span<const std::byte> rest, const Seal& s, const std::string& file,
                            std::uint64_t offset) {
  if (!s.whole) return Problem{file, offset, recordAt(offset) + s.why};
  if (s.batchStart < kHeaderBytes || s.batchStart > offset) {
    return Problem{file, offset + headField::batchStart,
                   recordAt(offset) + "batch start " + num(s.batchStart) + " is not between the header's end (" +
                       num(kHeaderBytes) + ") and the record"};
  }
  auto e = decodePayload(rest.subspan(kRecordHeadBytes, s.payloadBytes), file, offset);
  if (!e) return e.problems();
  return Record{std::move(e.value()), s.batchStart, kRecordHeadBytes + std::uint64_t(s.payloadBytes)};
}

/// The first record head after `bad` whose write began after `bad`: proof
/// that the bytes at `bad` had been made durable before a later flush, so
/// their damage is not a crash's torn tail. A head counts when its own CRC
/// holds, its payload size is in range and its batch start lies between
/// the header's end and itself; its payload need not be there (it may be
/// the torn tail itself). Scans every byte offset: a damaged record's
/// length cannot be trusted to find the next one.
struct Later {
  std::uint64_t offset = 0;
  std::uint64_t batchStart = 0;
};
std::optional<Later> laterWrite(std::span<const std::byte> bytes, std::uint64_t bad) {
  for (std::uint64_t p = bad + 1; p + kRecordHeadBytes <= bytes.size(); ++p) {
    const std::byte* h = bytes.data() + p;
    const std::uint64_t batch = loadLE<std::uint64_t>(h + headField::batchStart);
    if (batch <= bad || batch > p || !payloadSizeInRange(loadLE<std::uint32_t>(h + headField::payloadBytes))) continue;
    if (headCrcMatches(h)) return Later{p, batch};
  }
  return std::nullopt;
}

void putPayload(const edit::Edit& e, std::byte* p) {
  using namespace payloadField;
  storeLE<std::uint64_t>(p + id, e.id);
  storeLE<double>(p + time, e.time);
  storeLE<std::uint32_t>(p + origin, e.origin);
  storeLE<std::uint8_t>(p + kind, std::uint8_t(e.kind));
  storeLE<double>(p + radius, e.radius);
  storeLE<double>(p + depth, e.depth);
  storeLE<double>(p + width, e.width);
  storeLE<double>(p + height, e.height);
  storeLE<double>(p + sideSlope, e.sideSlope);
  storeLE<std::uint16_t>(p + icon, e.icon);
  storeLE<double>(p + heading, e.heading);
  storeLE<double>(p + scale, e.scale);
  storeLE<std::uint32_t>(p + moduleX, e.moduleX);
  storeLE<std::uint32_t>(p + moduleZ, e.moduleZ);
  storeLE<std::uint64_t>(p + object, e.object);
  storeLE<std::uint16_t>(p + munition, e.munition);
  storeLE<std::uint32_t>(p + pointCount, std::uint32_t(e.points.size()));
  for (std::size_t k = 0; k < e.points.size(); ++k) {
    storeLE<double>(p + points + kPointBytes * k, e.points[k][0]);
    storeLE<double>(p + points + kPointBytes * k + 8, e.points[k][1]);
  }
}

std::string errnoText() { return std::strerror(errno); }

/// Makes a new journal's name durable: fsync of the directory holding it.
void syncDirectory(const std::string& path) {
  std::string dir = std::filesystem::path(path).parent_path().string();
  if (dir.empty()) dir = ".";
  const int d = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (d < 0) return;
  ::fsync(d);
  ::close(d);
}

/// Creates `path` holding only the header, unless it exists: the header is
/// written and fsynced under a temp name, then linked into place (link
/// never replaces, so a journal another process created at the same moment
/// is kept, records and all).
Status createIfAbsent(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) return {};
  if (errno != ENOENT) return Problem{path, 0, "journal writer: cannot look at the journal: " + errnoText()};
  const std::string tmp = path + ".partial." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Problem{path, 0, "journal writer: cannot create " + tmp + ": " + errnoText()};
  const auto head = encodeHeader();
  Status w = pwriteAll(fd, head.data(), head.size(), 0);
  if (w && ::fsync(fd) != 0) w = Problem{path, 0, errnoText()};
  ::close(fd);
  if (w && ::link(tmp.c_str(), path.c_str()) != 0 && errno != EEXIST) w = Problem{path, 0, errnoText()};
  ::unlink(tmp.c_str());
  if (!w) return Problem{path, 0, "journal writer: cannot create the journal: " + w.message()};
  syncDirectory(path);
  return {};
}

}  // namespace

std::string defaultPath(const std::string& databaseDir) { return databaseDir + "/" + kFileName; }

std::uint32_t maxPoints(edit::Kind k) {
  switch (k) {
    case edit::Kind::berm:
    case edit::Kind::ditch:
    case edit::Kind::flatten: return kMaxLinePoints;
    case edit::Kind::crater:
    case edit::Kind::addObject:
    case edit::Kind::removeObject:
    case edit::Kind::switchObject:
    case edit::Kind::scaleObject: return 1;
  }
  return 0;
}

std::vector<std::byte> encodeHeader() {
  std::vector<std::byte> h(kHeaderBytes, std::byte{0});
  std::memcpy(h.data() + headerField::magic, kMagic.data(), kMagic.size());
  storeLE<std::uint32_t>(h.data() + headerField::version, kVersion);
  storeLE<std::uint32_t>(h.data() + headerField::headerBytes, kHeaderBytes);
  storeLE<std::uint32_t>(h.data() + headerField::flags, 0);
  storeLE<std::uint32_t>(h.data() + headerField::headerCrc, crc32(std::span(h).first(headerField::headerCrc)));
  return h;
}

Status decodeHeader(std::span<const std::byte> bytes, const std::string& file) {
  if (bytes.size() < kHeaderBytes) {
    return Problem{file, bytes.size(),
                   "journal: truncated header: the header needs " + num(kHeaderBytes) +
                       " bytes, the file ends at byte " + num(bytes.size())};
  }
  const std::byte* h = bytes.data();
  if (std::memcmp(h + headerField::magic, kMagic.data(), kMagic.size()) != 0) {
    return Problem{file, headerField::magic, "journal: bad magic: not a sandtable edit journal (expected \"SANDJRNL\")"};
  }
  if (const auto v = loadLE<std::uint32_t>(h + headerField::version); v != kVersion) {
    return Problem{file, headerField::version,
                   "journal: version " + num(v) + " is not supported (this reader knows version " + num(kVersion) +
                       "); use a matching sandtable"};
  }
  if (const auto n = loadLE<std::uint32_t>(h + headerField::headerBytes); n != kHeaderBytes) {
    return Problem{file, headerField::headerBytes, "journal: header size " + num(n) + " must be " + num(kHeaderBytes)};
  }
  const std::uint32_t stored = loadLE<std::uint32_t>(h + headerField::headerCrc);
  if (const std::uint32_t c = crc32(bytes.first(headerField::headerCrc)); c != stored) {
    return Problem{file, headerField::headerCrc,
                   "journal: header checksum mismatch (stored " + crcHex(stored) + ", computed " + crcHex(c) +
                       "): the header is corrupt"};
  }
  if (const auto f = loadLE<std::uint32_t>(h + headerField::flags); f != 0) {
    return Problem{file, headerField::flags, "journal: flags " + crcHex(f) + " are not zero; version 1 defines none"};
  }
  return {};
}

Status encodeRecord(const edit::Edit& e, std::uint64_t batchStart, std::vector<std::byte>& out) {
  if (const std::string bad = edit::checkEdit(e); !bad.empty()) return Problem{"", 0, bad};
  if (e.points.size() > maxPoints(e.kind)) {
    return Problem{"", 0, "journal: a " + std::string(edit::kindName(e.kind)) + " holds at most " +
                              num(maxPoints(e.kind)) + " points, this edit has " + num(e.points.size())};
  }
  const auto payloadBytes = static_cast<std::uint32_t>(kFixedPayloadBytes + kPointBytes * e.points.size());
  const std::size_t at = out.size();
  out.resize(at + kRecordHeadBytes + payloadBytes);
  std::byte* r = out.data() + at;
  putPayload(e, r + kRecordHeadBytes);
  storeLE<std::uint32_t>(r + headField::payloadBytes, payloadBytes);
  storeLE<std::uint64_t>(r + headField::batchStart, batchStart);
  storeLE<std::uint32_t>(r + headField::payloadCrc, crc32(std::span(r + kRecordHeadBytes, payloadBytes)));
  storeLE<std::uint32_t>(r + headField::headCrc, crc32(std::span(r, headField::headCrc)));
  return {};
}

Result<Record> decodeRecord(std::span<const std::byte> bytes, const std::string& file, std::uint64_t offset) {
  return decodeSealed(bytes, sealOf(bytes, offset), file, offset);
}

Result<Journal> decodeJournal(std::span<const std::byte> bytes, const std::string& file) {
  if (const Status h = decodeHeader(bytes, file); !h) return h.problems();
  Journal j;
  std::uint64_t off = kHeaderBytes;
  std::uint64_t previousBatch = 0;
  while (off < bytes.size()) {
    const auto rest = bytes.subspan(off);
    const Seal s = sealOf(rest, off);
    if (!s.whole) {
      if (const auto later = laterWrite(bytes, off)) {
        return Problem{file, off,
                       recordAt(off) + s.why + "; a record of a later write (it began at byte " + num(later->batchStart) +
                           ") follows at byte " + num(later->offset) +
                           ", so this is damage to flushed edits, not a tail a crash cut short: the journal is "
                           "corrupt before its end"};
      }
      j.warnings.push_back({file, off,
                            "journal: torn tail at byte " + num(off) + ": " + s.why + "; cut at the last whole record (" +
                                num(bytes.size() - off) + " bytes dropped, " + num(j.edits.size()) +
                                " edits kept): a write that a crash cut short"});
      break;
    }
    auto r = decodeSealed(rest, s, file, off);
    if (!r) return r.problems();
    // One write holds whole records that share its start; the next write
    // begins where the durable bytes ended, at its first record.
    if (r->batchStart != off && r->batchStart != previousBatch) {
      return Problem{file, off + headField::batchStart,
                     recordAt(off) + "batch start " + num(r->batchStart) + " is neither the record's own offset nor " +
                         "the previous record's batch start (" + num(previousBatch) +
                         "); the records of one write share its start"};
    }
    previousBatch = r->batchStart;
    off += r->bytes;
    j.edits.push_back(std::move(r->edit));
  }
  j.validBytes = off;
  return j;
}

Result<Journal> readJournal(const std::string& path) {
  auto bytes = readSmallFile(path, kMaxFileBytes);
  if (!bytes) return Problem{path, 0, "journal: " + bytes.message()};
  return decodeJournal(bytes.value(), path);
}

// ---------------------------------------------------------------- writer

JournalWriter::JournalWriter(std::string path, int fd, WriterOptions options, std::uint64_t durable,
                             std::size_t edits)
    : path_(std::move(path)), fd_(fd), options_(std::move(options)), durable_(durable), editsAtOpen_(edits) {}

JournalWriter::~JournalWriter() {
  if (fd_ < 0) return;
  if (broken_.empty()) (void)flush();
  ::close(fd_);
}

Result<std::unique_ptr<JournalWriter>> JournalWriter::open(const std::string& path, WriterOptions options) {
  if (Status c = createIfAbsent(path); !c) return c.problems();
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) return Problem{path, 0, "journal writer: cannot open: " + errnoText()};
  auto fail = [&](std::vector<Problem> ps) {
    ::close(fd);
    return Result<std::unique_ptr<JournalWriter>>(std::move(ps));
  };
  // The lock before the read: what is checked is what is appended to.
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const bool held = errno == EWOULDBLOCK;
    return fail({{path, 0, "journal writer: " +
                               (held ? std::string("another writer holds the journal (one writer at a time)")
                                     : "cannot lock: " + errnoText())}});
  }
  auto read = readJournal(path);
  if (!read) return fail(read.problems());
  const Journal& j = read.value();
  Warnings warnings = j.warnings;
  struct stat st {};
  if (::fstat(fd, &st) != 0) return fail({{path, 0, "journal writer: cannot stat: " + errnoText()}});
  if (std::uint64_t(st.st_size) > j.validBytes) {
    if (::ftruncate(fd, static_cast<off_t>(j.validBytes)) != 0 || ::fdatasync(fd) != 0) {
      return fail({{path, j.validBytes, "journal writer: cannot cut the torn tail: " + errnoText()}});
    }
    warnings.push_back({path, j.validBytes,
                        "journal writer: truncated the journal to " + num(j.validBytes) + " bytes (from " +
                            num(std::uint64_t(st.st_size)) + "); appending after its last whole record"});
  }
  Result<std::unique_ptr<JournalWriter>> out(
      std::unique_ptr<JournalWriter>(new JournalWriter(path, fd, std::move(options), j.validBytes, j.edits.size())));
  out.addWarnings(warnings);
  return out;
}

std::chrono::steady_clock::time_point JournalWriter::now() const {
  return options_.now ? options_.now() : std::chrono::steady_clock::now();
}

Status JournalWriter::refuseIfBroken() const {
  if (broken_.empty()) return {};
  return Problem{path_, durable_, "journal writer: " + broken_};
}

Status JournalWriter::append(const edit::Edit& e) {
  if (Status b = refuseIfBroken(); !b) return b;
  // Encoded against the durable size: the next flush writes it there.
  if (Status enc = encodeRecord(e, durable_, batch_); !enc) {
    return Problem{path_, durable_ + batch_.size(), enc.message()};
  }
  if (waiting_ == 0) firstWaiting_ = now();
  ++waiting_;
  if (waiting_ >= options_.batchRecords || now() - firstWaiting_ >= options_.batchDelay) return flush();
  return {};
}

Status JournalWriter::flushIfDue() {
  if (Status b = refuseIfBroken(); !b) return b;
  if (waiting_ > 0 && now() - firstWaiting_ >= options_.batchDelay) return flush();
  return {};
}

Status JournalWriter::flush() {
  if (Status b = refuseIfBroken(); !b) return b;
  if (waiting_ == 0) return {};
  const std::string what = num(waiting_) + " records (" + num(batch_.size()) + " bytes) at byte " + num(durable_);
  if (Status w = pwriteAll(fd_, batch_.data(), batch_.size(), durable_); !w) {
    // A short write leaves part of a record: cut it, so that the file ends
    // at its last whole record and the batch can be written again.
    if (::ftruncate(fd_, static_cast<off_t>(durable_)) != 0) {
      broken_ = "a write failed and its partial bytes could not be cut (" + errnoText() + "); reopen the journal";
    }
    return Problem{path_, durable_, "journal writer: cannot write " + what + ": " + w.message() +
                                        (broken_.empty() ? "; they stay waiting" : "")};
  }
  if (::fdatasync(fd_) != 0) {
    // After a failed fdatasync the kernel may have dropped the dirty pages:
    // nothing about the file can be assumed, so refuse until reopened.
    broken_ = "fdatasync failed (" + errnoText() + "); reopen the journal, which checks it";
    return Problem{path_, durable_, "journal writer: cannot make " + what + " durable: " + broken_};
  }
  durable_ += batch_.size();
  flushed_ += waiting_;
  waiting_ = 0;
  batch_.clear();
  return {};
}

Status JournalWriter::close() {
  if (fd_ < 0) return refuseIfBroken();
  Status st = broken_.empty() ? flush() : refuseIfBroken();
  ::close(fd_);
  fd_ = -1;
  if (broken_.empty()) broken_ = "the journal is closed";
  return st;
}

}  // namespace sandtable::journal
