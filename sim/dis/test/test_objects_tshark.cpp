// Wireshark (tshark, Debian's 4.0.17) on the object PDUs of terrain edits
// (docs/DIS.md §14): an independent reader of the standard. Its dissector
// has no body for types 43 and 44 (docs/DIS.md §3.5), so it reads the
// header only: the PDU types and the family by the standard's names, the
// lengths, and the edit's time in the timestamp, with nothing malformed.
// The object type fields it cannot read; the byte-for-byte tests in
// test_objects.cpp and Open-DIS (tests/opendis) check those.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "sandtable/dis/pcap.h"
#include "sandtable/sim_dis/objects.h"
#include "sandtable/testing/process.h"
#include "sim_dis_support.h"

namespace sandtable::sim_dis {
namespace {

TEST(SimDisObjectsTshark, wiresharkReadsOurObjectPdus) {
  ASSERT_EQ(std::system("command -v tshark >/dev/null 2>&1"), 0) << "tshark is missing: run tools/setup.sh";
  const DisFrame frame = test::testFrame();
  ObjectSender s;
  s.exercise = 3;
  s.site = 1;
  s.application = 2;
  edit::Edit crater;
  crater.id = 17;
  crater.time = 123.5;
  crater.kind = edit::Kind::crater;
  crater.points = {{1000, 2000}};
  crater.radius = 3;
  crater.depth = 1.2;
  edit::Edit berm;
  berm.id = 18;
  berm.time = 3723.5;  // 1 h 2 min 3.5 s: the timestamp is the time past the hour
  berm.kind = edit::Kind::berm;
  berm.points = {{1000, 2000}, {1100, 2000}, {1100, 2100}};
  berm.width = 2;
  berm.height = 1.5;
  berm.sideSlope = 0.5;
  const auto dir = std::filesystem::temp_directory_path() / ("sandtable_objects_tshark_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto path = dir / "objects.pcap";
  {
    auto w = dis::PcapWriter::create(path);
    ASSERT_TRUE(w) << w.error();
    const dis::Address loopback{0x7f000001u, 3000};
    for (const edit::Edit& e : {crater, berm}) {
      auto encoded = encodeEdit(e, frame, s);
      ASSERT_TRUE(encoded.ok()) << encoded.error();
      ASSERT_TRUE(w->write({0, loopback, loopback, encoded->bytes}));
    }
    ASSERT_TRUE(w->close());
  }
  const std::string read = "tshark -r '" + path.string() + "' 2>/dev/null ";
  EXPECT_EQ(fixtures::commandOutput(read + "-Y '_ws.malformed && dis'"), "");
  EXPECT_EQ(fixtures::commandOutput(read + "-T fields -E separator=/t -e dis.proto_ver -e dis.exer_id -e dis.pdu_type "
                                           "-e dis.proto_fam -e dis.pdu_length -e dis.timestamp"),
            "7\t3\t43\t9\t88\t123.500000000\n"
            "7\t3\t44\t9\t168\t123.500000000\n");
  const std::string text = fixtures::commandOutput(read + "-V");
  for (const char* line : {"PDU type: Point Object State (43)", "PDU type: Linear Object State (44)",
                           "Proto Family: Synthetic environment (9)", "Timestamp: 02:03.500000 (relative)",
                           "Point Object State PDU", "Linear Object State PDU"}) {
    EXPECT_NE(text.find(line), std::string::npos) << line << " not in\n" << text;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::sim_dis
