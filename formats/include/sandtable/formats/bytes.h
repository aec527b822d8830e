#pragma once
// Little-endian field access through memcpy; never casts pointers onto bytes.
#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

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

/// CRC-32 of a whole file, read in chunks. Returns false if unreadable.
bool crc32File(const std::string& path, std::uint32_t& crc, std::uint64_t& bytes);

/// "0x" + 8 lowercase hex digits.
std::string crcHex(std::uint32_t crc);

/// Writes `data` to `path` atomically: temp file in the same directory,
/// fsync, then rename. Returns "" or an error message.
std::string writeFileAtomic(const std::string& path, std::span<const std::byte> data);

/// Writes all n bytes at `off`, retrying short writes and EINTR. "" or strerror.
std::string pwriteAll(int fd, const std::byte* data, std::size_t n, std::uint64_t off);

/// Reads a whole (small) file; refuses files larger than `maxBytes`.
bool readSmallFile(const std::string& path, std::vector<std::byte>& out,
                   std::uint64_t maxBytes, std::string& error);

}  // namespace sandtable
