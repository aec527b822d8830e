// The checks of index entries and records that the pack reader and
// validatePack share (pack_internal.h), and opening modules.pack.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "pack_internal.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::pack::detail {

/// The name of a record in messages: "module (kx,kz)" for the first record
/// (v1's whole module, v2's coarse record: v1's messages stand) and
/// "fine module (kx,kz)" for a v2 fine record.
std::string partName(std::uint32_t kx, std::uint32_t kz, Part part) {
  return (part == Part::fine ? "fine " : "") + moduleName(kx, kz);
}

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
                  const std::string& indexPath, bool* placed) {
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

void checkPackHead(std::span<const std::byte> head, std::uint64_t size, const std::string& packPath, const IndexHeader* h,
                   Status& out) {
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
  checkPackHead(head, size, packPath, h, out);
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

}  // namespace sandtable::pack::detail
