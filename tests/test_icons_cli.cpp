// `sandtable icons --model`: the report of a real model, and exit 2 with
// the file named for models that cannot become icons.
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

}  // namespace
