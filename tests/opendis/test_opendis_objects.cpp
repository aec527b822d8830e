// Terrain edits as DIS objects (sim_dis/objects.h; docs/DIS.md §14) read by
// Open-DIS for JavaScript (npm open-dis 1.3.6, DIS 7): a crater's Point
// Object State PDU through Open-DIS's own PduFactory, and a berm's Linear
// Object State PDU through its LinearObjectStatePdu class (the factory has
// no case for type 44: read_objects.js says so). Every field Open-DIS reads
// is what we sent, floats exactly, and Open-DIS's own geodesy puts each
// location where our database frame says the edit is. Fails, never skips,
// without node or the package.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "opendis_support.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/sim_dis/objects.h"

namespace sandtable::sim_dis {
namespace {

using namespace opendis_test;

void writeBytes(const fs::path& path, const std::vector<std::byte>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

void expectD(const json& j, double v, const std::string& what) { EXPECT_EQ(j.get<double>(), v) << what; }
void expectVec(const json& j, const dis::Vec3d& v, const std::string& what) {
  ASSERT_EQ(j.size(), 3u) << what;
  expectD(j[0], v.x, what + ".x");
  expectD(j[1], v.y, what + ".y");
  expectD(j[2], v.z, what + ".z");
}
void expectEuler(const json& j, const dis::Euler& e, const std::string& what) {
  ASSERT_EQ(j.size(), 3u) << what;
  expectD(j[0], e.psi, what + ".psi");
  expectD(j[1], e.theta, what + ".theta");
  expectD(j[2], e.phi, what + ".phi");
}
void expectHeader(const json& j, const dis::Header& h) {
  EXPECT_EQ(j["version"], h.version);
  EXPECT_EQ(j["exercise"], h.exercise);
  EXPECT_EQ(j["type"], h.type);
  EXPECT_EQ(j["family"], h.family);
  EXPECT_EQ(j["timestamp"], h.timestamp);
  EXPECT_EQ(j["length"], h.length);
  EXPECT_EQ(j["status"], h.status);
}
/// Open-DIS's lon, lat, height of a location against our frame's for the frame point.
void expectWhere(const json& g, const geodesy::DatabaseFrame& frame, const geodesy::FramePoint& p,
                 const std::string& what) {
  auto ours = frame.toLonLatHeight(p);
  ASSERT_TRUE(ours.ok()) << ours.error();
  ASSERT_EQ(g.size(), 3u) << what;
  EXPECT_NEAR(g[0].get<double>(), ours->lon, 1e-8) << what;  // 1e-8 degrees: under a millimetre
  EXPECT_NEAR(g[1].get<double>(), ours->lat, 1e-8) << what;
  EXPECT_NEAR(g[2].get<double>(), ours->height, 0.001) << what;
}

TEST(OpenDisObjects, openDisReadsTheCraterAndTheBermWeSend) {
  ASSERT_TRUE(haveOpenDis());
  // UTM 33N, north-west corner at E 300 km, N 5,600 km (about 12.2 E, 50.5 N), as sim_dis's tests.
  auto geo = geodesy::DatabaseFrame::create("EPSG:32633", 300000.0, 5600000.0);
  ASSERT_TRUE(geo.ok()) << geo.error();
  const DisFrame frame(geo.value());
  ObjectSender s;
  s.exercise = 3;
  s.site = 1;
  s.application = 2;
  s.ground = [](double, double) { return 250.0; };

  edit::Edit crater;
  crater.id = 17;
  crater.time = 123.5;
  crater.kind = edit::Kind::crater;
  crater.points = {{1000.3, 2000.7}};
  crater.radius = 7;  // large
  crater.depth = 2;
  edit::Edit berm;
  berm.id = 70000;  // object 4,464, update 1
  berm.time = 3723.5;
  berm.kind = edit::Kind::berm;
  berm.points = {{1000, 2000}, {1040, 1970}, {1040, 1900}};
  berm.width = 2.5;
  berm.height = 1.25;
  berm.sideSlope = 0.75;

  const fs::path dir = scratchDir("objects");
  std::vector<dis::Pdu> sent;
  std::string files;
  for (const auto& [e, name] : {std::pair{crater, "crater.pdu"}, std::pair{berm, "berm.pdu"}}) {
    auto pdu = toPdu(e, frame, s);
    ASSERT_TRUE(pdu.ok()) << pdu.error();
    writeBytes(dir / name, encodeObject(pdu.value()));
    sent.push_back(pdu.value());
    files += ' ' + shellQuoted(dir / name);
  }
  const auto out = node("read_objects.js", files);
  ASSERT_TRUE(out);
  const json& pdus = (*out)["pdus"];
  ASSERT_EQ(pdus.size(), 2u);

  // The crater, through Open-DIS's PduFactory.
  const json& c = pdus[0];
  EXPECT_EQ(c["via"], "factory");
  expectHeader(c["header"], sent[0].header);
  const json& p = c["object"];
  const dis::PointObjectState& point = *sent[0].pointObject;
  EXPECT_EQ(p["id"], (std::vector<int>{1, 2, 17}));
  EXPECT_EQ(p["referenced"], (std::vector<int>{0, 0, 0}));
  EXPECT_EQ(p["updateNumber"], 0);
  EXPECT_EQ(p["force"], 0);
  EXPECT_EQ(p["modifications"], 0);
  EXPECT_EQ(p["type"], (std::vector<int>{1, 1, 3, 3}));  // land, obstacle, crater, large
  expectVec(p["location"], point.location, "location");
  expectEuler(p["orientation"], point.orientation, "orientation");
  EXPECT_EQ(p["appearance"], 0);  // Open-DIS reads the 64 bits as a float64: 0 is 0
  EXPECT_EQ(p["requester"], (std::vector<int>{1, 2}));
  EXPECT_EQ(p["receiver"], (std::vector<int>{65535, 65535}));
  expectWhere(p["geodetic"], geo.value(), {1000.3, 250, 2000.7}, "crater");

  // The berm, through Open-DIS's LinearObjectStatePdu class.
  const json& b = pdus[1];
  EXPECT_EQ(b["via"], "class");
  expectHeader(b["header"], sent[1].header);
  const json& l = b["object"];
  const dis::LinearObjectState& linear = *sent[1].linearObject;
  EXPECT_EQ(l["id"], (std::vector<int>{1, 2, 4464}));
  EXPECT_EQ(l["updateNumber"], 1);
  EXPECT_EQ(l["segmentCount"], 2);
  EXPECT_EQ(l["type"], (std::vector<int>{1, 1, 0, 0}));  // land, obstacle, other
  EXPECT_EQ(l["requester"], (std::vector<int>{1, 2}));
  EXPECT_EQ(l["receiver"], (std::vector<int>{65535, 65535}));
  ASSERT_EQ(l["segments"].size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    const json& g = l["segments"][k];
    const dis::LinearSegment& want = linear.segments[k];
    const std::string at = "segment " + std::to_string(k + 1);
    EXPECT_EQ(g["number"], k + 1) << at;
    EXPECT_EQ(g["modification"], 0) << at;
    EXPECT_EQ(g["general"], 0) << at;
    EXPECT_EQ(g["specific"], slopeAppearance(0.75)) << at;
    expectVec(g["location"], want.location, at + " location");
    expectEuler(g["orientation"], want.orientation, at + " orientation");
    expectD(g["length"], want.length, at + " length");
    expectD(g["width"], 2.5, at + " width");
    expectD(g["height"], 1.25, at + " height");
    expectD(g["depth"], 0, at + " depth");
    const auto& a = berm.points[k];
    const auto& z = berm.points[k + 1];
    expectWhere(g["geodetic"], geo.value(), {0.5 * (a[0] + z[0]), 250, 0.5 * (a[1] + z[1])}, at + " midpoint");
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::sim_dis
