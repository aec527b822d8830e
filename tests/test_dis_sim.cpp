// Two `sandtable sim` processes on one DIS exercise over loopback
// (docs/DIS.md §11) over real data (Bayreuth: SRTM and OSM): one publishes an exercise, the other
// watches with no entities of its own. Every entity the publisher had
// reaches the watcher, and where the watcher last had each (its final,
// deactivating PDU, converted frame -> geocentric -> frame across the two
// processes) agrees with where the publisher's simulation left it. Bad
// endpoints and a port another program holds exit 2 naming the flag.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <map>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "sandtable/geodesy/geodesy.h"
#include "sandtable/render/renderer.h"
#include "sandtable/testing/require.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

/// Real data, built once: north of Bayreuth from SRTM (N49E011) with its
/// OSM culture (forests, roads, a town), 30 m posts, the sample icons; and
/// a scenario there of 17 tanks and trucks that drive, turn and shoot.
class DisTwoProcesses : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    tmp_ = new TempDir("dis-two");
    auto build = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.55", "49.94",
                         "11.62", "49.99", "--spacing", "30", "--culture", data("culture/osm/north-bayreuth.osm.gz"),
                         "--icons", std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", *tmp_ / "db"});
    ASSERT_EQ(build.exitCode, 0) << build.err;
    spit(*tmp_ / "empty.scenario", "sandtable-scenario 1\n");
    spit(*tmp_ / "exercise.scenario",
         "sandtable-scenario 1\nframe lonlat\nseed 5\n"
         "entity lead icon=tank force=blue mobility=tracked at=11.585,49.962 heading=0 speed=20 behaviour=noise,engage\n"
         "group 12 name=red icon=tank force=red mobility=tracked area=11.58,49.965,11.60,49.975 heading=150..210 "
         "speed=10..20 behaviour=noise,engage\n"
         "group 4 name=truck icon=truck force=blue mobility=wheeled area=11.575,49.955,11.59,49.96 heading=0..60 "
         "speed=20..30 behaviour=zigzag\n");
  }
  void SetUp() override { SANDTABLE_REQUIRE_DATA(); }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  static std::string db() { return *tmp_ / "db"; }
  static std::string exercise() { return *tmp_ / "exercise.scenario"; }
  static std::string empty() { return *tmp_ / "empty.scenario"; }
  static TempDir* tmp_;
};
TempDir* DisTwoProcesses::tmp_ = nullptr;

TEST_F(DisTwoProcesses, aWatcherSeesEveryPublishedEntityWhereThePublisherLeftIt) {
  const std::string address = "127.255.255.255:" + std::to_string(20000 + ::getpid() % 20000);
  CommandResult watcher;
  std::thread watch([&] {
    watcher = runCli({"sim", db(), "--scenario", empty(), "--dis", address, "--site", "2",
                      "--duration", "9", "--json"});
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the watcher is listening
  const auto publisher = runCli({"sim", db(), "--scenario", exercise(), "--dis", address,
                                 "--site", "1", "--duration", "5", "--json"});
  watch.join();
  ASSERT_EQ(publisher.exitCode, 0) << publisher.err;
  ASSERT_EQ(watcher.exitCode, 0) << watcher.err;
  const auto pub = nlohmann::json::parse(publisher.out)["dis"];
  const auto seen = nlohmann::json::parse(watcher.out)["dis"];
  std::map<std::string, nlohmann::json> local;
  for (const auto& e : pub["local_entities"]) local[e["id"]] = e;
  ASSERT_EQ(local.size(), 17u);
  EXPECT_EQ(seen["malformed"], 0);
  EXPECT_EQ(seen["conflicts"], 0);
  EXPECT_EQ(seen["other_exercise"], 0);
  EXPECT_EQ(std::size_t(seen["removes"]), local.size());
  std::size_t matched = 0;
  double worst = 0;
  for (const auto& d : seen["departed"]) {
    if (d["why"] != "deactivated") continue;
    auto it = local.find(d["id"]);
    ASSERT_NE(it, local.end()) << d.dump();
    const auto& p = it->second["position"];
    const auto& q = d["position"];
    worst = std::max(worst, std::hypot(double(p[0]) - double(q[0]), double(p[1]) - double(q[1]),
                                       double(p[2]) - double(q[2])));
    EXPECT_EQ(d["marking"], std::string(it->second["name"]).substr(0, 11));
    ++matched;
  }
  EXPECT_EQ(matched, local.size());
  EXPECT_LT(worst, 0.01);  // metres: ECEF doubles both ways through PROJ
  EXPECT_EQ(pub["send_errors"], 0);
}

TEST_F(DisTwoProcesses, theStealthViewerDrawsAndFollowsANetworkedEntity) {
  // `fly --dis` headless beside a publishing `sim --dis`: the viewer
  // publishes nothing, tracks the publisher's entities, attaches its eye to
  // one by DIS id once it appears and draws them (frames on the wall clock).
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  const std::string address = "127.255.255.255:" + std::to_string(20000 + (::getpid() + 7) % 20000);
  const std::string png = *tmp_ / "fly";
  CommandResult viewer;
  std::thread fly([&] {
    viewer = runCli({"fly", db(), "--dis", address, "--site", "2", "--headless", "--png", png, "--frames", "150",
                     "--size", "320x180", "--attach", "1:1:2"});
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const auto publisher = runCli({"sim", db(), "--scenario", exercise(), "--dis", address,
                                 "--site", "1", "--duration", "6", "--json"});
  fly.join();
  ASSERT_EQ(publisher.exitCode, 0) << publisher.err;
  ASSERT_EQ(viewer.exitCode, 0) << viewer.err;
  EXPECT_NE(viewer.out.find("dis: sent 0 PDUs"), std::string::npos) << viewer.out;  // passive
  const auto stats = nlohmann::json::parse(slurpFile(png + "/stats.json"));
  const auto pub = nlohmann::json::parse(publisher.out)["dis"];
  std::string attachedName;
  for (const auto& e : pub["local_entities"]) {
    if (e["id"] == "1:1:2") attachedName = e["name"];
  }
  ASSERT_FALSE(attachedName.empty());
  bool sawAll = false, drew = false, attached = false;
  for (const auto& f : stats["frames"]) {
    const auto& s = f["sim"];
    sawAll = sawAll || std::size_t(s["entities"]) == pub["local_entities"].size();
    drew = drew || int(f["dynamic"]["entities_drawn"]) > 0;
    attached = attached || (s.contains("attached") && s["attached"] == attachedName);
  }
  EXPECT_TRUE(sawAll);
  EXPECT_TRUE(drew);
  EXPECT_TRUE(attached) << attachedName;
}

/// tshark's fields of every packet of `pcap` that `filter` passes, one row
/// each; UDP `port` is dissected as DIS (tshark does so only on 3000 by itself).
std::vector<std::vector<std::string>> tsharkRows(const std::string& pcap, unsigned port, const std::string& filter,
                                                 const std::vector<std::string>& fields) {
  std::string command = "tshark -r '" + pcap + "' -d udp.port==" + std::to_string(port) + ",dis -Y '" + filter +
                        "' -T fields -E separator=/t";
  for (const auto& f : fields) command += " -e " + f;
  std::vector<std::vector<std::string>> rows;
  std::unique_ptr<FILE, int (*)(FILE*)> p(popen(command.c_str(), "r"), pclose);
  if (!p) return rows;
  char line[4096];
  while (std::fgets(line, sizeof line, p.get())) {
    std::vector<std::string> row;
    std::string cell;
    for (const char* c = line; *c && *c != '\n'; ++c) {
      if (*c == '\t') {
        row.push_back(cell);
        cell.clear();
      } else {
        cell += *c;
      }
    }
    row.push_back(cell);
    rows.push_back(std::move(row));
  }
  return rows;
}

TEST_F(DisTwoProcesses, aRecordedRunReadsInWiresharkAsItWasSent) {
  // `dis record` logs a publishing `sim --dis`; Wireshark's dissector (an
  // implementation nobody here wrote) finds nothing malformed, counts the
  // PDUs the publisher says it sent, and reads every entity's last Entity
  // State PDU (deactivating, with its true final state) at the place the
  // publisher's simulation left it: tshark's geocentric location taken
  // into the database frame with PROJ.
  const unsigned port = 20000 + unsigned(::getpid() + 13) % 20000;
  const std::string address = "127.255.255.255:" + std::to_string(port);
  const std::string pcap = *tmp_ / "run.pcap";
  CommandResult recorder;
  std::thread record([&] { recorder = runCli({"dis", "record", "--dis", address, "-o", pcap, "--seconds", "7"}); });
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  const auto publisher = runCli({"sim", db(), "--scenario", exercise(), "--dis", address,
                                 "--site", "1", "--duration", "4", "--json"});
  record.join();
  ASSERT_EQ(publisher.exitCode, 0) << publisher.err;
  ASSERT_EQ(recorder.exitCode, 0) << recorder.err;
  EXPECT_TRUE(tsharkRows(pcap, port, "_ws.malformed && dis", {"frame.number"}).empty());
  const auto pub = nlohmann::json::parse(publisher.out)["dis"];
  const auto all = tsharkRows(pcap, port, "dis", {"dis.pdu_type"});
  EXPECT_EQ(all.size(), std::size_t(pub["sent_pdus"]));
  const auto frame = geodesy::DatabaseFrame::create(
      nlohmann::json::parse(slurpFile(db() + "/manifest.json"))["crs"]["wkt"],
      double(nlohmann::json::parse(slurpFile(db() + "/manifest.json"))["grid"]["origin_easting"]),
      double(nlohmann::json::parse(slurpFile(db() + "/manifest.json"))["grid"]["origin_northing"]));
  ASSERT_TRUE(frame.ok()) << frame.error();
  std::map<std::string, std::vector<std::string>> last;  // entity id -> its last Entity State PDU
  for (auto& row : tsharkRows(pcap, port, "dis.pdu_type == 1",
                              {"dis.entity_id_site", "dis.entity_id_application", "dis.entity_id_entity",
                               "dis.entity_location.x", "dis.entity_location.y", "dis.entity_location.z",
                               "dis.entity_marking"})) {
    ASSERT_EQ(row.size(), 7u);
    last[row[0] + ":" + row[1] + ":" + row[2]] = row;
  }
  std::size_t matched = 0;
  double worst = 0;
  for (const auto& e : pub["local_entities"]) {
    auto it = last.find(e["id"]);
    ASSERT_NE(it, last.end()) << e.dump();
    const auto& r = it->second;
    auto p = frame->fromEcef({std::stod(r[3]), std::stod(r[4]), std::stod(r[5])});
    ASSERT_TRUE(p.ok()) << p.error();
    const auto& q = e["position"];
    worst = std::max(worst, std::hypot(p->x - double(q[0]), p->y - double(q[1]), p->z - double(q[2])));
    EXPECT_EQ(r[6], std::string(e["name"]).substr(0, 11));
    ++matched;
  }
  EXPECT_EQ(matched, pub["local_entities"].size());
  EXPECT_LT(worst, 0.01);
}

TEST_F(DisTwoProcesses, aBadAddressInterfaceOrPortIsAClearErrorWithExitTwo) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--dis", "300.1.2.3:3000"}, "--dis"},
      {{"--dis", "127.0.0.1:0"}, "--dis"},
      {{"--dis", "3000", "--dis-interface", "nosuch0"}, "--dis-interface"},
      {{"--dis", "3000", "--exercise", "0"}, "--exercise"},
      {{"--dis", "3000", "--site", "65535"}, "--site"},
  };
  for (const auto& [flags, named] : cases) {
    std::vector<std::string> args = {"sim", db(), "--scenario", empty(), "--duration", "1"};
    args.insert(args.end(), flags.begin(), flags.end());
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, 2) << flags[1];
    EXPECT_NE(r.err.find(named), std::string::npos) << r.err;
  }
}

TEST_F(DisTwoProcesses, aPortInUseIsAClearErrorWithExitTwo) {
  // A program that holds the port without SO_REUSEADDR: nobody may share it.
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in at{};
  at.sin_family = AF_INET;
  at.sin_addr.s_addr = htonl(INADDR_ANY);
  at.sin_port = 0;  // the kernel picks a free one
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&at), sizeof at), 0);
  socklen_t len = sizeof at;
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&at), &len), 0);
  const std::string port = std::to_string(ntohs(at.sin_port));
  const auto r = runCli({"sim", db(), "--scenario", empty(), "--duration", "1", "--dis", "127.0.0.1:" + port});
  ::close(fd);
  EXPECT_EQ(r.exitCode, 2) << r.err;
  EXPECT_NE(r.err.find("--dis"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("port " + port + " is taken"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sandtable::test
