// UDP for DIS on this host: the user's [ADDR:]PORT, addresses resolved,
// unicast, broadcast and multicast between sockets on loopback, the shared
// port, the taken port, bad addresses and interfaces, a host with only the
// loopback interface (a network namespace made by the test), and the
// Receiver under a burst. Every wait is bounded.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <net/if.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "sandtable/testing/process.h"
#include "sandtable/dis/socket.h"
#include "sandtable/testing/require.h"

namespace sandtable::dis {
namespace {

constexpr std::uint32_t ip4(unsigned a, unsigned b, unsigned c, unsigned d) { return a << 24 | b << 16 | c << 8 | d; }
constexpr std::uint32_t kLoopback = ip4(127, 0, 0, 1);

/// A plain socket bound to ip:port without SO_REUSEADDR: a program that does not share.
int bindExclusive(std::uint32_t ip, std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in s{};
  s.sin_family = AF_INET;
  s.sin_addr.s_addr = htonl(ip);
  s.sin_port = htons(port);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&s), sizeof s) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

std::vector<std::byte> bytesOf(const std::string& s) {
  std::vector<std::byte> o;
  for (char c : s) o.push_back(std::byte(c));
  return o;
}

double steadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// What `s` receives within 2 s (at most one batch), or nothing.
std::vector<Datagram> receiveOne(UdpSocket& s) {
  std::vector<Datagram> out;
  EXPECT_TRUE(s.receive(out, 2000));
  return out;
}

SocketOptions options(const std::string& address, std::uint16_t port, const std::string& interface = {}) {
  SocketOptions o;
  o.address = address;
  o.port = port;
  o.interface = interface;
  return o;
}

// ---- the user's words

TEST(DisSocket, parseDisEndpointSplitsAddressAndPort) {
  struct Case {
    const char* text;
    const char* address;
    std::uint16_t port;
  };
  for (const Case& c : {Case{"", "", 3000}, Case{"3001", "", 3001}, Case{"239.1.2.3:3002", "239.1.2.3", 3002},
                        Case{"239.1.2.3", "239.1.2.3", 3000}, Case{":3003", "", 3003},
                        Case{"localhost:65535", "localhost", 65535}, Case{"host.example", "host.example", 3000}}) {
    Result<SocketOptions> o = parseDisEndpoint(c.text);
    ASSERT_TRUE(o) << c.text << ": " << o.error();
    EXPECT_EQ(o->address, c.address) << c.text;
    EXPECT_EQ(o->port, c.port) << c.text;
  }
  // The other fields come through.
  SocketOptions base;
  base.interface = "lo";
  EXPECT_EQ(parseDisEndpoint("3001", base)->interface, "lo");
  for (const char* bad : {"239.1.2.3:", "x:0", "x:65536", "x:30a", "x:-1", "x:123456"}) {
    Result<SocketOptions> o = parseDisEndpoint(bad);
    ASSERT_FALSE(o) << bad;
    EXPECT_EQ(o.problems().front().file, "SocketOptions::port") << bad;
  }
  EXPECT_EQ(parseDisEndpoint("239.1.2.3:http").message(),
            "socket: 'http' in '239.1.2.3:http' is not a UDP port (1 to 65535); write [ADDR:]PORT, e.g. 3000 or "
            "239.1.2.3:3000 (SocketOptions::port)");
}

TEST(DisSocket, addressesResolveToTheirKind) {
  struct Case {
    const char* address;
    Delivery delivery;
    std::uint32_t ip;
  };
  for (const Case& c : {Case{"255.255.255.255", Delivery::broadcast, 0xffffffffu},
                        Case{"127.255.255.255", Delivery::broadcast, ip4(127, 255, 255, 255)},
                        Case{"239.1.2.3", Delivery::multicast, ip4(239, 1, 2, 3)},
                        Case{"224.0.0.1", Delivery::multicast, ip4(224, 0, 0, 1)},
                        Case{"127.0.0.1", Delivery::unicast, kLoopback},
                        Case{"localhost", Delivery::unicast, kLoopback}}) {
    Result<Endpoint> e = resolveEndpoint(options(c.address, 3000));
    ASSERT_TRUE(e) << c.address << ": " << e.error();
    EXPECT_EQ(e->delivery, c.delivery) << c.address;
    EXPECT_EQ(e->destination, (Address{c.ip, 3000})) << c.address;
  }
  // The default is a broadcast; on the loopback interface it is 127.255.255.255.
  Result<Endpoint> byDefault = resolveEndpoint(options("", 3000));
  ASSERT_TRUE(byDefault) << byDefault.error();
  EXPECT_EQ(byDefault->delivery, Delivery::broadcast);
  Result<Endpoint> onLo = resolveEndpoint(options("", 3000, "lo"));
  ASSERT_TRUE(onLo) << onLo.error();
  EXPECT_EQ(onLo->text(), "broadcast to 127.255.255.255:3000 on lo");
}

TEST(DisSocket, badAddressesPortsAndInterfacesAreClearProblems) {
  struct Case {
    SocketOptions o;
    const char* field;
    const char* message;
  };
  const std::vector<Case> cases = {
      {options("300.1.2.3", 3000), "SocketOptions::address",
       "socket: '300.1.2.3' is not an IPv4 address (four numbers 0 to 255, e.g. 239.1.2.3) (SocketOptions::address)"},
      {options("1.2.3", 3000), "SocketOptions::address",
       "socket: '1.2.3' is not an IPv4 address (four numbers 0 to 255, e.g. 239.1.2.3) (SocketOptions::address)"},
      {options("::1", 3000), "SocketOptions::address",
       "socket: '::1' looks like an IPv6 address; DIS here is IPv4: give an IPv4 address, multicast group or host "
       "name (SocketOptions::address)"},
      {options("0.0.0.0", 3000), "SocketOptions::address",
       "socket: 0.0.0.0 is not a destination; leave the address out for the default broadcast, or give a multicast "
       "group or a host (SocketOptions::address)"},
      {options("", 0), "SocketOptions::port",
       "socket: port 0 is not a DIS port; DIS uses 3000 unless the exercise says (SocketOptions::port)"},
  };
  for (const Case& c : cases) {
    Result<UdpSocket> s = UdpSocket::open(c.o);
    ASSERT_FALSE(s) << c.message;
    EXPECT_EQ(s.problems().front().file, c.field);
    EXPECT_EQ(s.message(), c.message);
  }
  Result<UdpSocket> unknown = UdpSocket::open(options("", fixtures::freeUdpPort(), "nosuch0"));
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.problems().front().file, "SocketOptions::interface");
  EXPECT_NE(unknown.message().find("no network interface named 'nosuch0' on this host (it has "), std::string::npos)
      << unknown.message();
  EXPECT_NE(unknown.message().find("lo"), std::string::npos) << unknown.message();
}

// ---- sockets on this host

TEST(DisSocket, unicastToItselfCarriesSenderDestinationAndTime) {
  const std::uint16_t port = fixtures::freeUdpPort();
  Result<UdpSocket> s = UdpSocket::open(options("127.0.0.1", port));
  ASSERT_TRUE(s) << s.error();
  EXPECT_EQ(s->endpoint().delivery, Delivery::unicast);
  EXPECT_EQ(s->local(), (Address{0, port}));
  const double before = steadyNow();
  ASSERT_TRUE(s->send(bytesOf("hello DIS")));
  std::vector<Datagram> got = receiveOne(s.value());
  const double after = steadyNow();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].bytes, bytesOf("hello DIS"));
  EXPECT_EQ(got[0].sender, (Address{kLoopback, port}));
  EXPECT_EQ(got[0].destination, (Address{kLoopback, port}));
  EXPECT_GE(got[0].timeS, before);
  EXPECT_LE(got[0].timeS, after);
  // Nothing more: a wait that runs out gives 0.
  std::vector<Datagram> none;
  Result<std::size_t> n = s->receive(none, 10);
  ASSERT_TRUE(n);
  EXPECT_EQ(n.value(), 0u);
}

/// Two sockets on one port, `address`: a datagram from the first reaches both.
void bothHear(const SocketOptions& o, std::uint32_t wantDestination) {
  Result<UdpSocket> a = UdpSocket::open(o);
  ASSERT_TRUE(a) << a.error();
  Result<UdpSocket> b = UdpSocket::open(o);
  ASSERT_TRUE(b) << "a second process on the same port: " << b.error();
  ASSERT_TRUE(a->send(bytesOf("to everyone"))) << a->endpoint().text();
  for (UdpSocket* s : {&a.value(), &b.value()}) {
    std::vector<Datagram> got = receiveOne(*s);
    ASSERT_EQ(got.size(), 1u) << a->endpoint().text();
    EXPECT_EQ(got[0].bytes, bytesOf("to everyone"));
    EXPECT_EQ(got[0].sender.port, o.port);
    EXPECT_EQ(got[0].destination, (Address{wantDestination, o.port})) << a->endpoint().text();
  }
}

TEST(DisSocket, broadcastReachesEverySocketOnThePort) {
  bothHear(options("127.255.255.255", fixtures::freeUdpPort()), ip4(127, 255, 255, 255));
  bothHear(options("", fixtures::freeUdpPort(), "lo"), ip4(127, 255, 255, 255));
  // The default: whichever broadcast this host's routes give, heard here too.
  Result<Endpoint> e = resolveEndpoint(options("", 3000));
  ASSERT_TRUE(e);
  bothHear(options("", fixtures::freeUdpPort()), e->destination.ip);
}

TEST(DisSocket, multicastReachesEveryMemberOnThePort) {
  bothHear(options("239.255.36.1", fixtures::freeUdpPort()), ip4(239, 255, 36, 1));
  bothHear(options("239.255.36.2", fixtures::freeUdpPort(), "lo"), ip4(239, 255, 36, 2));
  // A socket of another group on the same port hears neither (IP_MULTICAST_ALL off).
  const std::uint16_t port = fixtures::freeUdpPort();
  Result<UdpSocket> a = UdpSocket::open(options("239.255.36.3", port, "lo"));
  Result<UdpSocket> other = UdpSocket::open(options("239.255.36.4", port, "lo"));
  ASSERT_TRUE(a && other);
  ASSERT_TRUE(a->send(bytesOf("group 3")));
  EXPECT_EQ(receiveOne(a.value()).size(), 1u);
  std::vector<Datagram> none;
  EXPECT_EQ(other->receive(none, 200).value(), 0u);
}

TEST(DisSocket, aPortTakenByAProgramThatDoesNotShareIsAClearProblem) {
  for (std::uint32_t ip : {0u, kLoopback}) {
    const std::uint16_t port = fixtures::freeUdpPort();
    const int fd = bindExclusive(ip, port);
    ASSERT_GE(fd, 0);
    Result<UdpSocket> s = UdpSocket::open(options("127.0.0.1", port));
    ::close(fd);
    ASSERT_FALSE(s);
    EXPECT_EQ(s.problems().front().file, "SocketOptions::port");
    EXPECT_EQ(s.message(), "socket: UDP port " + std::to_string(port) +
                               " is taken by a program that does not share it (it bound the port without "
                               "SO_REUSEADDR); stop that program or choose another port (SocketOptions::port)");
    // Once it is gone the port opens.
    EXPECT_TRUE(UdpSocket::open(options("127.0.0.1", port)));
  }
}

// ---- a host with only the loopback interface

/// In a fresh network namespace (only lo, brought up here): the default
/// broadcast, a multicast group without an interface, and unicast, each
/// between two sockets. "" when all hold, else what failed; "unshare: ..."
/// when the namespace cannot be made.
std::string loopbackOnlyHost() {
  if (::unshare(CLONE_NEWNET) != 0 && ::unshare(CLONE_NEWUSER | CLONE_NEWNET) != 0) {
    return std::string("unshare: ") + std::strerror(errno);
  }
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ifreq r{};
  std::strcpy(r.ifr_name, "lo");
  if (::ioctl(fd, SIOCGIFFLAGS, &r) != 0) return "SIOCGIFFLAGS failed";
  r.ifr_flags = short(r.ifr_flags | IFF_UP);
  if (::ioctl(fd, SIOCSIFFLAGS, &r) != 0) return std::string("bringing lo up: ") + std::strerror(errno);
  ::close(fd);
  struct Case {
    const char* address;
    Delivery delivery;
    std::uint32_t destination;
  };
  for (const Case& c : {Case{"", Delivery::broadcast, ip4(127, 255, 255, 255)},
                        Case{"239.255.36.9", Delivery::multicast, ip4(239, 255, 36, 9)},
                        Case{"127.0.0.1", Delivery::unicast, kLoopback}}) {
    const std::string name = std::string("'") + c.address + "': ";
    Result<UdpSocket> a = UdpSocket::open(options(c.address, 3000));
    if (!a) return name + a.error();
    if (a->endpoint().delivery != c.delivery || a->endpoint().destination.ip != c.destination) {
      return name + "resolved to " + a->endpoint().text();
    }
    Result<UdpSocket> b = UdpSocket::open(options(c.address, 3000));
    if (!b) return name + b.error();
    if (Status st = a->send(bytesOf("lo only")); !st) return name + st.error();
    // Unicast reaches one socket of the two; broadcast and multicast both.
    std::size_t heard = 0;
    for (UdpSocket* s : {&a.value(), &b.value()}) {
      std::vector<Datagram> got;
      if (!s->receive(got, 500)) return name + "receive failed";
      heard += got.size();
    }
    if (heard != (c.delivery == Delivery::unicast ? 1u : 2u)) return name + std::to_string(heard) + " sockets heard it";
  }
  return "";
}

TEST(DisSocket, aHostWithOnlyLoopbackBroadcastsAndMulticastsOnIt) {
  int pipeFds[2];
  ASSERT_EQ(::pipe(pipeFds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(pipeFds[0]);
    const std::string why = loopbackOnlyHost();
    (void)!::write(pipeFds[1], why.data(), why.size());
    ::_exit(why.empty() ? 0 : 1);
  }
  ::close(pipeFds[1]);
  std::string why;
  char buf[512];
  for (ssize_t n; (n = ::read(pipeFds[0], buf, sizeof buf)) > 0;) why.append(buf, std::size_t(n));
  ::close(pipeFds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  SANDTABLE_REQUIRE(why.rfind("unshare: ", 0) != 0, "a network namespace (unshare(CLONE_NEWNET)): " << why);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << why;
}

// ---- the receiver

TEST(DisReceiver, countsEveryDatagramOfABurst) {
  const std::uint16_t port = fixtures::freeUdpPort();
  Result<UdpSocket> listen = UdpSocket::open(options("127.0.0.1", port));
  ASSERT_TRUE(listen) << listen.error();
  Result<std::unique_ptr<Receiver>> r = Receiver::start(std::move(listen.value()));
  ASSERT_TRUE(r) << r.error();
  Receiver& receiver = *r.value();
  SocketOptions from = options("127.0.0.1", port);
  from.port = fixtures::freeUdpPort();  // the sender's own port; it sends to 127.0.0.1:port
  Result<UdpSocket> sender = UdpSocket::open(from);
  ASSERT_TRUE(sender) << sender.error();
  const Address to{kLoopback, port};

  constexpr std::uint32_t kBurst = 100000;
  std::vector<std::uint32_t> seen;
  std::vector<Datagram> step;
  auto drainAll = [&] {
    receiver.drain(step);
    for (const Datagram& d : step) {
      std::uint32_t k = 0;
      std::memcpy(&k, d.bytes.data(), sizeof k);
      seen.push_back(k);
    }
  };
  std::vector<std::byte> payload(144);
  for (std::uint32_t k = 0; k < kBurst; ++k) {
    std::memcpy(payload.data(), &k, sizeof k);
    ASSERT_TRUE(sender->sendTo(payload, to));
    if (k % 10000 == 0) drainAll();  // the simulation's pre-step hook, now and then
  }
  // Let the receiver catch up, then one last datagram: the kernel's drop
  // count rides on each datagram read, so the last one read must come
  // after the last drop.
  auto settled = [&] {
    ReceiverCounters before = receiver.counters();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    return receiver.counters().datagrams == before.datagrams;
  };
  for (int k = 0; k < 100 && !settled(); ++k) {
  }
  std::uint32_t last = kBurst;
  std::memcpy(payload.data(), &last, sizeof last);
  ASSERT_TRUE(sender->sendTo(payload, to));
  const std::uint64_t sent = kBurst + 1;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  ReceiverCounters c;
  for (;;) {
    drainAll();
    c = receiver.counters();
    if (c.datagrams + c.kernelDropped >= sent || std::chrono::steady_clock::now() > deadline) break;
    receiver.waitPending(100);
  }
  drainAll();
  c = receiver.counters();
  EXPECT_EQ(c.datagrams + c.kernelDropped, sent) << "kernel dropped " << c.kernelDropped;
  EXPECT_EQ(c.queueDropped, 0u);
  EXPECT_EQ(seen.size(), c.datagrams);
  EXPECT_EQ(c.bytes, c.datagrams * payload.size());
  EXPECT_EQ(c.errors, 0u) << receiver.firstError();
  // In order, each once, the last one among them.
  for (std::size_t k = 1; k < seen.size(); ++k) ASSERT_LT(seen[k - 1], seen[k]) << k;
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), kBurst);
  std::printf("burst of %u: %llu read, %llu dropped by the kernel\n", kBurst,
              static_cast<unsigned long long>(c.datagrams), static_cast<unsigned long long>(c.kernelDropped));
}

// The kernel's drop count (SO_RXQ_OVFL): a socket with a tiny buffer that
// nobody reads while a burst arrives.
TEST(DisReceiver, kernelDropsAreCountedWhenTheBufferOverflows) {
  SocketOptions o = options("127.0.0.1", fixtures::freeUdpPort());
  o.receiveBufferBytes = 1;  // the kernel's minimum
  Result<UdpSocket> s = UdpSocket::open(o);
  ASSERT_TRUE(s) << s.error();
  const std::vector<std::byte> payload(144);
  constexpr std::uint64_t kSent = 500;
  for (std::uint64_t k = 0; k < kSent; ++k) ASSERT_TRUE(s->send(payload));
  std::vector<Datagram> got;
  while (s->receive(got, 0).value() > 0) {
  }
  ASSERT_TRUE(s->send(payload));  // read after the drops: carries their count
  ASSERT_TRUE(s->receive(got, 2000));
  EXPECT_GT(s->kernelDrops(), 0u);
  EXPECT_EQ(got.size() + s->kernelDrops(), kSent + 1);
}

TEST(DisReceiver, aFullQueueDropsAndCountsTheNewest) {
  const std::uint16_t port = fixtures::freeUdpPort();
  Result<UdpSocket> listen = UdpSocket::open(options("127.0.0.1", port));
  ASSERT_TRUE(listen);
  Result<std::unique_ptr<Receiver>> r = Receiver::start(std::move(listen.value()), {.queueCapacity = 10});
  ASSERT_TRUE(r) << r.error();
  Receiver& receiver = *r.value();
  for (std::uint8_t k = 0; k < 25; ++k) {
    ASSERT_TRUE(receiver.socket().send(std::vector<std::byte>(3, std::byte{k})));
    // One at a time: a slow sender, so the kernel drops none.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (receiver.counters().datagrams < k + 1u && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  const ReceiverCounters c = receiver.counters();
  EXPECT_EQ(c.datagrams, 25u);
  EXPECT_EQ(c.queueDropped, 15u);
  EXPECT_EQ(c.kernelDropped, 0u);
  std::vector<Datagram> got;
  EXPECT_EQ(receiver.drain(got), 10u);
  EXPECT_EQ(got.front().bytes, std::vector<std::byte>(3, std::byte{0}));
  EXPECT_EQ(got.back().bytes, std::vector<std::byte>(3, std::byte{9}));
  EXPECT_EQ(receiver.drain(got), 0u);
  EXPECT_TRUE(got.empty());
  EXPECT_FALSE(Receiver::start(std::move(UdpSocket::open(options("127.0.0.1", fixtures::freeUdpPort())).value()),
                               {.queueCapacity = 0}));
}

TEST(DisReceiver, stopsPromptlyWithNothingArriving) {
  Result<UdpSocket> listen = UdpSocket::open(options("127.0.0.1", fixtures::freeUdpPort()));
  ASSERT_TRUE(listen);
  Result<std::unique_ptr<Receiver>> r = Receiver::start(std::move(listen.value()));
  ASSERT_TRUE(r);
  EXPECT_FALSE(r.value()->waitPending(10));
  r.value().reset();  // blocks in poll until the stop eventfd: a hang here fails by the test's timeout
}

}  // namespace
}  // namespace sandtable::dis
