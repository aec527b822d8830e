// Pack file I/O (pack_internal.h, pack.h): whole preads, the mapped index,
// per-thread zstd contexts, and compress and decompress.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <cerrno>
#include <cstring>
#include <memory>

#include "pack_internal.h"

namespace sandtable::pack {
namespace detail {

// ---------------------------------------------------------------- file I/O

/// Reads exactly n bytes at `off` (a short file is an error). The problem
/// has no file, only the offset and the reason.
Status preadAll(int fd, std::byte* data, std::size_t n, std::uint64_t off) {
  while (n > 0) {
    const ssize_t r = ::pread(fd, data, n, static_cast<off_t>(off));
    if (r < 0) {
      if (errno == EINTR) continue;
      return Problem{"", off, std::strerror(errno)};
    }
    if (r == 0) return Problem{"", off, "the file ends at byte " + str(off)};
    data += r;
    n -= static_cast<std::size_t>(r);
    off += static_cast<std::uint64_t>(r);
  }
  return {};
}

MappedFile::~MappedFile() {
  if (base_) ::munmap(const_cast<std::byte*>(base_), size_);
}

Status Source::read(std::byte* data, std::size_t n, std::uint64_t off) const {
  if (!remote) return preadAll(fd, data, n, off);
  if (const Status r = remote->read(off, {data, n}); !r) return Problem{"", off, r.message()};
  return {};
}

Status MappedFile::open(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Problem{path, 0, std::string("cannot open: ") + std::strerror(errno)};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return Problem{path, 0, "not a regular file"};
  }
  size_ = static_cast<std::size_t>(st.st_size);
  if (size_ > 0) {
    void* m = ::mmap(nullptr, size_, PROT_READ, MAP_SHARED, fd, 0);
    if (m == MAP_FAILED) {
      const std::string e = std::strerror(errno);
      ::close(fd);
      size_ = 0;
      return Problem{path, 0, "mmap failed: " + e};
    }
    base_ = static_cast<const std::byte*>(m);
  }
  ::close(fd);
  return {};
}

// ---------------------------------------------------------------- zstd contexts

namespace {

struct CCtxFree {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxFree {
  void operator()(ZSTD_DCtx* c) const { ZSTD_freeDCtx(c); }
};

}  // namespace

ZSTD_CCtx* threadCCtx() {
  thread_local std::unique_ptr<ZSTD_CCtx, CCtxFree> c(ZSTD_createCCtx());
  return c.get();
}

ZSTD_DCtx* threadDCtx() {
  thread_local std::unique_ptr<ZSTD_DCtx, DCtxFree> c(ZSTD_createDCtx());
  return c.get();
}

}  // namespace detail

using namespace detail;

// ---------------------------------------------------------------- zstd

std::vector<std::byte> compress(std::span<const std::byte> raw, int level) {
  std::vector<std::byte> out(ZSTD_compressBound(raw.size()));
  const std::size_t n =
      ZSTD_compressCCtx(threadCCtx(), out.data(), out.size(), raw.data(), raw.size(), level);
  if (ZSTD_isError(n)) return {};
  out.resize(n);
  return out;
}

Status decompress(std::span<const std::byte> packed, std::uint32_t rawBytes, std::vector<std::byte>& out) {
  const unsigned long long declared = ZSTD_getFrameContentSize(packed.data(), packed.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR) return Problem{"", 0, "not a zstd frame"};
  if (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared != rawBytes) {
    return Problem{"", 0, "the frame holds " + str(declared) + " bytes, the index says " + str(rawBytes)};
  }
  out.resize(rawBytes);
  const std::size_t n =
      ZSTD_decompressDCtx(threadDCtx(), out.data(), out.size(), packed.data(), packed.size());
  if (ZSTD_isError(n)) return Problem{"", 0, std::string("zstd: ") + ZSTD_getErrorName(n)};
  if (n != rawBytes) {
    return Problem{"", 0, "decompressed to " + str(n) + " bytes, the index says " + str(rawBytes)};
  }
  return {};
}

}  // namespace sandtable::pack
