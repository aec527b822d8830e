// PackSource: modules.pack as the pager's module source (module_source.h).
#include "sandtable/paging/module_source.h"

#include "sandtable/base/range_source.h"

#include <fcntl.h>
#include <sys/stat.h>

#include <algorithm>
#include <utility>

namespace sandtable::paging {

PackSource::PackSource(std::shared_ptr<const pack::PackReader> pack) : pack_(std::move(pack)) {
  if (pack_->remote()) prefetches_ = std::make_unique<jobs::SerialQueue>();
}

ModuleInfo PackSource::info(std::uint32_t kx, std::uint32_t kz) const {
  const pack::Entry e = pack_->entry(kx, kz);
  return {e.storedBytes(), e.storedRawBytes(), e.fine.compressedBytes};
}

namespace {
Problem missingProblem(const pack::PackReader& p, std::uint32_t kx, std::uint32_t kz) {
  return Problem{p.indexPath(), 0,
                 "pack index: module (" + std::to_string(kx) + ", " + std::to_string(kz) +
                     ") is missing (its entry has no record)"};
}
}  // namespace

Result<std::uint64_t> PackSource::read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  if (pack_->entry(kx, kz).compressedBytes == 0) return missingProblem(*pack_, kx, kz);
  if (Status read = pack_->readInto(kx, kz, into); !read) return read.problems();
  return std::uint64_t{0};
}

Result<std::uint64_t> PackSource::readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  if (pack_->entry(kx, kz).compressedBytes == 0) return missingProblem(*pack_, kx, kz);
  if (Status read = pack_->readCoarseInto(kx, kz, into); !read) return read.problems();
  return std::uint64_t{0};
}

Status PackSource::readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  return pack_->readFineInto(kx, kz, into);
}

bool PackSource::missing(std::uint32_t kx, std::uint32_t kz) const {
  const pack::Entry e = pack_->entry(kx, kz);
  if (e.compressedBytes == 0) return true;
  std::uint64_t size = 0;
  if (const RangeSource* r = pack_->remote()) {
    size = r->size();
  } else {
    struct stat st {};
    if (::fstat(pack_->packFd(), &st) != 0) return false;
    size = std::uint64_t(st.st_size);
  }
  return e.offset + e.compressedBytes > size ||
         (e.fine.compressedBytes > 0 && e.fine.offset + e.fine.compressedBytes > size);
}

namespace {

using Runs = std::vector<std::pair<std::uint64_t, std::uint64_t>>;  // [begin, end)

/// Records closer than this are read as one run: the disk reads the gap
/// faster than it seeks, and a web server sends it faster than a round trip.
constexpr std::uint64_t kMergeGap = 64 << 10;

/// The records of `keys` (coarse, or fine), sorted by offset and merged
/// where they lie within kMergeGap of each other (pack v2 in Morton order
/// puts a strip's coarse records in a few runs).
void recordRuns(const pack::PackReader& pack, std::span<const ModuleKey> keys, bool fine, Runs& runs) {
  runs.clear();
  const pack::IndexHeader& h = pack.header();
  for (const ModuleKey& k : keys) {
    if (k.kx >= h.modulesX || k.kz >= h.modulesZ) continue;
    const pack::Entry e = pack.entry(k.kx, k.kz);
    const pack::Extent r = fine ? e.fine : e.coarse();
    if (r.compressedBytes > 0) runs.emplace_back(r.offset, r.offset + r.compressedBytes);
  }
  std::sort(runs.begin(), runs.end());
  std::size_t out = 0;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (out > 0 && runs[i].first <= runs[out - 1].second + kMergeGap) {
      runs[out - 1].second = std::max(runs[out - 1].second, runs[i].second);
    } else {
      runs[out++] = runs[i];
    }
  }
  runs.resize(out);
}

}  // namespace

PackSource::~PackSource() = default;

void PackSource::willNeed(std::span<const ModuleKey> keys, bool fine) const {
  if (const RangeSource* remote = pack_->remote()) {
    prefetchRemote(*remote, keys, fine);
    return;
  }
  // Reused per thread: a loader hints every strip without allocating once warm.
  thread_local Runs runs;
  for (const bool f : {false, true}) {
    if (f && !fine) break;
    recordRuns(*pack_, keys, f, runs);
    for (const auto& [b, e] : runs) ::posix_fadvise(pack_->packFd(), off_t(b), off_t(e - b), POSIX_FADV_WILLNEED);
  }
}

void PackSource::prefetchRemote(const RangeSource& remote, std::span<const ModuleKey> keys, bool fine) const {
  // Strips the viewer has passed are not worth their requests: the loaders
  // read what they still need themselves.
  constexpr std::size_t kMaxQueued = 4;
  if (!prefetches_ || prefetches_->pending() >= kMaxQueued) return;
  // The coarse runs first: a late coarse record is a hole, a late fine one
  // a coarse frame.
  for (const bool f : {false, true}) {
    if (f && !fine) break;
    Runs runs;
    recordRuns(*pack_, keys, f, runs);
    if (runs.empty()) continue;
    // One request for all the runs (several ranges); `remote` is the
    // pack's own, and the pack held here keeps it. A failure is the
    // loader's to report when it reads.
    prefetches_->submit([pack = pack_, source = &remote, runs = std::move(runs)] { source->prefetch(runs); });
  }
}

}  // namespace sandtable::paging
