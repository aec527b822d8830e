#pragma once
// A build part, version 1 (docs/FORMAT.md, "part"): what one task of a
// distributed build (issue 38; docs/DISTRIBUTED.md) hands to the merge.
// One file per task, little-endian:
//
//   header   64 bytes: magic "SANDPART", version, the plan's CRC, the task,
//            the grid block rows and load-module rows it holds, header CRC
//   blocks   blockRows x blocksX times: the block's grid table entry
//            (16 bytes, as in grid.stg) then its kBlockBytes bytes
//   modules  moduleRows x modulesX times: the module's pack v2 index entry
//            (64 bytes, offsets 0), its coarse record, its fine record
//   report   reportBytes of JSON (the task's counts, for the manifest)
//   trailer  20 bytes: reportBytes (u64), "SANDPEND", CRC-32 of every byte
//            before the CRC
//
// Blocks and modules are in row-major order, so the merge copies them into
// grid.stg and modules.pack in one forward pass over each part.
//
// Thread safety: a PartWriter or PartReader is used by one thread at a
// time; distinct ones may run concurrently.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/pack.h"

namespace sandtable::part {

inline constexpr std::array<char, 8> kMagic = {'S', 'A', 'N', 'D', 'P', 'A', 'R', 'T'};
inline constexpr std::array<char, 8> kEndMagic = {'S', 'A', 'N', 'D', 'P', 'E', 'N', 'D'};
inline constexpr std::uint32_t kVersion = 1;
inline constexpr std::uint32_t kHeaderBytes = 64;
inline constexpr std::uint32_t kTrailerBytes = 20;
inline constexpr std::uint32_t kBlockEntryBytes = grid::kBlockEntryBytes;  ///< 16
inline constexpr std::uint32_t kModuleEntryBytes = pack::kEntryBytesV2;    ///< 64
/// Caps on sizes read from a part, checked before anything is allocated.
inline constexpr std::uint64_t kMaxReportBytes = 16ull << 20;
inline constexpr std::uint32_t kMaxRecordBytes = 256u << 20;
/// Cap on blocksX, modulesX and on the end of each row range.
inline constexpr std::uint32_t kMaxPerAxis = 1u << 22;

/// Header field offsets; shared by writer, reader and docs.
namespace field {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, planCrc = 16, task = 20, blockRow0 = 24,
                             blockRows = 28, blocksX = 32, moduleRow0 = 36, moduleRows = 40, modulesX = 44,
                             levels = 48, reserved = 52, headerCrc = 60;
}
static_assert(field::headerCrc + 4 == kHeaderBytes, "part header layout");

struct Header {
  std::uint32_t version = kVersion;
  std::uint32_t planCrc = 0;  ///< CRC-32 of the plan file's bytes
  std::uint32_t task = 0;
  std::uint32_t blockRow0 = 0, blockRows = 0, blocksX = 0;     ///< grid block rows [blockRow0, +blockRows)
  std::uint32_t moduleRow0 = 0, moduleRows = 0, modulesX = 0;  ///< load-module rows [moduleRow0, +moduleRows)
  std::uint32_t levels = 0;  ///< levels of detail per module
  std::uint64_t blockCount() const { return std::uint64_t(blockRows) * blocksX; }
  std::uint64_t moduleCount() const { return std::uint64_t(moduleRows) * modulesX; }
};

/// The 64 header bytes (CRC filled in).
std::array<std::byte, kHeaderBytes> encodeHeader(const Header& h);
/// Checks magic, version, CRC, header size, reserved bytes and that the
/// counts are sane (blocksX, modulesX <= 2^22, row ranges ending at or
/// before row 2^22, levels 1..module::kMaxLevels = 16, as a pack allows).
/// Problems name `file` and the field's offset.
Result<Header> decodeHeader(std::span<const std::byte> bytes, const std::string& file);

/// Writes a part as PATH.tmp.<pid>; finish() renames it to PATH after an
/// fsync, so a killed task leaves no part (and no torn one). A writer
/// destroyed before finish() removes its temporary file. Problems name the
/// path; messages start "part writer: ".
class PartWriter {
 public:
  static Result<std::unique_ptr<PartWriter>> create(const std::string& path, const Header& h);
  ~PartWriter();
  PartWriter(const PartWriter&) = delete;
  PartWriter& operator=(const PartWriter&) = delete;

  /// The next block in row-major order: its table entry and kBlockBytes bytes.
  Status addBlock(const grid::BlockEntry& e, std::span<const std::byte> bytes);
  /// The next module in row-major order: its entry (offsets ignored; the
  /// records' sizes must equal the entry's compressedBytes) and records.
  Status addModule(const pack::Entry& e, std::span<const std::byte> coarse, std::span<const std::byte> fine);
  /// Fails unless every block and module was added; writes the report and
  /// the trailer, fsyncs, renames into place.
  Status finish(std::string_view reportJson);
  /// CRC-32 in the trailer, valid after finish().
  std::uint32_t crc() const { return crc_; }

 private:
  PartWriter(std::string path, std::string tmp, int fd, Header h);
  Status put(std::span<const std::byte> bytes);
  std::string path_, tmp_;
  int fd_ = -1;
  Header header_;
  std::uint64_t offset_ = 0, blocks_ = 0, modules_ = 0;
  std::uint32_t crc_ = 0;
  bool finished_ = false, failed_ = false;
  std::string failure_;  ///< the failed write's message, repeated by every later call
};

/// One module as the part holds it.
struct ModuleRecord {
  pack::Entry entry;  ///< offsets 0
  std::vector<std::byte> coarse, fine;
};

/// Reads a part forwards. open() checks the header, the trailer's magic and
/// that the report fits; verify() reads every byte once (bounded memory)
/// and checks the CRC and that the records end exactly at the report.
/// Problems name the file and the byte offset.
class PartReader {
 public:
  static Result<std::unique_ptr<PartReader>> open(const std::string& path);
  ~PartReader();
  PartReader(const PartReader&) = delete;
  PartReader& operator=(const PartReader&) = delete;

  const Header& header() const { return header_; }
  const std::string& path() const { return path_; }
  std::uint64_t fileBytes() const { return size_; }
  /// The trailer's CRC (as stored).
  std::uint32_t storedCrc() const { return storedCrc_; }
  /// The report's JSON text (read by open).
  const std::string& report() const { return report_; }
  Status verify() const;

  /// The next block: its entry, and its bytes into `out` (kBlockBytes).
  /// The block's CRC is checked against its entry.
  Result<grid::BlockEntry> nextBlock(std::span<std::byte> out);
  /// The next module, after every block was read. Sizes are checked against
  /// kMaxRecordBytes and the bytes left before the report first.
  Result<ModuleRecord> nextModule();

 private:
  PartReader() = default;
  std::string path_;
  int fd_ = -1;
  Header header_;
  std::uint64_t size_ = 0, reportOffset_ = 0, cursor_ = kHeaderBytes, blocksRead_ = 0, modulesRead_ = 0;
  std::uint32_t storedCrc_ = 0;
  std::string report_;
};

}  // namespace sandtable::part
