#include "sandtable/testing/process.h"

#include <array>
#include <cstdio>
#include <memory>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

namespace sandtable::fixtures {

std::string commandOutput(const std::string& command) {
  std::string out;
  std::unique_ptr<FILE, int (*)(FILE*)> p(popen(command.c_str(), "r"), pclose);
  if (!p) return out;
  std::array<char, 4096> buf{};
  while (std::size_t n = std::fread(buf.data(), 1, buf.size(), p.get())) out.append(buf.data(), n);
  return out;
}

std::uint16_t freeUdpPort() {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return 0;
  sockaddr_in s{};
  s.sin_family = AF_INET;
  socklen_t len = sizeof s;
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&s), sizeof s) == 0 &&
                  ::getsockname(fd, reinterpret_cast<sockaddr*>(&s), &len) == 0;
  ::close(fd);
  return ok ? ntohs(s.sin_port) : 0;
}

}  // namespace sandtable::fixtures
