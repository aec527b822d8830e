#pragma once
// Pack files, version 1 (docs/FORMAT.md, "pack"): every load module of a
// database, each compressed on its own (zstd), appended to one pack file
// (modules.pack), plus a dense index (modules.idx) that gives each
// module's offset, size and checksums. Reading one module is one pread of
// the pack; the index is memory-mapped and needs no parsing.
//
// modules.pack: a 64-byte header, then the records (one zstd frame each)
// back to back in the order they were added. A record's place comes only
// from the index; the pack has no per-record header.
//
// modules.idx: a 4096-byte header page, then a table of modulesX * modulesZ
// entries of 32 bytes, row-major (entry kz * modulesX + kx). The table
// starts on a page boundary so it can be mapped and read in place.
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

namespace sandtable::pack {

inline constexpr std::array<char, 8> kPackMagic = {'S', 'A', 'N', 'D', 'P', 'A', 'C', 'K'};
inline constexpr std::array<char, 8> kIndexMagic = {'S', 'A', 'N', 'D', 'I', 'D', 'X', '1'};
inline constexpr std::uint32_t kVersion = 1;
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
inline constexpr std::uint32_t kEntryBytes = 32;
inline constexpr std::uint32_t kMaxModulesPerAxis = 65536;

/// Byte offsets of the pack header fields (bytes 24..59 are reserved, zero).
namespace packField {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, flags = 16, codec = 20,
                             reserved = 24, headerCrc = 60;
}
static_assert(packField::headerCrc + 4 == kPackHeaderBytes, "pack header layout");

/// Byte offsets of the index header fields (bytes 76..123 are reserved, zero).
namespace indexField {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, modulesX = 16, modulesZ = 20,
                             levels = 24, moduleSquares = 28, moduleSize = 32, packBytes = 40,
                             packHeaderCrc = 48, entryBytes = 52, entryCount = 56, tableOffset = 64,
                             tableCrc = 72, reserved = 76, headerCrc = 124;
}
static_assert(indexField::headerCrc + 4 == kIndexHeaderFieldBytes, "index header layout");

/// Byte offsets of the fields of one index entry.
namespace entryField {
inline constexpr std::size_t offset = 0, compressedBytes = 8, rawBytes = 12, compressedCrc = 16,
                             rawCrc = 20, kx = 24, kz = 28;
}
static_assert(entryField::kz + 4 == kEntryBytes, "index entry layout");

/// Index header fields (decoded).
struct IndexHeader {
  std::uint32_t version = kVersion;
  std::uint32_t modulesX = 0;       ///< 1..65536
  std::uint32_t modulesZ = 0;       ///< 1..65536
  std::uint32_t levels = 0;         ///< levels in every module, 1..16
  std::uint32_t moduleSquares = 0;  ///< level-0 squares along a module edge, 1..65536
  double moduleSize = 0;            ///< metres along a module edge
  std::uint64_t packBytes = 0;      ///< exact size of modules.pack
  std::uint32_t packHeaderCrc = 0;  ///< CRC-32 of all 64 bytes of the pack file's header (FORMAT.md 10.2)
  std::uint32_t tableCrc = 0;       ///< CRC-32 of the entry table

  std::uint64_t entryCount() const { return std::uint64_t(modulesX) * modulesZ; }
  /// Exact size of modules.idx.
  std::uint64_t indexBytes() const { return kIndexHeaderBytes + kEntryBytes * entryCount(); }
};

/// One index entry: where module (kx, kz) lies in the pack.
struct Entry {
  std::uint64_t offset = 0;           ///< byte offset in modules.pack
  std::uint32_t compressedBytes = 0;  ///< bytes stored in the pack; 0 = missing
  std::uint32_t rawBytes = 0;         ///< bytes of module::encode output
  std::uint32_t compressedCrc = 0;    ///< CRC-32 of the stored bytes
  std::uint32_t rawCrc = 0;           ///< CRC-32 of the decompressed bytes
  std::uint32_t kx = 0;               ///< the module's column, stored for self-check
  std::uint32_t kz = 0;               ///< the module's row, stored for self-check
};

/// Size statistics over the modules added so far (bytes). Median and p95
/// are nearest-rank: the sorted sizes' elements ceil(0.5 n) and
/// ceil(0.95 n) (1-based).
struct SizeStats {
  std::uint64_t count = 0;
  std::uint64_t totalCompressed = 0;
  std::uint64_t totalRaw = 0;
  std::uint32_t minCompressed = 0, medianCompressed = 0, p95Compressed = 0, maxCompressed = 0;
};

/// The 64-byte pack header (CRC filled in). It has no per-database fields.
std::vector<std::byte> encodePackHeader();
/// Checks a pack header: size, magic, version, CRC, header size, flags,
/// codec. Ok when sound. Messages start with "pack: ".
Status checkPackHeader(std::span<const std::byte> bytes, const std::string& file);

/// The 4096-byte index header page (entry count, table offset and header
/// CRC filled in from `h`).
std::vector<std::byte> encodeIndexHeader(const IndexHeader& h);
/// Decodes and checks an index header page; `fileSize` is the real size of
/// modules.idx, which must equal h.indexBytes(). Messages start with
/// "pack index: ". Does not check the table CRC or the padding.
Result<IndexHeader> decodeIndexHeader(std::span<const std::byte> bytes, const std::string& file,
                                      std::uint64_t fileSize);
/// One 32-byte entry.
void encodeEntry(const Entry& e, std::span<std::byte> out);
Entry decodeEntry(std::span<const std::byte> in);

/// Writes modules.pack and modules.idx into a directory. The files are
/// written as NAME.tmp.<pid> and appear under their final names only when
/// finish() succeeds; a writer destroyed before that removes them. Output
/// is deterministic for a given order of add() calls (no timestamps).
class PackWriter {
 public:
  /// `header` gives modulesX, modulesZ, levels, moduleSquares and
  /// moduleSize; the writer fills in the rest. Errors start "pack writer: ".
  static Result<std::unique_ptr<PackWriter>> create(const std::string& directory,
                                                    const IndexHeader& header,
                                                    int zstdLevel = kDefaultZstdLevel);
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
    Entry entry;                  ///< all but offset filled in
    std::vector<std::byte> bytes; ///< the compressed record
  };
  /// The checks, the encoding and the compression of add(), in the calling
  /// thread. Changes nothing in the writer; any thread, any time before
  /// finish(). The problems are add()'s.
  Result<Record> compress(const module::Module& m) const;
  /// The rest of add(), under the lock: appends the record at the end of
  /// the pack and fills its entry. Same errors and poisoning as add().
  Status append(Record r);
  /// Fails if any module was not added. Otherwise writes the index, fsyncs
  /// both files, renames them into place and fsyncs the directory.
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
  ~PackReader();
  PackReader(const PackReader&) = delete;
  PackReader& operator=(const PackReader&) = delete;

  const IndexHeader& header() const;
  /// The entry of module (kx, kz); kx < modulesX and kz < modulesZ (asserted).
  Entry entry(std::uint32_t kx, std::uint32_t kz) const;
  /// Reads, checks (both CRCs) and decompresses one module: one pread.
  Result<std::vector<std::byte>> readRaw(std::uint32_t kx, std::uint32_t kz) const;
  /// Checks and decompresses a record the caller read itself (for example
  /// with its own I/O on packFd()): `record` must be the entry's
  /// compressedBytes bytes at its offset.
  Result<std::vector<std::byte>> unpack(std::uint32_t kx, std::uint32_t kz,
                                        std::span<const std::byte> record) const;
  /// readRaw + module::decode, and the module's kx, kz and level count must
  /// match the entry and the index. (The raw CRC is not computed here:
  /// decode's header and payload CRCs cover the same bytes.)
  Result<module::Module> read(std::uint32_t kx, std::uint32_t kz) const;
  /// read into `out`, reusing its vectors' capacity and per-thread record
  /// and decompression buffers: a loader thread that reads module after
  /// module allocates nothing once its buffers have grown to the largest
  /// module. On failure returns read's problem.
  Status readInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const;
  int packFd() const;
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
