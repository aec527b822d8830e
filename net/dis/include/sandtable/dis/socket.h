#pragma once
// DIS over UDP/IPv4 (docs/DIS.md, "The wire"): the user's `[ADDR:]PORT`,
// a socket that sends to the exercise and reads batches with recvmmsg, and
// a Receiver that owns a thread blocked on the socket and queues what
// arrives for the simulation's pre-step hook.
//
// Addresses. ADDR is a multicast group (224.0.0.0/4: joined, TTL and
// loopback set), a broadcast address (255.255.255.255, 127.255.255.255 or
// a directed broadcast of one of this host's interfaces) or a unicast
// IPv4 address or host name. Without ADDR the socket broadcasts: to
// 255.255.255.255 when the host has a route for it, else to the directed
// broadcast of its first broadcast-capable interface that is up, else (a
// host with only the loopback interface) to 127.255.255.255, which every
// process on this host that listens on the port receives.
//
// Sharing. Every socket binds 0.0.0.0:PORT with SO_REUSEADDR, so several
// processes on one host share the port and each receives every broadcast
// and multicast datagram (a unicast datagram reaches one of them). A port
// bound by a program that does not share it is an error, as is a bad
// address or an unknown interface; every such Problem names the option
// field (SocketOptions::address, ::port, ::interface) in Problem::file
// and says how to fix it.
//
// Thread safety: parseDisEndpoint and resolveEndpoint are pure functions
// (resolveEndpoint reads the host's interfaces and may ask the resolver
// for a host name). UdpSocket: send() and sendTo() may be called from any
// threads at once; receive() from one thread at a time. Receiver: its
// thread is the only caller of its socket's receive(); drain() and
// counters() may be called from any thread (one lock, held for a swap);
// socket().send() from any thread. The destructor stops the thread and
// returns within one poll wake-up.
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/dis/datagram.h"

namespace sandtable::dis {

/// The DIS port (IEEE 1278.2 names none; 3000 is the common use).
inline constexpr std::uint16_t kDisPort = 3000;

/// What the user asks for.
struct SocketOptions {
  std::string address;             ///< "" = the default broadcast; IPv4 dotted quad or host name
  std::uint16_t port = kDisPort;   ///< sent to and received on
  std::string interface;           ///< "" = the routing table's choice; else "eth0", "lo", ...
  int multicastTtl = 1;            ///< hops a multicast datagram may take (1: this LAN)
  bool multicastLoopback = true;   ///< this host's other processes see our multicast
  int receiveBufferBytes = 4 << 20;///< SO_RCVBUF asked for (the kernel caps it at net.core.rmem_max)
};

/// How datagrams reach the exercise.
enum class Delivery { broadcast, multicast, unicast };
const char* deliveryName(Delivery d);

/// The options resolved against this host.
struct Endpoint {
  Delivery delivery = Delivery::broadcast;
  Address destination;      ///< where send() goes (its port is also the port bound)
  std::string interface;    ///< the interface used ("" = the routing table's choice)
  unsigned interfaceIndex = 0;
  std::uint32_t interfaceIp = 0;  ///< the interface's IPv4 address (0 when none is named)
  /// "broadcast to 255.255.255.255:3000", "multicast to 239.1.2.3:3000 on lo", ...
  std::string text() const;
};

/// Splits the user's `[ADDR:]PORT` into `base`'s address and port: "3000",
/// "239.1.2.3:3000", "host.example:3001", "239.1.2.3" (port 3000), ""
/// (both defaults). Checks the port (1 to 65535); the address is checked
/// by resolveEndpoint.
Result<SocketOptions> parseDisEndpoint(std::string_view text, SocketOptions base = {});

/// Resolves `o` against this host: the address's kind, the default
/// broadcast address, the interface. Problems name the option field.
Result<Endpoint> resolveEndpoint(const SocketOptions& o);

/// One UDP socket bound to the DIS port.
class UdpSocket {
 public:
  /// At most this many datagrams per receive() (one recvmmsg call).
  static constexpr std::size_t kBatch = 64;

  /// Resolves, binds 0.0.0.0:port (shared), joins the group for
  /// multicast, asks for each datagram's destination (IP_PKTINFO) and the
  /// kernel's drop count (SO_RXQ_OVFL).
  static Result<UdpSocket> open(const SocketOptions& o);
  UdpSocket(UdpSocket&&) noexcept;
  UdpSocket& operator=(UdpSocket&&) noexcept;
  ~UdpSocket();

  /// One datagram to endpoint().destination.
  Status send(std::span<const std::byte> bytes) const;
  /// One datagram to `to` (a replay to another address, a test).
  Status sendTo(std::span<const std::byte> bytes, Address to) const;

  /// Appends to `out` what is pending, up to kBatch datagrams, after
  /// waiting up to `timeoutMs` for the first (0: no wait, -1: forever).
  /// Each Datagram has the sender, the destination (IP_PKTINFO: the
  /// group, broadcast or our own address; port: the bound port) and
  /// timeS, the steady clock in seconds when the batch was read. Returns
  /// how many it appended (0 when the wait ran out).
  Result<std::size_t> receive(std::vector<Datagram>& out, int timeoutMs);

  const Endpoint& endpoint() const;
  /// The address bound (0.0.0.0 and the port).
  Address local() const;
  /// Datagrams the kernel dropped because the receive buffer was full,
  /// as of the last datagram read (SO_RXQ_OVFL; 0 on a kernel without it).
  std::uint64_t kernelDrops() const;
  /// The descriptor, for poll().
  int fd() const;

 private:
  struct Impl;
  explicit UdpSocket(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

struct ReceiverOptions {
  /// Datagrams held between two drains; more are dropped and counted.
  std::size_t queueCapacity = 1 << 16;
};

struct ReceiverCounters {
  std::uint64_t datagrams = 0;     ///< read from the socket (queued or dropped)
  std::uint64_t bytes = 0;         ///< their payload bytes
  std::uint64_t queueDropped = 0;  ///< not queued: the queue was full (the newest are dropped)
  std::uint64_t kernelDropped = 0; ///< dropped by the kernel before we read them (SO_RXQ_OVFL)
  std::uint64_t errors = 0;        ///< failed reads (the first one's words: Receiver::firstError)
};

/// A thread blocked on a socket, queueing what arrives.
class Receiver {
 public:
  /// Takes the socket and starts the thread.
  static Result<std::unique_ptr<Receiver>> start(UdpSocket socket, ReceiverOptions options = {});
  /// Stops the thread (an eventfd wakes its poll) and joins it.
  ~Receiver();
  Receiver(const Receiver&) = delete;
  Receiver& operator=(const Receiver&) = delete;

  /// Everything pending, in arrival order, into `out` (cleared first;
  /// its storage goes back to the queue). Returns how many.
  std::size_t drain(std::vector<Datagram>& out);
  /// Waits up to `timeoutMs` for something to be pending (tests, the
  /// monitor's idle loop); true when there is.
  bool waitPending(int timeoutMs);
  ReceiverCounters counters() const;
  /// The first failed read's words ("" when none failed).
  std::string firstError() const;
  /// The socket, for send() (receive() is the thread's).
  UdpSocket& socket() { return socket_; }

 private:
  Receiver(UdpSocket socket, ReceiverOptions options, int stopFd);
  void run();

  UdpSocket socket_;
  ReceiverOptions options_;
  int stopFd_ = -1;
  mutable std::mutex mutex_;
  std::condition_variable pendingChanged_;
  std::vector<Datagram> pending_;
  ReceiverCounters counters_;
  std::string firstError_;
  std::thread thread_;
};

}  // namespace sandtable::dis
