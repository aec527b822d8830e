#include "sandtable/dis/socket.h"

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <set>
#include <system_error>

namespace sandtable::dis {

namespace {

constexpr const char* kAddressField = "SocketOptions::address";
constexpr const char* kPortField = "SocketOptions::port";
constexpr const char* kInterfaceField = "SocketOptions::interface";
constexpr std::uint32_t kLimitedBroadcast = 0xffffffffu;
constexpr std::uint32_t kLoopbackBroadcast = 0x7fffffffu;  // 127.255.255.255
constexpr std::uint32_t kLoopbackIp = 0x7f000001u;
// The largest UDP payload over IPv4, rounded up: one receive buffer.
constexpr std::size_t kDatagramBuffer = 65536;

std::string ipText(std::uint32_t ip) {
  const std::string t = Address{ip, 0}.text();
  return t.substr(0, t.rfind(':'));
}

std::string errnoText(int e) { return std::strerror(e); }

sockaddr_in sockaddrOf(Address a) {
  sockaddr_in s{};
  s.sin_family = AF_INET;
  s.sin_addr.s_addr = htonl(a.ip);
  s.sin_port = htons(a.port);
  return s;
}

bool isMulticast(std::uint32_t ip) { return (ip >> 28) == 0xe; }

/// One IPv4 address of an interface, from getifaddrs.
struct InterfaceAddress {
  std::string name;
  unsigned flags = 0;
  std::uint32_t ip = 0;
  std::uint32_t mask = 0;
  std::uint32_t broadcast = 0;  ///< 0 when the interface has none
};

std::uint32_t ipOf(const sockaddr* sa) {
  return sa && sa->sa_family == AF_INET ? ntohl(reinterpret_cast<const sockaddr_in*>(sa)->sin_addr.s_addr) : 0;
}

/// The host's interfaces with an IPv4 address (and the names of all of
/// them, for a message that lists them).
std::vector<InterfaceAddress> interfaces(std::set<std::string>* allNames = nullptr) {
  std::vector<InterfaceAddress> out;
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return out;
  for (const ifaddrs* i = list; i; i = i->ifa_next) {
    if (allNames && i->ifa_name) allNames->insert(i->ifa_name);
    if (!i->ifa_addr || i->ifa_addr->sa_family != AF_INET) continue;
    InterfaceAddress a;
    a.name = i->ifa_name;
    a.flags = i->ifa_flags;
    a.ip = ipOf(i->ifa_addr);
    a.mask = ipOf(i->ifa_netmask);
    if ((i->ifa_flags & IFF_BROADCAST) && i->ifa_broadaddr) a.broadcast = ipOf(i->ifa_broadaddr);
    out.push_back(a);
  }
  freeifaddrs(list);
  return out;
}

/// The broadcast address of `a`'s network: the one the interface
/// announces, else (the loopback interface has none) address | ~mask.
std::uint32_t broadcastOf(const InterfaceAddress& a) {
  if (a.broadcast) return a.broadcast;
  return a.mask && a.mask != 0xffffffffu ? (a.ip | ~a.mask) : 0;
}

/// True when the routing table has a route for `ip` (a UDP connect does
/// the lookup and sends nothing).
bool routable(std::uint32_t ip, std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  const int on = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_BROADCAST, &on, sizeof on);
  const sockaddr_in s = sockaddrOf({ip, port});
  const bool ok = ::connect(fd, reinterpret_cast<const sockaddr*>(&s), sizeof s) == 0;
  ::close(fd);
  return ok;
}

Problem fieldProblem(const char* field, const std::string& message) {
  return {field, 0, "socket: " + message + " (" + field + ")"};
}

/// `text` as an IPv4 address: a dotted quad, else a host name resolved.
Result<std::uint32_t> parseAddress(const std::string& text) {
  in_addr a{};
  if (inet_pton(AF_INET, text.c_str(), &a) == 1) return std::uint32_t(ntohl(a.s_addr));
  if (text.find(':') != std::string::npos) {
    return fieldProblem(kAddressField, "'" + text +
                                           "' looks like an IPv6 address; DIS here is IPv4: give an IPv4 address, "
                                           "multicast group or host name");
  }
  if (text.find_first_not_of("0123456789.") == std::string::npos) {
    return fieldProblem(kAddressField, "'" + text + "' is not an IPv4 address (four numbers 0 to 255, e.g. 239.1.2.3)");
  }
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const int rc = getaddrinfo(text.c_str(), nullptr, &hints, &found);
  if (rc != 0 || !found) {
    return fieldProblem(kAddressField, "cannot resolve host name '" + text + "' to an IPv4 address (" +
                                           gai_strerror(rc) + "); give an IPv4 address or a known host name");
  }
  const std::uint32_t ip = ipOf(found->ai_addr);
  freeaddrinfo(found);
  return ip;
}

bool isBroadcast(std::uint32_t ip, const std::vector<InterfaceAddress>& ifs) {
  if (ip == kLimitedBroadcast || ip == kLoopbackBroadcast) return true;
  return std::any_of(ifs.begin(), ifs.end(), [&](const InterfaceAddress& a) { return broadcastOf(a) == ip; });
}

std::string joined(const std::set<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

}  // namespace

const char* deliveryName(Delivery d) {
  switch (d) {
    case Delivery::broadcast: return "broadcast";
    case Delivery::multicast: return "multicast";
    case Delivery::unicast: return "unicast";
  }
  return "";
}

std::string Endpoint::text() const {
  return std::string(deliveryName(delivery)) + " to " + destination.text() +
         (interface.empty() ? std::string() : " on " + interface);
}

Result<SocketOptions> parseDisEndpoint(std::string_view text, SocketOptions base) {
  std::string address;
  std::string port;
  const std::size_t colon = text.rfind(':');
  if (colon != std::string_view::npos) {
    address = std::string(text.substr(0, colon));
    port = std::string(text.substr(colon + 1));
  } else if (!text.empty() && text.find_first_not_of("0123456789") == std::string_view::npos) {
    port = std::string(text);
  } else {
    address = std::string(text);
  }
  if (colon != std::string_view::npos || !port.empty()) {
    unsigned long value = 0;
    const bool digits = !port.empty() && port.size() <= 5 && port.find_first_not_of("0123456789") == std::string::npos;
    if (digits) value = std::stoul(port);
    if (!digits || value < 1 || value > 65535) {
      return fieldProblem(kPortField, "'" + port + "' in '" + std::string(text) +
                                          "' is not a UDP port (1 to 65535); write [ADDR:]PORT, e.g. 3000 or "
                                          "239.1.2.3:3000");
    }
    base.port = std::uint16_t(value);
  } else {
    base.port = kDisPort;
  }
  base.address = address;
  return base;
}

Result<Endpoint> resolveEndpoint(const SocketOptions& o) {
  if (o.port == 0) return fieldProblem(kPortField, "port 0 is not a DIS port; DIS uses 3000 unless the exercise says");
  if (o.multicastTtl < 0 || o.multicastTtl > 255) {
    return fieldProblem("SocketOptions::multicastTtl", "multicast TTL " + std::to_string(o.multicastTtl) +
                                                           " is outside 0 to 255 (1 keeps datagrams on this LAN)");
  }
  std::set<std::string> names;
  const std::vector<InterfaceAddress> ifs = interfaces(&names);
  Endpoint e;
  e.destination.port = o.port;
  const InterfaceAddress* chosen = nullptr;
  if (!o.interface.empty()) {
    e.interfaceIndex = if_nametoindex(o.interface.c_str());
    if (e.interfaceIndex == 0) {
      return fieldProblem(kInterfaceField, "no network interface named '" + o.interface + "' on this host (it has " +
                                               joined(names) + "); name one of them or leave the interface out");
    }
    e.interface = o.interface;
    for (const InterfaceAddress& a : ifs) {
      if (a.name == o.interface) {
        chosen = &a;
        break;
      }
    }
    if (chosen) e.interfaceIp = chosen->ip;
  }
  if (o.address.empty()) {
    e.delivery = Delivery::broadcast;
    if (!o.interface.empty()) {
      if (!chosen || !broadcastOf(*chosen)) {
        return fieldProblem(kInterfaceField, "interface '" + o.interface +
                                                 "' has no IPv4 broadcast address to send to; give an address "
                                                 "(a multicast group or a host) or another interface");
      }
      e.destination.ip = broadcastOf(*chosen);
    } else if (routable(kLimitedBroadcast, o.port)) {
      e.destination.ip = kLimitedBroadcast;
    } else {
      // No route for the limited broadcast (no default route): the first
      // LAN that is up, else this host alone.
      e.destination.ip = kLoopbackBroadcast;
      for (const InterfaceAddress& a : ifs) {
        if ((a.flags & IFF_UP) && !(a.flags & IFF_LOOPBACK) && a.broadcast) {
          e.destination.ip = a.broadcast;
          break;
        }
      }
    }
    return e;
  }
  Result<std::uint32_t> ip = parseAddress(o.address);
  if (!ip) return ip.problems();
  if (ip.value() == 0) {
    return fieldProblem(kAddressField, "0.0.0.0 is not a destination; leave the address out for the default "
                                       "broadcast, or give a multicast group or a host");
  }
  e.destination.ip = ip.value();
  e.delivery = isMulticast(ip.value())      ? Delivery::multicast
               : isBroadcast(ip.value(), ifs) ? Delivery::broadcast
                                              : Delivery::unicast;
  if (o.interface.empty() && !routable(ip.value(), o.port)) {
    if (e.delivery != Delivery::multicast) {
      return fieldProblem(kAddressField, "this host has no route to " + ipText(ip.value()) +
                                             "; give an address on one of its networks or name the interface");
    }
    // A multicast group with no route (a host with only the loopback
    // interface): use the loopback interface, so that processes on this
    // host still hear each other.
    e.interface = "lo";
    e.interfaceIndex = if_nametoindex("lo");
    e.interfaceIp = kLoopbackIp;
  }
  return e;
}

// ---------------------------------------------------------------- the socket

struct UdpSocket::Impl {
  int fd = -1;
  Endpoint endpoint;
  Address local;
  std::uint64_t kernelDrops = 0;
  // recvmmsg's buffers, made on the first receive (a sending socket needs none).
  std::unique_ptr<std::byte[]> buffers;
  std::vector<mmsghdr> messages;
  std::vector<iovec> iovecs;
  std::vector<sockaddr_in> senders;
  struct alignas(cmsghdr) Control {
    char bytes[CMSG_SPACE(sizeof(in_pktinfo)) + CMSG_SPACE(sizeof(std::uint32_t)) + 64];
  };
  std::vector<Control> controls;

  ~Impl() {
    if (fd >= 0) ::close(fd);
  }
  void makeBuffers() {
    buffers.reset(new std::byte[kBatch * kDatagramBuffer]);
    messages.resize(kBatch);
    iovecs.resize(kBatch);
    senders.resize(kBatch);
    controls.resize(kBatch);
  }
};

UdpSocket::UdpSocket(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
UdpSocket::UdpSocket(UdpSocket&&) noexcept = default;
UdpSocket& UdpSocket::operator=(UdpSocket&&) noexcept = default;
UdpSocket::~UdpSocket() = default;

Result<UdpSocket> UdpSocket::open(const SocketOptions& o) {
  Result<Endpoint> endpoint = resolveEndpoint(o);
  if (!endpoint) return endpoint.problems();
  auto impl = std::make_unique<Impl>();
  impl->endpoint = endpoint.value();
  const Endpoint& e = impl->endpoint;
  impl->fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  const int fd = impl->fd;
  if (fd < 0) return Problem{"", 0, "socket: cannot make a UDP socket: " + errnoText(errno)};
  auto option = [&](int level, int name, int value, const char* what) -> Status {
    if (::setsockopt(fd, level, name, &value, sizeof value) == 0) return {};
    return Problem{"", 0, std::string("socket: cannot set ") + what + ": " + errnoText(errno)};
  };
  // Shared port: every process on this host gets the broadcasts and the
  // multicasts. Not SO_REUSEPORT: it would deal unicast datagrams out
  // among the sockets, each process seeing part of the stream.
  for (Status st : {option(SOL_SOCKET, SO_REUSEADDR, 1, "SO_REUSEADDR"),
                    option(SOL_SOCKET, SO_BROADCAST, 1, "SO_BROADCAST"),
                    option(IPPROTO_IP, IP_PKTINFO, 1, "IP_PKTINFO")}) {
    if (!st) return st.problems();
  }
  // Best effort: an older kernel without the drop count, a capped buffer.
  (void)option(SOL_SOCKET, SO_RXQ_OVFL, 1, "SO_RXQ_OVFL");
  (void)option(SOL_SOCKET, SO_RCVBUF, o.receiveBufferBytes, "SO_RCVBUF");
  if (!o.interface.empty()) {
    if (::setsockopt(fd, SOL_SOCKET, SO_BINDTODEVICE, o.interface.c_str(), socklen_t(o.interface.size())) != 0) {
      return fieldProblem(kInterfaceField, "cannot bind the socket to interface '" + o.interface +
                                               "': " + errnoText(errno) +
                                               (errno == EPERM ? " (this kernel wants CAP_NET_RAW for it)" : ""));
    }
  }
  if (e.delivery == Delivery::multicast) {
    for (Status st : {option(IPPROTO_IP, IP_MULTICAST_TTL, o.multicastTtl, "IP_MULTICAST_TTL"),
                      option(IPPROTO_IP, IP_MULTICAST_LOOP, o.multicastLoopback ? 1 : 0, "IP_MULTICAST_LOOP"),
                      // Only the groups this socket joined, not every group any socket on the host joined.
                      option(IPPROTO_IP, IP_MULTICAST_ALL, 0, "IP_MULTICAST_ALL")}) {
      if (!st) return st.problems();
    }
    if (e.interfaceIndex) {
      ip_mreqn out{};
      out.imr_ifindex = int(e.interfaceIndex);
      if (::setsockopt(fd, IPPROTO_IP, IP_MULTICAST_IF, &out, sizeof out) != 0) {
        return fieldProblem(kInterfaceField, "cannot send multicast on '" + e.interface + "': " + errnoText(errno));
      }
    }
  }
  const sockaddr_in any = sockaddrOf({0, o.port});
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&any), sizeof any) != 0) {
    const int err = errno;
    const std::string port = std::to_string(o.port);
    if (err == EADDRINUSE) {
      return fieldProblem(kPortField, "UDP port " + port +
                                          " is taken by a program that does not share it (it bound the port "
                                          "without SO_REUSEADDR); stop that program or choose another port");
    }
    if (err == EACCES) {
      return fieldProblem(kPortField, "UDP port " + port + " needs privileges (ports below 1024); use 3000 or another "
                                                           "port above 1023");
    }
    return fieldProblem(kPortField, "cannot bind UDP port " + port + ": " + errnoText(err));
  }
  if (e.delivery == Delivery::multicast) {
    ip_mreqn join{};
    join.imr_multiaddr.s_addr = htonl(e.destination.ip);
    join.imr_ifindex = int(e.interfaceIndex);
    if (::setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &join, sizeof join) != 0) {
      return fieldProblem(kAddressField, "cannot join multicast group " + ipText(e.destination.ip) +
                                             (e.interface.empty() ? "" : " on " + e.interface) + ": " +
                                             errnoText(errno) + "; name the interface to join it on");
    }
  }
  sockaddr_in bound{};
  socklen_t len = sizeof bound;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &len);
  impl->local = {ntohl(bound.sin_addr.s_addr), ntohs(bound.sin_port)};
  return UdpSocket(std::move(impl));
}

Status UdpSocket::send(std::span<const std::byte> bytes) const { return sendTo(bytes, impl_->endpoint.destination); }

Status UdpSocket::sendTo(std::span<const std::byte> bytes, Address to) const {
  const sockaddr_in s = sockaddrOf(to);
  for (;;) {
    if (::sendto(impl_->fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&s), sizeof s) >= 0) {
      return {};
    }
    if (errno != EINTR) break;
  }
  return Problem{to.text(), 0,
                 "socket: cannot send " + std::to_string(bytes.size()) + " bytes to " + to.text() + ": " +
                     errnoText(errno)};
}

Result<std::size_t> UdpSocket::receive(std::vector<Datagram>& out, int timeoutMs) {
  Impl& m = *impl_;
  if (timeoutMs != 0) {
    pollfd p{m.fd, POLLIN, 0};
    const int n = ::poll(&p, 1, timeoutMs);
    if (n == 0 || (n < 0 && errno == EINTR)) return std::size_t(0);
    if (n < 0) return Problem{"", 0, "socket: poll failed: " + errnoText(errno)};
  }
  if (!m.buffers) m.makeBuffers();
  for (std::size_t k = 0; k < kBatch; ++k) {
    m.iovecs[k] = {m.buffers.get() + k * kDatagramBuffer, kDatagramBuffer};
    msghdr& h = m.messages[k].msg_hdr;
    h = {};
    h.msg_name = &m.senders[k];
    h.msg_namelen = sizeof(sockaddr_in);
    h.msg_iov = &m.iovecs[k];
    h.msg_iovlen = 1;
    h.msg_control = m.controls[k].bytes;
    h.msg_controllen = sizeof m.controls[k].bytes;
  }
  int n = -1;
  do {
    n = ::recvmmsg(m.fd, m.messages.data(), unsigned(kBatch), MSG_DONTWAIT, nullptr);
  } while (n < 0 && errno == EINTR);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK) return std::size_t(0);
    return Problem{"", 0, "socket: recvmmsg failed: " + errnoText(errno)};
  }
  const double now = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  for (int k = 0; k < n; ++k) {
    const msghdr& h = m.messages[std::size_t(k)].msg_hdr;
    Datagram d;
    d.timeS = now;
    d.sender = {ntohl(m.senders[std::size_t(k)].sin_addr.s_addr), ntohs(m.senders[std::size_t(k)].sin_port)};
    d.destination = {0, m.local.port};
    for (cmsghdr* c = CMSG_FIRSTHDR(&h); c; c = CMSG_NXTHDR(const_cast<msghdr*>(&h), c)) {
      if (c->cmsg_level == IPPROTO_IP && c->cmsg_type == IP_PKTINFO) {
        in_pktinfo info;
        std::memcpy(&info, CMSG_DATA(c), sizeof info);
        d.destination.ip = ntohl(info.ipi_addr.s_addr);
      } else if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t drops = 0;
        std::memcpy(&drops, CMSG_DATA(c), sizeof drops);
        m.kernelDrops = drops;
      }
    }
    const std::byte* b = m.buffers.get() + std::size_t(k) * kDatagramBuffer;
    d.bytes.assign(b, b + m.messages[std::size_t(k)].msg_len);
    out.push_back(std::move(d));
  }
  return std::size_t(n);
}

const Endpoint& UdpSocket::endpoint() const { return impl_->endpoint; }
Address UdpSocket::local() const { return impl_->local; }
std::uint64_t UdpSocket::kernelDrops() const { return impl_->kernelDrops; }
int UdpSocket::fd() const { return impl_->fd; }

// ---------------------------------------------------------------- the receiver

Receiver::Receiver(UdpSocket socket, ReceiverOptions options, int stopFd)
    : socket_(std::move(socket)), options_(options), stopFd_(stopFd) {}

Result<std::unique_ptr<Receiver>> Receiver::start(UdpSocket socket, ReceiverOptions options) {
  if (options.queueCapacity == 0) {
    return Problem{"ReceiverOptions::queueCapacity", 0, "receiver: a queue of 0 datagrams would drop everything"};
  }
  const int stop = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (stop < 0) return Problem{"", 0, "receiver: cannot make an eventfd: " + errnoText(errno)};
  std::unique_ptr<Receiver> r(new Receiver(std::move(socket), options, stop));
  try {
    r->thread_ = std::thread(&Receiver::run, r.get());
  } catch (const std::system_error& e) {
    return Problem{"", 0, std::string("receiver: cannot start its thread: ") + e.what()};
  }
  return r;
}

Receiver::~Receiver() {
  if (thread_.joinable()) {
    const std::uint64_t one = 1;
    while (::write(stopFd_, &one, sizeof one) < 0 && errno == EINTR) {
    }
    thread_.join();
  }
  if (stopFd_ >= 0) ::close(stopFd_);
}

void Receiver::run() {
  std::vector<Datagram> batch;
  batch.reserve(UdpSocket::kBatch);
  pollfd fds[2] = {{socket_.fd(), POLLIN, 0}, {stopFd_, POLLIN, 0}};
  auto fail = [&](const std::string& message) {
    std::lock_guard lock(mutex_);
    ++counters_.errors;
    if (firstError_.empty()) firstError_ = message;
  };
  for (;;) {
    if (::poll(fds, 2, -1) < 0) {
      if (errno == EINTR) continue;
      fail("receiver: poll failed: " + errnoText(errno));
      return;
    }
    if (fds[1].revents != 0) return;
    // Read until the socket is empty: a burst costs one poll, not one per batch.
    do {
      batch.clear();
      Result<std::size_t> got = socket_.receive(batch, 0);
      if (!got) {
        fail(got.error());
        return;
      }
      std::lock_guard lock(mutex_);
      counters_.datagrams += batch.size();
      counters_.kernelDropped = socket_.kernelDrops();
      for (Datagram& d : batch) {
        counters_.bytes += d.bytes.size();
        if (pending_.size() < options_.queueCapacity) {
          pending_.push_back(std::move(d));
        } else {
          ++counters_.queueDropped;
        }
      }
    } while (batch.size() == UdpSocket::kBatch);
    pendingChanged_.notify_all();
  }
}

std::size_t Receiver::drain(std::vector<Datagram>& out) {
  out.clear();
  std::lock_guard lock(mutex_);
  std::swap(out, pending_);
  return out.size();
}

bool Receiver::waitPending(int timeoutMs) {
  std::unique_lock lock(mutex_);
  return pendingChanged_.wait_for(lock, std::chrono::milliseconds(timeoutMs), [&] { return !pending_.empty(); });
}

ReceiverCounters Receiver::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

std::string Receiver::firstError() const {
  std::lock_guard lock(mutex_);
  return firstError_;
}

}  // namespace sandtable::dis
