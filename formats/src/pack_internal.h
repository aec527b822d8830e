#pragma once
// What the pack files' parts share (pack.h; docs/FORMAT.md §10): names in
// messages, file I/O (a mapped index, whole preads, per-thread zstd
// contexts) and the checks of entries and records that the reader and
// validatePack both make. Internal to formats/src/pack*.cpp.
#include <zstd.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/range_source.h"
#include "sandtable/formats/pack.h"

namespace sandtable::pack::detail {

inline std::string str(std::uint64_t v) { return std::to_string(v); }

inline std::string join(const std::string& directory, const char* name) {
  return (std::filesystem::path(directory) / name).string();
}

inline std::string moduleName(std::uint32_t kx, std::uint32_t kz) {
  return "module (" + str(kx) + "," + str(kz) + ")";
}

inline std::uint64_t entryOffset(const IndexHeader& h, std::uint32_t kx, std::uint32_t kz) {
  return kIndexHeaderBytes + std::uint64_t(h.entryBytes()) * (std::uint64_t(kz) * h.modulesX + kx);
}

// ---------------------------------------------------------------- file I/O

/// Reads exactly n bytes at `off` (a short file is an error). The problem
/// has no file, only the offset and the reason.
Status preadAll(int fd, std::byte* data, std::size_t n, std::uint64_t off);

/// Where a reader's pack bytes come from: a local descriptor, or a
/// RangeSource (a pack on a web server) when `remote` is set.
struct Source {
  int fd = -1;
  const RangeSource* remote = nullptr;
  /// Exactly n bytes at `off`; the problem's message says why not.
  Status read(std::byte* data, std::size_t n, std::uint64_t off) const;
};

/// A whole file mapped read-only (nothing mapped when it is empty).
class MappedFile {
 public:
  MappedFile() = default;
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  /// The problem names `path`; its message says why.
  Status open(const std::string& path);
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

/// This thread's zstd contexts, made on first use.
ZSTD_CCtx* threadCCtx();
ZSTD_DCtx* threadDCtx();

// ---------------------------------------------------------------- shared checks

/// The name of a record in messages: "module (kx,kz)" for the first record
/// (v1's whole module, v2's coarse record: v1's messages stand) and
/// "fine module (kx,kz)" for a v2 fine record.
std::string partName(std::uint32_t kx, std::uint32_t kz, Part part);

inline Extent extentOf(const Entry& e, Part part) { return part == Part::fine ? e.fine : e.coarse(); }

/// Offset in modules.idx of a field of entry (kx, kz) (the first record's
/// fields are at the same place in both versions).
std::uint64_t fieldAt(const IndexHeader& h, std::uint32_t kx, std::uint32_t kz, std::size_t field);

/// Checks the sizes and placement of one record of an entry.
Status checkExtent(const IndexHeader& h, const Extent& x, std::uint32_t kx, std::uint32_t kz, Part part,
                   const std::string& indexPath);

/// Checks an entry against the index header, with no I/O. The problems
/// are in modules.idx; `placed` (when given) says whether its records lie
/// within the pack and have sane sizes, so that they can be read.
Status checkEntry(const IndexHeader& h, const Entry& e, std::uint32_t kx, std::uint32_t kz,
                  const std::string& indexPath, bool* placed = nullptr);

/// Checks a record's CRC, decompresses it and checks the raw size and (with
/// `checkRawCrc`) the raw CRC.
Result<std::vector<std::byte>> unpackRecord(const Extent& e, std::uint32_t kx, std::uint32_t kz, Part part,
                                            std::span<const std::byte> record,
                                            const std::string& packPath, bool checkRawCrc);

/// Levels a record of `part` holds: v1 every level (coarse) and none
/// (fine); v2 coarse levels - coarseLevel, fine coarseLevel.
std::uint32_t partLevels(const IndexHeader& h, Part part);

/// Checks a decoded record's kx, kz and level count.
std::string checkDecoded(const IndexHeader& h, const module::Module& m, std::uint32_t kx, std::uint32_t kz,
                         Part part);

/// Decodes a record's raw bytes and checks it against its entry and index.
Result<module::Module> decodeRecord(const IndexHeader& h, const Extent& e, std::uint32_t kx,
                                    std::uint32_t kz, Part part, std::span<const std::byte> raw,
                                    const std::string& packPath);

/// Opens modules.pack and checks its header; with the index header `h`,
/// also its size and header CRC. Returns the descriptor (or -1) and appends
/// problems to `out` (an open pack with a bad header still returns its
/// descriptor, so that validatePack can go on to the records).
int openPack(const std::string& packPath, const IndexHeader* h, Status& out);
/// openPack's checks of the pack's first bytes (`head`, up to the header's
/// size) and its `size` (against the index header `h` when given), for a
/// pack read some other way (a RangeSource).
void checkPackHead(std::span<const std::byte> head, std::uint64_t size, const std::string& packPath, const IndexHeader* h,
                   Status& out);

/// Checks the entry table against the header's CRC.
Status checkTableCrc(const IndexHeader& h, std::span<const std::byte> index, const std::string& indexPath);

}  // namespace sandtable::pack::detail
