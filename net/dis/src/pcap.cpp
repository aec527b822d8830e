#include "sandtable/dis/pcap.h"

#include <pcap/pcap.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <system_error>

namespace sandtable::dis {

namespace {

// Link-layer and IP numbers the reader knows.
constexpr unsigned kEtherIpv4 = 0x0800;
constexpr unsigned kEtherVlan = 0x8100;     // 802.1Q
constexpr unsigned kEtherQinQ = 0x88a8;     // 802.1ad
constexpr unsigned kEtherQinQOld = 0x9100;  // pre-standard double tagging
constexpr unsigned kIpProtoUdp = 17;
constexpr std::size_t kEthernetBytes = 14;
constexpr std::size_t kSllBytes = 16;
constexpr std::size_t kSll2Bytes = 20;
constexpr std::size_t kNullBytes = 4;
constexpr std::size_t kIpv4Bytes = 20;
constexpr std::size_t kUdpBytes = 8;
// libpcap's MAXIMUM_SNAPLEN: room for the largest Ethernet/IPv4/UDP frame.
constexpr int kWriteSnapLen = 262144;
// DLT_LINUX_SLL2 and DLT_IPV4 are recent; spelled out for older headers.
constexpr int kDltLinuxSll2 = 276;
constexpr int kDltIpv4 = 228;

unsigned be16(const unsigned char* p) { return unsigned(p[0]) << 8 | p[1]; }
std::uint32_t be32(const unsigned char* p) {
  return std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 | std::uint32_t(p[2]) << 8 | p[3];
}

enum class Skip { none, notIpv4, notUdp, fragment, truncated, malformed, otherPort };

const char* skipName(Skip s) {
  switch (s) {
    case Skip::notIpv4: return "not IPv4";
    case Skip::notUdp: return "not UDP";
    case Skip::fragment: return "IPv4 fragment";
    case Skip::truncated: return "truncated (captured length below the frame's length)";
    case Skip::malformed: return "malformed";
    case Skip::otherPort: return "other port";
    case Skip::none: break;
  }
  return "";
}

/// The counter of `k` in PcapSkips.
std::uint64_t PcapSkips::*counter(Skip k) {
  switch (k) {
    case Skip::notIpv4: return &PcapSkips::notIpv4;
    case Skip::notUdp: return &PcapSkips::notUdp;
    case Skip::fragment: return &PcapSkips::fragment;
    case Skip::truncated: return &PcapSkips::truncated;
    case Skip::otherPort: return &PcapSkips::otherPort;
    case Skip::malformed:
    case Skip::none: break;
  }
  return &PcapSkips::malformed;
}

/// Where the network-layer packet starts in a frame of `link`, and whether
/// it is IPv4; `why` says what else it is.
struct NetworkStart {
  std::size_t offset = 0;
  Skip why = Skip::none;
  std::string detail;
};

NetworkStart networkStart(int link, const unsigned char* f, std::size_t n) {
  auto fromEthertype = [](unsigned type, std::size_t at) {
    if (type == kEtherIpv4) return NetworkStart{at, Skip::none, {}};
    char text[32];
    std::snprintf(text, sizeof text, "ethertype 0x%04x", type);
    return NetworkStart{at, Skip::notIpv4, text};
  };
  switch (link) {
    case DLT_EN10MB: {
      if (n < kEthernetBytes) return {0, Skip::malformed, "Ethernet header cut short"};
      std::size_t at = 12;
      unsigned type = be16(f + at);
      // VLAN tags (possibly stacked): 2 bytes tag protocol, 2 bytes tag.
      while (type == kEtherVlan || type == kEtherQinQ || type == kEtherQinQOld) {
        at += 4;
        if (at + 2 > n) return {0, Skip::malformed, "VLAN tag cut short"};
        type = be16(f + at);
      }
      return fromEthertype(type, at + 2);
    }
    case DLT_LINUX_SLL:
      if (n < kSllBytes) return {0, Skip::malformed, "Linux cooked header cut short"};
      return fromEthertype(be16(f + 14), kSllBytes);
    case kDltLinuxSll2:
      if (n < kSll2Bytes) return {0, Skip::malformed, "Linux cooked v2 header cut short"};
      return fromEthertype(be16(f), kSll2Bytes);
    case DLT_RAW:
    case kDltIpv4:
      if (n < 1) return {0, Skip::malformed, "empty raw IP packet"};
      if ((f[0] >> 4) != 4) return {0, Skip::notIpv4, "IP version " + std::to_string(f[0] >> 4)};
      return {0, Skip::none, {}};
    case DLT_NULL:
    case DLT_LOOP: {
      if (n < kNullBytes) return {0, Skip::malformed, "loopback header cut short"};
      // The family is AF_INET (2) on every BSD; DLT_NULL writes it in the
      // capturing host's byte order, DLT_LOOP in network order: take both.
      const std::uint32_t family = be32(f);
      if (family == 2 || family == 0x02000000u) return {kNullBytes, Skip::none, {}};
      return {0, Skip::notIpv4, "address family " + std::to_string(family)};
    }
    default: break;
  }
  return {0, Skip::malformed, "unknown link type"};
}

bool knownLink(int link) {
  return link == DLT_EN10MB || link == DLT_LINUX_SLL || link == kDltLinuxSll2 || link == DLT_RAW ||
         link == kDltIpv4 || link == DLT_NULL || link == DLT_LOOP;
}

std::string linkName(int link) {
  const char* name = pcap_datalink_val_to_name(link);
  return std::to_string(link) + (name ? std::string(" (") + name + ")" : std::string());
}

}  // namespace

struct PcapReader::Impl {
  std::string file;
  PcapReadOptions options;
  pcap_t* pcap = nullptr;
  int link = 0;
  std::uint64_t packets = 0;
  PcapSkips skips;
  bool ended = false;
  ~Impl() {
    if (pcap) pcap_close(pcap);
  }

  /// Why the frame `f` (`caplen` of `len` bytes) gives no datagram, or
  /// none with `out` filled.
  std::pair<Skip, std::string> parse(const unsigned char* f, std::size_t caplen, std::size_t len,
                                     Datagram& out) const {
    if (caplen < len) {
      return {Skip::truncated, std::to_string(caplen) + " of " + std::to_string(len) + " bytes captured"};
    }
    const NetworkStart start = networkStart(link, f, caplen);
    if (start.why != Skip::none) return {start.why, start.detail};
    const unsigned char* ip = f + start.offset;
    const std::size_t avail = caplen - start.offset;
    if (avail < kIpv4Bytes) return {Skip::malformed, "IPv4 header cut short"};
    if ((ip[0] >> 4) != 4) return {Skip::malformed, "IPv4 ethertype with IP version " + std::to_string(ip[0] >> 4)};
    const std::size_t ihl = std::size_t(ip[0] & 15) * 4;
    const std::size_t total = be16(ip + 2);
    if (ihl < kIpv4Bytes || ihl > avail) return {Skip::malformed, "IPv4 header length " + std::to_string(ihl)};
    // Ethernet pads short frames: the IPv4 total length says where the packet ends.
    if (total < ihl || total > avail) {
      return {Skip::malformed, "IPv4 total length " + std::to_string(total) + " with " + std::to_string(avail) +
                                   " bytes in the frame"};
    }
    const unsigned flagsFragment = be16(ip + 6);
    if ((flagsFragment & 0x2000) != 0 || (flagsFragment & 0x1fff) != 0) {
      return {Skip::fragment, "fragment offset " + std::to_string((flagsFragment & 0x1fff) * 8)};
    }
    if (ip[9] != kIpProtoUdp) return {Skip::notUdp, "IP protocol " + std::to_string(ip[9])};
    if (total - ihl < kUdpBytes) return {Skip::malformed, "UDP header cut short"};
    const unsigned char* udp = ip + ihl;
    const std::size_t udpLength = be16(udp + 4);
    if (udpLength < kUdpBytes || udpLength > total - ihl) {
      return {Skip::malformed, "UDP length " + std::to_string(udpLength) + " in an IPv4 payload of " +
                                   std::to_string(total - ihl) + " bytes"};
    }
    const std::uint16_t destinationPort = std::uint16_t(be16(udp + 2));
    if (options.port != 0 && destinationPort != options.port) return {Skip::otherPort, {}};
    out.sender = {be32(ip + 12), std::uint16_t(be16(udp))};
    out.destination = {be32(ip + 16), destinationPort};
    const auto* payload = reinterpret_cast<const std::byte*>(udp + kUdpBytes);
    out.bytes.assign(payload, payload + (udpLength - kUdpBytes));
    return {Skip::none, {}};
  }

  void summary(Warnings* warnings) const {
    if (!warnings) return;
    for (Skip k : {Skip::notIpv4, Skip::notUdp, Skip::fragment, Skip::truncated, Skip::malformed}) {
      const std::uint64_t n = skips.*counter(k);
      if (n > options.warningsPerReason) {
        warnings->push_back({file, 0,
                             "pcap: " + std::to_string(n - options.warningsPerReason) + " more " + skipName(k) +
                                 " packets skipped (" + std::to_string(n) + " in all)"});
      }
    }
  }
};

PcapReader::PcapReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PcapReader::PcapReader(PcapReader&&) noexcept = default;
PcapReader& PcapReader::operator=(PcapReader&&) noexcept = default;
PcapReader::~PcapReader() = default;

Result<PcapReader> PcapReader::open(const std::filesystem::path& path, PcapReadOptions options) {
  auto impl = std::make_unique<Impl>();
  impl->file = path.string();
  impl->options = options;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Problem{impl->file, 0, "pcap: cannot open " + impl->file + ": no such file"};
  }
  char errbuf[PCAP_ERRBUF_SIZE] = {};
  // Nanosecond precision: libpcap scales microsecond files up, so one
  // conversion serves both.
  impl->pcap = pcap_open_offline_with_tstamp_precision(impl->file.c_str(), PCAP_TSTAMP_PRECISION_NANO, errbuf);
  if (!impl->pcap) {
    return Problem{impl->file, 0,
                   "pcap: " + impl->file + " is not a capture file libpcap reads (pcap or pcapng): " + errbuf};
  }
  impl->link = pcap_datalink(impl->pcap);
  if (!knownLink(impl->link)) {
    return Problem{impl->file, 0,
                   "pcap: link type " + linkName(impl->link) +
                       " is not one the DIS reader takes (Ethernet, Linux cooked SLL or SLL2, raw IPv4, BSD loopback)"};
  }
  return PcapReader(std::move(impl));
}

bool PcapReader::next(Datagram& out, Warnings* warnings) {
  Impl& m = *impl_;
  while (!m.ended) {
    FILE* f = pcap_file(m.pcap);
    const long at = f ? std::ftell(f) : 0;
    const std::uint64_t offset = at > 0 ? std::uint64_t(at) : 0;
    pcap_pkthdr* h = nullptr;
    const unsigned char* data = nullptr;
    const int rc = pcap_next_ex(m.pcap, &h, &data);
    if (rc != 1) {
      m.ended = true;
      if (rc != PCAP_ERROR_BREAK && warnings) {
        warnings->push_back({m.file, offset,
                             "pcap: reading stopped in packet " + std::to_string(m.packets + 1) + " (" +
                                 pcap_geterr(m.pcap) + "); the " + std::to_string(m.packets) +
                                 " packets before it are read"});
      }
      m.summary(warnings);
      return false;
    }
    ++m.packets;
    const auto [why, detail] = m.parse(data, h->caplen, h->len, out);
    if (why == Skip::none) {
      out.timeS = double(h->ts.tv_sec) + double(h->ts.tv_usec) * 1e-9;
      return true;
    }
    const std::uint64_t n = ++(m.skips.*counter(why));
    if (why != Skip::otherPort && warnings && n <= m.options.warningsPerReason) {
      warnings->push_back({m.file, offset,
                           "pcap: packet " + std::to_string(m.packets) + " skipped: " + skipName(why) +
                               (detail.empty() ? "" : ": " + detail)});
    }
  }
  return false;
}

std::uint64_t PcapReader::packets() const { return impl_->packets; }
const PcapSkips& PcapReader::skips() const { return impl_->skips; }
int PcapReader::linkType() const { return impl_->link; }

Result<std::vector<Datagram>> readPcap(const std::filesystem::path& path, Warnings* warnings,
                                       PcapReadOptions options) {
  Result<PcapReader> reader = PcapReader::open(path, options);
  if (!reader) return reader.problems();
  std::vector<Datagram> out;
  Datagram d;
  while (reader->next(d, warnings)) out.push_back(std::move(d));
  return out;
}

// ---------------------------------------------------------------- writing

namespace {

void put16(std::vector<std::byte>& o, unsigned v) {
  o.push_back(std::byte(v >> 8));
  o.push_back(std::byte(v));
}
void put32(std::vector<std::byte>& o, std::uint32_t v) {
  put16(o, v >> 16);
  put16(o, v & 0xffff);
}

/// The MAC address a frame to or from `ip` carries: the broadcast and
/// IPv4 multicast mappings (RFC 1112), else a locally administered
/// address that spells the IPv4 address, so the frame reads back alike.
void putMac(std::vector<std::byte>& o, std::uint32_t ip) {
  if (ip == 0xffffffffu) {  // a directed broadcast cannot be told without the netmask
    for (int k = 0; k < 6; ++k) o.push_back(std::byte{0xff});
    return;
  }
  if ((ip >> 28) == 0xe) {
    put16(o, 0x0100);
    put32(o, 0x5e000000u | (ip & 0x7fffff));
    return;
  }
  put16(o, 0x0200);
  put32(o, ip);
}

}  // namespace

std::vector<std::byte> udpFrame(const Datagram& d) {
  std::vector<std::byte> o;
  if (d.bytes.size() > kMaxUdpPayload) return o;
  o.reserve(kEthernetBytes + kIpv4Bytes + kUdpBytes + d.bytes.size());
  putMac(o, d.destination.ip);
  putMac(o, d.sender.ip);
  put16(o, kEtherIpv4);
  const std::size_t ip = o.size();
  put16(o, 0x4500);                                              // version 4, 20-byte header; DSCP 0
  put16(o, unsigned(kIpv4Bytes + kUdpBytes + d.bytes.size()));  // total length
  put16(o, 0);                                                   // identification
  put16(o, 0x4000);                                              // don't fragment, offset 0
  put16(o, 64 << 8 | kIpProtoUdp);                               // TTL, protocol
  put16(o, 0);                                                   // checksum, below
  put32(o, d.sender.ip);
  put32(o, d.destination.ip);
  // RFC 791: the ones' complement of the ones' complement sum of the header's 16-bit words.
  std::uint32_t sum = 0;
  for (std::size_t k = ip; k < ip + kIpv4Bytes; k += 2) sum += unsigned(o[k]) << 8 | unsigned(o[k + 1]);
  while (sum >> 16) sum = (sum & 0xffff) + (sum >> 16);
  o[ip + 10] = std::byte(~sum >> 8);
  o[ip + 11] = std::byte(~sum);
  put16(o, d.sender.port);
  put16(o, d.destination.port);
  put16(o, unsigned(kUdpBytes + d.bytes.size()));
  put16(o, 0);  // no checksum: allowed over IPv4 (RFC 768)
  o.insert(o.end(), d.bytes.begin(), d.bytes.end());
  return o;
}

struct PcapWriter::Impl {
  std::filesystem::path path;
  std::filesystem::path temp;
  pcap_t* dead = nullptr;
  pcap_dumper_t* dumper = nullptr;
  std::uint64_t count = 0;
  bool closed = false;

  ~Impl() {
    if (dumper) pcap_dump_close(dumper);
    if (dead) pcap_close(dead);
    if (!closed && !temp.empty()) {
      std::error_code ec;
      std::filesystem::remove(temp, ec);
    }
  }
  Problem problem(const std::string& message) const { return {path.string(), 0, "pcap: " + message}; }
};

PcapWriter::PcapWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PcapWriter::PcapWriter(PcapWriter&&) noexcept = default;
PcapWriter& PcapWriter::operator=(PcapWriter&&) noexcept = default;
PcapWriter::~PcapWriter() = default;

Result<PcapWriter> PcapWriter::create(const std::filesystem::path& path) {
  static std::atomic<unsigned> serial{0};
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->temp = path;
  impl->temp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(serial++);
  FILE* f = std::fopen(impl->temp.c_str(), "wbx");
  if (!f) {
    return impl->problem("cannot create " + impl->temp.string() + ": " + std::strerror(errno) +
                         " (the directory must exist and be writable)");
  }
  impl->dead = pcap_open_dead_with_tstamp_precision(DLT_EN10MB, kWriteSnapLen, PCAP_TSTAMP_PRECISION_MICRO);
  impl->dumper = impl->dead ? pcap_dump_fopen(impl->dead, f) : nullptr;
  if (!impl->dumper) {
    std::fclose(f);
    std::filesystem::remove(impl->temp);
    impl->temp.clear();
    return impl->problem(std::string("libpcap cannot start a capture file") +
                         (impl->dead ? std::string(": ") + pcap_geterr(impl->dead) : std::string()));
  }
  return PcapWriter(std::move(impl));
}

Status PcapWriter::write(const Datagram& d) {
  Impl& m = *impl_;
  if (m.closed || !m.dumper) return m.problem("write after close");
  if (d.bytes.size() > kMaxUdpPayload) {
    return m.problem("datagram " + std::to_string(m.count + 1) + " carries " + std::to_string(d.bytes.size()) +
                     " bytes, more than UDP over IPv4 holds (" + std::to_string(kMaxUdpPayload) + ")");
  }
  if (!(d.timeS >= 0) || !std::isfinite(d.timeS)) {
    return m.problem("datagram " + std::to_string(m.count + 1) + " has time " + std::to_string(d.timeS) +
                     " s; a capture needs seconds since 1970");
  }
  const std::vector<std::byte> frame = udpFrame(d);
  pcap_pkthdr h{};
  double whole = std::floor(d.timeS);
  long micro = std::lround((d.timeS - whole) * 1e6);
  if (micro >= 1000000) {
    whole += 1;
    micro -= 1000000;
  }
  h.ts.tv_sec = time_t(whole);
  h.ts.tv_usec = suseconds_t(micro);
  h.caplen = h.len = bpf_u_int32(frame.size());
  pcap_dump(reinterpret_cast<u_char*>(m.dumper), &h, reinterpret_cast<const u_char*>(frame.data()));
  // pcap_dump() reports nothing: the stream's error flag does.
  if (std::ferror(pcap_dump_file(m.dumper))) {
    return m.problem("cannot write " + m.temp.string() + " (disk full?)");
  }
  ++m.count;
  return {};
}

Status PcapWriter::close() {
  Impl& m = *impl_;
  if (m.closed) return m.problem("closed twice");
  const bool flushed = pcap_dump_flush(m.dumper) == 0 && !std::ferror(pcap_dump_file(m.dumper)) &&
                       ::fsync(fileno(pcap_dump_file(m.dumper))) == 0;
  pcap_dump_close(m.dumper);
  m.dumper = nullptr;
  if (!flushed) return m.problem("cannot write " + m.temp.string() + " (disk full?)");
  std::error_code ec;
  std::filesystem::rename(m.temp, m.path, ec);
  if (ec) return m.problem("cannot rename " + m.temp.string() + " to " + m.path.string() + ": " + ec.message());
  m.closed = true;
  return {};
}

std::uint64_t PcapWriter::count() const { return impl_->count; }

}  // namespace sandtable::dis
