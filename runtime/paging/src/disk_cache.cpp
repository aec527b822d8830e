// DiskCachedRange: remote bytes kept in a sparse local file (disk_cache.h).
#include "sandtable/paging/disk_cache.h"

#include "sandtable/formats/bytes.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

namespace sandtable::paging {
namespace fs = std::filesystem;

std::string cacheStem(const std::string& name, std::uint64_t size, std::uint32_t crc) {
  char tag[64];
  std::snprintf(tag, sizeof tag, ".%llu.%08x", static_cast<unsigned long long>(size), crc);
  return name + tag;
}

void removeOtherCaches(const std::string& dir, const std::string& name, const std::string& keep) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string f = e.path().filename().string();
    if (f.rfind(name + ".", 0) != 0 || f.rfind(keep, 0) == 0) continue;
    if (f.ends_with(".cache") || f.ends_with(".map")) fs::remove(e.path(), ec);
  }
}

Result<std::shared_ptr<const DiskCachedRange>> DiskCachedRange::open(std::shared_ptr<const RangeSource> source,
                                                                     const std::string& dir, const std::string& name,
                                                                     std::uint32_t crc, DiskCacheOptions options) {
  std::shared_ptr<DiskCachedRange> c(new DiskCachedRange());
  c->source_ = std::move(source);
  c->options_ = options;
  c->options_.blockBytes = std::max<std::uint32_t>(options.blockBytes, 4096);
  const std::string stem = cacheStem(name, c->source_->size(), crc);
  std::error_code ec;
  fs::create_directories(dir, ec);
  removeOtherCaches(dir, name, stem);
  c->dataPath_ = dir + "/" + stem + ".cache";
  c->mapPath_ = dir + "/" + stem + ".map";
  c->blocks_ = (c->source_->size() + c->options_.blockBytes - 1) / c->options_.blockBytes;
  c->data_ = ::open(c->dataPath_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  c->map_ = ::open(c->mapPath_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (c->data_ < 0 || c->map_ < 0) return Problem{dir, 0, "pack cache: cannot open " + c->dataPath_ + " or its map"};
  struct stat st{};
  const bool sameMap = ::fstat(c->map_, &st) == 0 && std::uint64_t(st.st_size) == c->blocks_;
  if (::ftruncate(c->data_, off_t(c->source_->size())) != 0 || (!sameMap && ::ftruncate(c->map_, 0) != 0) ||
      ::ftruncate(c->map_, off_t(c->blocks_)) != 0) {
    return Problem{dir, 0, "pack cache: cannot size " + c->dataPath_ + " (is the disk full?)"};
  }
  c->present_.assign(c->blocks_, 0);
  if (c->blocks_ > 0 && !preadAll(c->map_, reinterpret_cast<std::byte*>(c->present_.data()), c->present_.size(), 0)) {
    c->present_.assign(c->blocks_, 0);
  }
  for (auto& p : c->present_) p = p == 1 ? 1 : 0;
  c->resident_ = std::uint64_t(std::count(c->present_.begin(), c->present_.end(), 1));
  return std::shared_ptr<const DiskCachedRange>(std::move(c));
}

DiskCachedRange::~DiskCachedRange() {
  if (data_ >= 0) ::close(data_);
  if (map_ >= 0) ::close(map_);
}

void DiskCachedRange::evictFor(std::uint64_t blocks) const {
  const std::uint64_t cap = std::max<std::uint64_t>(options_.maxBytes / options_.blockBytes, 1);
  for (std::uint64_t scanned = 0; resident_ + blocks > cap && resident_ > 0 && scanned < 2 * blocks_; ++scanned) {
    const std::uint64_t b = sweep_;
    sweep_ = (sweep_ + 1) % blocks_;
    if (!present_[b]) continue;
    present_[b] = 0;
    const std::byte zero{0};
    (void)pwriteAll(map_, &zero, 1, b);  // a map byte not cleared only costs a CRC failure and a fetch
    ::fallocate(data_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, off_t(b * options_.blockBytes),
                off_t(options_.blockBytes));
    --resident_;
    evicted_.fetch_add(1, std::memory_order_relaxed);
  }
}

Status DiskCachedRange::read(std::uint64_t offset, std::span<std::byte> out) const {
  if (out.empty()) return {};
  if (offset > size() || out.size() > size() - offset) return source_->read(offset, out);  // its error
  const std::uint64_t B = options_.blockBytes;
  const std::uint64_t b0 = offset / B, b1 = (offset + out.size() - 1) / B + 1;
  bool whole = true;
  {
    const std::lock_guard lock(mutex_);
    for (std::uint64_t b = b0; b < b1 && whole; ++b) whole = present_[b] != 0;
  }
  if (whole && preadAll(data_, out.data(), out.size(), offset)) {
    hitBytes_.fetch_add(out.size(), std::memory_order_relaxed);
    return {};
  }
  // Fetch the whole blocks (one request below), keep them, hand out the part asked for.
  const std::uint64_t from = b0 * B, to = std::min(b1 * B, size());
  std::vector<std::byte> buf(to - from);
  if (Status st = source_->read(from, buf); !st) return st;
  fetchedBytes_.fetch_add(buf.size(), std::memory_order_relaxed);
  std::memcpy(out.data(), buf.data() + (offset - from), out.size());
  const std::lock_guard lock(mutex_);
  std::uint64_t fresh = 0;
  for (std::uint64_t b = b0; b < b1; ++b) fresh += present_[b] == 0;
  evictFor(fresh);
  if (!pwriteAll(data_, buf.data(), buf.size(), from)) return {};  // a full disk: served, not kept
  const std::vector<std::byte> ones(b1 - b0, std::byte{1});
  if (!pwriteAll(map_, ones.data(), ones.size(), b0)) return {};
  for (std::uint64_t b = b0; b < b1; ++b) present_[b] = 1;
  resident_ += fresh;
  return {};
}

void DiskCachedRange::prefetch(std::span<const std::pair<std::uint64_t, std::uint64_t>> ranges) const {
  // Only what is not on disk goes on to the source (one request there).
  const std::uint64_t B = options_.blockBytes;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> missing;
  {
    const std::lock_guard lock(mutex_);
    for (const auto& [a, e] : ranges) {
      if (e <= a || e > size()) continue;
      for (std::uint64_t b = a / B; b <= (e - 1) / B; ++b) {
        if (present_[b]) continue;
        missing.emplace_back(std::max(a, b * B), std::min(e, (b + 1) * B));
      }
    }
  }
  if (!missing.empty()) source_->prefetch(missing);
}

void DiskCachedRange::refresh(std::uint64_t offset, std::uint64_t n) const {
  const std::uint64_t B = options_.blockBytes;
  if (n > 0 && offset < size()) {
    const std::uint64_t b0 = offset / B, b1 = std::min(blocks_, (offset + n - 1) / B + 1);
    const std::lock_guard lock(mutex_);
    for (std::uint64_t b = b0; b < b1; ++b) {
      if (!present_[b]) continue;
      present_[b] = 0;
      const std::byte zero{0};
      (void)pwriteAll(map_, &zero, 1, b);
      --resident_;
    }
  }
  source_->refresh(offset, n);
}

DiskCacheStats DiskCachedRange::stats() const {
  const std::lock_guard lock(mutex_);
  return {hitBytes_.load(), fetchedBytes_.load(), evicted_.load(), resident_};
}

}  // namespace sandtable::paging
