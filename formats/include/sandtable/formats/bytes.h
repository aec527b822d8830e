#pragma once
// Little-endian field access through memcpy; never casts pointers onto bytes.
#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable {

static_assert(std::endian::native == std::endian::little,
              "sandtable formats assume a little-endian host");

template <typename T>
inline T loadLE(const std::byte* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

template <typename T>
inline void storeLE(std::byte* p, T v) {
  std::memcpy(p, &v, sizeof(T));
}

/// CRC-32 (zlib polynomial) of a byte range; `seed` chains ranges.
std::uint32_t crc32(std::span<const std::byte> data, std::uint32_t seed = 0);

/// CRC-32 and size of a whole file.
struct FileCrc {
  std::uint32_t crc = 0;
  std::uint64_t bytes = 0;
};
/// CRC-32 of a whole file, read in chunks. Fails if unreadable.
Result<FileCrc> crc32File(const std::string& path);

/// "0x" + 8 lowercase hex digits.
std::string crcHex(std::uint32_t crc);

/// Writes `data` to `path` atomically: temp file in the same directory,
/// fsync, then rename. The problem names `path`; its message names the
/// temp file and the system's reason.
Status writeFileAtomic(const std::string& path, std::span<const std::byte> data);

/// Writes all n bytes at `off`, retrying short writes and EINTR. The
/// problem's message is strerror, its offset where the write failed.
Status pwriteAll(int fd, const std::byte* data, std::size_t n, std::uint64_t off);

/// Reads all n bytes at `off`, retrying short reads and EINTR; the end of
/// the file before n bytes is a problem ("end of file") at its offset.
Status preadAll(int fd, std::byte* data, std::size_t n, std::uint64_t off);

/// Reads a whole (small) file; refuses files larger than `maxBytes`. The
/// problem names `path`; its message says why ("cannot open: ...").
Result<std::vector<std::byte>> readSmallFile(const std::string& path, std::uint64_t maxBytes);

}  // namespace sandtable
