#pragma once
// Pack files, version 1 (docs/FORMAT.md, "pack"): every load module of a
// database, each compressed on its own (zstd), appended to one pack file
// (modules.pack), plus a dense index (modules.idx) that gives each
// module's offset, size and checksums. Reading one module is one pread of
// the pack; the index is memory-mapped and needs no parsing.
//
// Thread safety: PackWriter::add may be called from several threads (it
// serialises appends); PackReader is immutable after open and every const
// method may be called from any thread.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sandtable/formats/module.h"
#include "sandtable/formats/result.h"

namespace sandtable::pack {

inline constexpr std::array<char, 8> kPackMagic = {'S', 'A', 'N', 'D', 'P', 'A', 'C', 'K'};
inline constexpr std::array<char, 8> kIndexMagic = {'S', 'A', 'N', 'D', 'I', 'D', 'X', '1'};
inline constexpr std::uint32_t kVersion = 1;
inline constexpr const char* kPackFileName = "modules.pack";
inline constexpr const char* kIndexFileName = "modules.idx";
/// Largest module accepted, compressed or not (hostile sizes are refused).
inline constexpr std::uint32_t kMaxModuleBytes = 64u << 20;

/// Index header fields (decoded).
struct IndexHeader {
  std::uint32_t version = kVersion;
  std::uint32_t modulesX = 0;
  std::uint32_t modulesZ = 0;
  std::uint32_t levels = 0;
  std::uint32_t moduleSquares = 0;  ///< level-0 squares along a module edge
  double moduleSize = 0;            ///< metres along a module edge
  std::uint64_t packBytes = 0;      ///< exact size of modules.pack
  std::uint32_t packHeaderCrc = 0;  ///< CRC-32 of the pack file's header
  std::uint32_t tableCrc = 0;       ///< CRC-32 of the entry table
};

/// One index entry: where module (kx, kz) lies in the pack.
struct Entry {
  std::uint64_t offset = 0;          ///< byte offset in modules.pack
  std::uint32_t compressedBytes = 0; ///< bytes stored in the pack
  std::uint32_t rawBytes = 0;        ///< bytes of module::encode output
  std::uint32_t compressedCrc = 0;   ///< CRC-32 of the stored bytes
  std::uint32_t rawCrc = 0;          ///< CRC-32 of the decompressed bytes
};

/// Size statistics over all modules (bytes).
struct SizeStats {
  std::uint64_t count = 0;
  std::uint64_t totalCompressed = 0;
  std::uint64_t totalRaw = 0;
  std::uint32_t minCompressed = 0, medianCompressed = 0, p95Compressed = 0, maxCompressed = 0;
};

/// Writes modules.pack and modules.idx into a directory. Files appear under
/// their final names only when finish() succeeds.
class PackWriter {
 public:
  static Result<std::unique_ptr<PackWriter>> create(const std::string& directory,
                                                     const IndexHeader& header,
                                                     int zstdLevel = 9);
  ~PackWriter();
  PackWriter(const PackWriter&) = delete;
  PackWriter& operator=(const PackWriter&) = delete;

  /// Compresses (in the calling thread) and appends one module. Each
  /// (kx, kz) must be added exactly once. Returns "" or an error.
  std::string add(const module::Module& m);
  /// Writes the index, fsyncs both files and renames them into place.
  std::string finish();
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
  /// Checks the index header, its table CRC and the pack header (O(table)).
  static Result<std::shared_ptr<const PackReader>> open(const std::string& directory);
  ~PackReader();
  PackReader(const PackReader&) = delete;
  PackReader& operator=(const PackReader&) = delete;

  const IndexHeader& header() const;
  Entry entry(std::uint32_t kx, std::uint32_t kz) const;
  /// Reads, checks (both CRCs) and decompresses one module: one pread.
  Result<std::vector<std::byte>> readRaw(std::uint32_t kx, std::uint32_t kz) const;
  /// readRaw + module::decode.
  Result<module::Module> read(std::uint32_t kx, std::uint32_t kz) const;
  int packFd() const;
  std::string packPath() const;

 private:
  struct State;
  explicit PackReader(std::unique_ptr<State> s);
  std::unique_ptr<State> state_;
};

/// Every structural check: index header and table CRC, pack header, every
/// entry within the pack, no overlaps, every module's CRCs and decode.
/// Each problem names the file and offset.
std::vector<Problem> validatePack(const std::string& directory);

/// Zstd helpers (exposed for tests and benchmarks).
std::vector<std::byte> compress(std::span<const std::byte> raw, int level);
/// Fails when the frame is corrupt or does not decompress to `rawBytes`.
bool decompress(std::span<const std::byte> packed, std::uint32_t rawBytes,
                std::vector<std::byte>& out, std::string& error);

}  // namespace sandtable::pack
