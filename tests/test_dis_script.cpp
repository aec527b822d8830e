// The data logger's conversions on the command line (docs/DIS.md §9,
// "Scripts and captures"): `dis from-script` makes a capture of
// samples/demo.script that Wireshark's dissector reads without a malformed
// PDU and with as many Entity State PDUs as the tool says, and `dis
// to-script` turns it back into a script whose entity paths are the
// original's within the dead-reckoning threshold. Bad input exits 2.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "sandtable/sim/script.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

/// A 12 km synthetic square at 125 m posts (a few seconds), with the sample icons.
class DisScripts : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new TempDir("dis-script");
    auto synth = runCli({"synth", "-o", *tmp_ / "in", "--size-km", "12", "--force"});
    ASSERT_EQ(synth.exitCode, 0) << synth.err;
    const auto bounds = nlohmann::json::parse(slurpFile(*tmp_ / "in/synth.json"))["bounds"];
    auto build = runCli({"build", "--elevation", *tmp_ / "in/dted2", "--extent", std::to_string(double(bounds["west"])),
                         std::to_string(double(bounds["south"])), std::to_string(double(bounds["east"])),
                         std::to_string(double(bounds["north"])), "--spacing", "125", "--icons",
                         std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", *tmp_ / "db"});
    ASSERT_EQ(build.exitCode, 0) << build.err;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  static std::string path(const std::string& name) { return *tmp_ / name; }
  static TempDir* tmp_;
};
TempDir* DisScripts::tmp_ = nullptr;

std::string shell(const std::string& command) {
  std::string out;
  if (FILE* p = ::popen(command.c_str(), "r")) {
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
    ::pclose(p);
  }
  return out;
}

/// Where a script puts `entity` at `t`, as the simulator plays it (the same
/// rule as sim_dis::scriptPosition, which this target does not link): the
/// last line at or before t dead reckoned, held from an Alive_Flag 0 line on.
std::optional<Eigen::Vector2d> positionAt(const std::vector<sim::ScriptLine>& lines, std::uint32_t entity, double t) {
  const sim::ScriptLine* last = nullptr;
  for (const sim::ScriptLine& l : lines) {
    if (l.timeS > t + sim::kScriptTimeResolutionS / 2) break;
    if (l.entity != entity) continue;
    if (last && !last->alive) break;
    last = &l;
  }
  if (!last) return std::nullopt;
  if (!last->alive) return Eigen::Vector2d(last->x, last->z);
  return sim::deadReckon(*last, t);
}

std::size_t lineCount(const std::string& text) { return std::size_t(std::count(text.begin(), text.end(), '\n')); }

TEST_F(DisScripts, aScriptBecomesACaptureWiresharkReadsAndComesBackWithinTheThreshold) {
  const std::string demo = std::string(SANDTABLE_SOURCE_DIR) + "/samples/demo.script";
  const std::string pcap = path("demo.pcap"), back = path("back.script");
  // demo.script's Entity_Type 2 is the M1 tank (the sample pack's icon 2 is a tree).
  auto out = runCli({"dis", "from-script", demo, path("db"), "-o", pcap, "--type", "2=1.1.225.1.1.3.0", "--json"});
  ASSERT_EQ(out.exitCode, 0) << out.err;
  const auto sent = nlohmann::json::parse(out.out);
  const std::size_t states = sent["entity_states"];
  EXPECT_GT(states, 50u);
  EXPECT_EQ(sent["fires"], 1);
  EXPECT_EQ(sent["removes"], 2);
  ASSERT_EQ(sent["entities"].size(), 2u);
  EXPECT_EQ(sent["entities"][0]["id"], "1:1:59");
  EXPECT_EQ(sent["entities"][0]["type"], "1.1.225.1.1.3.0");
  EXPECT_EQ(sent["entities"][0]["type_from"], "--type");

  if (std::system("command -v tshark >/dev/null 2>&1") == 0) {
    EXPECT_EQ(shell("tshark -r '" + pcap + "' -Y '_ws.malformed && dis' 2>/dev/null"), "");
    EXPECT_EQ(lineCount(shell("tshark -r '" + pcap + "' -Y 'dis.pdu_type == 1' 2>/dev/null")), states);
    EXPECT_EQ(lineCount(shell("tshark -r '" + pcap + "' -Y 'dis.pdu_type == 2' 2>/dev/null")), 1u);
    // The first PDU: entity 59 at time 0, its marking its number.
    EXPECT_EQ(shell("tshark -r '" + pcap + "' -c 1 -T fields -E occurrence=f -e dis.entity_id_entity "
                    "-e dis.entity_marking -e frame.time_epoch 2>/dev/null"),
              "59\t59\t0.000000000\n");
  } else {
    ADD_FAILURE() << "tshark is missing: run tools/setup.sh";
  }

  auto in = runCli({"dis", "to-script", pcap, path("db"), "-o", back, "--json"});
  ASSERT_EQ(in.exitCode, 0) << in.err;
  const auto got = nlohmann::json::parse(in.out);
  EXPECT_EQ(got["entity_states"], states);
  EXPECT_EQ(got["malformed"], 0);
  ASSERT_EQ(got["entities"].size(), 2u);
  EXPECT_EQ(got["entities"][0]["script_entity"], 59);
  EXPECT_EQ(got["entities"][0]["icon"], "tank");  // 1.1.225.1.1.3.0 is drawn as the tank
  EXPECT_EQ(got["entities"][0]["icon_fallback"], false);

  auto original = sim::readScriptFile(demo);
  auto replayed = sim::readScriptFile(back);
  ASSERT_TRUE(original.ok() && replayed.ok()) << replayed.error();
  // Within the 1 m threshold, plus one 60 Hz sample's growth at 10 m/s and the recorder's 5 mm.
  for (std::uint32_t entity : {59u, 60u}) {
    double worst = 0;
    for (double t = entity == 59 ? 0 : 5; t <= 200; t += 0.05) {
      const auto p = positionAt(original.value(), entity, t);
      const auto q = positionAt(replayed.value(), entity, t);
      ASSERT_TRUE(p && q) << entity << " at " << t;
      worst = std::max(worst, (*p - *q).norm());
    }
    EXPECT_LT(worst, 1.0 + 10.0 / 60 + 0.005) << "entity " << entity;
  }

  // The text summary prints the mapping.
  auto text = runCli({"dis", "to-script", pcap, path("db"), "-o", back});
  ASSERT_EQ(text.exitCode, 0) << text.err;
  EXPECT_NE(text.out.find("1:1:60"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("ENTITY_TYPE"), std::string::npos) << text.out;
}

TEST_F(DisScripts, badInputIsAClearErrorWithExitTwo) {
  const std::string demo = std::string(SANDTABLE_SOURCE_DIR) + "/samples/demo.script";
  auto r = runCli({"dis", "to-script", path("missing.pcap"), path("db"), "-o", path("x.script")});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("missing.pcap"), std::string::npos) << r.err;
  r = runCli({"dis", "from-script", path("missing.script"), path("db"), "-o", path("x.pcap")});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("missing.script"), std::string::npos) << r.err;

  spit(path("bad.script"), "00 00 00 1 2 0 0.0 0 0 0 0 0 0 0 1\n00 00 01 1 2 0 0.0 0 0 0 0 0 0 0 7\n");
  r = runCli({"dis", "from-script", path("bad.script"), path("db"), "-o", path("x.pcap")});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("line 2, column 34"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(path("x.pcap")));

  r = runCli({"dis", "from-script", demo, path("db"), "-o", path("x.pcap"), "--type", "2=1.x"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("--type"), std::string::npos) << r.err;
  r = runCli({"dis", "from-script", demo, path("db"), "-o", path("x.pcap"), "--rate", "0"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("--rate"), std::string::npos) << r.err;
  r = runCli({"dis", "to-script", demo, path("db"), "-o", path("x.script")});  // not a capture
  EXPECT_EQ(r.exitCode, 2);

  // A database without a coordinate system (refused as it opens), or with one
  // PROJ cannot take to geocentric, cannot place DIS positions.
  std::filesystem::copy(path("db"), path("nocrs"), std::filesystem::copy_options::recursive);
  for (const char* wkt : {"", "ENGCRS[\"local\",EDATUM[\"site\"],CS[Cartesian,2],AXIS[\"x\",east],"
                              "AXIS[\"y\",north],LENGTHUNIT[\"metre\",1]]"}) {
    resealManifest(path("nocrs"), [&](nlohmann::json& m) { m["crs"]["wkt"] = wkt; });
    r = runCli({"dis", "from-script", demo, path("nocrs"), "-o", path("x.pcap")});
    EXPECT_EQ(r.exitCode, 2) << wkt;
    EXPECT_NE(r.err.find("crs"), std::string::npos) << r.err;
    r = runCli({"dis", "to-script", path("demo.pcap"), path("nocrs"), "-o", path("x.script")});
    EXPECT_EQ(r.exitCode, 2) << wkt;
  }
  EXPECT_FALSE(std::filesystem::exists(path("x.pcap")));
  EXPECT_FALSE(std::filesystem::exists(path("x.script")));
}

}  // namespace
}  // namespace sandtable::test
