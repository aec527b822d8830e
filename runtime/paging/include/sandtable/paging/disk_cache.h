#pragma once
// An on-disk cache of the bytes read from a remote file (issue 38 part B:
// a database's modules.pack on a web server). Blocks of blockBytes are kept
// in a sparse local file the size of the remote one, with a one-byte-per-
// block map beside it, so a second flight (or a second process) over the
// same ground reads them from disk. Nothing here trusts the cached bytes:
// the pack reader checks every record's CRCs as for a local pack, and a
// record that fails is refresh()ed, which drops its blocks here and in the
// source below before they are fetched again.
//
// Bounded: past maxBytes, blocks are evicted (holes punched in the file)
// in a round-robin sweep of the map. The files are named by the remote
// file's size and CRC-32 (the manifest's), so a new build on the server
// starts an empty cache and the old one's files are removed.
//
// Thread contract: every member may be called from any thread at once.
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "sandtable/base/range_source.h"
#include "sandtable/base/result.h"

namespace sandtable::paging {

struct DiskCacheOptions {
  std::uint64_t maxBytes = 1ull << 30;  ///< 1 GiB
  std::uint32_t blockBytes = 64u << 10;  ///< as the HTTP client's memory cache
};

struct DiskCacheStats {
  std::uint64_t hitBytes = 0, fetchedBytes = 0, evictedBlocks = 0, residentBlocks = 0;
};

/// NAME.SIZE.CRC: the stem of a cache file of a remote file whose whole
/// bytes are SIZE long with CRC-32 CRC (the manifest's).
std::string cacheStem(const std::string& name, std::uint64_t size, std::uint32_t crc);
/// Removes DIR/NAME.*.cache and .map files whose name does not start with
/// `keep`: the caches of other builds.
void removeOtherCaches(const std::string& dir, const std::string& name, const std::string& keep);

class DiskCachedRange final : public RangeSource {
 public:
  /// Opens (or starts) the cache of `source`, whose whole bytes have CRC-32
  /// `crc`, as DIR/NAME.<size>.<crc>.cache and .map. Problems name DIR.
  static Result<std::shared_ptr<const DiskCachedRange>> open(std::shared_ptr<const RangeSource> source,
                                                             const std::string& dir, const std::string& name,
                                                             std::uint32_t crc, DiskCacheOptions options = {});
  ~DiskCachedRange() override;

  const std::string& name() const override { return source_->name(); }
  std::uint64_t size() const override { return source_->size(); }
  Status read(std::uint64_t offset, std::span<std::byte> out) const override;
  void refresh(std::uint64_t offset, std::uint64_t n) const override;
  /// The parts of `ranges` not on disk, passed to the source's prefetch.
  void prefetch(std::span<const std::pair<std::uint64_t, std::uint64_t>> ranges) const override;
  DiskCacheStats stats() const;
  const std::string& cachePath() const { return dataPath_; }

 private:
  DiskCachedRange() = default;
  Status fetch(std::uint64_t b0, std::uint64_t b1) const;
  void evictFor(std::uint64_t blocks) const;

  std::shared_ptr<const RangeSource> source_;
  DiskCacheOptions options_;
  std::string dataPath_, mapPath_;
  int data_ = -1, map_ = -1;
  std::uint64_t blocks_ = 0;
  mutable std::mutex mutex_;  ///< the map, the counts and the sweep
  mutable std::vector<std::uint8_t> present_;
  mutable std::uint64_t resident_ = 0, sweep_ = 0;
  mutable std::atomic<std::uint64_t> hitBytes_{0}, fetchedBytes_{0}, evicted_{0};
};

}  // namespace sandtable::paging
