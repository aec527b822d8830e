// Pack files, versions 1 and 2 (pack.h; docs/FORMAT.md §10): the layout
// of the pack header, the index header and its entries, and the order of
// the records. Writing, reading and validating are in pack_writer.cpp,
// pack_reader.cpp and pack_validate.cpp.
#include "sandtable/formats/pack.h"

#include <algorithm>
#include <cassert>
#include <cstring>

#include "pack_internal.h"
#include "sandtable/base/morton.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::pack {
using namespace detail;

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

}  // namespace sandtable::pack
