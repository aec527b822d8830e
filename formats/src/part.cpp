// Build parts (part.h; docs/FORMAT.md §15): the header, the sequential
// writer with its running CRC and atomic publish, and the forward reader
// whose every size is checked against the file before anything is read.
#include "sandtable/formats/part.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>

#include "sandtable/formats/bytes.h"

namespace sandtable::part {
namespace {

std::string str(std::uint64_t v) { return std::to_string(v); }

/// Bytes of one block in the part: its table entry and its bytes.
constexpr std::uint64_t kBlockRecordBytes = kBlockEntryBytes + grid::kBlockBytes;

/// A header field that is out of range: its offset and the message (no prefix).
struct Bad {
  std::size_t offset;
  std::string message;
};

/// The range checks shared by decodeHeader and PartWriter::create.
std::optional<Bad> checkFields(const Header& h) {
  if (h.version != kVersion) {
    return Bad{field::version, "version " + str(h.version) + " is not supported (this reader knows version " +
                                   str(kVersion) + "); use a matching sandtable"};
  }
  if (h.blocksX > kMaxPerAxis) {
    return Bad{field::blocksX, "blocksX " + str(h.blocksX) + " is out of range (0 to " + str(kMaxPerAxis) + ")"};
  }
  if (std::uint64_t(h.blockRow0) + h.blockRows > kMaxPerAxis) {
    return Bad{field::blockRows, "block rows " + str(h.blockRow0) + " + " + str(h.blockRows) + " end past row " +
                                     str(kMaxPerAxis)};
  }
  if (h.modulesX > kMaxPerAxis) {
    return Bad{field::modulesX, "modulesX " + str(h.modulesX) + " is out of range (0 to " + str(kMaxPerAxis) + ")"};
  }
  if (std::uint64_t(h.moduleRow0) + h.moduleRows > kMaxPerAxis) {
    return Bad{field::moduleRows, "module rows " + str(h.moduleRow0) + " + " + str(h.moduleRows) +
                                      " end past row " + str(kMaxPerAxis)};
  }
  if (h.levels < 1 || h.levels > module::kMaxLevels) {
    return Bad{field::levels,
               "level count " + str(h.levels) + " is out of range (1 to " + str(module::kMaxLevels) + ")"};
  }
  return std::nullopt;
}

/// "block K (bx,bz)" and "module K (kx,kz)": the K-th in the part, and its
/// place in the grid / the pack.
std::string blockName(const Header& h, std::uint64_t k) {
  return "block " + str(k) + " (" + str(k % h.blocksX) + "," + str(h.blockRow0 + k / h.blocksX) + ")";
}
std::string moduleName(const Header& h, std::uint64_t k) {
  return "module " + str(k) + " (" + str(k % h.modulesX) + "," + str(h.moduleRow0 + k / h.modulesX) + ")";
}

/// Reads exactly n bytes at `off`; "" or the reason.
std::string readExactly(int fd, std::byte* data, std::size_t n, std::uint64_t off) {
  while (n > 0) {
    const ssize_t r = ::pread(fd, data, n, static_cast<off_t>(off));
    if (r < 0) {
      if (errno == EINTR) continue;
      return std::string("cannot read: ") + std::strerror(errno);
    }
    if (r == 0) return "the file ends at byte " + str(off);
    data += r;
    n -= static_cast<std::size_t>(r);
    off += static_cast<std::uint64_t>(r);
  }
  return "";
}

void encodeBlockEntry(const grid::BlockEntry& e, std::byte* p) {
  storeLE<std::uint32_t>(p + 0, e.crc);
  storeLE<float>(p + 4, e.minElevation);
  storeLE<float>(p + 8, e.maxElevation);
  storeLE<std::uint32_t>(p + 12, e.reserved);
}

grid::BlockEntry decodeBlockEntry(const std::byte* p) {
  return {loadLE<std::uint32_t>(p), loadLE<float>(p + 4), loadLE<float>(p + 8), loadLE<std::uint32_t>(p + 12)};
}

/// Checks the module entry at file offset `at` (the k-th module), whose
/// records must end by `reportOffset`. Fills `e`; the problem or nothing.
std::optional<Problem> checkModuleEntry(std::span<const std::byte> bytes, const Header& h, std::uint64_t k,
                                        std::uint64_t at, std::uint64_t reportOffset, const std::string& file,
                                        pack::Entry& e) {
  auto bad = [&](std::uint64_t off, const std::string& msg) { return Problem{file, off, "part: " + msg}; };
  const std::string name = moduleName(h, k);
  e = pack::decodeEntry(bytes, pack::kVersion2);
  if (e.offset != 0) return bad(at + pack::entryFieldV2::offset, name + "'s entry has a record offset that is not 0");
  if (e.fine.offset != 0) {
    return bad(at + pack::entryFieldV2::fineOffset, name + "'s entry has a fine record offset that is not 0");
  }
  if (loadLE<std::uint64_t>(bytes.data() + pack::entryFieldV2::reserved) != 0) {
    return bad(at + pack::entryFieldV2::reserved, name + "'s entry has reserved bytes 56..63 that are not zero");
  }
  const std::uint64_t kx = k % h.modulesX, kz = h.moduleRow0 + k / h.modulesX;
  if (e.kx != kx || e.kz != kz) {
    return bad(at + pack::entryFieldV2::kx,
               name + "'s entry names module (" + str(e.kx) + "," + str(e.kz) + "): the modules are out of order");
  }
  if (e.compressedBytes > kMaxRecordBytes || e.fine.compressedBytes > kMaxRecordBytes) {
    return bad(at + (e.compressedBytes > kMaxRecordBytes ? pack::entryFieldV2::compressedBytes
                                                          : pack::entryFieldV2::fineCompressedBytes),
               name + " record sizes (" + str(e.compressedBytes) + " coarse, " + str(e.fine.compressedBytes) +
                   " fine) are over the cap of " + str(kMaxRecordBytes) + " bytes");
  }
  const std::uint64_t end = at + kModuleEntryBytes + e.storedBytes();
  if (at > reportOffset || end > reportOffset) {
    return bad(at + pack::entryFieldV2::compressedBytes,
               name + "'s records (bytes " + str(at + kModuleEntryBytes) + ".." + str(end) +
                   ") run past the report at byte " + str(reportOffset));
  }
  return std::nullopt;
}

}  // namespace

// ---------------------------------------------------------------- header

std::array<std::byte, kHeaderBytes> encodeHeader(const Header& h) {
  std::array<std::byte, kHeaderBytes> b{};
  std::byte* p = b.data();
  std::memcpy(p + field::magic, kMagic.data(), kMagic.size());
  storeLE<std::uint32_t>(p + field::version, h.version);
  storeLE<std::uint32_t>(p + field::headerBytes, kHeaderBytes);
  storeLE<std::uint32_t>(p + field::planCrc, h.planCrc);
  storeLE<std::uint32_t>(p + field::task, h.task);
  storeLE<std::uint32_t>(p + field::blockRow0, h.blockRow0);
  storeLE<std::uint32_t>(p + field::blockRows, h.blockRows);
  storeLE<std::uint32_t>(p + field::blocksX, h.blocksX);
  storeLE<std::uint32_t>(p + field::moduleRow0, h.moduleRow0);
  storeLE<std::uint32_t>(p + field::moduleRows, h.moduleRows);
  storeLE<std::uint32_t>(p + field::modulesX, h.modulesX);
  storeLE<std::uint32_t>(p + field::levels, h.levels);
  // Bytes 52..59 stay zero (reserved).
  storeLE<std::uint32_t>(p + field::headerCrc, crc32(std::span<const std::byte>(p, field::headerCrc)));
  return b;
}

Result<Header> decodeHeader(std::span<const std::byte> bytes, const std::string& file) {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Result<Header>(Problem{file, off, "part: " + msg});
  };
  if (bytes.size() < kHeaderBytes) {
    return fail(bytes.size(), "truncated: the header needs " + str(kHeaderBytes) + " bytes, the file ends at byte " +
                                  str(bytes.size()));
  }
  const std::byte* p = bytes.data();
  if (std::memcmp(p + field::magic, kMagic.data(), kMagic.size()) != 0) {
    return fail(field::magic, "bad magic: not a sandtable build part (expected \"SANDPART\")");
  }
  Header h;
  h.version = loadLE<std::uint32_t>(p + field::version);
  if (h.version != kVersion) {
    return fail(field::version, "version " + str(h.version) + " is not supported (this reader knows version " +
                                    str(kVersion) + "); use a matching sandtable");
  }
  const std::uint32_t stored = loadLE<std::uint32_t>(p + field::headerCrc);
  const std::uint32_t actual = crc32(bytes.first(field::headerCrc));
  if (stored != actual) {
    return fail(field::headerCrc, "header checksum mismatch (stored " + crcHex(stored) + ", computed " +
                                      crcHex(actual) + "): the header is corrupt");
  }
  if (loadLE<std::uint32_t>(p + field::headerBytes) != kHeaderBytes) {
    return fail(field::headerBytes, "header size must be " + str(kHeaderBytes));
  }
  for (std::size_t k = field::reserved; k < field::headerCrc; ++k) {
    if (p[k] != std::byte{0}) return fail(k, "header reserved bytes 52..59 are not zero");
  }
  h.planCrc = loadLE<std::uint32_t>(p + field::planCrc);
  h.task = loadLE<std::uint32_t>(p + field::task);
  h.blockRow0 = loadLE<std::uint32_t>(p + field::blockRow0);
  h.blockRows = loadLE<std::uint32_t>(p + field::blockRows);
  h.blocksX = loadLE<std::uint32_t>(p + field::blocksX);
  h.moduleRow0 = loadLE<std::uint32_t>(p + field::moduleRow0);
  h.moduleRows = loadLE<std::uint32_t>(p + field::moduleRows);
  h.modulesX = loadLE<std::uint32_t>(p + field::modulesX);
  h.levels = loadLE<std::uint32_t>(p + field::levels);
  if (const auto bad = checkFields(h)) return fail(bad->offset, bad->message);
  return h;
}

// ---------------------------------------------------------------- writer

PartWriter::PartWriter(std::string path, std::string tmp, int fd, Header h)
    : path_(std::move(path)), tmp_(std::move(tmp)), fd_(fd), header_(h) {}

PartWriter::~PartWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (!finished_) ::unlink(tmp_.c_str());
}

Result<std::unique_ptr<PartWriter>> PartWriter::create(const std::string& path, const Header& h) {
  if (const auto bad = checkFields(h)) return Problem{path, 0, "part writer: header: " + bad->message};
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Problem{path, 0, "part writer: cannot create " + tmp + ": " + std::strerror(errno)};
  std::unique_ptr<PartWriter> w(new PartWriter(path, tmp, fd, h));
  const auto head = encodeHeader(h);
  if (const Status s = w->put(head); !s) return s.problems();
  return w;
}

Status PartWriter::put(std::span<const std::byte> bytes) {
  if (const Status w = pwriteAll(fd_, bytes.data(), bytes.size(), offset_); !w) {
    failed_ = true;
    failure_ = "part writer: cannot write " + tmp_ + ": " + w.message() + " (is the disk full?)";
    return Problem{path_, offset_, failure_};
  }
  crc_ = crc32(bytes, crc_);
  offset_ += bytes.size();
  return {};
}

Status PartWriter::addBlock(const grid::BlockEntry& e, std::span<const std::byte> bytes) {
  auto fail = [&](const std::string& msg) { return Status(Problem{path_, offset_, "part writer: " + msg}); };
  if (finished_) return fail("addBlock() after finish()");
  if (failed_) return Problem{path_, offset_, failure_};
  const std::uint64_t count = header_.blockCount();
  if (blocks_ >= count) return fail("addBlock(): all " + str(count) + " blocks were already added");
  const std::string name = blockName(header_, blocks_);
  if (bytes.size() != grid::kBlockBytes) {
    return fail(name + " has " + str(bytes.size()) + " bytes, not " + str(grid::kBlockBytes));
  }
  if (e.reserved != 0) return fail(name + "'s entry has a reserved field that is not 0");
  if (const std::uint32_t c = crc32(bytes); c != e.crc) {
    return fail(name + "'s bytes do not match its entry's CRC (entry " + crcHex(e.crc) + ", bytes " + crcHex(c) + ")");
  }
  std::array<std::byte, kBlockEntryBytes> entry{};
  encodeBlockEntry(e, entry.data());
  if (Status s = put(entry); !s) return s;
  if (Status s = put(bytes); !s) return s;
  ++blocks_;
  return {};
}

Status PartWriter::addModule(const pack::Entry& e, std::span<const std::byte> coarse,
                             std::span<const std::byte> fine) {
  auto fail = [&](const std::string& msg) { return Status(Problem{path_, offset_, "part writer: " + msg}); };
  if (finished_) return fail("addModule() after finish()");
  if (failed_) return Problem{path_, offset_, failure_};
  const std::uint64_t count = header_.moduleCount(), blockCount = header_.blockCount();
  if (blocks_ < blockCount) {
    return fail("addModule() before every block was added (" + str(blocks_) + " of " + str(blockCount) + ")");
  }
  if (modules_ >= count) return fail("addModule(): all " + str(count) + " modules were already added");
  const std::string name = moduleName(header_, modules_);
  const std::uint64_t kx = modules_ % header_.modulesX, kz = header_.moduleRow0 + modules_ / header_.modulesX;
  if (e.kx != kx || e.kz != kz) {
    return fail(name + " was expected, the entry is module (" + str(e.kx) + "," + str(e.kz) +
                "): modules go in row-major order");
  }
  if (coarse.size() != e.compressedBytes || fine.size() != e.fine.compressedBytes) {
    return fail(name + " records are " + str(coarse.size()) + " and " + str(fine.size()) + " bytes, its entry says " +
                str(e.compressedBytes) + " and " + str(e.fine.compressedBytes));
  }
  if (coarse.size() > kMaxRecordBytes || fine.size() > kMaxRecordBytes) {
    return fail(name + " has a record over the cap of " + str(kMaxRecordBytes) + " bytes");
  }
  if (const std::uint32_t c = crc32(coarse); c != e.compressedCrc) {
    return fail(name + "'s coarse record does not match its entry's CRC (entry " + crcHex(e.compressedCrc) +
                ", bytes " + crcHex(c) + ")");
  }
  if (const std::uint32_t c = crc32(fine); c != e.fine.compressedCrc) {
    return fail(name + "'s fine record does not match its entry's CRC (entry " + crcHex(e.fine.compressedCrc) +
                ", bytes " + crcHex(c) + ")");
  }
  pack::Entry stored = e;
  stored.offset = 0;
  stored.fine.offset = 0;
  std::array<std::byte, kModuleEntryBytes> entry{};
  pack::encodeEntry(stored, entry, pack::kVersion2);
  if (Status s = put(entry); !s) return s;
  if (Status s = put(coarse); !s) return s;
  if (Status s = put(fine); !s) return s;
  ++modules_;
  return {};
}

Status PartWriter::finish(std::string_view reportJson) {
  auto fail = [&](const std::string& msg) { return Status(Problem{path_, offset_, "part writer: " + msg}); };
  if (finished_) return fail("finish() was already called");
  if (failed_) return Problem{path_, offset_, failure_};
  if (blocks_ < header_.blockCount()) {
    return fail("finish() before every block was added: " + str(blocks_) + " of " + str(header_.blockCount()) +
                " blocks added");
  }
  if (modules_ < header_.moduleCount()) {
    return fail("finish() before every module was added: " + str(modules_) + " of " + str(header_.moduleCount()) +
                " modules added");
  }
  if (reportJson.size() > kMaxReportBytes) {
    return fail("the report is " + str(reportJson.size()) + " bytes, over the cap of " + str(kMaxReportBytes));
  }
  if (Status s = put(std::as_bytes(std::span(reportJson.data(), reportJson.size()))); !s) return s;
  std::array<std::byte, kTrailerBytes> trailer{};
  storeLE<std::uint64_t>(trailer.data(), reportJson.size());
  std::memcpy(trailer.data() + 8, kEndMagic.data(), kEndMagic.size());
  storeLE<std::uint32_t>(trailer.data() + 16, crc32(std::span(trailer).first(16), crc_));
  if (Status s = put(trailer); !s) return s;
  crc_ = loadLE<std::uint32_t>(trailer.data() + 16);  // put() chained the CRC's own bytes in
  auto failWith = [&](const std::string& what) {
    failed_ = true;
    failure_ = "part writer: " + what;
    return Status(Problem{path_, offset_, failure_});
  };
  if (::fsync(fd_) != 0) return failWith("cannot flush " + tmp_ + ": " + std::strerror(errno));
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) return failWith("cannot close " + tmp_ + ": " + std::strerror(errno));
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) {
    return failWith("cannot rename " + tmp_ + " to " + path_ + ": " + std::strerror(errno));
  }
  finished_ = true;
  std::string dir = std::filesystem::path(path_).parent_path().string();
  if (dir.empty()) dir = ".";
  if (const int d = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); d >= 0) {
    ::fsync(d);
    ::close(d);
  }
  return {};
}

// ---------------------------------------------------------------- reader

PartReader::~PartReader() {
  if (fd_ >= 0) ::close(fd_);
}

Result<std::unique_ptr<PartReader>> PartReader::open(const std::string& path) {
  using R = Result<std::unique_ptr<PartReader>>;
  auto fail = [&](std::uint64_t off, const std::string& msg) { return R(Problem{path, off, "part: " + msg}); };
  std::unique_ptr<PartReader> r(new PartReader());
  r->path_ = path;
  r->fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (r->fd_ < 0) return fail(0, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(r->fd_, &st) != 0 || !S_ISREG(st.st_mode)) return fail(0, "not a regular file");
  const auto size = static_cast<std::uint64_t>(st.st_size);
  r->size_ = size;
  constexpr std::uint64_t kMinBytes = kHeaderBytes + kTrailerBytes;
  if (size < kMinBytes) {
    return fail(size, "truncated: a part needs at least " + str(kMinBytes) +
                          " bytes (header and trailer), the file ends at byte " + str(size));
  }
  std::array<std::byte, kHeaderBytes> head{};
  if (std::string e = readExactly(r->fd_, head.data(), head.size(), 0); !e.empty()) return fail(0, e);
  auto h = decodeHeader(head, path);
  if (!h) return h.problems();
  r->header_ = h.value();
  const std::uint64_t trailerAt = size - kTrailerBytes;
  std::array<std::byte, kTrailerBytes> trailer{};
  if (std::string e = readExactly(r->fd_, trailer.data(), trailer.size(), trailerAt); !e.empty()) {
    return fail(trailerAt, e);
  }
  if (std::memcmp(trailer.data() + 8, kEndMagic.data(), kEndMagic.size()) != 0) {
    return fail(trailerAt + 8, "bad end magic (expected \"SANDPEND\"): the part is truncated or damaged");
  }
  const auto reportBytes = loadLE<std::uint64_t>(trailer.data());
  if (reportBytes > kMaxReportBytes || reportBytes > size - kMinBytes) {
    return fail(trailerAt, "the report size " + str(reportBytes) + " is over the cap of " + str(kMaxReportBytes) +
                               " or more than the " + str(size - kMinBytes) + " bytes the file has for it");
  }
  r->storedCrc_ = loadLE<std::uint32_t>(trailer.data() + 16);
  r->reportOffset_ = trailerAt - reportBytes;
  // The least the header's counts need, before anything is allocated (the
  // counts are at most 2^44 and 2^44 here; __int128 needs no such reasoning).
  const unsigned __int128 need = (unsigned __int128)kHeaderBytes +
                                 (unsigned __int128)r->header_.blockCount() * kBlockRecordBytes +
                                 (unsigned __int128)r->header_.moduleCount() * kModuleEntryBytes + kTrailerBytes +
                                 reportBytes;
  if (need > size) {
    const bool huge = need > (unsigned __int128)UINT64_MAX;
    return fail(size, "truncated: the header's " + str(r->header_.blockCount()) + " blocks and " +
                          str(r->header_.moduleCount()) + " modules and the " + str(reportBytes) +
                          "-byte report need at least " + (huge ? std::string("2^64") : str(std::uint64_t(need))) +
                          " bytes, the file ends at byte " + str(size));
  }
  r->report_.resize(static_cast<std::size_t>(reportBytes));
  if (std::string e = readExactly(r->fd_, reinterpret_cast<std::byte*>(r->report_.data()), r->report_.size(),
                                  r->reportOffset_);
      !e.empty()) {
    return fail(r->reportOffset_, e);
  }
  return r;
}

Status PartReader::verify() const {
  Status out;
  auto problem = [&](std::uint64_t off, const std::string& msg) { return Problem{path_, off, "part: " + msg}; };
  // Every byte before the trailer's CRC, in bounded chunks.
  const std::uint64_t end = size_ - 4;
  std::vector<std::byte> buf(static_cast<std::size_t>(std::min<std::uint64_t>(1u << 20, end)));
  std::uint32_t crc = 0;
  for (std::uint64_t off = 0; off < end;) {
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(buf.size(), end - off));
    if (std::string e = readExactly(fd_, buf.data(), n, off); !e.empty()) return problem(off, e);
    crc = crc32(std::span(buf.data(), n), crc);
    off += n;
  }
  if (crc != storedCrc_) {
    out.add(problem(end, "checksum mismatch (stored " + crcHex(storedCrc_) + ", computed " + crcHex(crc) +
                             "): the part is corrupt"));
  }
  // The structure: blocks by size (open checked they fit), each module's
  // entry and its records, ending exactly at the report.
  std::uint64_t at = kHeaderBytes + header_.blockCount() * kBlockRecordBytes;
  const std::uint64_t modules = header_.moduleCount();
  std::array<std::byte, kModuleEntryBytes> entry{};
  for (std::uint64_t k = 0; k < modules; ++k) {
    if (at > reportOffset_ || reportOffset_ - at < kModuleEntryBytes) {
      out.add(problem(at, moduleName(header_, k) + "'s entry at byte " + str(at) + " runs past the report at byte " +
                              str(reportOffset_)));
      return out;
    }
    if (std::string e = readExactly(fd_, entry.data(), entry.size(), at); !e.empty()) {
      out.add(problem(at, e));
      return out;
    }
    pack::Entry e;
    if (auto bad = checkModuleEntry(entry, header_, k, at, reportOffset_, path_, e)) {
      out.add(*bad);
      return out;
    }
    at += kModuleEntryBytes + e.storedBytes();
  }
  if (at != reportOffset_) {
    out.add(problem(at, "the modules end at byte " + str(at) + ", but the report starts at byte " +
                            str(reportOffset_)));
  }
  return out;
}

Result<grid::BlockEntry> PartReader::nextBlock(std::span<std::byte> out) {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Result<grid::BlockEntry>(Problem{path_, off, "part: " + msg});
  };
  const std::uint64_t count = header_.blockCount();
  if (blocksRead_ >= count) return fail(cursor_, "nextBlock() after the last of the " + str(count) + " blocks");
  if (out.size() != grid::kBlockBytes) {
    return fail(cursor_, "nextBlock() needs a buffer of " + str(grid::kBlockBytes) + " bytes, not " + str(out.size()));
  }
  const std::string name = blockName(header_, blocksRead_);
  if (cursor_ > reportOffset_ || reportOffset_ - cursor_ < kBlockRecordBytes) {
    return fail(cursor_, name + " at byte " + str(cursor_) + " runs past the report at byte " + str(reportOffset_));
  }
  std::array<std::byte, kBlockEntryBytes> entry{};
  if (std::string e = readExactly(fd_, entry.data(), entry.size(), cursor_); !e.empty()) return fail(cursor_, e);
  const grid::BlockEntry e = decodeBlockEntry(entry.data());
  if (e.reserved != 0) return fail(cursor_ + 12, name + "'s entry has reserved bytes 12..15 that are not zero");
  const std::uint64_t at = cursor_ + kBlockEntryBytes;
  if (std::string err = readExactly(fd_, out.data(), out.size(), at); !err.empty()) return fail(at, err);
  if (const std::uint32_t c = crc32(out); c != e.crc) {
    return fail(at, name + "'s bytes do not match its CRC (stored " + crcHex(e.crc) + ", computed " + crcHex(c) + ")");
  }
  cursor_ += kBlockRecordBytes;
  ++blocksRead_;
  return e;
}

Result<ModuleRecord> PartReader::nextModule() {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Result<ModuleRecord>(Problem{path_, off, "part: " + msg});
  };
  const std::uint64_t blocks = header_.blockCount(), count = header_.moduleCount();
  if (blocksRead_ < blocks) {
    return fail(cursor_, "nextModule() before every block was read (" + str(blocksRead_) + " of " + str(blocks) + ")");
  }
  if (modulesRead_ >= count) return fail(cursor_, "nextModule() after the last of the " + str(count) + " modules");
  const std::string name = moduleName(header_, modulesRead_);
  if (cursor_ > reportOffset_ || reportOffset_ - cursor_ < kModuleEntryBytes) {
    return fail(cursor_, name + "'s entry at byte " + str(cursor_) + " runs past the report at byte " +
                             str(reportOffset_));
  }
  std::array<std::byte, kModuleEntryBytes> entry{};
  if (std::string e = readExactly(fd_, entry.data(), entry.size(), cursor_); !e.empty()) return fail(cursor_, e);
  ModuleRecord m;
  if (auto bad = checkModuleEntry(entry, header_, modulesRead_, cursor_, reportOffset_, path_, m.entry)) {
    return *bad;
  }
  const std::uint64_t coarseAt = cursor_ + kModuleEntryBytes, fineAt = coarseAt + m.entry.compressedBytes;
  const std::uint64_t end = fineAt + m.entry.fine.compressedBytes;
  if (modulesRead_ + 1 == count && end != reportOffset_) {
    return fail(end, "the modules end at byte " + str(end) + ", but the report starts at byte " + str(reportOffset_));
  }
  // Both sizes are capped and lie within the file (checkModuleEntry).
  m.coarse.resize(m.entry.compressedBytes);
  m.fine.resize(m.entry.fine.compressedBytes);
  if (std::string e = readExactly(fd_, m.coarse.data(), m.coarse.size(), coarseAt); !e.empty()) {
    return fail(coarseAt, e);
  }
  if (std::string e = readExactly(fd_, m.fine.data(), m.fine.size(), fineAt); !e.empty()) return fail(fineAt, e);
  if (const std::uint32_t c = crc32(m.coarse); c != m.entry.compressedCrc) {
    return fail(coarseAt, name + "'s coarse record does not match its CRC (stored " + crcHex(m.entry.compressedCrc) +
                              ", computed " + crcHex(c) + ")");
  }
  if (!m.fine.empty()) {
    if (const std::uint32_t c = crc32(m.fine); c != m.entry.fine.compressedCrc) {
      return fail(fineAt, name + "'s fine record does not match its CRC (stored " +
                              crcHex(m.entry.fine.compressedCrc) + ", computed " + crcHex(c) + ")");
    }
  }
  cursor_ = end;
  ++modulesRead_;
  return m;
}

}  // namespace sandtable::part
