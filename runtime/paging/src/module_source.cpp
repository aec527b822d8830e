// PackSource: modules.pack as the pager's module source (module_source.h).
#include "sandtable/paging/module_source.h"

#include <sys/stat.h>

namespace sandtable::runtime {

PackSource::PackSource(std::shared_ptr<const pack::PackReader> pack) : pack_(std::move(pack)) {}

ModuleInfo PackSource::info(std::uint32_t kx, std::uint32_t kz) const {
  const pack::Entry e = pack_->entry(kx, kz);
  return {e.compressedBytes, e.rawBytes};
}

Result<std::uint64_t> PackSource::read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  if (pack_->entry(kx, kz).compressedBytes == 0) {
    return Problem{pack_->indexPath(), 0,
                   "pack index: module (" + std::to_string(kx) + ", " + std::to_string(kz) +
                       ") is missing (its entry has no record)"};
  }
  if (Status read = pack_->readInto(kx, kz, into); !read) return read.problems();
  return std::uint64_t{0};
}

bool PackSource::missing(std::uint32_t kx, std::uint32_t kz) const {
  const pack::Entry e = pack_->entry(kx, kz);
  if (e.compressedBytes == 0) return true;
  struct stat st {};
  if (::fstat(pack_->packFd(), &st) != 0) return false;
  return e.offset + e.compressedBytes > std::uint64_t(st.st_size);
}

}  // namespace sandtable::runtime
