// `sandtable dis inspect` end to end (docs/DIS.md, "The network monitor"):
// a capture of known PDUs written with PcapWriter, read by the CLI with
// --json, and checked against references nobody here wrote: Wireshark's
// dissector (tshark -T fields) for ids, locations and markings, GDAL/OSR
// for geocentric <-> lon/lat/height, and hand arithmetic for dead
// reckoning (--at) and a heading at the equator. A malformed PDU in the
// capture must be reported with its reason and its offset.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>
#include <ogr_spatialref.h>

#include "sandtable/testing/process.h"
#include "sandtable/dis/pcap.h"
#include "sandtable/dis/pdu.h"
#include "test_support.h"

namespace sandtable {
namespace {

using namespace sandtable::dis;

constexpr double kPi = 3.14159265358979323846;
constexpr Address kSender{0x7f000001u, 3001};  // 127.0.0.1:3001
constexpr Address kTo{0x7f000001u, 3000};

/// WGS 84 geographic (lon, lat, ellipsoidal height) <-> geocentric through OSR.
std::array<double, 3> osr(const std::array<double, 3>& in, bool toGeocentric) {
  OGRSpatialReference geographic, geocentric;
  geographic.importFromEPSG(4979);
  geographic.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  geocentric.importFromEPSG(4978);
  auto* ct = toGeocentric ? OGRCreateCoordinateTransformation(&geographic, &geocentric)
                          : OGRCreateCoordinateTransformation(&geocentric, &geographic);
  double x = in[0], y = in[1], z = in[2];
  EXPECT_TRUE(ct && ct->Transform(1, &x, &y, &z));
  OGRCoordinateTransformation::DestroyCT(ct);
  return {x, y, z};
}

std::vector<std::vector<std::string>> tsv(const std::string& text) {
  std::vector<std::vector<std::string>> rows(1);
  std::string cell;
  for (char c : text) {
    if (c == '\t' || c == '\n') {
      rows.back().push_back(cell);
      cell.clear();
      if (c == '\n') rows.emplace_back();
    } else {
      cell += c;
    }
  }
  rows.pop_back();
  return rows;
}

Header header() {
  Header h;
  h.exercise = 1;
  return h;
}

struct Capture {
  std::array<double, 3> alpha0;  // ALPHA's first location (ECEF)
  Vec3f alphaVelocity{10.0f, -5.0f, 2.0f};
};

/// The capture, times from 1000 s (since 1970):
///  1000.0  ALPHA 1:2:1 (FPW) at lon 12.1, lat 50.4, 300 m
///  1000.5  BRAVO 1:2:2 (Static) at (a, 0, 0), heading 90, turret azimuth 0.5 rad
///  1001.0  ALPHA, 1 s on, then a Fire PDU of length 100 (malformed, 4 bytes of junk)
///  1002.0  a Fire PDU from 1:2:1
///  1004.0  ALPHA, 4 s on
Capture writeCapture(const std::string& path) {
  Capture c;
  c.alpha0 = osr({12.1, 50.4, 300.0}, true);
  auto w = PcapWriter::create(path);
  EXPECT_TRUE(w.ok()) << w.error();
  auto put = [&](double t, std::vector<std::vector<std::byte>> pdus) {
    Datagram d{t, kSender, kTo, {}};
    for (const auto& p : pdus) d.bytes.insert(d.bytes.end(), p.begin(), p.end());
    EXPECT_TRUE(w->write(d).ok());
  };
  auto alpha = [&](double dt) {
    EntityState e;
    e.id = {1, 2, 1};
    e.force = 1;
    e.type = {1, 1, 225, 1, 1, 3, 0};
    e.velocity = c.alphaVelocity;
    e.location = {c.alpha0[0] + dt * c.alphaVelocity.x, c.alpha0[1] + dt * c.alphaVelocity.y,
                  c.alpha0[2] + dt * c.alphaVelocity.z};
    e.deadReckoning.algorithm = 2;
    e.marking = Marking::ascii("ALPHA");
    return encode(header(), e);
  };
  EntityState bravo;
  bravo.id = {1, 2, 2};
  bravo.force = 2;
  bravo.type = {1, 1, 222, 1, 2, 0, 0};
  bravo.location = {6378137.0, 0.0, 0.0};
  bravo.orientation = {float(kPi / 2), 0.0f, float(-kPi / 2)};
  bravo.deadReckoning.algorithm = 1;
  bravo.marking = Marking::ascii("BRAVO");
  bravo.parameters.push_back(toParameter(ArticulatedPart{1, 0, 4096 + 11, 0.5f}));
  Fire fire;
  fire.firing = {1, 2, 1};
  fire.location = {c.alpha0[0], c.alpha0[1], c.alpha0[2]};
  auto badFire = encode(header(), fire);
  badFire[9] = std::byte(100);
  badFire.resize(100, std::byte{0});

  put(1000.0, {alpha(0)});
  put(1000.5, {encode(header(), bravo)});
  put(1001.0, {alpha(1), badFire});
  put(1002.0, {encode(header(), fire)});
  put(1004.0, {alpha(4)});
  EXPECT_TRUE(w->close().ok());
  return c;
}

const nlohmann::json* entityById(const nlohmann::json& j, const std::string& id) {
  for (const auto& e : j["entities"]) {
    if (e["id"] == id) return &e;
  }
  return nullptr;
}

TEST(DisMonitorCli, inspectReportsWhatWiresharkReadsAndDeadReckonsByHand) {
  test::TempDir dir("dis_inspect");
  const std::string pcap = dir / "exercise.pcap";
  const Capture c = writeCapture(pcap);

  const auto r = test::runCli({"dis", "inspect", pcap, "--at", "2.5", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["datagrams"], 5);
  EXPECT_EQ(j["pdus"], 5);  // four Entity State, one Fire; the malformed Fire apart
  EXPECT_EQ(j["fires"], 1);
  EXPECT_DOUBLE_EQ(j["window_s"].get<double>(), 4.0);
  ASSERT_EQ(j["entities"].size(), 2u);

  // Wireshark's reading of every Entity State PDU: the last of each id is
  // what the monitor reports as sent.
  if (std::system("command -v tshark >/dev/null 2>&1") == 0) {
    const auto rows = tsv(fixtures::commandOutput("tshark -r '" + pcap + "' -Y 'dis.pdu_type == 1' -T fields -E occurrence=f "
                                "-e dis.entity_id_site -e dis.entity_id_application -e dis.entity_id_entity "
                                "-e dis.entity_location.x -e dis.entity_location.y -e dis.entity_location.z "
                                "-e dis.entity_marking 2>/dev/null"));
    ASSERT_EQ(rows.size(), 4u);
    std::map<std::string, std::vector<std::string>> last;
    for (const auto& row : rows) {
      ASSERT_EQ(row.size(), 7u);
      last[row[0] + ":" + row[1] + ":" + row[2]] = row;
    }
    ASSERT_EQ(last.size(), 2u);
    for (const auto& [id, row] : last) {
      const nlohmann::json* e = entityById(j, id);
      ASSERT_NE(e, nullptr) << id;
      EXPECT_NEAR((*e)["location"]["x"].get<double>(), std::stod(row[3]), 1e-6) << id;
      EXPECT_NEAR((*e)["location"]["y"].get<double>(), std::stod(row[4]), 1e-6) << id;
      EXPECT_NEAR((*e)["location"]["z"].get<double>(), std::stod(row[5]), 1e-6) << id;
      EXPECT_EQ((*e)["marking"], row[6]) << id;
    }
  } else {
    ADD_FAILURE() << "tshark is missing: run tools/setup.sh";
  }

  const nlohmann::json* alpha = entityById(j, "1:2:1");
  ASSERT_NE(alpha, nullptr);
  EXPECT_EQ((*alpha)["updates"], 3);
  EXPECT_DOUBLE_EQ((*alpha)["largest_gap_s"].get<double>(), 3.0);
  EXPECT_EQ((*alpha)["dr_algorithm"], 2);
  EXPECT_EQ((*alpha)["type"], "1.1.225.1.1.3.0");
  EXPECT_EQ((*alpha)["force"], 1);
  // --at 2.5 s after the first packet: from the PDU at 1001.0, 1.5 s of
  // constant velocity: x = x0 + 1 v + 1.5 v.
  const auto& at = (*alpha)["at"];
  EXPECT_DOUBLE_EQ(at["pdu_time_s"].get<double>(), 1.0);
  const std::array<double, 3> want = {c.alpha0[0] + 2.5 * 10.0, c.alpha0[1] - 2.5 * 5.0, c.alpha0[2] + 2.5 * 2.0};
  EXPECT_NEAR(at["location"]["x"].get<double>(), want[0], 1e-6);
  EXPECT_NEAR(at["location"]["y"].get<double>(), want[1], 1e-6);
  EXPECT_NEAR(at["location"]["z"].get<double>(), want[2], 1e-6);
  // lon/lat/height of the sent and the reckoned location, against OSR.
  const auto g0 = osr({(*alpha)["location"]["x"], (*alpha)["location"]["y"], (*alpha)["location"]["z"]}, false);
  EXPECT_NEAR((*alpha)["geodetic"]["lon_deg"].get<double>(), g0[0], 1e-9);
  EXPECT_NEAR((*alpha)["geodetic"]["lat_deg"].get<double>(), g0[1], 1e-9);
  EXPECT_NEAR((*alpha)["geodetic"]["height_m"].get<double>(), g0[2], 1e-4);
  const auto g = osr(want, false);
  EXPECT_NEAR(at["geodetic"]["lon_deg"].get<double>(), g[0], 1e-9);
  EXPECT_NEAR(at["geodetic"]["lat_deg"].get<double>(), g[1], 1e-9);
  EXPECT_NEAR(at["geodetic"]["height_m"].get<double>(), g[2], 1e-4);

  // BRAVO at (a, 0, 0): north is +Z, east +Y, down -X. psi 90, theta 0,
  // phi -90 puts body x on +Y (east) and body z on -X (down): heading 90,
  // pitch 0, roll 0.
  const nlohmann::json* bravo = entityById(j, "1:2:2");
  ASSERT_NE(bravo, nullptr);
  EXPECT_EQ((*bravo)["marking"], "BRAVO");
  EXPECT_EQ((*bravo)["force"], 2);
  EXPECT_NEAR((*bravo)["geodetic"]["lon_deg"].get<double>(), 0.0, 1e-12);
  EXPECT_NEAR((*bravo)["geodetic"]["lat_deg"].get<double>(), 0.0, 1e-12);
  EXPECT_NEAR((*bravo)["geodetic"]["height_m"].get<double>(), 0.0, 1e-6);
  EXPECT_NEAR((*bravo)["attitude"]["heading_deg"].get<double>(), 90.0, 1e-4);
  EXPECT_NEAR((*bravo)["attitude"]["pitch_deg"].get<double>(), 0.0, 1e-4);
  EXPECT_NEAR((*bravo)["attitude"]["roll_deg"].get<double>(), 0.0, 1e-4);
  EXPECT_NEAR((*bravo)["orientation"]["psi"].get<double>(), kPi / 2, 1e-6);
  ASSERT_EQ((*bravo)["articulated"].size(), 1u);
  EXPECT_EQ((*bravo)["articulated"][0]["parameter_type"], 4107);
  EXPECT_EQ((*bravo)["articulated"][0]["value"], 0.5);
  EXPECT_NEAR((*bravo)["at"]["location"]["x"].get<double>(), 6378137.0, 1e-9);  // static

  // The malformed Fire: the second PDU of datagram 3, its length field at
  // byte 144 + 8 of the datagram.
  EXPECT_EQ(j["malformed"]["count"], 1);
  ASSERT_EQ(j["malformed"]["reasons"].size(), 1u);
  const auto& reason = j["malformed"]["reasons"][0];
  EXPECT_EQ(reason["reason"], "a Fire PDU is N bytes; the length is N");
  EXPECT_EQ(reason["examples"][0]["offset"], 152);
  EXPECT_EQ(reason["examples"][0]["datagram"], 3);
  EXPECT_EQ(reason["examples"][0]["sender"], "127.0.0.1:3001");
  EXPECT_EQ(reason["examples"][0]["message"], "dis: a Fire PDU is 96 bytes; the length is 100");

  // Per sender: 127.0.0.1:3001 as 1:2 sent 5 PDUs over 4 s.
  bool found = false;
  for (const auto& s : j["senders"]) {
    if (s["address"] == "127.0.0.1:3001" && s["site_application"] == "1:2") {
      found = true;
      EXPECT_EQ(s["pdus"], 5);
      EXPECT_DOUBLE_EQ(s["rate_per_s"].get<double>(), 1.25);
      EXPECT_EQ(s["entities"], 2);
      EXPECT_EQ(s["fires"], 1);
      EXPECT_DOUBLE_EQ(s["largest_gap_s"].get<double>(), 2.0);
      EXPECT_DOUBLE_EQ(s["largest_heartbeat_gap_s"].get<double>(), 3.0);
    }
  }
  EXPECT_TRUE(found) << j["senders"].dump();

  // The human report names the malformed reason and both markings.
  const auto text = test::runCli({"dis", "inspect", pcap});
  ASSERT_EQ(text.exitCode, 0) << text.err;
  EXPECT_NE(text.out.find("ALPHA"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("BRAVO"), std::string::npos);
  EXPECT_NE(text.out.find("a Fire PDU is N bytes; the length is N"), std::string::npos);
}

TEST(DisMonitorCli, theExerciseFilterAndErrorsExitTwo) {
  test::TempDir dir("dis_inspect_err");
  const std::string pcap = dir / "exercise.pcap";
  writeCapture(pcap);
  auto r = test::runCli({"dis", "inspect", pcap, "--exercise", "2", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["pdus"], 0);
  EXPECT_EQ(j["other_exercise"], 6);
  EXPECT_TRUE(j["entities"].empty());

  r = test::runCli({"dis", "inspect", dir / "missing.pcap"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("missing.pcap"), std::string::npos) << r.err;
  test::spit(dir / "text.pcap", "this is not a capture file\n");
  r = test::runCli({"dis", "inspect", dir / "text.pcap"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("text.pcap"), std::string::npos) << r.err;
  r = test::runCli({"dis", "inspect", pcap, "--at", "-1"});
  EXPECT_EQ(r.exitCode, 2);
}

// The data logger on loopback multicast: `record` hears what `play` sends
// and writes it again; `inspect` reads the same PDUs at the same pace.
TEST(DisMonitorCli, recordHearsWhatPlaySendsAtTheRecordedPace) {
  test::TempDir dir("dis_record");
  const std::string pcap = dir / "exercise.pcap", again = dir / "again.pcap";
  writeCapture(pcap);
  const std::string where = "239.255.36.1:" + std::to_string(20000 + ::getpid() % 20000);
  test::CommandResult recorded;
  std::thread recorder([&] { recorded = test::runCli({"dis", "record", "--dis", where, "-o", again, "--seconds", "4"}); });
  std::this_thread::sleep_for(std::chrono::milliseconds(800));  // the recorder's socket is up
  const auto played = test::runCli({"dis", "play", pcap, "--dis", where, "--speed", "2", "--json"});
  recorder.join();
  ASSERT_EQ(played.exitCode, 0) << played.err;
  EXPECT_EQ(nlohmann::json::parse(played.out)["datagrams_sent"], 5);
  ASSERT_EQ(recorded.exitCode, 0) << recorded.err;
  const auto r = test::runCli({"dis", "inspect", again, "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["datagrams"], 5);
  EXPECT_EQ(j["pdus"], 5);
  EXPECT_EQ(j["malformed"]["count"], 1);
  ASSERT_EQ(j["entities"].size(), 2u);
  EXPECT_EQ(j["entities"][0]["marking"], "ALPHA");
  EXPECT_EQ(j["entities"][1]["marking"], "BRAVO");
  // 4 s of capture at twice the pace: 2 s, give or take the scheduler.
  EXPECT_NEAR(j["window_s"].get<double>(), 2.0, 0.5);  // a loaded machine delays sends, never hurries them
}

}  // namespace
}  // namespace sandtable
