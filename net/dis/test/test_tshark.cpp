// Wireshark's DIS dissector (tshark, Debian's 4.0) reads what we encode:
// the example Entity State PDU, in a pcap as one UDP datagram to port 3000,
// is dissected without a malformed mark and every field reads back as the
// value written into it (docs/DIS.md §3). tshark is an independent
// implementation of the standard; tools/setup.sh installs it.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include <unistd.h>

#include "dis_example.h"
#include "sandtable/testing/process.h"
#include "sandtable/dis/pcap.h"

namespace sandtable::dis {
namespace {

/// A pcap (Ethernet, IPv4 loopback, UDP 3000 -> 3000) of one datagram, by PcapWriter.
void writePcap(const std::filesystem::path& path, const std::vector<std::byte>& pdu) {
  Result<PcapWriter> w = PcapWriter::create(path);
  ASSERT_TRUE(w) << w.error();
  const Address loopback{0x7f000001u, 3000};
  ASSERT_TRUE(w->write({0, loopback, loopback, pdu}));
  ASSERT_TRUE(w->close());
}

/// tshark's first value (`occurrence` "f"; "l" the last, "a" all: 4.0 takes
/// no number, and entity-id fields are shared by every id in a PDU) of each
/// field in the capture `read` opens, against `want`.
void expectFields(const std::string& read, const std::vector<std::pair<std::string, std::string>>& want,
                  const std::string& occurrence = "f") {
  std::string command = read + "-T fields -E occurrence=" + occurrence + " -E separator=/t";
  for (const auto& [field, value] : want) command += " -e " + field;
  const std::string line = fixtures::commandOutput(command);
  std::vector<std::string> got;
  std::string cell;
  for (char c : line) {
    if (c == '\t' || c == '\n') {
      got.push_back(cell);
      cell.clear();
      if (c == '\n') break;
    } else {
      cell += c;
    }
  }
  ASSERT_EQ(got.size(), want.size()) << line;
  for (std::size_t k = 0; k < want.size(); ++k) EXPECT_EQ(got[k], want[k].second) << want[k].first;
}

TEST(DisTshark, wiresharkReadsEveryFieldOfOurEntityStatePdu) {
  ASSERT_EQ(std::system("command -v tshark >/dev/null 2>&1"), 0) << "tshark is missing: run tools/setup.sh";
  const auto dir = std::filesystem::temp_directory_path() / ("sandtable_dis_tshark_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto pcap = dir / "es.pcap";
  writePcap(pcap, encode(testexample::exampleHeader(), testexample::example()));
  const std::string read = "tshark -r '" + pcap.string() + "' 2>/dev/null ";
  EXPECT_EQ(fixtures::commandOutput(read + "-Y '_ws.malformed && dis'"), "");
  // First occurrences: the entity type's fields come before the alternative type's.
  const std::vector<std::pair<std::string, std::string>> want = {
      {"dis.proto_ver", "7"},
      {"dis.exer_id", "3"},
      {"dis.pdu_type", "1"},
      {"dis.pdu_length", "176"},
      {"dis.entity_id_site", "1"},
      {"dis.entity_id_application", "2"},
      {"dis.entity_id_entity", "772"},
      {"dis.force_id", "2"},
      {"dis.num_articulation_params", "2"},
      {"dis.entityKind", "1"},
      {"dis.entityDomain", "1"},
      {"dis.country", "225"},
      {"dis.subcategory", "1"},
      {"dis.specific", "3"},
      {"dis.entity_linear_velocity.x", "1"},
      {"dis.entity_linear_velocity.y", "-0.5"},
      {"dis.entity_linear_velocity.z", "2.5"},
      {"dis.entity_location.x", "1024"},
      {"dis.entity_location.y", "-2"},
      {"dis.entity_location.z", "3"},
      {"dis.entity_orientation.psi", "0.5"},
      {"dis.entity_orientation.theta", "-1"},
      {"dis.entity_orientation.phi", "0.25"},
      {"dis.entity_linear_acceleration.z", "-2"},
      {"dis.entity_angular_velocity.y", "0.125"},
      {"dis.entity_marking", "T72 A"},
      {"dis.vp.artic_param_type", "4107"},
      {"dis.vp.parameter_value", "1.5"},
  };
  expectFields(read, want);
  std::filesystem::remove_all(dir);
}

// The Fire and Detonation PDUs of test_pdu.cpp's golden bytes, as Wireshark reads them.
TEST(DisTshark, wiresharkReadsOurFireAndDetonationPdus) {
  ASSERT_EQ(std::system("command -v tshark >/dev/null 2>&1"), 0) << "tshark is missing: run tools/setup.sh";
  const auto dir = std::filesystem::temp_directory_path() / ("sandtable_dis_tshark_fd_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  Fire f;
  f.firing = {1, 2, 3};
  f.target = {1, 2, 4};
  f.event = {1, 2, 9};
  f.location = {1024.0, -2.0, 3.0};
  f.descriptor = {{2, 9, 225, 2, 1, 0, 0}, 1000, 1000, 1, 0};
  f.velocity = {1.0f, -0.5f, 2.5f};
  f.range = 2.0f;
  writePcap(dir / "fire.pcap", encode(testexample::exampleHeader(), f));
  std::string read = "tshark -r '" + (dir / "fire.pcap").string() + "' 2>/dev/null ";
  EXPECT_EQ(fixtures::commandOutput(read + "-Y '_ws.malformed && dis'"), "");
  expectFields(read, {{"dis.pdu_type", "2"},
                      {"dis.pdu_length", "96"},
                      {"dis.entity_id_site", "1"},
                      {"dis.entity_id_entity", "3"},
                      {"dis.event_number", "9"},
                      {"dis.entityKind", "2"},
                      {"dis.country", "225"},
                      {"dis.warhead", "1000"},
                      {"dis.fuse", "1000"},
                      {"dis.quality", "1"},
                      {"dis.range", "2"}});
  Detonation d;
  d.firing = f.firing;
  d.target = f.target;
  d.event = f.event;
  d.velocity = f.velocity;
  d.location = f.location;
  d.descriptor = f.descriptor;
  d.entityLocation = {0.5f, -1.0f, 0.25f};
  d.result = 1;
  d.parameters.push_back(toParameter(ArticulatedPart{0, 0, 4096 + 11, 1.5f}));
  writePcap(dir / "detonation.pcap", encode(testexample::exampleHeader(), d));
  read = "tshark -r '" + (dir / "detonation.pcap").string() + "' 2>/dev/null ";
  EXPECT_EQ(fixtures::commandOutput(read + "-Y '_ws.malformed && dis'"), "");
  expectFields(read, {{"dis.pdu_type", "3"},
                      {"dis.pdu_length", "120"},
                      {"dis.event_number", "9"},
                      {"dis.warhead", "1000"},
                      {"dis.detonation.result", "1"},
                      {"dis.num_articulation_params", "1"},
                      {"dis.vp.artic_param_type", "4107"},
                      {"dis.vp.parameter_value", "1.5"}});
  std::filesystem::remove_all(dir);
}

// Create Entity and Remove Entity (test_pdu.cpp's golden bytes, docs/DIS.md §3.3), field by
// field; Point and Linear Object State, whose bodies this tshark build does not dissect: their
// headers read back and nothing is marked malformed.
TEST(DisTshark, wiresharkReadsOurSimulationManagementAndObjectPdus) {
  ASSERT_EQ(std::system("command -v tshark >/dev/null 2>&1"), 0) << "tshark is missing: run tools/setup.sh";
  const auto dir = std::filesystem::temp_directory_path() / ("sandtable_dis_tshark_sm_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  CreateEntity create;
  create.originating = {1, 3, 0};
  create.receiving = {1, 2, 772};
  create.requestId = 0x0A0B0C0Du;
  RemoveEntity remove;
  static_cast<EntityRequest&>(remove) = create;
  const std::vector<std::pair<std::string, std::vector<std::byte>>> requests = {
      {"11", encode(testexample::exampleHeader(), create)}, {"12", encode(testexample::exampleHeader(), remove)}};
  for (const auto& [type, bytes] : requests) {
    writePcap(dir / "request.pcap", bytes);
    const std::string read = "tshark -r '" + (dir / "request.pcap").string() + "' 2>/dev/null ";
    EXPECT_EQ(fixtures::commandOutput(read + "-Y '_ws.malformed && dis'"), "");
    expectFields(read, {{"dis.proto_ver", "7"},
                        {"dis.pdu_type", type},
                        {"dis.proto_fam", "5"},
                        {"dis.pdu_length", "28"},
                        {"dis.entity_id_site", "1"},  // the originating id
                        {"dis.entity_id_application", "3"},
                        {"dis.entity_id_entity", "0"},
                        {"dis.request_id", "168496141"}});
    expectFields(read,  // the receiving id, the last of the two
                 {{"dis.entity_id_site", "1"}, {"dis.entity_id_application", "2"}, {"dis.entity_id_entity", "772"}},
                 "l");
  }
  PointObjectState point;
  point.id = {1, 2, 17};
  point.location = {1024.0, -2.0, 3.0};
  LinearObjectState linear;
  linear.id = {1, 2, 18};
  linear.segments.resize(2);
  const std::vector<std::tuple<std::string, std::string, std::vector<std::byte>>> objects = {
      {"43", "88", encode(testexample::exampleHeader(), point)},
      {"44", "168", encode(testexample::exampleHeader(), linear)}};
  for (const auto& [type, length, bytes] : objects) {
    writePcap(dir / "object.pcap", bytes);
    const std::string read = "tshark -r '" + (dir / "object.pcap").string() + "' 2>/dev/null ";
    EXPECT_EQ(fixtures::commandOutput(read + "-Y '_ws.malformed && dis'"), "");
    expectFields(read, {{"dis.proto_ver", "7"},
                        {"dis.exer_id", "3"},
                        {"dis.pdu_type", type},
                        {"dis.proto_fam", "9"},
                        {"dis.pdu_length", length}});
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::dis
