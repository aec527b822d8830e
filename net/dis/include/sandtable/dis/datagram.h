#pragma once
// One UDP datagram as the DIS layer sees it: when it arrived, who sent it
// and its payload (one or more PDUs back to back). The socket receiver,
// the pcap reader and the monitor all pass these.
//
// Thread safety: plain values.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sandtable::dis {

/// An IPv4 address and UDP port, both in host order.
struct Address {
  std::uint32_t ip = 0;
  std::uint16_t port = 0;
  bool operator==(const Address&) const = default;
  auto operator<=>(const Address&) const = default;
  /// "a.b.c.d:port".
  std::string text() const;
};

struct Datagram {
  double timeS = 0;  ///< arrival: the capture's clock (pcap) or the receiver's steady clock
  Address sender;
  Address destination;  ///< where it was sent (0.0.0.0:port when the socket cannot tell)
  std::vector<std::byte> bytes;
};

}  // namespace sandtable::dis
