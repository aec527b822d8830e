// PackSource: modules.pack as the pager's module source (module_source.h).
#include "sandtable/paging/module_source.h"

#include "sandtable/base/range_source.h"

#include <fcntl.h>
#include <sys/stat.h>

#include <algorithm>
#include <utility>

namespace sandtable::paging {

PackSource::PackSource(std::shared_ptr<const pack::PackReader> pack) : pack_(std::move(pack)) {}

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

void PackSource::willNeed(std::span<const ModuleKey> keys, bool fine) const {
  if (pack_->remote()) return;  // a web server's pack: the loaders' own reads are the requests
  // Reused per thread: a loader hints every strip without allocating once warm.
  thread_local std::vector<std::pair<std::uint64_t, std::uint64_t>> runs;  // [begin, end)
  runs.clear();
  const pack::IndexHeader& h = pack_->header();
  for (const ModuleKey& k : keys) {
    if (k.kx >= h.modulesX || k.kz >= h.modulesZ) continue;
    const pack::Entry e = pack_->entry(k.kx, k.kz);
    if (e.compressedBytes > 0) runs.emplace_back(e.offset, e.offset + e.compressedBytes);
    if (fine && e.fine.compressedBytes > 0) runs.emplace_back(e.fine.offset, e.fine.offset + e.fine.compressedBytes);
  }
  if (runs.empty()) return;
  std::sort(runs.begin(), runs.end());
  // Records closer than this are read as one run: the disk reads the gap
  // faster than it seeks, and one fadvise covers both.
  constexpr std::uint64_t kMergeGap = 64 << 10;
  std::uint64_t b = runs.front().first, e = runs.front().second;
  auto advise = [&] { ::posix_fadvise(pack_->packFd(), off_t(b), off_t(e - b), POSIX_FADV_WILLNEED); };
  for (std::size_t i = 1; i < runs.size(); ++i) {
    if (runs[i].first <= e + kMergeGap) {
      e = std::max(e, runs[i].second);
    } else {
      advise();
      b = runs[i].first;
      e = runs[i].second;
    }
  }
  advise();
}

}  // namespace sandtable::paging
