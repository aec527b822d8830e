#include "sandtable/formats/pack.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>

#include "sandtable/base/capped_problems.h"
#include "sandtable/base/morton.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::pack {
namespace {

std::string str(std::uint64_t v) { return std::to_string(v); }

std::string join(const std::string& directory, const char* name) {
  return (std::filesystem::path(directory) / name).string();
}

std::string moduleName(std::uint32_t kx, std::uint32_t kz) {
  return "module (" + str(kx) + "," + str(kz) + ")";
}

std::uint64_t entryOffset(const IndexHeader& h, std::uint32_t kx, std::uint32_t kz) {
  return kIndexHeaderBytes + std::uint64_t(h.entryBytes()) * (std::uint64_t(kz) * h.modulesX + kx);
}

// ---------------------------------------------------------------- file I/O

/// Reads exactly n bytes at `off` (a short file is an error). The problem
/// has no file, only the offset and the reason.
Status preadAll(int fd, std::byte* data, std::size_t n, std::uint64_t off) {
  while (n > 0) {
    const ssize_t r = ::pread(fd, data, n, static_cast<off_t>(off));
    if (r < 0) {
      if (errno == EINTR) continue;
      return Problem{"", off, std::strerror(errno)};
    }
    if (r == 0) return Problem{"", off, "the file ends at byte " + str(off)};
    data += r;
    n -= static_cast<std::size_t>(r);
    off += static_cast<std::uint64_t>(r);
  }
  return {};
}

/// A whole file mapped read-only (nothing mapped when it is empty).
class MappedFile {
 public:
  MappedFile() = default;
  ~MappedFile() {
    if (base_) ::munmap(const_cast<std::byte*>(base_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  /// The problem names `path`; its message says why.
  Status open(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return Problem{path, 0, std::string("cannot open: ") + std::strerror(errno)};
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd);
      return Problem{path, 0, "not a regular file"};
    }
    size_ = static_cast<std::size_t>(st.st_size);
    if (size_ > 0) {
      void* m = ::mmap(nullptr, size_, PROT_READ, MAP_SHARED, fd, 0);
      if (m == MAP_FAILED) {
        const std::string e = std::strerror(errno);
        ::close(fd);
        size_ = 0;
        return Problem{path, 0, "mmap failed: " + e};
      }
      base_ = static_cast<const std::byte*>(m);
    }
    ::close(fd);
    return {};
  }
  std::span<const std::byte> bytes() const { return {base_, size_}; }
  std::size_t size() const { return size_; }

 private:
  const std::byte* base_ = nullptr;
  std::size_t size_ = 0;
};

/// Closes a descriptor on scope exit.
struct FdGuard {
  int fd = -1;
  ~FdGuard() {
    if (fd >= 0) ::close(fd);
  }
};

// ---------------------------------------------------------------- zstd contexts

struct CCtxFree {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxFree {
  void operator()(ZSTD_DCtx* c) const { ZSTD_freeDCtx(c); }
};

ZSTD_CCtx* threadCCtx() {
  thread_local std::unique_ptr<ZSTD_CCtx, CCtxFree> c(ZSTD_createCCtx());
  return c.get();
}

ZSTD_DCtx* threadDCtx() {
  thread_local std::unique_ptr<ZSTD_DCtx, DCtxFree> c(ZSTD_createDCtx());
  return c.get();
}

// ---------------------------------------------------------------- shared checks

/// The name of a record in messages: "module (kx,kz)" for the first record
/// (v1's whole module, v2's coarse record: v1's messages stand) and
/// "fine module (kx,kz)" for a v2 fine record.
std::string partName(std::uint32_t kx, std::uint32_t kz, Part part) {
  return (part == Part::fine ? "fine " : "") + moduleName(kx, kz);
}

Extent extentOf(const Entry& e, Part part) { return part == Part::fine ? e.fine : e.coarse(); }

/// Offset in modules.idx of a field of entry (kx, kz) (the first record's
/// fields are at the same place in both versions).
std::uint64_t fieldAt(const IndexHeader& h, std::uint32_t kx, std::uint32_t kz, std::size_t field) {
  return entryOffset(h, kx, kz) + field;
}

/// Checks the sizes and placement of one record of an entry.
Status checkExtent(const IndexHeader& h, const Extent& x, std::uint32_t kx, std::uint32_t kz, Part part,
                   const std::string& indexPath) {
  const bool fine = part == Part::fine;
  // Built only for a problem: a fine name does not fit the small-string
  // buffer, and a sound read must not allocate.
  auto name = [&] { return partName(kx, kz, part); };
  const std::size_t sizeField = fine ? entryFieldV2::fineCompressedBytes : entryField::compressedBytes;
  const std::size_t offsetField = fine ? entryFieldV2::fineOffset : entryField::offset;
  if (x.compressedBytes == 0) {
    return Problem{indexPath, fieldAt(h, kx, kz, sizeField),
                   fine ? "pack index: " + moduleName(kx, kz) + " has a coarse record but no fine record (coarse level " +
                              str(h.coarseLevel) + " needs one)"
                        : "pack index: " + name() + " is missing (its entry has no record)"};
  }
  if (x.compressedBytes > kMaxModuleBytes || x.rawBytes == 0 || x.rawBytes > kMaxModuleBytes) {
    return Problem{indexPath, fieldAt(h, kx, kz, sizeField),
                   "pack index: " + name() + " sizes (" + str(x.compressedBytes) + " compressed, " +
                       str(x.rawBytes) + " raw) are out of range (1 to " + str(kMaxModuleBytes) + " bytes)"};
  }
  if (x.offset < kPackHeaderBytes || x.offset > h.packBytes || x.compressedBytes > h.packBytes - x.offset) {
    return Problem{indexPath, fieldAt(h, kx, kz, offsetField),
                   "pack index: " + name() + " record at bytes " + str(x.offset) + ".." +
                       str(x.offset + x.compressedBytes - 1) + " is not within the records of modules.pack (bytes " +
                       str(kPackHeaderBytes) + ".." + str(h.packBytes - 1) + ")"};
  }
  return {};
}

/// Checks an entry against the index header, with no I/O. The problems
/// are in modules.idx; `placed` (when given) says whether its records lie
/// within the pack and have sane sizes, so that they can be read.
Status checkEntry(const IndexHeader& h, const Entry& e, std::uint32_t kx, std::uint32_t kz,
                  const std::string& indexPath, bool* placed = nullptr) {
  Status out;
  if (placed) *placed = false;
  const std::string name = moduleName(kx, kz);
  if (e.kx != kx || e.kz != kz) {
    out.add({indexPath, fieldAt(h, kx, kz, h.version >= kVersion2 ? entryFieldV2::kx : entryField::kx),
             "pack index: the entry of " + name + " names " + moduleName(e.kx, e.kz)});
  }
  if (const Status c = checkExtent(h, e.coarse(), kx, kz, Part::coarse, indexPath); !c) {
    out.merge(c);
    return out;
  }
  if (h.version >= kVersion2) {
    if (h.coarseLevel == 0) {
      if (e.fine.offset != 0 || e.fine.compressedBytes != 0 || e.fine.rawBytes != 0 || e.fine.compressedCrc != 0 ||
          e.fine.rawCrc != 0) {
        out.add({indexPath, fieldAt(h, kx, kz, entryFieldV2::fineOffset),
                 "pack index: " + name + " has a fine record, but coarse level 0 leaves none"});
        return out;
      }
    } else if (const Status f = checkExtent(h, e.fine, kx, kz, Part::fine, indexPath); !f) {
      out.merge(f);
      return out;
    }
  }
  if (placed) *placed = true;
  return out;
}

/// Checks a record's CRC, decompresses it and checks the raw size and (with
/// `checkRawCrc`) the raw CRC.
Result<std::vector<std::byte>> unpackRecord(const Extent& e, std::uint32_t kx, std::uint32_t kz, Part part,
                                            std::span<const std::byte> record,
                                            const std::string& packPath, bool checkRawCrc) {
  const std::string name = partName(kx, kz, part);
  auto fail = [&](const std::string& msg) {
    return Result<std::vector<std::byte>>(Problem{packPath, e.offset, "pack: " + name + msg});
  };
  if (record.size() != e.compressedBytes) {
    return fail(" record is " + str(record.size()) + " bytes, the index says " +
                str(e.compressedBytes));
  }
  const std::uint32_t c = crc32(record);
  if (c != e.compressedCrc) {
    return fail(" record checksum mismatch (stored " + crcHex(e.compressedCrc) + ", computed " +
                crcHex(c) + "): the pack is corrupt; rebuild the database");
  }
  std::vector<std::byte> raw;
  if (const Status z = decompress(record, e.rawBytes, raw); !z) {
    return fail(" record does not decompress: " + z.message());
  }
  if (!checkRawCrc) return raw;
  const std::uint32_t rc = crc32(raw);
  if (rc != e.rawCrc) {
    return fail(" decompressed checksum mismatch (stored " + crcHex(e.rawCrc) + ", computed " +
                crcHex(rc) + ")");
  }
  return raw;
}

/// Levels a record of `part` holds: v1 every level (coarse) and none
/// (fine); v2 coarse
/// levels - coarseLevel, fine coarseLevel.
std::uint32_t partLevels(const IndexHeader& h, Part part) {
  if (h.version < kVersion2) return part == Part::fine ? 0 : h.levels;
  return part == Part::fine ? h.coarseLevel : h.levels - h.coarseLevel;
}

/// Checks a decoded record's kx, kz and level count.
std::string checkDecoded(const IndexHeader& h, const module::Module& m, std::uint32_t kx, std::uint32_t kz,
                         Part part) {
  if (m.kx != kx || m.kz != kz) return ": the record holds " + moduleName(m.kx, m.kz);
  if (m.levels.size() != partLevels(h, part)) {
    return " has " + str(m.levels.size()) + " levels, the index says " + str(partLevels(h, part)) +
           (h.version >= kVersion2 ? std::string(part == Part::fine ? " (levels 0.." : " (levels ") +
                                         (part == Part::fine ? str(h.coarseLevel) + ")"
                                                             : str(h.coarseLevel) + ".." + str(h.levels) + ")")
                                   : "");
  }
  return "";
}

/// Decodes a record's raw bytes and checks it against its entry and index.
Result<module::Module> decodeRecord(const IndexHeader& h, const Extent& e, std::uint32_t kx,
                                    std::uint32_t kz, Part part, std::span<const std::byte> raw,
                                    const std::string& packPath) {
  const std::string name = partName(kx, kz, part);
  auto m = module::decode(raw, packPath, 0);
  if (!m) {
    const Problem& p = m.problems().front();
    return Problem{packPath, e.offset,
                   "pack: " + name + ", decompressed byte " + str(p.offset) + ": " + p.message};
  }
  if (m->kx != kx || m->kz != kz) {
    return Problem{packPath, e.offset,
                   "pack: the record of " + name + " holds " + moduleName(m->kx, m->kz)};
  }
  if (const std::string bad = checkDecoded(h, m.value(), kx, kz, part); !bad.empty()) {
    return Problem{packPath, e.offset, "pack: " + name + bad};
  }
  return m;
}

/// Opens modules.pack and checks its header; with the index header `h`,
/// also its size and header CRC. Returns the descriptor (or -1) and appends
/// problems to `out` (an open pack with a bad header still returns its
/// descriptor, so that validatePack can go on to the records).
int openPack(const std::string& packPath, const IndexHeader* h, Status& out) {
  const int fd = ::open(packPath.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    out.add({packPath, 0, std::string("pack: cannot open: ") + std::strerror(errno)});
    return -1;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    out.add({packPath, 0, "pack: not a regular file"});
    return -1;
  }
  const auto size = static_cast<std::uint64_t>(st.st_size);
  std::vector<std::byte> head(
      static_cast<std::size_t>(std::min<std::uint64_t>(size, kPackHeaderBytes)));
  if (const Status read = preadAll(fd, head.data(), head.size(), 0); !read) {
    ::close(fd);
    out.add({packPath, 0, "pack: cannot read the header: " + read.message()});
    return -1;
  }
  const Status header = checkPackHeader(head, packPath);
  const bool headerOk = header.ok();
  out.merge(header);
  if (h) {
    if (size != h->packBytes) {
      out.add({packPath, std::min(size, h->packBytes),
                     "pack: file is " + str(size) + " bytes but the index says " +
                         str(h->packBytes) +
                         (size < h->packBytes ? ": truncated" : ": trailing bytes") +
                         "; rebuild the database"});
    }
    // headerOk: the header is 64 bytes, so its version can be read.
    const std::uint32_t version = headerOk ? loadLE<std::uint32_t>(head.data() + packField::version) : 0;
    if (headerOk && version != h->version) {
      out.add({packPath, packField::version,
               "pack: version " + str(version) + " differs from the index's version " + str(h->version) +
                   ": modules.pack and modules.idx are not from the same build"});
    } else if (headerOk) {
      const std::uint32_t c = crc32(head);
      if (c != h->packHeaderCrc) {
        out.add({packPath, packField::headerCrc,
                       "pack: header checksum " + crcHex(c) + " differs from the index's " +
                           crcHex(h->packHeaderCrc) +
                           ": modules.pack and modules.idx are not from the same build"});
      }
    }
  }
  return fd;
}

Status checkTableCrc(const IndexHeader& h, std::span<const std::byte> index, const std::string& indexPath) {
  const std::uint32_t c = crc32(
      index.subspan(kIndexHeaderBytes, static_cast<std::size_t>(std::uint64_t(h.entryBytes()) * h.entryCount())));
  if (c == h.tableCrc) return {};
  return Problem{indexPath, kIndexHeaderBytes,
                 "pack index: entry table checksum mismatch (stored " + crcHex(h.tableCrc) + ", computed " +
                     crcHex(c) + "): the index is corrupt; rebuild the database"};
}

}  // namespace

// ---------------------------------------------------------------- headers

std::vector<std::byte> encodePackHeader(std::uint32_t version) {
  std::vector<std::byte> b(kPackHeaderBytes, std::byte{0});
  std::byte* p = b.data();
  std::memcpy(p + packField::magic, kPackMagic.data(), kPackMagic.size());
  storeLE<std::uint32_t>(p + packField::version, version);
  storeLE<std::uint32_t>(p + packField::headerBytes, kPackHeaderBytes);
  storeLE<std::uint32_t>(p + packField::flags, 0);
  storeLE<std::uint32_t>(p + packField::codec, kCodecZstd);
  storeLE<std::uint32_t>(p + packField::headerCrc, crc32(std::span(b).first(packField::headerCrc)));
  return b;
}

Status checkPackHeader(std::span<const std::byte> bytes, const std::string& file) {
  auto fail = [&](std::uint64_t off, const std::string& msg) { return Status(Problem{file, off, "pack: " + msg}); };
  if (bytes.size() < kPackHeaderBytes) {
    return fail(bytes.size(), "truncated: the header needs " + str(kPackHeaderBytes) +
                                  " bytes, the file ends at byte " + str(bytes.size()) +
                                  "; rebuild the database");
  }
  const std::byte* p = bytes.data();
  if (std::memcmp(p + packField::magic, kPackMagic.data(), kPackMagic.size()) != 0) {
    return fail(packField::magic, "bad magic: not a sandtable pack file (expected \"SANDPACK\")");
  }
  const auto version = loadLE<std::uint32_t>(p + packField::version);
  if (version < kVersion1 || version > kVersion) {
    return fail(packField::version, "version " + str(version) +
                                        " is not supported (this reader knows versions 1 to " +
                                        str(kVersion) + "); use a matching sandtable");
  }
  const auto stored = loadLE<std::uint32_t>(p + packField::headerCrc);
  const auto actual = crc32(bytes.first(packField::headerCrc));
  if (stored != actual) {
    return fail(packField::headerCrc, "header checksum mismatch (stored " + crcHex(stored) +
                                          ", computed " + crcHex(actual) +
                                          "): the header is corrupt; rebuild the database");
  }
  if (loadLE<std::uint32_t>(p + packField::headerBytes) != kPackHeaderBytes) {
    return fail(packField::headerBytes, "header size must be " + str(kPackHeaderBytes));
  }
  if (loadLE<std::uint32_t>(p + packField::flags) != 0) {
    return fail(packField::flags, "flags must be 0 in versions 1 and 2");
  }
  const auto codec = loadLE<std::uint32_t>(p + packField::codec);
  if (codec != kCodecZstd) {
    return fail(packField::codec, "codec " + str(codec) + " is not supported (1 = zstd)");
  }
  return {};
}

std::vector<std::byte> encodeIndexHeader(const IndexHeader& h) {
  std::vector<std::byte> page(kIndexHeaderBytes, std::byte{0});
  std::byte* p = page.data();
  std::memcpy(p + indexField::magic, kIndexMagic.data(), kIndexMagic.size());
  storeLE<std::uint32_t>(p + indexField::version, h.version);
  storeLE<std::uint32_t>(p + indexField::headerBytes, kIndexHeaderBytes);
  storeLE<std::uint32_t>(p + indexField::modulesX, h.modulesX);
  storeLE<std::uint32_t>(p + indexField::modulesZ, h.modulesZ);
  storeLE<std::uint32_t>(p + indexField::levels, h.levels);
  storeLE<std::uint32_t>(p + indexField::moduleSquares, h.moduleSquares);
  storeLE<double>(p + indexField::moduleSize, h.moduleSize);
  storeLE<std::uint64_t>(p + indexField::packBytes, h.packBytes);
  storeLE<std::uint32_t>(p + indexField::packHeaderCrc, h.packHeaderCrc);
  storeLE<std::uint32_t>(p + indexField::entryBytes, h.entryBytes());
  storeLE<std::uint64_t>(p + indexField::entryCount, h.entryCount());
  storeLE<std::uint64_t>(p + indexField::tableOffset, kIndexHeaderBytes);
  storeLE<std::uint32_t>(p + indexField::tableCrc, h.tableCrc);
  if (h.version >= kVersion2) {
    storeLE<std::uint32_t>(p + indexField::coarseLevel, h.coarseLevel);
    storeLE<std::uint32_t>(p + indexField::order, static_cast<std::uint32_t>(h.order));
  }
  storeLE<std::uint32_t>(p + indexField::headerCrc,
                         crc32(std::span(page).first(indexField::headerCrc)));
  return page;
}

Result<IndexHeader> decodeIndexHeader(std::span<const std::byte> bytes, const std::string& file,
                                      std::uint64_t fileSize) {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Result<IndexHeader>(Problem{file, off, "pack index: " + msg});
  };
  if (bytes.size() < kIndexHeaderFieldBytes) {
    return fail(bytes.size(), "truncated: the header needs " + str(kIndexHeaderFieldBytes) +
                                  " bytes, the file ends at byte " + str(bytes.size()) +
                                  "; rebuild the database");
  }
  const std::byte* p = bytes.data();
  if (std::memcmp(p + indexField::magic, kIndexMagic.data(), kIndexMagic.size()) != 0) {
    return fail(indexField::magic, "bad magic: not a sandtable pack index (expected \"SANDIDX1\")");
  }
  IndexHeader h;
  h.version = loadLE<std::uint32_t>(p + indexField::version);
  if (h.version < kVersion1 || h.version > kVersion) {
    return fail(indexField::version, "version " + str(h.version) +
                                         " is not supported (this reader knows versions 1 to " +
                                         str(kVersion) + "); use a matching sandtable");
  }
  const auto stored = loadLE<std::uint32_t>(p + indexField::headerCrc);
  const auto actual = crc32(bytes.first(indexField::headerCrc));
  if (stored != actual) {
    return fail(indexField::headerCrc, "header checksum mismatch (stored " + crcHex(stored) +
                                           ", computed " + crcHex(actual) +
                                           "): the header is corrupt; rebuild the database");
  }
  if (loadLE<std::uint32_t>(p + indexField::headerBytes) != kIndexHeaderBytes) {
    return fail(indexField::headerBytes, "header size must be " + str(kIndexHeaderBytes));
  }
  h.modulesX = loadLE<std::uint32_t>(p + indexField::modulesX);
  h.modulesZ = loadLE<std::uint32_t>(p + indexField::modulesZ);
  h.levels = loadLE<std::uint32_t>(p + indexField::levels);
  h.moduleSquares = loadLE<std::uint32_t>(p + indexField::moduleSquares);
  h.moduleSize = loadLE<double>(p + indexField::moduleSize);
  h.packBytes = loadLE<std::uint64_t>(p + indexField::packBytes);
  h.packHeaderCrc = loadLE<std::uint32_t>(p + indexField::packHeaderCrc);
  h.tableCrc = loadLE<std::uint32_t>(p + indexField::tableCrc);
  const auto entryBytes = loadLE<std::uint32_t>(p + indexField::entryBytes);
  const auto entryCount = loadLE<std::uint64_t>(p + indexField::entryCount);
  const auto tableOffset = loadLE<std::uint64_t>(p + indexField::tableOffset);

  for (const std::size_t f : {indexField::modulesX, indexField::modulesZ}) {
    const auto n = loadLE<std::uint32_t>(p + f);
    if (n < 1 || n > kMaxModulesPerAxis) {
      return fail(f, "module counts " + str(h.modulesX) + " x " + str(h.modulesZ) +
                         " are out of range (1 to " + str(kMaxModulesPerAxis) + " each)");
    }
  }
  if (h.levels < 1 || h.levels > module::kMaxLevels) {
    return fail(indexField::levels, "level count " + str(h.levels) + " is out of range (1 to " +
                                        str(module::kMaxLevels) + ")");
  }
  if (h.moduleSquares < 1 || h.moduleSquares > module::kMaxSquaresPerAxis) {
    return fail(indexField::moduleSquares, "module squares " + str(h.moduleSquares) +
                                               " is out of range (1 to " +
                                               str(module::kMaxSquaresPerAxis) + ")");
  }
  if (!(std::isfinite(h.moduleSize) && h.moduleSize > 0)) {
    return fail(indexField::moduleSize, "module size is not a finite positive number");
  }
  if (h.packBytes < kPackHeaderBytes) {
    return fail(indexField::packBytes, "pack size " + str(h.packBytes) +
                                           " is smaller than the pack header (" +
                                           str(kPackHeaderBytes) + " bytes)");
  }
  if (h.version >= kVersion2) {
    h.coarseLevel = loadLE<std::uint32_t>(p + indexField::coarseLevel);
    const auto order = loadLE<std::uint32_t>(p + indexField::order);
    if (h.coarseLevel >= h.levels) {
      return fail(indexField::coarseLevel, "coarse level " + str(h.coarseLevel) + " is out of range (0 to " +
                                               str(h.levels - 1) + " for " + str(h.levels) + " levels)");
    }
    if (order >= kPackOrderCount) {
      return fail(indexField::order, "record order " + str(order) + " is not known (0 = row-major, 1 = Morton)");
    }
    h.order = static_cast<PackOrder>(order);
  }
  if (entryBytes != h.entryBytes()) {
    return fail(indexField::entryBytes, "entry size must be " + str(h.entryBytes()) + " in version " + str(h.version));
  }
  if (entryCount != h.entryCount()) {
    return fail(indexField::entryCount, "entry count " + str(entryCount) + " is not " +
                                            str(h.modulesX) + " x " + str(h.modulesZ));
  }
  if (tableOffset != kIndexHeaderBytes) {
    return fail(indexField::tableOffset, "table offset must be " + str(kIndexHeaderBytes));
  }
  if (fileSize != h.indexBytes()) {
    return fail(std::min(fileSize, h.indexBytes()),
                "file is " + str(fileSize) + " bytes but the header says " + str(h.indexBytes()) +
                    (fileSize < h.indexBytes() ? ": truncated" : ": trailing bytes") +
                    "; rebuild the database");
  }
  return h;
}

void encodeEntry(const Entry& e, std::span<std::byte> out, std::uint32_t version) {
  assert(out.size() >= entryBytesOf(version));
  std::byte* p = out.data();
  storeLE<std::uint64_t>(p + entryField::offset, e.offset);
  storeLE<std::uint32_t>(p + entryField::compressedBytes, e.compressedBytes);
  storeLE<std::uint32_t>(p + entryField::rawBytes, e.rawBytes);
  storeLE<std::uint32_t>(p + entryField::compressedCrc, e.compressedCrc);
  storeLE<std::uint32_t>(p + entryField::rawCrc, e.rawCrc);
  if (version < kVersion2) {
    storeLE<std::uint32_t>(p + entryField::kx, e.kx);
    storeLE<std::uint32_t>(p + entryField::kz, e.kz);
    return;
  }
  storeLE<std::uint64_t>(p + entryFieldV2::fineOffset, e.fine.offset);
  storeLE<std::uint32_t>(p + entryFieldV2::fineCompressedBytes, e.fine.compressedBytes);
  storeLE<std::uint32_t>(p + entryFieldV2::fineRawBytes, e.fine.rawBytes);
  storeLE<std::uint32_t>(p + entryFieldV2::fineCompressedCrc, e.fine.compressedCrc);
  storeLE<std::uint32_t>(p + entryFieldV2::fineRawCrc, e.fine.rawCrc);
  storeLE<std::uint32_t>(p + entryFieldV2::kx, e.kx);
  storeLE<std::uint32_t>(p + entryFieldV2::kz, e.kz);
  storeLE<std::uint64_t>(p + entryFieldV2::reserved, 0);
}

Entry decodeEntry(std::span<const std::byte> in, std::uint32_t version) {
  assert(in.size() >= entryBytesOf(version));
  const std::byte* p = in.data();
  Entry e;
  e.offset = loadLE<std::uint64_t>(p + entryField::offset);
  e.compressedBytes = loadLE<std::uint32_t>(p + entryField::compressedBytes);
  e.rawBytes = loadLE<std::uint32_t>(p + entryField::rawBytes);
  e.compressedCrc = loadLE<std::uint32_t>(p + entryField::compressedCrc);
  e.rawCrc = loadLE<std::uint32_t>(p + entryField::rawCrc);
  if (version < kVersion2) {
    e.kx = loadLE<std::uint32_t>(p + entryField::kx);
    e.kz = loadLE<std::uint32_t>(p + entryField::kz);
    return e;
  }
  e.fine.offset = loadLE<std::uint64_t>(p + entryFieldV2::fineOffset);
  e.fine.compressedBytes = loadLE<std::uint32_t>(p + entryFieldV2::fineCompressedBytes);
  e.fine.rawBytes = loadLE<std::uint32_t>(p + entryFieldV2::fineRawBytes);
  e.fine.compressedCrc = loadLE<std::uint32_t>(p + entryFieldV2::fineCompressedCrc);
  e.fine.rawCrc = loadLE<std::uint32_t>(p + entryFieldV2::fineRawCrc);
  e.kx = loadLE<std::uint32_t>(p + entryFieldV2::kx);
  e.kz = loadLE<std::uint32_t>(p + entryFieldV2::kz);
  return e;
}

std::vector<std::uint32_t> moduleOrder(std::uint32_t modulesX, std::uint32_t modulesZ, PackOrder order) {
  std::vector<std::uint32_t> out(std::size_t(modulesX) * modulesZ);
  for (std::size_t k = 0; k < out.size(); ++k) out[k] = static_cast<std::uint32_t>(k);
  if (order == PackOrder::morton) {
    // Morton codes of a 65536 x 65536 grid fit in 32 bits; ties cannot occur.
    auto code = [&](std::uint32_t k) { return morton::encode(k % modulesX, k / modulesX); };
    std::sort(out.begin(), out.end(), [&](std::uint32_t a, std::uint32_t b) { return code(a) < code(b); });
  }
  return out;
}

// ---------------------------------------------------------------- zstd

std::vector<std::byte> compress(std::span<const std::byte> raw, int level) {
  std::vector<std::byte> out(ZSTD_compressBound(raw.size()));
  const std::size_t n =
      ZSTD_compressCCtx(threadCCtx(), out.data(), out.size(), raw.data(), raw.size(), level);
  if (ZSTD_isError(n)) return {};
  out.resize(n);
  return out;
}

Status decompress(std::span<const std::byte> packed, std::uint32_t rawBytes, std::vector<std::byte>& out) {
  const unsigned long long declared = ZSTD_getFrameContentSize(packed.data(), packed.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR) return Problem{"", 0, "not a zstd frame"};
  if (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared != rawBytes) {
    return Problem{"", 0, "the frame holds " + str(declared) + " bytes, the index says " + str(rawBytes)};
  }
  out.resize(rawBytes);
  const std::size_t n =
      ZSTD_decompressDCtx(threadDCtx(), out.data(), out.size(), packed.data(), packed.size());
  if (ZSTD_isError(n)) return Problem{"", 0, std::string("zstd: ") + ZSTD_getErrorName(n)};
  if (n != rawBytes) {
    return Problem{"", 0, "decompressed to " + str(n) + " bytes, the index says " + str(rawBytes)};
  }
  return {};
}

// ---------------------------------------------------------------- writer

struct PackWriter::State {
  std::string directory, packPath, indexPath, packTmp, indexTmp;
  std::string spillTmp;  ///< v2: records in append order, copied into the pack by finish()
  int fd = -1;
  int spillFd = -1;
  std::uint64_t spillEnd = 0;
  PackLayout layout;
  int level = kDefaultZstdLevel;
  IndexHeader header;
  mutable std::mutex mutex;
  std::vector<Entry> entries;            ///< row-major; compressedBytes == 0 until added
  std::uint64_t end = kPackHeaderBytes;  ///< bytes written to the pack so far
  std::uint32_t crc = 0;                 ///< CRC-32 of the pack bytes so far
  Status failed;                         ///< first write error; poisons the writer
  bool finished = false;
  std::uint32_t indexCrc = 0;
  std::uint64_t indexBytes = 0;

  ~State() {
    if (fd >= 0) ::close(fd);
    if (spillFd >= 0) {
      ::close(spillFd);
      ::unlink(spillTmp.c_str());
    }
    if (!finished) {
      ::unlink(packTmp.c_str());
      ::unlink(indexTmp.c_str());
    }
  }
};

PackWriter::PackWriter(std::unique_ptr<State> s) : state_(std::move(s)) {}
PackWriter::~PackWriter() = default;

Result<std::unique_ptr<PackWriter>> PackWriter::create(const std::string& directory,
                                                       const IndexHeader& header, int zstdLevel,
                                                       const PackLayout& layout) {
  auto fail = [&](const std::string& msg) {
    return Result<std::unique_ptr<PackWriter>>(Problem{directory, 0, "pack writer: " + msg});
  };
  if (header.modulesX < 1 || header.modulesZ < 1 || header.modulesX > kMaxModulesPerAxis ||
      header.modulesZ > kMaxModulesPerAxis) {
    return fail("module counts " + str(header.modulesX) + " x " + str(header.modulesZ) +
                " are out of range (1 to " + str(kMaxModulesPerAxis) + " each)");
  }
  if (header.levels < 1 || header.levels > module::kMaxLevels) {
    return fail("level count " + str(header.levels) + " is out of range (1 to " +
                str(module::kMaxLevels) + ")");
  }
  if (header.moduleSquares < 1 || header.moduleSquares > module::kMaxSquaresPerAxis) {
    return fail("module squares " + str(header.moduleSquares) + " is out of range");
  }
  if (!(std::isfinite(header.moduleSize) && header.moduleSize > 0)) {
    return fail("module size is not a finite positive number");
  }
  if (zstdLevel < ZSTD_minCLevel() || zstdLevel > ZSTD_maxCLevel()) {
    return fail("zstd level " + std::to_string(zstdLevel) + " is out of range (" +
                std::to_string(ZSTD_minCLevel()) + " to " + std::to_string(ZSTD_maxCLevel()) + ")");
  }
  if (layout.version < kVersion1 || layout.version > kVersion) {
    return fail("version " + str(layout.version) + " is not supported (1 to " + str(kVersion) + ")");
  }
  if (layout.version >= kVersion2 && layout.coarseLevel >= header.levels) {
    return fail("coarse level " + str(layout.coarseLevel) + " is out of range (0 to " + str(header.levels - 1) +
                " for " + str(header.levels) + " levels)");
  }
  if (static_cast<std::uint32_t>(layout.order) >= kPackOrderCount) return fail("unknown record order");
  if (layout.encode.version < module::kVersion || layout.encode.version > module::kNewestVersion) {
    return fail("module version " + str(layout.encode.version) + " is not 1, 2 or 3");
  }
  auto s = std::make_unique<State>();
  s->directory = directory;
  s->layout = layout;
  s->packPath = join(directory, kPackFileName);
  s->indexPath = join(directory, kIndexFileName);
  const std::string pid = std::to_string(::getpid());
  s->packTmp = s->packPath + ".tmp." + pid;
  s->indexTmp = s->indexPath + ".tmp." + pid;
  s->level = zstdLevel;
  s->header = header;
  s->header.version = layout.version;
  s->header.coarseLevel = layout.version >= kVersion2 ? layout.coarseLevel : 0;
  s->header.order = layout.version >= kVersion2 ? layout.order : PackOrder::rowMajor;
  s->entries.resize(static_cast<std::size_t>(header.entryCount()));
  s->fd = ::open(s->packTmp.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (s->fd < 0) return fail("cannot create " + s->packTmp + ": " + std::strerror(errno));
  if (layout.version >= kVersion2) {
    s->spillTmp = s->packPath + ".spill.tmp." + pid;
    s->spillFd = ::open(s->spillTmp.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (s->spillFd < 0) return fail("cannot create " + s->spillTmp + ": " + std::strerror(errno));
  }
  const auto head = encodePackHeader(layout.version);
  if (const Status w = pwriteAll(s->fd, head.data(), head.size(), 0); !w) {
    return fail("cannot write " + s->packTmp + ": " + w.message());
  }
  s->crc = crc32(head);
  s->header.packHeaderCrc = s->crc;
  return std::unique_ptr<PackWriter>(new PackWriter(std::move(s)));
}

Status PackWriter::add(const module::Module& m) {
  auto r = compress(m);
  if (!r) return Status(r.problems());
  return append(std::move(r.value()));
}

namespace {

/// Checks, encodes and compresses one record's module (the whole module,
/// or the levels of one v2 part); fills the extent's sizes and CRCs.
std::string compressPart(const module::Module& m, int level, const module::EncodeOptions& encode,
                         const std::string& name, std::vector<std::byte>& out, Extent& x) {
  if (const Status e = module::checkEncodable(m); !e) return name + ": " + e.message();
  if (const std::uint64_t n = module::encodedBytes(m); n > kMaxModuleBytes) {
    return name + " encodes to " + str(n) + " bytes, more than the " + str(kMaxModuleBytes) + " allowed";
  }
  const std::vector<std::byte> raw = module::encode(m, encode);
  // Decoding our own encoding checks everything checkEncodable leaves out
  // (index ranges, group order, squares), so a pack never holds a module
  // that its reader would refuse.
  if (auto back = module::decode(raw, "encoded module"); !back) {
    const Problem& p = back.problems().front();
    return name + " is malformed: " + p.message + " (byte " + str(p.offset) + " of its encoding)";
  }
  out = sandtable::pack::compress(raw, level);
  if (out.empty()) return name + ": zstd compression failed (out of memory?)";
  if (out.size() > kMaxModuleBytes) return name + " compresses to more than the allowed size";
  x.compressedBytes = static_cast<std::uint32_t>(out.size());
  x.rawBytes = static_cast<std::uint32_t>(raw.size());
  x.compressedCrc = crc32(out);
  x.rawCrc = crc32(raw);
  return "";
}

}  // namespace

Result<PackWriter::Record> PackWriter::compress(const module::Module& m) const {
  const State& s = *state_;
  const std::string name = "pack writer: " + moduleName(m.kx, m.kz);
  // Problems name the module, not a file: the pack is not in place yet.
  auto fail = [](const std::string& msg) { return Problem{"", 0, msg}; };
  if (m.kx >= s.header.modulesX || m.kz >= s.header.modulesZ) {
    return fail(name + " is outside the pack's " + str(s.header.modulesX) + " x " +
                str(s.header.modulesZ) + " modules");
  }
  if (m.levels.size() != s.header.levels) {
    return fail(name + " has " + str(m.levels.size()) + " levels, the pack holds " +
                str(s.header.levels));
  }
  Record r;
  Entry& e = r.entry;
  e.kx = m.kx;
  e.kz = m.kz;
  if (s.header.version < kVersion2) {
    Extent x;
    if (std::string bad = compressPart(m, s.level, s.layout.encode, name, r.bytes, x); !bad.empty()) return fail(bad);
    e.compressedBytes = x.compressedBytes;
    e.rawBytes = x.rawBytes;
    e.compressedCrc = x.compressedCrc;
    e.rawCrc = x.rawCrc;
    return r;
  }
  // v2: each part is a module of its own levels (module::encode knows no
  // level numbers; the index's coarseLevel gives them back).
  const auto split = m.levels.begin() + std::ptrdiff_t(s.header.coarseLevel);
  // Both records carry every object, each with its own levels' elevations.
  const module::Module coarse{m.kx, m.kz, std::vector<module::Level>(split, m.levels.end()), m.objects};
  Extent c;
  if (std::string bad = compressPart(coarse, s.level, s.layout.encode, name + " (coarse record)", r.bytes, c); !bad.empty()) {
    return fail(bad);
  }
  e.compressedBytes = c.compressedBytes;
  e.rawBytes = c.rawBytes;
  e.compressedCrc = c.compressedCrc;
  e.rawCrc = c.rawCrc;
  if (s.header.coarseLevel > 0) {
    const module::Module fine{m.kx, m.kz, std::vector<module::Level>(m.levels.begin(), split), m.objects};
    if (std::string bad = compressPart(fine, s.level, s.layout.encode, name + " (fine record)", r.fineBytes, e.fine); !bad.empty()) {
      return fail(bad);
    }
  }
  return r;
}

Status PackWriter::append(Record r) {
  State& s = *state_;
  Entry& e = r.entry;
  auto fail = [](const std::string& msg) { return Status(Problem{"", 0, msg}); };
  const std::lock_guard lock(s.mutex);
  if (s.finished) return fail("pack writer: add() after finish()");
  if (!s.failed) return s.failed;
  const bool v2 = s.header.version >= kVersion2;
  const bool needFine = v2 && s.header.coarseLevel > 0;
  if (e.kx >= s.header.modulesX || e.kz >= s.header.modulesZ || e.compressedBytes != r.bytes.size() ||
      e.fine.compressedBytes != r.fineBytes.size() || (needFine != !r.fineBytes.empty())) {
    return fail("pack writer: append() of a record that compress() did not make");
  }
  Entry& slot = s.entries[std::size_t(e.kz) * s.header.modulesX + e.kx];
  if (slot.compressedBytes != 0) return fail("pack writer: " + moduleName(e.kx, e.kz) + " was added twice");
  if (!v2) {
    e.offset = s.end;
    if (const Status w = pwriteAll(s.fd, r.bytes.data(), r.bytes.size(), s.end); !w) {
      s.failed = fail("pack writer: cannot write " + s.packTmp + ": " + w.message() + " (is the disk full?)");
      return s.failed;
    }
    s.end += r.bytes.size();
    s.crc = crc32(r.bytes, s.crc);
    slot = e;
    return {};
  }
  // v2: spill both records; until finish() the offsets are in the spill file.
  e.offset = s.spillEnd;
  e.fine.offset = r.fineBytes.empty() ? 0 : s.spillEnd + r.bytes.size();  // no fine record: all zero
  for (const auto* bytes : {&r.bytes, &r.fineBytes}) {
    if (const Status w = pwriteAll(s.spillFd, bytes->data(), bytes->size(), s.spillEnd); !w) {
      s.failed = fail("pack writer: cannot write " + s.spillTmp + ": " + w.message() + " (is the disk full?)");
      return s.failed;
    }
    s.spillEnd += bytes->size();
  }
  slot = e;
  return {};
}

namespace {

/// Copies the records of `entries` (offsets in the spill file) into the
/// pack at `end` in the order given, coarse records of every module first,
/// then fine records, and points each entry at its place in the pack.
/// Extends the pack's running CRC. Returns the error, or "".
std::string copySpilled(int spillFd, int packFd, std::vector<Entry>& entries, const std::vector<std::uint32_t>& order,
                        std::uint64_t& end, std::uint32_t& crc) {
  std::vector<std::byte> buf;
  constexpr std::size_t kBatch = 4u << 20;  // write in batches of a few MB: few syscalls
  std::vector<std::byte> out;
  out.reserve(kBatch + kMaxModuleBytes / 64);
  std::uint64_t outAt = end;
  auto flush = [&]() -> std::string {
    if (out.empty()) return "";
    if (const Status w = pwriteAll(packFd, out.data(), out.size(), outAt); !w) return w.message();
    crc = crc32(out, crc);
    outAt += out.size();
    out.clear();
    return "";
  };
  for (const Part part : {Part::coarse, Part::fine}) {
    for (const std::uint32_t k : order) {
      Entry& e = entries[k];
      std::uint64_t& offset = part == Part::fine ? e.fine.offset : e.offset;
      const std::uint32_t n = part == Part::fine ? e.fine.compressedBytes : e.compressedBytes;
      if (n == 0) continue;
      buf.resize(n);
      if (const Status r = preadAll(spillFd, buf.data(), n, offset); !r) return "cannot read the spill file: " + r.message();
      offset = end;
      end += n;
      out.insert(out.end(), buf.begin(), buf.end());
      if (out.size() >= kBatch) {
        if (std::string bad = flush(); !bad.empty()) return bad;
      }
    }
  }
  return flush();
}

}  // namespace

Status PackWriter::finish() {
  State& s = *state_;
  auto fail = [](const std::string& msg) { return Status(Problem{"", 0, msg}); };
  const std::lock_guard lock(s.mutex);
  if (s.finished) return fail("pack writer: finish() was already called");
  if (!s.failed) return s.failed;
  std::uint64_t missing = 0;
  std::size_t firstMissing = 0;
  for (std::size_t k = 0; k < s.entries.size(); ++k) {
    if (s.entries[k].compressedBytes == 0 && missing++ == 0) firstMissing = k;
  }
  if (missing > 0) {
    const auto kx = static_cast<std::uint32_t>(firstMissing % s.header.modulesX);
    const auto kz = static_cast<std::uint32_t>(firstMissing / s.header.modulesX);
    return fail("pack writer: " + str(missing) + " of " + str(s.entries.size()) +
                " modules were not added (the first is " + moduleName(kx, kz) + ")");
  }
  auto failWith = [&](const std::string& what) {
    s.failed = fail("pack writer: " + what);
    return s.failed;
  };
  if (s.spillFd >= 0) {
    const auto order = moduleOrder(s.header.modulesX, s.header.modulesZ, s.header.order);
    if (std::string bad = copySpilled(s.spillFd, s.fd, s.entries, order, s.end, s.crc); !bad.empty()) {
      return failWith("cannot write " + s.packTmp + ": " + bad + " (is the disk full?)");
    }
    ::close(s.spillFd);
    s.spillFd = -1;
    ::unlink(s.spillTmp.c_str());
  }
  std::vector<std::byte> index(static_cast<std::size_t>(s.header.indexBytes()), std::byte{0});
  const std::uint32_t entryBytes = s.header.entryBytes();
  for (std::size_t k = 0; k < s.entries.size(); ++k) {
    encodeEntry(s.entries[k], std::span(index).subspan(kIndexHeaderBytes + std::size_t(entryBytes) * k),
                s.header.version);
  }
  s.header.packBytes = s.end;
  s.header.tableCrc = crc32(std::span(index).subspan(kIndexHeaderBytes));
  const auto head = encodeIndexHeader(s.header);
  std::copy(head.begin(), head.end(), index.begin());

  if (::fsync(s.fd) != 0)
    return failWith("cannot flush " + s.packTmp + ": " + std::strerror(errno));
  FdGuard idx{::open(s.indexTmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
  if (idx.fd < 0) return failWith("cannot create " + s.indexTmp + ": " + std::strerror(errno));
  std::string err = pwriteAll(idx.fd, index.data(), index.size(), 0).message();
  if (err.empty() && ::fsync(idx.fd) != 0) err = std::strerror(errno);
  if (!err.empty()) return failWith("cannot write " + s.indexTmp + ": " + err);
  // The pack first, the index last: an index under its final name always
  // describes the pack beside it.
  if (::rename(s.packTmp.c_str(), s.packPath.c_str()) != 0) {
    return failWith("cannot rename " + s.packTmp + ": " + std::strerror(errno));
  }
  if (::rename(s.indexTmp.c_str(), s.indexPath.c_str()) != 0) {
    const std::string e = std::strerror(errno);
    ::unlink(s.packPath.c_str());
    return failWith("cannot rename " + s.indexTmp + ": " + e);
  }
  FdGuard dir{::open(s.directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (dir.fd >= 0) ::fsync(dir.fd);
  s.finished = true;
  s.indexCrc = crc32(index);
  s.indexBytes = index.size();
  return {};
}

SizeStats PackWriter::stats() const {
  const State& s = *state_;
  const std::lock_guard lock(s.mutex);
  SizeStats st;
  std::vector<std::uint32_t> sizes;
  sizes.reserve(s.entries.size());
  for (const Entry& e : s.entries) {
    if (e.compressedBytes == 0) continue;
    sizes.push_back(static_cast<std::uint32_t>(e.storedBytes()));  // both records: at most 2 x 64 MiB
    st.totalCompressed += e.storedBytes();
    st.totalRaw += e.storedRawBytes();
  }
  st.count = sizes.size();
  if (sizes.empty()) return st;
  std::sort(sizes.begin(), sizes.end());
  const std::size_t n = sizes.size();
  st.minCompressed = sizes.front();
  st.maxCompressed = sizes.back();
  st.medianCompressed = sizes[(n + 1) / 2 - 1];
  st.p95Compressed = sizes[(95 * n + 99) / 100 - 1];
  return st;
}

std::uint32_t PackWriter::packCrc() const {
  const std::lock_guard lock(state_->mutex);
  return state_->crc;
}
std::uint32_t PackWriter::indexCrc() const {
  const std::lock_guard lock(state_->mutex);
  return state_->indexCrc;
}
std::uint64_t PackWriter::packBytes() const {
  const std::lock_guard lock(state_->mutex);
  return state_->end;
}
std::uint64_t PackWriter::indexBytes() const {
  const std::lock_guard lock(state_->mutex);
  return state_->indexBytes;
}

// ---------------------------------------------------------------- reader

struct PackReader::State {
  std::string packPath, indexPath;
  MappedFile index;
  FdGuard pack;
  IndexHeader header;
};

PackReader::PackReader(std::unique_ptr<State> s) : state_(std::move(s)) {}
PackReader::~PackReader() = default;

Result<std::shared_ptr<const PackReader>> PackReader::open(const std::string& directory) {
  auto s = std::make_unique<State>();
  s->packPath = join(directory, kPackFileName);
  s->indexPath = join(directory, kIndexFileName);
  if (const Status mapped = s->index.open(s->indexPath); !mapped) {
    return Problem{s->indexPath, 0, "pack index: " + mapped.message()};
  }
  auto h = decodeIndexHeader(s->index.bytes(), s->indexPath, s->index.size());
  if (!h) return h.problems();
  s->header = h.value();
  if (const Status table = checkTableCrc(s->header, s->index.bytes(), s->indexPath); !table) {
    return table.problems();
  }
  Status pack;
  s->pack.fd = openPack(s->packPath, &s->header, pack);
  if (!pack) return pack.problems();
  return std::shared_ptr<const PackReader>(new PackReader(std::move(s)));
}

const IndexHeader& PackReader::header() const { return state_->header; }
int PackReader::packFd() const { return state_->pack.fd; }
std::string PackReader::packPath() const { return state_->packPath; }
std::string PackReader::indexPath() const { return state_->indexPath; }

Entry PackReader::entry(std::uint32_t kx, std::uint32_t kz) const {
  const IndexHeader& h = state_->header;
  assert(kx < h.modulesX && kz < h.modulesZ);
  return decodeEntry(state_->index.bytes().subspan(entryOffset(h, kx, kz), h.entryBytes()), h.version);
}

std::uint32_t PackReader::coarseLevel() const { return state_->header.coarseLevel; }

Result<std::vector<std::byte>> PackReader::unpack(std::uint32_t kx, std::uint32_t kz,
                                                  std::span<const std::byte> record, Part part) const {
  const Entry e = entry(kx, kz);
  if (const Status checked = checkEntry(state_->header, e, kx, kz, state_->indexPath); !checked) {
    return checked.problems();
  }
  if (part == Part::fine && partLevels(state_->header, Part::fine) == 0) {
    return Problem{state_->indexPath, 0, "pack: " + moduleName(kx, kz) + " has no fine record (version " +
                                             str(state_->header.version) + ", coarse level " +
                                             str(state_->header.coarseLevel) + ")"};
  }
  return unpackRecord(extentOf(e, part), kx, kz, part, record, state_->packPath, true);
}

namespace {

/// One pread of a record of (kx, kz), checked and decompressed.
Result<std::vector<std::byte>> readRecord(const IndexHeader& h, const Entry& e, std::uint32_t kx,
                                          std::uint32_t kz, Part part, int fd, const std::string& packPath,
                                          const std::string& indexPath, bool checkRawCrc) {
  if (const Status checked = checkEntry(h, e, kx, kz, indexPath); !checked) return checked.problems();
  if (partLevels(h, part) == 0) {
    return Problem{indexPath, 0, "pack: " + moduleName(kx, kz) + " has no fine record (version " + str(h.version) +
                                     ", coarse level " + str(h.coarseLevel) + ")"};
  }
  const Extent x = extentOf(e, part);
  thread_local std::vector<std::byte> record;  // reused: no allocation per read
  record.resize(x.compressedBytes);
  if (const Status read = preadAll(fd, record.data(), record.size(), x.offset); !read) {
    return Problem{packPath, x.offset,
                   "pack: cannot read the record of " + partName(kx, kz, part) + ": " + read.message()};
  }
  return unpackRecord(x, kx, kz, part, record, packPath, checkRawCrc);
}

/// Reads one record of (kx, kz) and decodes it into `out` (the part's
/// levels only), reusing per-thread buffers and out's capacity.
Status readPartInto(const IndexHeader& h, const Extent& x, std::uint32_t kx, std::uint32_t kz, Part part, int fd,
                    const std::string& packPath, module::Module& out) {
  thread_local std::vector<std::byte> record, raw;  // reused: no allocation per read
  record.resize(x.compressedBytes);
  // The name only on failure: "fine module (kx,kz)" is too long for the
  // small-string buffer, and a sound read must not allocate.
  auto fail = [&](const std::string& msg) {
    return Status(Problem{packPath, x.offset, "pack: " + partName(kx, kz, part) + msg});
  };
  if (const Status read = preadAll(fd, record.data(), record.size(), x.offset); !read) {
    return fail(": cannot read the record: " + read.message());
  }
  if (const std::uint32_t c = crc32(record); c != x.compressedCrc) {
    return fail(" record checksum mismatch (stored " + crcHex(x.compressedCrc) + ", computed " + crcHex(c) +
                "): the pack is corrupt; rebuild the database");
  }
  if (const Status z = decompress(record, x.rawBytes, raw); !z) {
    return fail(" record does not decompress: " + z.message());
  }
  if (const Status d = module::decodeInto(raw, packPath, 0, out); !d) {
    const Problem& p = d.problems().front();
    return fail(", decompressed byte " + str(p.offset) + ": " + p.message);
  }
  if (const std::string bad = checkDecoded(h, out, kx, kz, part); !bad.empty()) return fail(bad);
  return {};
}

/// Moves the levels of a decoded part into `out` at level `first` by
/// swapping vectors, so both keep their capacity from read to read.
void placeLevels(module::Module& part, std::uint32_t first, std::uint32_t levels, module::Module& out) {
  out.kx = part.kx;
  out.kz = part.kz;
  if (out.levels.size() != levels) out.levels.resize(levels);
  for (std::size_t l = 0; l < part.levels.size(); ++l) std::swap(part.levels[l], out.levels[first + l]);
  std::swap(part.objects, out.objects);  // the records' lists are the same (validate compares them)
}

}  // namespace

Result<std::vector<std::byte>> PackReader::readRaw(std::uint32_t kx, std::uint32_t kz, Part part) const {
  const State& s = *state_;
  return readRecord(s.header, entry(kx, kz), kx, kz, part, s.pack.fd, s.packPath, s.indexPath, true);
}

Result<module::Module> PackReader::read(std::uint32_t kx, std::uint32_t kz) const {
  module::Module m;
  if (Status r = readInto(kx, kz, m); !r) return r.problems();
  return m;
}

Status PackReader::readCoarseInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const {
  const State& s = *state_;
  const Entry e = entry(kx, kz);
  if (Status checked = checkEntry(s.header, e, kx, kz, s.indexPath); !checked) return checked.problems().front();
  if (s.header.version < kVersion2) {
    // The whole module decodes straight into `out`.
    return readPartInto(s.header, e.coarse(), kx, kz, Part::coarse, s.pack.fd, s.packPath, out);
  }
  thread_local module::Module part;  // its vectors trade places with out's: no allocation once warm
  if (Status r = readPartInto(s.header, e.coarse(), kx, kz, Part::coarse, s.pack.fd, s.packPath, part); !r) return r;
  placeLevels(part, s.header.coarseLevel, s.header.levels, out);
  return {};
}

Status PackReader::readFineInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const {
  const State& s = *state_;
  if (partLevels(s.header, Part::fine) == 0 || s.header.version < kVersion2) {
    if (out.levels.size() != s.header.levels) out.levels.resize(s.header.levels);
    return {};
  }
  const Entry e = entry(kx, kz);
  if (Status checked = checkEntry(s.header, e, kx, kz, s.indexPath); !checked) return checked.problems().front();
  thread_local module::Module part;
  if (Status r = readPartInto(s.header, e.fine, kx, kz, Part::fine, s.pack.fd, s.packPath, part); !r) return r;
  placeLevels(part, 0, s.header.levels, out);
  return {};
}

Status PackReader::readInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const {
  if (Status c = readCoarseInto(kx, kz, out); !c) return c;
  return readFineInto(kx, kz, out);
}

// ---------------------------------------------------------------- validate

namespace {

/// The pack's problems, at most `kPerKind` of each kind listed.
class Report : public CappedProblems<> {
 public:
  Report() : CappedProblems(kPerKind) {}
  Status take() { return CappedProblems::take("pack"); }

 private:
  static constexpr int kPerKind = 20;
};

struct Placed {
  Extent entry;  ///< the record's extent
  std::uint32_t kx = 0, kz = 0;
  Part part = Part::coarse;
};

}  // namespace

Status validatePack(const std::string& directory, const Work& work) {
  const std::string indexPath = join(directory, kIndexFileName);
  const std::string packPath = join(directory, kPackFileName);
  Report r;
  MappedFile index;
  IndexHeader h;
  bool haveHeader = false;
  if (const Status mapped = index.open(indexPath); !mapped) {
    r.add("index", Problem{indexPath, 0, "pack index: " + mapped.message()});
  } else if (auto dh = decodeIndexHeader(index.bytes(), indexPath, index.size()); !dh) {
    r.add("index", Status(dh.problems()));
  } else {
    h = dh.value();
    haveHeader = true;
  }
  Status packProblems;
  FdGuard pack{openPack(packPath, haveHeader ? &h : nullptr, packProblems)};
  r.add("pack", packProblems);
  if (!haveHeader) return r.take();

  const auto all = index.bytes();
  for (std::size_t k = kIndexHeaderFieldBytes; k < kIndexHeaderBytes; ++k) {
    if (all[k] != std::byte{0}) {
      r.add("index", Problem{indexPath, k, "pack index: header padding is not zero"});
      break;
    }
  }
  r.add("index", checkTableCrc(h, all, indexPath));
  // Reserved header bytes: the CRCs cover them, so only a writer that
  // resealed the CRC can put anything there; v1 and v2 write zeros.
  const std::size_t reservedFrom = h.version >= kVersion2 ? indexField::reservedV2 : indexField::reserved;
  for (std::size_t k = reservedFrom; k < indexField::headerCrc; ++k) {
    if (all[k] != std::byte{0}) {
      r.add("index", Problem{indexPath, k, "pack index: header reserved bytes " + str(reservedFrom) +
                                               "..123 are not zero"});
      break;
    }
  }
  if (pack.fd >= 0) {
    std::array<std::byte, kPackHeaderBytes> head{};
    if (preadAll(pack.fd, head.data(), head.size(), 0)) {
      for (std::size_t k = packField::reserved; k < packField::headerCrc; ++k) {
        if (head[k] != std::byte{0}) {
          r.add("pack", Problem{packPath, k, "pack: header reserved bytes 24..59 are not zero"});
          break;
        }
      }
    }
  }

  // Entries: each on its own, then their placement in the pack.
  std::vector<Placed> placed;
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      const Entry e = decodeEntry(all.subspan(entryOffset(h, kx, kz), h.entryBytes()), h.version);
      bool ok = false;
      r.add("entry", checkEntry(h, e, kx, kz, indexPath, &ok));
      if (h.version >= kVersion2) {
        const std::uint64_t at = entryOffset(h, kx, kz) + entryFieldV2::reserved;
        if (loadLE<std::uint64_t>(all.data() + at) != 0) {
          r.add("entry", Problem{indexPath, at, "pack index: the entry of " + moduleName(kx, kz) +
                                                    " has reserved bytes 56..63 that are not zero"});
        }
      }
      if (!ok) continue;
      placed.push_back({e.coarse(), kx, kz, Part::coarse});
      if (partLevels(h, Part::fine) > 0) placed.push_back({e.fine, kx, kz, Part::fine});
    }
  }
  std::sort(placed.begin(), placed.end(),
            [](const Placed& a, const Placed& b) { return a.entry.offset < b.entry.offset; });
  std::uint64_t covered = kPackHeaderBytes;  // end of the furthest record so far
  const Placed* last = nullptr;
  for (const Placed& p : placed) {
    const std::uint64_t begin = p.entry.offset, end = begin + p.entry.compressedBytes;
    if (begin < covered && last) {
      r.add("overlap",
            Problem{indexPath, entryOffset(h, p.kx, p.kz),
                    "pack index: the record of " + partName(p.kx, p.kz, p.part) + " (bytes " +
                        str(begin) + ".." + str(end - 1) + ") overlaps the record of " +
                        partName(last->kx, last->kz, last->part) + " (bytes " + str(last->entry.offset) +
                        ".." + str(last->entry.offset + last->entry.compressedBytes - 1) + ")"});
    } else if (begin > covered) {
      r.add("gap", Problem{packPath, covered,
                           "pack: bytes " + str(covered) + ".." + str(begin - 1) +
                               " are in no module's record"});
    }
    if (end > covered) {
      covered = end;
      last = &p;
    }
  }
  if (covered < h.packBytes) {
    r.add("gap", Problem{packPath, covered,
                         "pack: bytes " + str(covered) + ".." + str(h.packBytes - 1) +
                             " are in no module's record"});
  }

  // Records, in pack order (sequential reads).
  if (pack.fd < 0) return r.take();
  std::vector<std::byte> record;
  std::size_t done = 0;
  for (const Placed& p : placed) {
    if (done++ % 64 == 0) {
      work.report(double(done - 1) / double(placed.size()), "checking pack");
      if (work.cancelled()) {
        auto out = r.take();
        out.add({packPath, 0, kCancelledMessage});
        return out;
      }
    }
    record.resize(p.entry.compressedBytes);
    if (const Status read = preadAll(pack.fd, record.data(), record.size(), p.entry.offset); !read) {
      r.add("record",
            Problem{packPath, p.entry.offset,
                    "pack: cannot read the record of " + partName(p.kx, p.kz, p.part) + ": " + read.message()});
      continue;
    }
    auto raw = unpackRecord(p.entry, p.kx, p.kz, p.part, record, packPath, true);
    if (!raw) {
      r.add("record", Status(raw.problems()));
      continue;
    }
    auto m = decodeRecord(h, p.entry, p.kx, p.kz, p.part, raw.value(), packPath);
    if (!m) r.add("module", Status(m.problems()));
  }
  work.report(1.0, "checking pack");
  return r.take();
}

}  // namespace sandtable::pack
