// Capture files: the writer's bytes worked out by hand, read back, read by
// Wireshark (tshark), and the reader over pcapng, every link type it takes
// (frames built here by hand), the packets it skips, truncated files and
// files that are not captures.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include "dis_example.h"
#include "sandtable/testing/process.h"
#include "sandtable/dis/pcap.h"

namespace sandtable::dis {
namespace {

namespace fs = std::filesystem;

std::vector<std::byte> bytesOf(std::initializer_list<int> v) {
  std::vector<std::byte> o;
  for (int b : v) o.push_back(std::byte(b));
  return o;
}

std::vector<std::byte> slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::vector<char> c((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> o(c.size());
  for (std::size_t k = 0; k < c.size(); ++k) o[k] = std::byte(c[k]);
  return o;
}

void spit(const fs::path& p, const std::vector<std::byte>& b) {
  std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

constexpr std::uint32_t ip4(unsigned a, unsigned b, unsigned c, unsigned d) { return a << 24 | b << 16 | c << 8 | d; }

/// A fresh directory for one test, removed with it.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() / ("sandtable_pcap_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

Datagram datagram(double t, Address from, Address to, std::vector<std::byte> bytes) {
  Datagram d;
  d.timeS = t;
  d.sender = from;
  d.destination = to;
  d.bytes = std::move(bytes);
  return d;
}

// ---- a classic pcap of any link type, built by hand (independent of PcapWriter)

void le32(std::vector<std::byte>& o, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) o.push_back(std::byte(v >> (8 * k)));
}
void be16(std::vector<std::byte>& o, unsigned v) {
  o.push_back(std::byte(v >> 8));
  o.push_back(std::byte(v));
}

struct Record {
  std::vector<std::byte> frame;
  std::uint32_t len = 0;  ///< 0: the frame's size (not truncated)
};

std::vector<std::byte> handPcap(std::uint32_t link, const std::vector<Record>& records) {
  std::vector<std::byte> o;
  le32(o, 0xa1b2c3d4);
  le32(o, 0x00040002);  // version 2.4
  le32(o, 0);
  le32(o, 0);
  le32(o, 65535);
  le32(o, link);
  std::uint32_t second = 100;
  for (const Record& r : records) {
    le32(o, second++);
    le32(o, 500000);
    le32(o, std::uint32_t(r.frame.size()));
    le32(o, r.len ? r.len : std::uint32_t(r.frame.size()));
    o.insert(o.end(), r.frame.begin(), r.frame.end());
  }
  return o;
}

/// IPv4 + UDP from 10.1.2.3:3001 to 10.1.2.255:3000 with `payload`, header checksum 0
/// (the reader does not check it); `protocol` and `fragment` to make skipped packets.
std::vector<std::byte> ipUdp(const std::vector<std::byte>& payload, int protocol = 17, unsigned fragment = 0x4000) {
  std::vector<std::byte> o;
  be16(o, 0x4500);
  be16(o, unsigned(28 + payload.size()));
  be16(o, 7);
  be16(o, fragment);
  be16(o, 64u << 8 | unsigned(protocol));
  be16(o, 0);
  be16(o, 0x0a01);
  be16(o, 0x0203);
  be16(o, 0x0a01);
  be16(o, 0x02ff);
  be16(o, 3001);
  be16(o, 3000);
  be16(o, unsigned(8 + payload.size()));
  be16(o, 0);
  o.insert(o.end(), payload.begin(), payload.end());
  return o;
}

std::vector<std::byte> withHeader(std::vector<std::byte> head, const std::vector<std::byte>& rest) {
  head.insert(head.end(), rest.begin(), rest.end());
  return head;
}

std::vector<std::byte> ethernet(unsigned ethertype, const std::vector<std::byte>& rest) {
  std::vector<std::byte> h(12, std::byte{0x11});
  be16(h, ethertype);
  return withHeader(h, rest);
}

const Address kHandSender{ip4(10, 1, 2, 3), 3001};
const Address kHandDestination{ip4(10, 1, 2, 255), 3000};

// ---- the writer

TEST(Pcap, writerBytesAreTheHandWorkedFile) {
  TempDir dir("golden");
  const fs::path file = dir.path / "one.pcap";
  {
    Result<PcapWriter> w = PcapWriter::create(file);
    ASSERT_TRUE(w) << w.error();
    ASSERT_TRUE(w->write(datagram(1.25, {ip4(10, 0, 0, 1), 3000}, {0xffffffffu, 3000}, bytesOf({0xde, 0xad, 0xbe, 0xef}))));
    EXPECT_FALSE(fs::exists(file)) << "the file appears only on close";
    ASSERT_TRUE(w->close());
    EXPECT_EQ(w->count(), 1u);
  }
  const std::vector<std::byte> want = bytesOf({
      // global header: magic (microseconds), version 2.4, zone 0, sigfigs 0, snap length 262144, Ethernet
      0xd4, 0xc3, 0xb2, 0xa1, 0x02, 0x00, 0x04, 0x00, 0, 0, 0, 0, 0, 0, 0, 0, 0x00, 0x00, 0x04, 0x00, 1, 0, 0, 0,
      // record header: 1 s, 250000 µs (0x0003d090), captured 46 of 46 bytes
      1, 0, 0, 0, 0x90, 0xd0, 0x03, 0x00, 46, 0, 0, 0, 46, 0, 0, 0,
      // Ethernet: to the broadcast MAC, from 02:00 + 10.0.0.1, IPv4
      0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02, 0x00, 10, 0, 0, 1, 0x08, 0x00,
      // IPv4: 45 00, length 32, id 0, don't fragment, TTL 64, UDP, checksum, 10.0.0.1 -> 255.255.255.255
      // checksum: 4500+0020+0000+4000+4011+0a00+0001+ffff+ffff = 2cf30 -> cf32, ones' complement 30cd
      0x45, 0x00, 0x00, 0x20, 0x00, 0x00, 0x40, 0x00, 0x40, 0x11, 0x30, 0xcd, 10, 0, 0, 1, 0xff, 0xff, 0xff, 0xff,
      // UDP: 3000 -> 3000, length 12, checksum 0, payload
      0x0b, 0xb8, 0x0b, 0xb8, 0x00, 0x0c, 0x00, 0x00, 0xde, 0xad, 0xbe, 0xef});
  EXPECT_EQ(slurp(file), want);
}

TEST(Pcap, writtenDatagramsReadBackAlike) {
  TempDir dir("roundtrip");
  const fs::path file = dir.path / "three.pcap";
  const std::vector<Datagram> sent = {
      datagram(1700000000.5, {ip4(192, 168, 1, 7), 3000}, {ip4(192, 168, 1, 255), 3000}, bytesOf({1, 2, 3})),
      datagram(1700000000.75, {ip4(10, 0, 0, 2), 40000}, {ip4(239, 1, 2, 3), 3000}, {}),
      datagram(1700000001.000001, {ip4(127, 0, 0, 1), 3000}, {ip4(127, 0, 0, 1), 3001},
               std::vector<std::byte>(1500, std::byte{0x5a})),
  };
  {
    Result<PcapWriter> w = PcapWriter::create(file);
    ASSERT_TRUE(w) << w.error();
    for (const Datagram& d : sent) ASSERT_TRUE(w->write(d));
    ASSERT_TRUE(w->close());
  }
  Warnings warnings;
  Result<std::vector<Datagram>> got = readPcap(file, &warnings);
  ASSERT_TRUE(got) << got.error();
  EXPECT_TRUE(warnings.empty()) << warnings.front().str();
  ASSERT_EQ(got->size(), sent.size());
  for (std::size_t k = 0; k < sent.size(); ++k) {
    EXPECT_NEAR(got.value()[k].timeS, sent[k].timeS, 1e-6) << k;
    EXPECT_EQ(got.value()[k].sender, sent[k].sender) << k;
    EXPECT_EQ(got.value()[k].destination, sent[k].destination) << k;
    EXPECT_EQ(got.value()[k].bytes, sent[k].bytes) << k;
  }
  // The port filter keeps datagrams to one port and counts the rest.
  Result<PcapReader> r = PcapReader::open(file, {.port = 3001});
  ASSERT_TRUE(r) << r.error();
  Datagram d;
  ASSERT_TRUE(r->next(d, &warnings));
  EXPECT_EQ(d.destination.port, 3001);
  EXPECT_FALSE(r->next(d, &warnings));
  EXPECT_EQ(r->skips().otherPort, 2u);
  EXPECT_EQ(r->packets(), 3u);
  EXPECT_EQ(r->linkType(), 1);
  EXPECT_TRUE(warnings.empty());
}

TEST(Pcap, writerRefusesWhatACaptureCannotHold) {
  TempDir dir("refuse");
  Result<PcapWriter> w = PcapWriter::create(dir.path / "x.pcap");
  ASSERT_TRUE(w);
  Status big = w->write(datagram(1, {}, {}, std::vector<std::byte>(kMaxUdpPayload + 1)));
  EXPECT_FALSE(big);
  EXPECT_NE(big.error().find("65507"), std::string::npos) << big.error();
  EXPECT_TRUE(w->write(datagram(1, {}, {}, std::vector<std::byte>(kMaxUdpPayload))));
  EXPECT_FALSE(w->write(datagram(-1, {}, {}, {})));
  Result<PcapWriter> nowhere = PcapWriter::create(dir.path / "missing" / "x.pcap");
  ASSERT_FALSE(nowhere);
  EXPECT_NE(nowhere.error().find("directory must exist"), std::string::npos) << nowhere.error();
}

TEST(Pcap, writerDestroyedWithoutCloseLeavesNothing) {
  TempDir dir("abandon");
  const fs::path file = dir.path / "x.pcap";
  {
    Result<PcapWriter> w = PcapWriter::create(file);
    ASSERT_TRUE(w);
    ASSERT_TRUE(w->write(datagram(1, {}, {}, bytesOf({1}))));
  }
  EXPECT_TRUE(fs::is_empty(dir.path));
  // An existing file stays as it was until close() replaces it.
  spit(file, bytesOf({7}));
  {
    Result<PcapWriter> w = PcapWriter::create(file);
    ASSERT_TRUE(w);
  }
  EXPECT_EQ(slurp(file), bytesOf({7}));
}

// ---- Wireshark reads what the writer writes

TEST(Pcap, tsharkDissectsTheWrittenFileAsDis) {
  ASSERT_EQ(std::system("command -v tshark >/dev/null 2>&1"), 0) << "tshark is missing: run tools/setup.sh";
  TempDir dir("tshark");
  const fs::path file = dir.path / "dis.pcap";
  EntityState es = testexample::example();
  {
    Result<PcapWriter> w = PcapWriter::create(file);
    ASSERT_TRUE(w);
    ASSERT_TRUE(w->write(datagram(1700000000.25, {ip4(192, 168, 1, 7), 3000}, {0xffffffffu, 3000},
                                  encode(testexample::exampleHeader(), es))));
    es.id.entity = 9;
    ASSERT_TRUE(w->write(datagram(1700000000.5, {ip4(192, 168, 1, 8), 3000}, {ip4(239, 1, 2, 3), 3000},
                                  encode(testexample::exampleHeader(), es))));
    ASSERT_TRUE(w->close());
  }
  const std::string read = "tshark -r '" + file.string() + "' -o ip.check_checksum:TRUE 2>/dev/null ";
  EXPECT_EQ(fixtures::commandOutput(read + "-Y '_ws.malformed || _ws.expert.severity >= warning'"), "");
  EXPECT_EQ(fixtures::commandOutput(read + "-T fields -E separator=, -E occurrence=f -e frame.time_epoch -e ip.src -e ip.dst "
                       "-e ip.checksum.status -e udp.dstport -e dis.pdu_type -e dis.entity_id_entity"),
            "1700000000.250000000,192.168.1.7,255.255.255.255,1,3000,1,772\n"
            "1700000000.500000000,192.168.1.8,239.1.2.3,1,3000,1,9\n");
}

// ---- the reader over other writers' files

TEST(Pcap, readsPcapngFromEditcap) {
  ASSERT_EQ(std::system("command -v editcap >/dev/null 2>&1"), 0) << "editcap (tshark's package) is missing";
  TempDir dir("pcapng");
  const fs::path file = dir.path / "a.pcap";
  const fs::path ng = dir.path / "a.pcapng";
  {
    Result<PcapWriter> w = PcapWriter::create(file);
    ASSERT_TRUE(w);
    ASSERT_TRUE(w->write(datagram(5.5, {ip4(10, 0, 0, 1), 3000}, {ip4(10, 0, 0, 255), 3000}, bytesOf({1, 2}))));
    ASSERT_TRUE(w->write(datagram(6.25, {ip4(10, 0, 0, 2), 3000}, {ip4(10, 0, 0, 255), 3000}, bytesOf({3}))));
    ASSERT_TRUE(w->close());
  }
  ASSERT_EQ(std::system(("editcap -F pcapng '" + file.string() + "' '" + ng.string() + "'").c_str()), 0);
  EXPECT_NE(slurp(ng), slurp(file));
  Warnings warnings;
  Result<std::vector<Datagram>> got = readPcap(ng, &warnings);
  ASSERT_TRUE(got) << got.error();
  EXPECT_TRUE(warnings.empty());
  ASSERT_EQ(got->size(), 2u);
  EXPECT_DOUBLE_EQ(got.value()[0].timeS, 5.5);
  EXPECT_DOUBLE_EQ(got.value()[1].timeS, 6.25);
  EXPECT_EQ(got.value()[1].sender, (Address{ip4(10, 0, 0, 2), 3000}));
  EXPECT_EQ(got.value()[1].bytes, bytesOf({3}));
}

struct LinkCase {
  const char* name;
  std::uint32_t link;  ///< LINKTYPE_* as the file has it
  std::vector<std::byte> frame;
};

TEST(Pcap, readsEveryLinkTypeItTakes) {
  const std::vector<std::byte> payload = bytesOf({0x07, 0x01, 0x01, 0x01});
  const std::vector<std::byte> packet = ipUdp(payload);
  std::vector<std::byte> vlan(12, std::byte{0x22});
  be16(vlan, 0x88a8);  // 802.1ad service tag, VLAN 5
  be16(vlan, 5);
  be16(vlan, 0x8100);  // 802.1Q customer tag, VLAN 6
  be16(vlan, 6);
  be16(vlan, 0x0800);
  std::vector<std::byte> sll = bytesOf({0, 1, 0, 1, 0, 6, 1, 2, 3, 4, 5, 6, 0, 0});  // broadcast, ARPHRD_ETHER, MAC
  be16(sll, 0x0800);
  std::vector<std::byte> sll2;
  be16(sll2, 0x0800);
  be16(sll2, 0);                                                  // reserved
  for (std::byte b : bytesOf({0, 0, 0, 2, 0, 1, 1, 6})) sll2.push_back(b);  // ifindex 2, ARPHRD_ETHER, broadcast, 6
  for (std::byte b : bytesOf({1, 2, 3, 4, 5, 6, 0, 0})) sll2.push_back(b);
  const std::vector<LinkCase> cases = {
      {"Ethernet", 1, ethernet(0x0800, packet)},
      {"Ethernet with padding after the IP packet", 1, withHeader(ethernet(0x0800, packet), bytesOf({0, 0, 0}))},
      {"Ethernet, two VLAN tags", 1, withHeader(vlan, packet)},
      {"Ethernet, one VLAN tag", 1, withHeader(withHeader(std::vector<std::byte>(vlan.begin(), vlan.begin() + 12), bytesOf({0x81, 0, 0, 7, 8, 0})), packet)},
      {"Linux cooked (SLL)", 113, withHeader(sll, packet)},
      {"Linux cooked v2 (SLL2)", 276, withHeader(sll2, packet)},
      {"raw IP", 101, packet},
      {"raw IPv4", 228, packet},
      {"BSD null, little-endian family", 0, withHeader(bytesOf({2, 0, 0, 0}), packet)},
      {"BSD null, big-endian family", 0, withHeader(bytesOf({0, 0, 0, 2}), packet)},
      {"OpenBSD loop", 108, withHeader(bytesOf({0, 0, 0, 2}), packet)},
  };
  TempDir dir("links");
  for (const LinkCase& c : cases) {
    const fs::path file = dir.path / "link.pcap";
    spit(file, handPcap(c.link, {{c.frame}}));
    Warnings warnings;
    Result<std::vector<Datagram>> got = readPcap(file, &warnings);
    ASSERT_TRUE(got) << c.name << ": " << got.error();
    EXPECT_TRUE(warnings.empty()) << c.name << ": " << warnings.front().str();
    ASSERT_EQ(got->size(), 1u) << c.name;
    EXPECT_EQ(got.value()[0].sender, kHandSender) << c.name;
    EXPECT_EQ(got.value()[0].destination, kHandDestination) << c.name;
    EXPECT_EQ(got.value()[0].bytes, payload) << c.name;
    EXPECT_DOUBLE_EQ(got.value()[0].timeS, 100.5) << c.name;
  }
}

// tshark agrees that the hand-built cooked captures hold one UDP datagram to
// port 3000: the frames above are what Linux writes, not just what we read.
TEST(Pcap, tsharkReadsTheHandBuiltCookedCaptures) {
  ASSERT_EQ(std::system("command -v tshark >/dev/null 2>&1"), 0) << "tshark is missing: run tools/setup.sh";
  TempDir dir("cooked");
  const std::vector<std::byte> packet = ipUdp(encode(testexample::exampleHeader(), testexample::example()));
  std::vector<std::byte> sll = bytesOf({0, 1, 0, 1, 0, 6, 1, 2, 3, 4, 5, 6, 0, 0});
  be16(sll, 0x0800);
  std::vector<std::byte> sll2;
  be16(sll2, 0x0800);
  be16(sll2, 0);
  for (std::byte b : bytesOf({0, 0, 0, 2, 0, 1, 1, 6, 1, 2, 3, 4, 5, 6, 0, 0})) sll2.push_back(b);
  for (auto [link, head] : {std::pair{113u, sll}, std::pair{276u, sll2}}) {
    const fs::path file = dir.path / ("cooked" + std::to_string(link) + ".pcap");
    spit(file, handPcap(link, {{withHeader(head, packet)}}));
    EXPECT_EQ(fixtures::commandOutput("tshark -r '" + file.string() + "' -T fields -e ip.src -e udp.dstport -e dis.pdu_type 2>/dev/null"),
              "10.1.2.3\t3000\t1\n")
        << link;
    ASSERT_TRUE(readPcap(file, nullptr)) << link;
  }
}

TEST(Pcap, skipsAndCountsWhatIsNotAnIpv4UdpDatagram) {
  const std::vector<std::byte> payload = bytesOf({1, 2, 3, 4});
  const std::vector<std::byte> good = ethernet(0x0800, ipUdp(payload));
  std::vector<std::byte> ipv6 = ethernet(0x86dd, std::vector<std::byte>(48));
  std::vector<std::byte> badUdpLength = ethernet(0x0800, ipUdp(payload));
  badUdpLength[14 + 24] = std::byte{0x40};  // UDP length 0x400c, past the IPv4 packet
  const std::vector<Record> records = {
      {good},
      {ethernet(0x0806, std::vector<std::byte>(28))},             // 2: ARP
      {ipv6},                                                     // 3: IPv6
      {ethernet(0x0800, ipUdp(payload, 6))},                      // 4: TCP
      {ethernet(0x0800, ipUdp(payload, 17, 0x2000))},             // 5: first fragment (more fragments)
      {ethernet(0x0800, ipUdp(payload, 17, 0x0003))},             // 6: a later fragment
      {good, std::uint32_t(good.size() + 100)},                   // 7: cut by the snap length
      {badUdpLength},                                             // 8: UDP length past the packet
      {std::vector<std::byte>(10)},                               // 9: shorter than Ethernet
      {good},
  };
  TempDir dir("skips");
  const fs::path file = dir.path / "mixed.pcap";
  spit(file, handPcap(1, records));
  Result<PcapReader> r = PcapReader::open(file);
  ASSERT_TRUE(r) << r.error();
  Warnings warnings;
  std::vector<Datagram> got;
  Datagram d;
  while (r->next(d, &warnings)) got.push_back(d);
  EXPECT_EQ(got.size(), 2u);
  EXPECT_EQ(r->packets(), 10u);
  EXPECT_EQ(r->skips().notIpv4, 2u);
  EXPECT_EQ(r->skips().notUdp, 1u);
  EXPECT_EQ(r->skips().fragment, 2u);
  EXPECT_EQ(r->skips().truncated, 1u);
  EXPECT_EQ(r->skips().malformed, 2u);
  EXPECT_EQ(r->skips().total(), 8u);
  ASSERT_EQ(warnings.size(), 8u);
  // Packet 2 starts after the global header, packet 1's record header and its frame.
  const std::uint64_t second = 24 + 16 + good.size();
  EXPECT_EQ(warnings[0].str(), file.string() + " @" + std::to_string(second) +
                                   ": pcap: packet 2 skipped: not IPv4: ethertype 0x0806");
  EXPECT_EQ(warnings[1].message, "pcap: packet 3 skipped: not IPv4: ethertype 0x86dd");
  EXPECT_EQ(warnings[2].message, "pcap: packet 4 skipped: not UDP: IP protocol 6");
  EXPECT_EQ(warnings[3].message, "pcap: packet 5 skipped: IPv4 fragment: fragment offset 0");
  EXPECT_EQ(warnings[4].message, "pcap: packet 6 skipped: IPv4 fragment: fragment offset 24");
  EXPECT_EQ(warnings[5].message, "pcap: packet 7 skipped: truncated (captured length below the frame's length): " +
                                     std::to_string(good.size()) + " of " + std::to_string(good.size() + 100) +
                                     " bytes captured");
  EXPECT_EQ(warnings[6].message, "pcap: packet 8 skipped: malformed: UDP length 16396 in an IPv4 payload of 12 bytes");
  EXPECT_EQ(warnings[7].message, "pcap: packet 9 skipped: malformed: Ethernet header cut short");
}

TEST(Pcap, warningsPerReasonAreCappedAndSummedUp) {
  std::vector<Record> records(12, Record{ethernet(0x0806, std::vector<std::byte>(28))});
  TempDir dir("cap");
  const fs::path file = dir.path / "arp.pcap";
  spit(file, handPcap(1, records));
  Warnings warnings;
  Result<std::vector<Datagram>> got = readPcap(file, &warnings, {.port = 0, .warningsPerReason = 3});
  ASSERT_TRUE(got);
  EXPECT_TRUE(got->empty());
  ASSERT_EQ(warnings.size(), 4u);
  EXPECT_EQ(warnings[3].message, "pcap: 9 more not IPv4 packets skipped (12 in all)");
}

TEST(Pcap, everyTruncatedPrefixReadsWhatItHolds) {
  TempDir dir("prefix");
  const fs::path file = dir.path / "two.pcap";
  {
    Result<PcapWriter> w = PcapWriter::create(file);
    ASSERT_TRUE(w);
    ASSERT_TRUE(w->write(datagram(1, {ip4(10, 0, 0, 1), 3000}, {0xffffffffu, 3000}, bytesOf({1, 2, 3}))));
    ASSERT_TRUE(w->write(datagram(2, {ip4(10, 0, 0, 1), 3000}, {0xffffffffu, 3000}, bytesOf({4, 5, 6}))));
    ASSERT_TRUE(w->close());
  }
  const std::vector<std::byte> whole = slurp(file);
  const std::size_t first = 24 + 16 + 45;  // header, one record
  ASSERT_EQ(whole.size(), first + 16 + 45);
  const fs::path cut = dir.path / "cut.pcap";
  for (std::size_t n = 0; n < whole.size(); ++n) {
    spit(cut, std::vector<std::byte>(whole.begin(), whole.begin() + std::ptrdiff_t(n)));
    Warnings warnings;
    Result<std::vector<Datagram>> got = readPcap(cut, &warnings);
    if (n < 24) {
      ASSERT_FALSE(got) << n;
      EXPECT_EQ(got.problems().front().file, cut.string());
      EXPECT_NE(got.error().find("not a capture file"), std::string::npos) << got.error();
      continue;
    }
    ASSERT_TRUE(got) << n << ": " << got.error();
    const std::size_t whole_records = n >= first ? 1 : 0;
    EXPECT_EQ(got->size(), whole_records) << n;
    const bool atBoundary = n == 24 || n == first;
    EXPECT_EQ(warnings.size(), atBoundary ? 0u : 1u) << n;
    if (!atBoundary && !warnings.empty()) {
      EXPECT_EQ(warnings[0].offset, n < first ? 24u : first) << n;
      EXPECT_NE(warnings[0].message.find("reading stopped in packet " + std::to_string(whole_records + 1)),
                std::string::npos)
          << warnings[0].message;
    }
  }
}

TEST(Pcap, aFileThatIsNotACaptureIsAClearProblem) {
  TempDir dir("notpcap");
  const fs::path text = dir.path / "notes.pcap";
  spit(text, bytesOf({'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd', ' ', 't', 'h', 'i', 's', ' ', 'i',
                      's', ' ', 't', 'e', 'x', 't', '\n'}));
  Result<std::vector<Datagram>> got = readPcap(text, nullptr);
  ASSERT_FALSE(got);
  EXPECT_EQ(got.problems().front().file, text.string());
  EXPECT_NE(got.error().find("is not a capture file libpcap reads (pcap or pcapng)"), std::string::npos)
      << got.error();
  Result<std::vector<Datagram>> missing = readPcap(dir.path / "none.pcap", nullptr);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("no such file"), std::string::npos) << missing.error();
  Result<std::vector<Datagram>> directory = readPcap(dir.path, nullptr);
  ASSERT_FALSE(directory);
  // A capture of a link type the reader does not take (802.11) names it.
  spit(text, handPcap(105, {}));
  Result<std::vector<Datagram>> wifi = readPcap(text, nullptr);
  ASSERT_FALSE(wifi);
  EXPECT_NE(wifi.error().find("link type 105 (IEEE802_11)"), std::string::npos) << wifi.error();
}

}  // namespace
}  // namespace sandtable::dis
