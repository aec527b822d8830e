// `build --icons`: icons.pack in the database, listed in the manifest,
// listed by info, checked by validate; a bad definition file stops the build
// before anything is written.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <filesystem>

#include "sandtable/formats/bytes.h"
#include "test_support.h"

using namespace sandtable::test;
namespace fs = std::filesystem;

namespace {

const std::string kSample = std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt";

std::vector<std::string> monacoBuild(const std::string& db) {
  return {"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--extent", "7.40", "43.72", "7.44",
          "43.76", "--spacing", "60", "-o", db, "--force"};
}

TEST(IconsBuild, theDatabaseCarriesItsIconsAndInfoListsThem) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("iconsdb");
  auto args = monacoBuild(t / "db");
  args.insert(args.end(), {"--icons", kSample});
  const auto b = runCli(args);
  ASSERT_EQ(b.exitCode, 0) << b.err;
  ASSERT_TRUE(fs::exists(t / "db/icons.pack"));
  const auto manifest = nlohmann::json::parse(slurpFile(t / "db/manifest.json"));
  bool listed = false;
  for (const auto& f : manifest["files"]) {
    listed = listed || (f["path"] == "icons.pack" && f["bytes"] == fs::file_size(t / "db/icons.pack"));
  }
  EXPECT_TRUE(listed);
  EXPECT_EQ(runCli({"validate", t / "db"}).exitCode, 0);
  const auto info = runCli({"info", t / "db", "--json"});
  ASSERT_EQ(info.exitCode, 0) << info.err;
  const auto j = nlohmann::json::parse(info.out);
  ASSERT_EQ(j["icons"].size(), 11u);  // three trees, then the built-in vehicles and buildings
  EXPECT_EQ(j["icons"][1]["name"], "tree-small");
  // The built-in tree's levels (docs/ICONS.md section 4).
  EXPECT_EQ(j["icons"][0]["levels"][0]["triangles"], 80);
  EXPECT_EQ(j["icons"][0]["levels"][1]["triangles"], 40);
  EXPECT_EQ(j["icons"][2]["levels"][2]["range_m"], 6000.0);
}

TEST(IconsBuild, withoutDefinitionsThePackHoldsTheTree) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("iconsdefault");
  ASSERT_EQ(runCli(monacoBuild(t / "db")).exitCode, 0);
  const auto j = nlohmann::json::parse(runCli({"info", t / "db", "--json"}).out);
  ASSERT_EQ(j["icons"].size(), 1u);
  EXPECT_EQ(j["icons"][0]["name"], "tree");
}

TEST(IconsBuild, validateFindsACorruptPackEvenWithTheManifestResealed) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("iconscorrupt");
  auto args = monacoBuild(t / "db");
  args.insert(args.end(), {"--icons", kSample});
  ASSERT_EQ(runCli(args).exitCode, 0);
  std::string bytes = slurpFile(t / "db/icons.pack");
  ASSERT_GT(bytes.size(), 100u);
  bytes[100] = char(bytes[100] ^ 0x40);
  spit(t / "db/icons.pack", bytes);
  // The manifest's size and CRC made to agree, so only icons.pack's own
  // checksum can tell.
  resealManifest(t / "db", [&](nlohmann::json& m) {
    for (auto& f : m["files"]) {
      if (f["path"] != "icons.pack") continue;
      const auto c = sandtable::crc32File(t / "db/icons.pack");
      ASSERT_TRUE(c.ok()) << c.error();
      f["bytes"] = c->bytes;
      f["crc32"] = sandtable::crcHex(c->crc);
    }
  });
  const auto v = runCli({"validate", t / "db"});
  EXPECT_EQ(v.exitCode, 1);
  EXPECT_NE(v.out.find("icons.pack @32: icons.pack: body checksum mismatch"), std::string::npos) << v.out;
  EXPECT_EQ(v.out.find("does not match the manifest"), std::string::npos) << v.out;
  const auto info = runCli({"info", t / "db"});
  EXPECT_EQ(info.exitCode, 2);
  EXPECT_NE(info.err.find("body checksum mismatch"), std::string::npos) << info.err;
}

TEST(IconsBuild, aBadDefinitionFileStopsTheBuildWithNoOutput) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("iconsbad");
  spit(t / "defs.txt", "sandtable-icons 1\nicon a\n  model missing.glb\n");
  auto args = monacoBuild(t / "db");
  args.insert(args.end(), {"--icons", t / "defs.txt"});
  const auto b = runCli(args);
  EXPECT_EQ(b.exitCode, 2);
  EXPECT_NE(b.err.find("defs.txt @18: icons: icon 'a': model 'missing.glb'"), std::string::npos) << b.err;
  EXPECT_FALSE(fs::exists(t / "db"));
  auto absent = monacoBuild(t / "db");
  absent.insert(absent.end(), {"--icons", t / "nothing.txt"});
  const auto a = runCli(absent);
  EXPECT_EQ(a.exitCode, 2);
  EXPECT_NE(a.err.find("check the --icons path"), std::string::npos) << a.err;
}

}  // namespace
