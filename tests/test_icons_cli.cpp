// `sandtable icons --model`: the report of a real model, and exit 2 with
// the file named for models that cannot become icons. `sandtable icons
// DEFS`: the sample definition file's icons, and exit 2 with the line named
// for a bad one.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "test_support.h"

using namespace sandtable::test;

namespace {

TEST(IconsCli, aRealModelReportsItsCountsBoundsAndTexturesAsJson) {
  const std::string model = data("models/assimp/jeep1.3ds");
  if (!std::filesystem::exists(model)) GTEST_SKIP() << "no ../shared/data/models here";
  const auto r = runCli({"icons", "--model", model, "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  // 3DS face lists of the jeep sum to 2,032 (../shared/data/PROVENANCE.md; the library
  // test counts the chunks itself).
  EXPECT_EQ(j["triangles"], 2032);
  EXPECT_GT(j["vertices"].get<int>(), 0);
  EXPECT_EQ(j["bounds"]["min"].size(), 3u);
  ASSERT_EQ(j["textures"].size(), 1u);
  EXPECT_TRUE(j["textures"][0]["found"].get<bool>());
  EXPECT_EQ(j["levels"].size(), 4u);
  EXPECT_EQ(j["levels"][0]["triangles"], 2032);
}

TEST(IconsCli, modelsThatCannotBeIconsExit2NamingTheFile) {
  TempDir t("icons");
  spit(t / "points.obj", "v 0 0 0\nv 1 0 0\n");
  spit(t / "nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
  spit(t / "junk.glb", std::string("glTF\x02\x00\x00\x00", 8) + "garbage");
  const std::pair<std::string, std::string> cases[] = {
      {t / "points.obj", "icons:"},
      {t / "nan.off", "not a finite number"},
      {t / "junk.glb", "assimp cannot read the model"},
      {t / "absent.3ds", "not found"},
  };
  for (const auto& [path, words] : cases) {
    const auto r = runCli({"icons", "--model", path, "--json"});
    EXPECT_EQ(r.exitCode, 2) << path;
    EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(words), std::string::npos) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_FALSE(j["ok"].get<bool>());
  }
  spit(t / "two.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n");
  const auto over = runCli({"icons", "--model", t / "two.obj", "--max-triangles", "1"});
  EXPECT_EQ(over.exitCode, 2);
  EXPECT_NE(over.err.find("--max-triangles"), std::string::npos) << over.err;
  EXPECT_EQ(runCli({"icons", "--model", t / "two.obj", "--max-triangles", "2"}).exitCode, 0);
}

TEST(IconsCli, theSampleDefinitionFileListsItsIconsAsJson) {
  const auto r = runCli({"icons", std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err, "");  // no warning from the sample
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["icons"].size(), 3u);
  EXPECT_EQ(j["icons"][0]["name"], "tree");
  // The built-in tree: 80 triangles at level 0 (docs/ICONS.md section 4).
  EXPECT_EQ(j["icons"][0]["levels"][0]["triangles"], 80);
  EXPECT_EQ(j["icons"][2]["levels"][0]["range_m"], 400.0);
  EXPECT_GT(j["pack_bytes"].get<int>(), 0);
}

TEST(IconsCli, aBadDefinitionFileExits2NamingTheLine) {
  TempDir t("icondefs");
  spit(t / "defs.txt", "sandtable-icons 1\nicon a\n  model builtin:tree\n  lod 0.5\nicon b\n  model gone.glb\n");
  const auto bad = runCli({"icons", t / "defs.txt"});
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.err.find("defs.txt @46: icon definitions: the first lod must have ratio 1"), std::string::npos)
      << bad.err;
  spit(t / "defs.txt", "sandtable-icons 1\nicon b\n  model gone.glb\n");
  const auto missing = runCli({"icons", t / "defs.txt", "--json"});
  EXPECT_EQ(missing.exitCode, 2);
  EXPECT_NE(missing.err.find("defs.txt @18: icons: icon 'b': model 'gone.glb'"), std::string::npos) << missing.err;
  EXPECT_NE(missing.err.find("not found"), std::string::npos) << missing.err;
  EXPECT_EQ(runCli({"icons", t / "defs.txt", "--model", "x.glb"}).exitCode, 2);  // one or the other
  EXPECT_EQ(runCli({"icons"}).exitCode, 2);
}

}  // namespace
