// Hostile inputs to the CLI on a real database (DTED0 n43 with modules):
// manifests whose informational `build` object has the wrong shape, with
// the checksum resealed so only the shape is wrong.
#include <sstream>

#include <nlohmann/json.hpp>

#include "sandtable/converters/elevation.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

/// One small real database with load modules, built once for the suite.
class HostileCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    tmp_ = new TempDir("hostile");
    convert::ElevationOptions o;
    o.sources = {data("elevation/dted/n43.dt0")};
    o.output = *tmp_ / "db";
    auto r = convert::buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    db_ = o.output;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override { SANDTABLE_REQUIRE_DATA(); }

  /// A fresh copy of the database, removed by the suite's TempDir.
  static std::string copy(const std::string& name) {
    const std::string to = *tmp_ / name;
    fs::remove_all(to);
    fs::copy(db_, to);
    return to;
  }

  static TempDir* tmp_;
  static std::string db_;
};
TempDir* HostileCli::tmp_ = nullptr;
std::string HostileCli::db_;

struct BuildShape {
  const char* name;
  std::function<void(json& build)> edit;
};

TEST_F(HostileCli, infoAndValidateTreatTheBuildObjectAsInformational) {
  const BuildShape shapes[] = {
      {"build = {}", [](json& b) { b = json::object(); }},
      {"culture = {}", [](json& b) { b["culture"] = json::object(); }},
      {"modules = {}", [](json& b) { b["modules"] = json::object(); }},
      {"culture and modules = {}", [](json& b) { b["culture"] = json::object(), b["modules"] = json::object(); }},
      {"culture is an array", [](json& b) { b["culture"] = json::array({1, 2}); }},
      {"modules is a string", [](json& b) { b["modules"] = "many"; }},
      {"culture is null", [](json& b) { b["culture"] = nullptr; }},
      {"modules.bytes is an array", [](json& b) { b["modules"]["bytes"] = json::array(); }},
      {"modules.per_level is an object", [](json& b) { b["modules"]["per_level"] = {{"a", 1}}; }},
      {"per_level holds numbers", [](json& b) { b["modules"]["per_level"] = json::array({1, "x", nullptr}); }},
      {"counts are strings", [](json& b) { b["modules"]["count"] = "315", b["modules"]["modules_x"] = true; }},
      {"counts are huge or negative", [](json& b) {
         b["modules"]["count"] = 1e300, b["modules"]["modules_z"] = -7, b["voids_filled"] = -1.5e308;
       }},
      {"classes is an array", [](json& b) { b["culture"]["classes"] = json::array({"road"}); }},
      {"a class is a number", [](json& b) { b["culture"]["classes"] = {{"road", 5}, {"rail", json::array()}}; }},
      {"materials is a number", [](json& b) { b["culture"]["materials"] = 3; }},
      {"resample and seconds of the wrong type", [](json& b) { b["resample"] = 7, b["seconds"] = "slow"; }},
  };
  int n = 0;
  for (const auto& s : shapes) {
    const std::string db = copy("shape" + std::to_string(n++));
    resealManifest(db, [&](json& j) { s.edit(j["build"]); });
    const auto text = runCli({"info", db});
    EXPECT_EQ(text.exitCode, 0) << s.name << ": " << text.err;
    EXPECT_NE(text.out.find("posts      117 x 163"), std::string::npos) << s.name << ": " << text.out;
    EXPECT_EQ(text.err, "") << s.name;
    const auto asJson = runCli({"info", db, "--json"});
    EXPECT_EQ(asJson.exitCode, 0) << s.name << ": " << asJson.err;
    EXPECT_TRUE(json::accept(asJson.out)) << s.name << ": " << asJson.out;
    const auto v = runCli({"validate", db});
    EXPECT_EQ(v.exitCode, 0) << s.name << ": " << v.out << v.err;
  }
}

}  // namespace
}  // namespace sandtable::test
