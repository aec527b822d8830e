#include "sandtable/formats/bytes.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace sandtable {

std::uint32_t crc32(std::span<const std::byte> data, std::uint32_t seed) {
  uLong c = seed;
  const auto* p = reinterpret_cast<const Bytef*>(data.data());
  std::size_t left = data.size();
  // zlib takes a uInt length; feed large ranges in pieces.
  while (left > 0) {
    const auto n = static_cast<uInt>(left > (1u << 30) ? (1u << 30) : left);
    c = ::crc32(c, p, n);
    p += n;
    left -= n;
  }
  return static_cast<std::uint32_t>(c);
}

Result<FileCrc> crc32File(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Problem{path, 0, std::string("cannot open: ") + std::strerror(errno)};
  std::vector<std::byte> buf(1 << 20);
  FileCrc f;
  for (;;) {
    const ssize_t n = ::read(fd, buf.data(), buf.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string e = std::strerror(errno);
      ::close(fd);
      return Problem{path, f.bytes, "cannot read: " + e};
    }
    if (n == 0) break;
    f.crc = crc32(std::span(buf.data(), static_cast<std::size_t>(n)), f.crc);
    f.bytes += static_cast<std::uint64_t>(n);
  }
  ::close(fd);
  return f;
}

std::string crcHex(std::uint32_t crc) {
  char s[16];
  std::snprintf(s, sizeof s, "0x%08x", crc);
  return s;
}

Status writeFileAtomic(const std::string& path, std::span<const std::byte> data) {
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  auto fail = [&](const std::string& msg) { return Status(Problem{path, 0, msg}); };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return fail("cannot create " + tmp + ": " + std::strerror(errno));
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string e = std::strerror(errno);
      ::close(fd);
      ::unlink(tmp.c_str());
      return fail("cannot write " + tmp + ": " + e);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    ::unlink(tmp.c_str());
    return fail("cannot flush " + tmp);
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string e = std::strerror(errno);
    ::unlink(tmp.c_str());
    return fail("cannot rename " + tmp + " to " + path + ": " + e);
  }
  return {};
}

Result<std::vector<std::byte>> readSmallFile(const std::string& path, std::uint64_t maxBytes) {
  auto fail = [&](const std::string& msg) { return Result<std::vector<std::byte>>(Problem{path, 0, msg}); };
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a
  // writer for ever; a regular file reads the same either way.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return fail(std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return fail("not a regular file (a directory, device or FIFO)");
  }
  if (static_cast<std::uint64_t>(st.st_size) > maxBytes) {
    ::close(fd);
    return fail("file is " + std::to_string(st.st_size) + " bytes, more than the " +
                std::to_string(maxBytes) + " allowed");
  }
  std::vector<std::byte> out(static_cast<std::size_t>(st.st_size));
  std::size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::read(fd, out.data() + done, out.size() - done);
    if (n <= 0) {
      if (n < 0 && errno == EINTR) continue;
      ::close(fd);
      return fail("short read");
    }
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  return out;
}

Status pwriteAll(int fd, const std::byte* data, std::size_t n, std::uint64_t off) {
  while (n > 0) {
    const ssize_t w = ::pwrite(fd, data, n, static_cast<off_t>(off));
    if (w < 0) {
      if (errno == EINTR) continue;
      return Problem{"", off, std::strerror(errno)};
    }
    data += w;
    n -= static_cast<std::size_t>(w);
    off += static_cast<std::uint64_t>(w);
  }
  return {};
}

Status preadAll(int fd, std::byte* data, std::size_t n, std::uint64_t off) {
  while (n > 0) {
    const ssize_t r = ::pread(fd, data, n, static_cast<off_t>(off));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return Problem{"", off, r == 0 ? std::string("end of file") : std::strerror(errno)};
    data += r;
    n -= static_cast<std::size_t>(r);
    off += static_cast<std::uint64_t>(r);
  }
  return {};
}

}  // namespace sandtable
