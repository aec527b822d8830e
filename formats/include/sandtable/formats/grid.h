#pragma once
// The memory-mapped elevation grid file, version 1 (docs/FORMAT.md, "grid").
//
// Layout: a 4096-byte header page, a page-aligned block table, then square
// blocks of kBlockPosts x kBlockPosts posts. Each block holds elevation
// (float32), a unit normal (3 x int16 snorm) and a material index (uint8)
// for every post, as separate planes: a block is 11 pages covering a
// 64 x 64 post square of ground, so paging in a block brings in a square,
// not a strip. The block table holds every block's CRC-32.
//
// World frame (seed Figure 6): origin at the north-west corner post, X east,
// Y up, Z south. Post (i, j) lies at easting originEasting + i * spacing and
// northing originNorthing - j * spacing.
//
// Thread safety: GridFile is immutable after open(); every const method may
// be called from any thread (a remote grid fills its copy under a lock). GridWriter::writeBlock may be called
// concurrently for distinct blocks; finish() must run alone.
#include <algorithm>
#include <array>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "sandtable/base/range_source.h"
#include "sandtable/base/result.h"
#include "sandtable/base/work.h"

namespace sandtable::grid {

inline constexpr std::array<char, 8> kMagic = {'S', 'A', 'N', 'D', 'G', 'R', 'I', 'D'};
inline constexpr std::uint32_t kVersion = 1;
inline constexpr std::uint64_t kPageBytes = 4096;
inline constexpr std::uint32_t kHeaderFieldBytes = 128;  ///< fields + CRC; rest of page is zero
inline constexpr std::uint32_t kBlockPosts = 64;
inline constexpr std::uint32_t kPostsPerBlock = kBlockPosts * kBlockPosts;
inline constexpr std::uint64_t kElevationPlane = 0;
inline constexpr std::uint64_t kNormalXPlane = kElevationPlane + 4ull * kPostsPerBlock;
inline constexpr std::uint64_t kNormalYPlane = kNormalXPlane + 2ull * kPostsPerBlock;
inline constexpr std::uint64_t kNormalZPlane = kNormalYPlane + 2ull * kPostsPerBlock;
inline constexpr std::uint64_t kMaterialPlane = kNormalZPlane + 2ull * kPostsPerBlock;
inline constexpr std::uint64_t kBlockBytes = kMaterialPlane + 1ull * kPostsPerBlock;
inline constexpr std::uint32_t kBlockEntryBytes = 16;
/// Largest grid accepted, per axis (about 4,000 km at 1 m posts).
inline constexpr std::uint32_t kMaxPostsPerAxis = 4u << 20;
static_assert(kBlockBytes == 45056 && kBlockBytes % kPageBytes == 0,
              "a block must be a whole number of pages");

/// Header fields (decoded). Offsets are in docs/FORMAT.md.
struct Header {
  std::uint32_t version = kVersion;
  std::uint32_t postsX = 0;
  std::uint32_t postsZ = 0;
  std::uint32_t blockPosts = kBlockPosts;
  std::uint32_t blocksX = 0;
  std::uint32_t blocksZ = 0;
  std::uint32_t flags = 0;
  double spacing = 0;
  double originEasting = 0;
  double originNorthing = 0;
  float minElevation = 0;
  float maxElevation = 0;
  std::uint64_t blockTableOffset = 0;
  std::uint64_t dataOffset = 0;
  std::uint64_t blockBytes = kBlockBytes;
  std::uint64_t fileBytes = 0;
  std::uint32_t tableCrc = 0;

  std::uint64_t blockCount() const { return std::uint64_t(blocksX) * blocksZ; }
};

/// Byte offsets of header fields; shared by writer, reader and docs.
namespace field {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, postsX = 16,
                             postsZ = 20, blockPosts = 24, blocksX = 28, blocksZ = 32,
                             flags = 36, spacing = 40, originEasting = 48,
                             originNorthing = 56, minElevation = 64, maxElevation = 68,
                             blockTableOffset = 72, dataOffset = 80, blockBytes = 88,
                             fileBytes = 96, tableCrc = 104, reserved = 108, headerCrc = 124;
}

/// One block-table entry.
struct BlockEntry {
  std::uint32_t crc = 0;
  float minElevation = 0;
  float maxElevation = 0;
  std::uint32_t reserved = 0;
};

/// Derives block counts and offsets for a grid of postsX x postsZ.
Header makeHeader(std::uint32_t postsX, std::uint32_t postsZ, double spacing,
                  double originEasting, double originNorthing);

/// Encodes the header page (4096 bytes, CRC filled in).
std::vector<std::byte> encodeHeader(const Header& h);
/// Decodes and checks a header page. `fileSize` is the real size on disk.
Result<Header> decodeHeader(std::span<const std::byte> bytes, const std::string& file,
                            std::uint64_t fileSize);

/// One block's contents, decoded. Posts are row-major: index = z * 64 + x.
struct BlockData {
  std::array<float, kPostsPerBlock> elevation{};
  std::array<std::int16_t, kPostsPerBlock> normalX{};
  std::array<std::int16_t, kPostsPerBlock> normalY{};
  std::array<std::int16_t, kPostsPerBlock> normalZ{};
  std::array<std::uint8_t, kPostsPerBlock> material{};
};

/// Encodes a block's bytes (kBlockBytes) into `out`.
void encodeBlock(const BlockData& b, std::span<std::byte> out);
/// Snorm helpers: int16 = round(v * 32767).
std::int16_t toSnorm(float v);
inline float fromSnorm(std::int16_t v) { return float(v) / 32767.0f; }

#if defined(__GNUC__) || defined(__clang__)
#define SANDTABLE_GRID_INLINE [[gnu::always_inline]] inline
#else
#define SANDTABLE_GRID_INLINE inline
#endif

/// toSnorm for a finite value, inlined for the per-post loops: clamp to
/// [-1, 1], scale, round half away from zero (as lroundf; y - trunc(y) is
/// exact in float), so it gives toSnorm's values.
SANDTABLE_GRID_INLINE std::int16_t toSnormFinite(float v) {
  const float y = std::clamp(v, -1.0f, 1.0f) * 32767.0f;
  int t = static_cast<int>(y);  // toward zero; |y| <= 32767
  const float frac = y - static_cast<float>(t);
  t += int(frac >= 0.5f) - int(frac <= -0.5f);  // no branch: frac is noise
  return static_cast<std::int16_t>(t);
}

/// A post's normal as the grid stores it: X, Y, Z snorm (world frame).
using PostNormal = std::array<std::int16_t, 3>;

/// The normal at post (i, j) of a postsX x postsZ grid of posts `spacing`
/// apart, from the elevations `at(i, j)` (float) of its neighbours: central
/// differences, one-sided on the grid's edge (the missing neighbour is the
/// post itself and the difference counts double). The one rule: the
/// elevation build writes it into every block, the dynamic-terrain overlay
/// (runtime/edits, heights.h) recomputes it at edited posts, so an edited
/// post's normal is the one a build of the edited heights would write.
/// Always inlined so that it takes its caller's floating-point flags; both
/// callers are built -ffp-contract=off, so they round alike on every machine.
template <typename At>
  requires std::same_as<std::invoke_result_t<const At&, std::uint32_t, std::uint32_t>, float>
SANDTABLE_GRID_INLINE PostNormal postNormal(const At& at, std::uint32_t i, std::uint32_t j, std::uint32_t postsX,
                                            std::uint32_t postsZ, double spacing) {
  const double inv2s = 1.0 / (2.0 * spacing);
  const std::uint32_t il = i > 0 ? i - 1 : 0, ir = std::min(i + 1, postsX - 1);
  const std::uint32_t ju = j > 0 ? j - 1 : 0, jd = std::min(j + 1, postsZ - 1);
  // The differences in float (the posts' type), the rest in double.
  const double dx = (at(ir, j) - at(il, j)) * inv2s * (i == 0 || i == postsX - 1 ? 2.0 : 1.0);
  const double dz = (at(i, jd) - at(i, ju)) * inv2s * (j == 0 || j == postsZ - 1 ? 2.0 : 1.0);
  const double len = std::sqrt(dx * dx + 1.0 + dz * dz);
  return {toSnormFinite(static_cast<float>(-dx / len)), toSnormFinite(static_cast<float>(1.0 / len)),
          toSnormFinite(static_cast<float>(-dz / len))};
}

/// Writes a grid file. The file appears at `path` only when finish() succeeds.
class GridWriter {
 public:
  static Result<std::unique_ptr<GridWriter>> create(const std::string& path, const Header& h);
  ~GridWriter();
  GridWriter(const GridWriter&) = delete;
  GridWriter& operator=(const GridWriter&) = delete;

  /// Writes block (bx, bz). Safe to call concurrently for distinct blocks.
  /// Problems name the grid's path; messages start "grid writer: ".
  Status writeBlock(std::uint32_t bx, std::uint32_t bz, const BlockData& b);
  /// Writes block (bx, bz) as encoded bytes (kBlockBytes) with its table
  /// entry, as another writer made them (a distributed build's merge). The
  /// bytes must match the entry's CRC. Same concurrency as writeBlock.
  Status writeEncodedBlock(std::uint32_t bx, std::uint32_t bz, std::span<const std::byte> bytes,
                           const BlockEntry& e);
  /// Writes table and header, fsyncs, and renames into place.
  Status finish();
  const Header& header() const { return header_; }
  /// CRC-32 and size of the whole file as finish() wrote it, combined from
  /// the header's, the table's and the blocks' CRCs (no re-read).
  std::uint32_t fileCrc() const { return fileCrc_; }

 private:
  GridWriter(std::string path, std::string tmp, int fd, Header h);
  std::string path_, tmp_;
  int fd_ = -1;
  Header header_;
  std::vector<BlockEntry> entries_;
  bool finished_ = false;
  std::uint32_t fileCrc_ = 0;
};

/// A grid on a web server, read by block (issue 38 part B; docs/HTTP.md,
/// "The grid by range"): the options of GridFile::openRemote.
struct RemoteGridOptions {
  /// The local copy's bound; past it, blocks unused for evictAfterSeconds
  /// are punched out (the file stays sparse). 0: no bound. A reader holds
  /// a block's bytes only while it reads them: evictAfterSeconds must
  /// exceed the longest such read.
  std::uint64_t maxBytes = 1ull << 30;
  double evictAfterSeconds = 30;
  /// A block fetched on demand brings up to this many missing blocks east
  /// of it in the same request (a block row is contiguous in the file).
  std::uint32_t readaheadBlocks = 4;
  /// A block whose fetch failed stands in flat (its table entry's middle
  /// elevation, normals up) and is fetched again after this pause,
  /// doubling to retryMaxSeconds while it keeps failing.
  double retryFirstSeconds = 1, retryMaxSeconds = 30;
};

struct RemoteGridStats {
  std::uint64_t requests = 0;       ///< ranges asked of the source
  std::uint64_t fetchedBlocks = 0;  ///< blocks that came and passed their CRC
  std::uint64_t diskBlocks = 0;     ///< blocks found whole in the local copy
  std::uint64_t refetches = 0;      ///< blocks that failed their CRC and were asked again
  std::uint64_t failedFetches = 0;  ///< fetches that failed (flat stand-ins written)
  std::uint64_t evictedBlocks = 0;
  std::uint64_t standIns = 0;       ///< blocks standing in flat now
};

/// A read-only, memory-mapped grid. open() checks only the header and the
/// file size (O(1)); validateGrid() checks every byte.
///
/// A remote grid (openRemote) maps a sparse local copy and fills it block
/// by block: the first read of a block checks it against its table CRC
/// and fetches it when the copy lacks it or fails. Every accessor below
/// does this, so no reader sees an unchecked block; a block that cannot
/// be fetched reads as a flat stand-in until it can (remoteProblems()).
class GridFile {
 public:
  static Result<std::shared_ptr<const GridFile>> open(const std::string& path);
  /// Opens the grid in `source` (grid.stg on a web server) through the
  /// local copy at `localPath`, created sparse when missing. Reads the
  /// header page and the block table (one request) and checks them against
  /// `fileCrc`, the manifest's CRC-32 of the whole file (the table holds
  /// every block's CRC, so header, table and those CRCs combine to it).
  /// Problems name the source or the local path.
  static Result<std::shared_ptr<const GridFile>> openRemote(std::shared_ptr<const RangeSource> source,
                                                            const std::string& localPath, std::uint32_t fileCrc,
                                                            const RemoteGridOptions& options = {});
  ~GridFile();
  GridFile(const GridFile&) = delete;
  GridFile& operator=(const GridFile&) = delete;

  const Header& header() const { return header_; }
  const std::string& path() const { return path_; }
  std::uint32_t postsX() const { return header_.postsX; }
  std::uint32_t postsZ() const { return header_.postsZ; }
  double spacing() const { return header_.spacing; }

  /// Elevation at post (i, j); i < postsX, j < postsZ (asserted).
  float elevation(std::uint32_t i, std::uint32_t j) const;
  /// Unit normal in the world frame (X east, Y up, Z south).
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const;
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const;
  /// Raw bytes of block (bx, bz), kBlockBytes long.
  std::span<const std::byte> blockBytes(std::uint32_t bx, std::uint32_t bz) const;
  BlockEntry blockEntry(std::uint32_t bx, std::uint32_t bz) const;
  /// The whole file (a remote grid fetches every block first).
  std::span<const std::byte> bytes() const;

  /// Whether the blocks come from a web server (openRemote).
  bool remote() const { return remote_ != nullptr; }
  /// Fetches the missing blocks of [bx0, bx1] x [bz0, bz1], inclusive
  /// (clamped), one request per run of a block row; nothing for a local
  /// grid. The problems of blocks that could not be fetched.
  Status fetchBlocks(std::uint32_t bx0, std::uint32_t bz0, std::uint32_t bx1, std::uint32_t bz1) const;
  RemoteGridStats remoteStats() const;
  /// Fetch problems since the last call (each block's first failure once).
  std::vector<Problem> takeRemoteProblems() const;

  class Remote;  // grid_remote.cpp

 private:
  GridFile() = default;
  std::string path_;
  Header header_;
  const std::byte* base_ = nullptr;
  std::size_t size_ = 0;
  std::shared_ptr<Remote> remote_;
  void ensureBlock(std::uint64_t block) const;
  const std::byte* postAddress(std::uint32_t i, std::uint32_t j, std::uint64_t plane,
                               std::uint32_t width) const;
};

/// Every check on a grid file: header, sizes, reserved header bytes, table,
/// block CRCs, zero padding, NaN/inf, unit normals, plausible elevations,
/// edge padding repeating the edge posts, header min/max. Each problem
/// names the file and byte offset; ok when the grid is sound. Progress:
/// "checking grid", per block row.
Status validateGrid(const std::string& path, const Work& work = {});

}  // namespace sandtable::grid
