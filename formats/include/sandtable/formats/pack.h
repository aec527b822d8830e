#pragma once
// Pack files, versions 1 and 2 (docs/FORMAT.md, "pack"): every load module
// of a database, each compressed on its own (zstd), in one pack file
// (modules.pack), plus a dense index (modules.idx) that gives each
// module's offsets, sizes and checksums. The index is memory-mapped and
// needs no parsing.
//
// Version 1: one record per module (all levels); reading a module is one
// pread. Version 2: two records per module, a small coarse record (levels
// coarseLevel .. levels-1, an encoded module::Module holding only those
// levels) and a fine record (levels 0 .. coarseLevel-1), so a pager can
// read the coarse version of many modules first, each in its own small
// read. All coarse records come first in the pack, then all fine records,
// each group in the index's `order` (Morton by default), so a strip of
// modules is a few sequential runs of bytes.
//
// modules.pack: a 64-byte header, then the records (one zstd frame each)
// back to back. A record's place comes only from the index; the pack has
// no per-record header.
//
// modules.idx: a 4096-byte header page, then a table of modulesX * modulesZ
// entries (32 bytes in v1, 64 in v2), row-major (entry kz * modulesX + kx).
// The table starts on a page boundary so it can be mapped and read in place.
//
// Thread safety: PackWriter::add may be called from several threads (it
// compresses in the calling thread and serialises appends); finish() must
// not race with add(). PackReader is immutable after open and every const
// method may be called from any thread.
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sandtable/formats/module.h"
#include "sandtable/base/result.h"
#include "sandtable/base/work.h"

namespace sandtable {
class RangeSource;
}

namespace sandtable::pack {

inline constexpr std::array<char, 8> kPackMagic = {'S', 'A', 'N', 'D', 'P', 'A', 'C', 'K'};
inline constexpr std::array<char, 8> kIndexMagic = {'S', 'A', 'N', 'D', 'I', 'D', 'X', '1'};
inline constexpr std::uint32_t kVersion1 = 1;  ///< one record per module
inline constexpr std::uint32_t kVersion2 = 2;  ///< a coarse and a fine record per module
/// The newest version this reader knows (it reads 1 .. kVersion).
inline constexpr std::uint32_t kVersion = kVersion2;
inline constexpr const char* kPackFileName = "modules.pack";
inline constexpr const char* kIndexFileName = "modules.idx";
/// Largest module accepted, compressed or not (hostile sizes are refused).
inline constexpr std::uint32_t kMaxModuleBytes = 64u << 20;
/// Default zstd level of PackWriter (docs: level 3, 9 and 19 compared).
inline constexpr int kDefaultZstdLevel = 9;

// ------------------------------------------------------------------ layout
inline constexpr std::uint32_t kPackHeaderBytes = 64;
/// Codec id in the pack header: every record is one zstd frame.
inline constexpr std::uint32_t kCodecZstd = 1;
inline constexpr std::uint32_t kIndexHeaderBytes = 4096;  ///< the header page
inline constexpr std::uint32_t kIndexHeaderFieldBytes =
    128;  ///< fields + CRC; rest of page is zero
inline constexpr std::uint32_t kEntryBytes = 32;    ///< v1 entry
inline constexpr std::uint32_t kEntryBytesV2 = 64;  ///< v2 entry
/// Bytes of one index entry in `version` (1 or 2).
constexpr std::uint32_t entryBytesOf(std::uint32_t version) { return version >= kVersion2 ? kEntryBytesV2 : kEntryBytes; }
inline constexpr std::uint32_t kMaxModulesPerAxis = 65536;

/// Byte offsets of the pack header fields (bytes 24..59 are reserved, zero).
namespace packField {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, flags = 16, codec = 20,
                             reserved = 24, headerCrc = 60;
}
static_assert(packField::headerCrc + 4 == kPackHeaderBytes, "pack header layout");

/// Byte offsets of the index header fields (v1: bytes 76..123 are reserved,
/// zero; v2: coarseLevel at 76, order at 80, bytes 84..123 reserved).
namespace indexField {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, modulesX = 16, modulesZ = 20,
                             levels = 24, moduleSquares = 28, moduleSize = 32, packBytes = 40,
                             packHeaderCrc = 48, entryBytes = 52, entryCount = 56, tableOffset = 64,
                             tableCrc = 72, reserved = 76, headerCrc = 124;
inline constexpr std::size_t coarseLevel = 76, order = 80, reservedV2 = 84;  ///< v2
}
static_assert(indexField::headerCrc + 4 == kIndexHeaderFieldBytes, "index header layout");

/// Byte offsets of the fields of one index entry.
namespace entryField {
inline constexpr std::size_t offset = 0, compressedBytes = 8, rawBytes = 12, compressedCrc = 16,
                             rawCrc = 20, kx = 24, kz = 28;
}
static_assert(entryField::kz + 4 == kEntryBytes, "index entry layout");

/// Byte offsets of the fields of one v2 index entry: the coarse record's
/// extent, the fine record's, kx, kz, then 8 reserved zero bytes.
namespace entryFieldV2 {
inline constexpr std::size_t offset = 0, compressedBytes = 8, rawBytes = 12, compressedCrc = 16,
                             rawCrc = 20, fineOffset = 24, fineCompressedBytes = 32, fineRawBytes = 36,
                             fineCompressedCrc = 40, fineRawCrc = 44, kx = 48, kz = 52, reserved = 56;
}
static_assert(entryFieldV2::reserved + 8 == kEntryBytesV2, "v2 index entry layout");

/// Order of the records in a v2 pack (index field `order`): all coarse
/// records in this order of their modules, then all fine records in it.
enum class PackOrder : std::uint32_t {
  rowMajor = 0,  ///< kz * modulesX + kx
  morton = 1,    ///< Z-order: the bits of kx and kz interleaved (kx in the even bits)
};
inline constexpr std::uint32_t kPackOrderCount = 2;

/// Index header fields (decoded).
struct IndexHeader {
  std::uint32_t version = kVersion1;  ///< PackWriter sets it from its PackLayout
  std::uint32_t modulesX = 0;       ///< 1..65536
  std::uint32_t modulesZ = 0;       ///< 1..65536
  std::uint32_t levels = 0;         ///< levels in every module, 1..16
  std::uint32_t moduleSquares = 0;  ///< level-0 squares along a module edge, 1..65536
  double moduleSize = 0;            ///< metres along a module edge
  std::uint64_t packBytes = 0;      ///< exact size of modules.pack
  std::uint32_t packHeaderCrc = 0;  ///< CRC-32 of all 64 bytes of the pack file's header (FORMAT.md 10.2)
  std::uint32_t tableCrc = 0;       ///< CRC-32 of the entry table
  /// v2: the coarse record holds levels coarseLevel .. levels-1, the fine
  /// record levels 0 .. coarseLevel-1 (none when 0); 0 .. levels-1. v1: 0.
  std::uint32_t coarseLevel = 0;
  PackOrder order = PackOrder::rowMajor;  ///< v2: record order (v1: append order, not stored)

  std::uint64_t entryCount() const { return std::uint64_t(modulesX) * modulesZ; }
  std::uint32_t entryBytes() const { return entryBytesOf(version); }
  /// Exact size of modules.idx.
  std::uint64_t indexBytes() const { return kIndexHeaderBytes + std::uint64_t(entryBytes()) * entryCount(); }
};

/// Where one record lies in the pack, and its checksums.
struct Extent {
  std::uint64_t offset = 0;           ///< byte offset in modules.pack
  std::uint32_t compressedBytes = 0;  ///< bytes stored in the pack; 0 = none
  std::uint32_t rawBytes = 0;         ///< bytes of module::encode output
  std::uint32_t compressedCrc = 0;    ///< CRC-32 of the stored bytes
  std::uint32_t rawCrc = 0;           ///< CRC-32 of the decompressed bytes
};

/// One index entry: where module (kx, kz) lies in the pack. The first five
/// fields are the first record: the whole module in v1, its coarse levels
/// in v2 (compressedBytes 0: the module is missing).
struct Entry {
  std::uint64_t offset = 0;           ///< byte offset in modules.pack
  std::uint32_t compressedBytes = 0;  ///< bytes stored in the pack; 0 = missing
  std::uint32_t rawBytes = 0;         ///< bytes of module::encode output
  std::uint32_t compressedCrc = 0;    ///< CRC-32 of the stored bytes
  std::uint32_t rawCrc = 0;           ///< CRC-32 of the decompressed bytes
  std::uint32_t kx = 0;               ///< the module's column, stored for self-check
  std::uint32_t kz = 0;               ///< the module's row, stored for self-check
  Extent fine;                        ///< v2: the fine record (none in v1 or when coarseLevel is 0)

  Extent coarse() const { return {offset, compressedBytes, rawBytes, compressedCrc, rawCrc}; }
  /// Bytes a whole read of the module fetches (both records).
  std::uint64_t storedBytes() const { return std::uint64_t(compressedBytes) + fine.compressedBytes; }
  /// Decoded bytes of both records.
  std::uint64_t storedRawBytes() const { return std::uint64_t(rawBytes) + fine.rawBytes; }
};

/// The record of a module a partial read fetches: the coarse (first)
/// record, which in v1 is the whole module, or the v2 fine record.
enum class Part { coarse, fine };

/// Size statistics over the modules added so far (bytes). Median and p95
/// are nearest-rank: the sorted sizes' elements ceil(0.5 n) and
/// ceil(0.95 n) (1-based).
struct SizeStats {
  std::uint64_t count = 0;
  std::uint64_t totalCompressed = 0;
  std::uint64_t totalRaw = 0;
  std::uint32_t minCompressed = 0, medianCompressed = 0, p95Compressed = 0, maxCompressed = 0;
};

/// The 64-byte pack header of `version` (CRC filled in). It has no
/// per-database fields.
std::vector<std::byte> encodePackHeader(std::uint32_t version = kVersion1);
/// Checks a pack header: size, magic, version (1 .. kVersion), CRC, header
/// size, flags, codec. Ok when sound. Messages start with "pack: ".
Status checkPackHeader(std::span<const std::byte> bytes, const std::string& file);

/// The 4096-byte index header page (entry count, table offset and header
/// CRC filled in from `h`).
std::vector<std::byte> encodeIndexHeader(const IndexHeader& h);
/// Decodes and checks an index header page; `fileSize` is the real size of
/// modules.idx, which must equal h.indexBytes(). Messages start with
/// "pack index: ". Does not check the table CRC or the padding.
Result<IndexHeader> decodeIndexHeader(std::span<const std::byte> bytes, const std::string& file,
                                      std::uint64_t fileSize);
/// One entry of `version`: 32 bytes (v1; `fine` is not stored) or 64 (v2).
void encodeEntry(const Entry& e, std::span<std::byte> out, std::uint32_t version = kVersion1);
Entry decodeEntry(std::span<const std::byte> in, std::uint32_t version = kVersion1);

/// The linear indices (kz * modulesX + kx) of every module in `order`.
std::vector<std::uint32_t> moduleOrder(std::uint32_t modulesX, std::uint32_t modulesZ, PackOrder order);

/// How PackWriter lays out the pack. The default is version 1 (one record
/// per module, in append order). split() is version 2.
struct PackLayout {
  std::uint32_t version = kVersion1;
  /// v2: levels >= coarseLevel go in the coarse record (< levels).
  std::uint32_t coarseLevel = 0;
  PackOrder order = PackOrder::rowMajor;  ///< v2 only
  /// How every record's module is encoded (docs/FORMAT.md §9, §9.7): the
  /// module version and height step, independent of the pack version.
  module::EncodeOptions encode = {};
  /// Version 2 with the documented default split: levels >= levels / 2 in
  /// the coarse record (levels 2 and 3 of 4: 1/16 + 1/64 of the level-0
  /// lattice), records in Morton order.
  static PackLayout split(std::uint32_t levels, PackOrder order = PackOrder::morton) {
    return {kVersion2, levels / 2, order, {}};
  }
};

/// Writes modules.pack and modules.idx into a directory. The files are
/// written as NAME.tmp.<pid> and appear under their final names only when
/// finish() succeeds; a writer destroyed before that removes them. Output
/// is deterministic for a given order of add() calls (no timestamps).
class PackWriter {
 public:
  /// `header` gives modulesX, modulesZ, levels, moduleSquares and
  /// moduleSize; the writer fills in the rest. Errors start "pack writer: ".
  /// `layout` picks version 1 or 2 (docs/FORMAT.md 10.3).
  static Result<std::unique_ptr<PackWriter>> create(const std::string& directory,
                                                    const IndexHeader& header,
                                                    int zstdLevel = kDefaultZstdLevel,
                                                    const PackLayout& layout = {});
  ~PackWriter();
  PackWriter(const PackWriter&) = delete;
  PackWriter& operator=(const PackWriter&) = delete;

  /// Checks (module::checkEncodable, then module::decode of the encoding,
  /// kx/kz within the pack, level count), encodes and compresses in the
  /// calling thread, then appends under a lock. Each (kx, kz) must be added
  /// exactly once. A failed write poisons the writer (every later call
  /// fails). Problems name no file (offset 0); messages start "pack writer: ".
  Status add(const module::Module& m);

  /// add() in two halves, so a caller can compress on many threads and
  /// append in an order of its choosing (the build appends in row-major
  /// module order, which makes the pack independent of thread timing).
  struct Record {
    Entry entry;                  ///< all but the offsets filled in
    std::vector<std::byte> bytes; ///< the compressed (v2: coarse) record
    std::vector<std::byte> fineBytes;  ///< v2: the compressed fine record (empty without one)
  };
  /// The checks, the encoding and the compression of add(), in the calling
  /// thread. Changes nothing in the writer; any thread, any time before
  /// finish(). The problems are add()'s.
  Result<Record> compress(const module::Module& m) const;
  /// The rest of add(), under the lock: appends the record at the end of
  /// the pack (v2: of a spill file, which finish() copies into the pack in
  /// the layout's order) and fills its entry. Same errors and poisoning as add().
  Status append(Record r);
  /// Fails if any module was not added. Otherwise (v2: writes the records
  /// into the pack in order,) writes the index, fsyncs both files, renames
  /// them into place and fsyncs the directory.
  Status finish();
  SizeStats stats() const;
  /// CRC-32 and size of each file, valid after finish() (for the manifest).
  std::uint32_t packCrc() const;
  std::uint32_t indexCrc() const;
  std::uint64_t packBytes() const;
  std::uint64_t indexBytes() const;

 private:
  struct State;
  explicit PackWriter(std::unique_ptr<State> s);
  std::unique_ptr<State> state_;
};

/// A read-only pack: the index is memory-mapped, the pack is read by pread.
class PackReader {
 public:
  /// Checks the index header, its table CRC, the pack header, its CRC
  /// against the index and the pack's size (O(table)). Does not read any
  /// record; validatePack does.
  static Result<std::shared_ptr<const PackReader>> open(const std::string& directory);
  /// The same over bytes that are not local files (issue 38, a database
  /// on a web server): the index's bytes as read (`indexName` names them
  /// in messages) and the pack read by range through `pack`. The same
  /// checks; a record whose checksum fails is read once more, after
  /// pack->refresh(), before it is an error. packFd() is -1.
  static Result<std::shared_ptr<const PackReader>> openRemote(std::vector<std::byte> index, const std::string& indexName,
                                                              std::shared_ptr<const RangeSource> pack);
  ~PackReader();
  PackReader(const PackReader&) = delete;
  PackReader& operator=(const PackReader&) = delete;

  const IndexHeader& header() const;
  /// The entry of module (kx, kz); kx < modulesX and kz < modulesZ (asserted).
  Entry entry(std::uint32_t kx, std::uint32_t kz) const;
  /// Reads, checks (both CRCs) and decompresses one record: one pread. In
  /// v1 the coarse part is the whole module; a v2 record is the encoding of
  /// a module holding only that part's levels.
  Result<std::vector<std::byte>> readRaw(std::uint32_t kx, std::uint32_t kz, Part part = Part::coarse) const;
  /// Checks and decompresses a record the caller read itself (for example
  /// with its own I/O on packFd()): `record` must be the part's
  /// compressedBytes bytes at its offset.
  Result<std::vector<std::byte>> unpack(std::uint32_t kx, std::uint32_t kz, std::span<const std::byte> record,
                                        Part part = Part::coarse) const;
  /// The finest level the coarse record holds: the index's coarseLevel in
  /// v2, 0 in v1 (the first record holds every level).
  std::uint32_t coarseLevel() const;
  /// Reads the coarse record into `out` (one pread, CRC, zstd, decode),
  /// reusing capacity as readInto does: out.levels is sized to the index's
  /// level count and levels coarseLevel() .. levels-1 are written with
  /// their own level numbers; the others are left as they were. out.kx and
  /// out.kz are set. Problems as read's.
  Status readCoarseInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const;
  /// Reads the v2 fine record into levels 0 .. coarseLevel()-1 of `out`
  /// (sized as above; the coarse levels are left as they were). Nothing to
  /// read (v1, or coarseLevel() 0): ok, `out` untouched but for its size.
  Status readFineInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const;
  /// The whole module: v1 readRaw + module::decode, v2 both records, and
  /// the module's kx, kz and level count must match the entry and the
  /// index. (The raw CRC is not computed here: decode's header and payload
  /// CRCs cover the same bytes.)
  Result<module::Module> read(std::uint32_t kx, std::uint32_t kz) const;
  /// read into `out` (readCoarseInto, then readFineInto), reusing its
  /// vectors' capacity and per-thread record and decompression buffers: a
  /// loader thread that reads module after module allocates nothing once
  /// its buffers have grown to the largest module. On failure returns
  /// read's problem.
  Status readInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const;
  /// The pack's descriptor; -1 when it is read through remote().
  int packFd() const;
  /// The pack's RangeSource (openRemote), or null for a local file.
  const RangeSource* remote() const;
  std::string packPath() const;
  std::string indexPath() const;

 private:
  struct State;
  explicit PackReader(std::unique_ptr<State> s);
  std::unique_ptr<State> state_;
};

/// Every structural check: index header, padding, reserved bytes and table
/// CRC, pack header, its reserved bytes and its CRC against the index, pack size, every entry's kx/kz, sizes and
/// placement within the pack (after the header, no overlaps, no bytes
/// outside every record), every record's CRCs, every module's decode and
/// its kx, kz and level count. Each problem names the file and offset; at
/// most 20 problems of each kind are listed. Ok when the pack is sound.
/// Progress: "checking pack", per record.
Status validatePack(const std::string& directory, const Work& work = {});

/// Zstd helpers (exposed for tests and benchmarks). compress returns one
/// frame with the content size recorded, or an empty vector if zstd fails
/// (out of memory). Both keep one zstd context per thread.
std::vector<std::byte> compress(std::span<const std::byte> raw, int level);
/// Fails when the frame is corrupt or does not decompress to `rawBytes`
/// (the problem names no file). Never allocates more than `rawBytes` for
/// `out`, whose capacity is reused.
Status decompress(std::span<const std::byte> packed, std::uint32_t rawBytes, std::vector<std::byte>& out);

}  // namespace sandtable::pack
