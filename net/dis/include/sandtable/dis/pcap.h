#pragma once
// Capture files (pcap and pcapng, through libpcap) as DIS datagrams: the
// data logger's record and play, and the monitor's offline inspect
// (docs/DIS.md, "Capture files").
//
// Reading takes pcap and pcapng with the link types a DIS capture comes
// in: Ethernet (802.1Q / 802.1ad VLAN tags skipped), Linux cooked capture
// (SLL and SLL2, `tcpdump -i any`), raw IPv4, and BSD loopback (null and
// loop). Only IPv4 + UDP becomes a Datagram; everything else (ARP, IPv6,
// TCP, ICMP, IP fragments, frames cut short by the snap length, damaged
// headers) is skipped and counted by reason, and the first few of each
// reason become warnings naming the file, the packet number and its byte
// offset. Datagram::timeS is the capture time in seconds since 1970 (UTC),
// as the record header has it.
//
// Writing makes a classic pcap (microsecond times, little-endian, link
// type Ethernet) of Ethernet/IPv4/UDP frames carrying each datagram with
// its sender and destination, which Wireshark dissects as DIS on port
// 3000. The file appears only on close(): the writer fills a temporary
// file beside it and renames it, and a writer destroyed unclosed removes
// the temporary file.
//
// Thread safety: PcapReader and PcapWriter are move-only objects used from
// one thread at a time; distinct objects may be used from any threads.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/dis/datagram.h"

namespace sandtable::dis {

/// Packets a reader skipped, by reason.
struct PcapSkips {
  std::uint64_t notIpv4 = 0;    ///< ARP, IPv6, other link-layer protocols
  std::uint64_t notUdp = 0;     ///< IPv4 but TCP, ICMP, ...
  std::uint64_t fragment = 0;   ///< IPv4 fragments (a DIS datagram is never fragmented on a LAN)
  std::uint64_t truncated = 0;  ///< captured length below the frame's length (snap length)
  std::uint64_t malformed = 0;  ///< link, IPv4 or UDP header cut short or inconsistent
  std::uint64_t otherPort = 0;  ///< UDP to another port than PcapReadOptions::port (counted, not warned)
  std::uint64_t total() const { return notIpv4 + notUdp + fragment + truncated + malformed + otherPort; }
};

struct PcapReadOptions {
  /// Keep only UDP datagrams to this destination port (0: every port).
  std::uint16_t port = 0;
  /// Warnings kept per skip reason; the rest are summed up in one line.
  std::uint32_t warningsPerReason = 5;
};

/// Reads a capture file one UDP datagram at a time.
class PcapReader {
 public:
  /// Opens `path`; a missing file, a file that is not a capture or a link
  /// type not listed above gives a Problem naming the file.
  static Result<PcapReader> open(const std::filesystem::path& path, PcapReadOptions options = {});
  PcapReader(PcapReader&&) noexcept;
  PcapReader& operator=(PcapReader&&) noexcept;
  ~PcapReader();

  /// The next IPv4/UDP datagram into `out`; false at the end of the file.
  /// Skipped packets add warnings to `warnings` (may be null); so does a
  /// file that ends inside a record (the packets before it are kept), and
  /// the end of the file adds one summary line per reason over the cap.
  bool next(Datagram& out, Warnings* warnings);

  /// Packets read from the file so far (kept and skipped).
  std::uint64_t packets() const;
  const PcapSkips& skips() const;
  /// The file's link type (LINKTYPE_* number: 1 Ethernet, 113 SLL, ...).
  int linkType() const;

 private:
  struct Impl;
  explicit PcapReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Every IPv4/UDP datagram of the capture at `path`, in file order.
Result<std::vector<Datagram>> readPcap(const std::filesystem::path& path, Warnings* warnings,
                                       PcapReadOptions options = {});

/// Writes datagrams as a pcap that Wireshark opens.
class PcapWriter {
 public:
  /// Starts `path` (through a temporary file beside it); the directory
  /// must exist.
  static Result<PcapWriter> create(const std::filesystem::path& path);
  PcapWriter(PcapWriter&&) noexcept;
  PcapWriter& operator=(PcapWriter&&) noexcept;
  /// Without close(), removes the temporary file: `path` is untouched.
  ~PcapWriter();

  /// Appends one frame: Ethernet (destination MAC from the destination
  /// address: broadcast, IPv4 multicast, else 02:00:a.b.c.d), IPv4 (header
  /// checksum set, don't-fragment, TTL 64) and UDP (checksum 0) from
  /// `d.sender` to `d.destination`, stamped `d.timeS` (seconds since 1970,
  /// to the microsecond). A payload over 65,507 bytes (the most UDP over
  /// IPv4 carries) or a negative time is refused.
  Status write(const Datagram& d);
  /// Flushes, syncs and renames the temporary file to `path`.
  Status close();
  /// Datagrams written so far.
  std::uint64_t count() const;

 private:
  struct Impl;
  explicit PcapWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// The Ethernet/IPv4/UDP frame PcapWriter writes for `d` (bytes of the
/// record, without the pcap record header); empty when the payload is too
/// big. For tests and for anything that builds frames by hand.
std::vector<std::byte> udpFrame(const Datagram& d);

/// The largest UDP payload over IPv4: 65,535 - 20 (IPv4) - 8 (UDP).
inline constexpr std::size_t kMaxUdpPayload = 65507;

}  // namespace sandtable::dis
