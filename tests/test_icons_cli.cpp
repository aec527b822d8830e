// `sandtable icons --model`: the report of a real model, and exit 2 with
// the file named for models that cannot become icons. `sandtable icons
// DEFS`: the sample definition file's icons, and exit 2 with the line named
// for a bad one.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include "sandtable/render/icon_sheet.h"
#include "test_support.h"

using namespace sandtable::test;

namespace {

TEST(IconsCli, aRealModelReportsItsCountsBoundsAndTexturesAsJson) {
  const std::string model = data("models/assimp/jeep1.3ds");
  SANDTABLE_REQUIRE(std::filesystem::exists(model), "the models of ../shared/data: " << model);
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
  ASSERT_EQ(j["icons"].size(), 11u);  // three trees, then the built-in vehicles and buildings
  EXPECT_EQ(j["icons"][0]["name"], "tree");
  // The built-in tree: 80 triangles at level 0 (docs/ICONS.md section 4).
  EXPECT_EQ(j["icons"][0]["levels"][0]["triangles"], 80);
  EXPECT_EQ(j["icons"][2]["levels"][0]["range_m"], 400.0);
  EXPECT_GT(j["pack_bytes"].get<int>(), 0);
}

TEST(IconsCli, devicesAndFifosAreNotRegularFilesForModelsAndDefinitions) {
  TempDir t("iconfifo");
  const std::string fifo = t / "model.obj";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& path : {std::string("/dev/zero"), fifo}) {
    // Both the model and the definition file: a FIFO must not block the read.
    for (const std::vector<std::string>& args : {std::vector<std::string>{"icons", "--model", path},
                                                 std::vector<std::string>{"icons", path}}) {
      const auto r = runCli(args);
      EXPECT_EQ(r.exitCode, 2) << args.back();
      EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
      EXPECT_NE(r.err.find("not a regular file"), std::string::npos) << r.err;
    }
  }
}

TEST(IconsCli, aTextureOutsideTheModelsFolderIsNotEmbedded) {
  TempDir t("icontex");
  spit(t / "t.mtl", "newmtl skin\nKd 0.5 0.5 0.5\nmap_Kd /etc/passwd\n");
  spit(t / "t.obj", "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl skin\nf 1/1 2/2 3/3\n");
  const auto r = runCli({"icons", "--model", t / "t.obj", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;  // a warning: the base colour is used
  EXPECT_NE(r.err.find("points outside the model's folder"), std::string::npos) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["textures"].size(), 1u);
  EXPECT_FALSE(j["textures"][0]["found"].get<bool>());
  // A file of that name beside the model is found, and is not an image.
  spit(t / "passwd", "root:x:0:0:root:/root:/bin/bash\n");
  const auto text = runCli({"icons", "--model", t / "t.obj", "--json"});
  ASSERT_EQ(text.exitCode, 0) << text.err;
  EXPECT_NE(text.err.find(t / "passwd"), std::string::npos) << text.err;
  EXPECT_NE(text.err.find("is not an image"), std::string::npos) << text.err;
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

namespace {

/// Pixels of a cell that differ from the sheet's cell background.
struct CellInk {
  std::size_t pixels = 0;
  std::uint32_t minX = ~0u, minY = ~0u, maxX = 0, maxY = 0;
};

CellInk inkOf(const sandtable::render::Image& img, std::uint32_t x0, std::uint32_t y0, std::uint32_t n) {
  const sandtable::render::IconSheetOptions o;
  CellInk ink;
  for (std::uint32_t y = y0; y < y0 + n; ++y) {
    for (std::uint32_t x = x0; x < x0 + n; ++x) {
      const std::uint8_t* p = &img.rgba[(std::size_t(y) * img.width + x) * 4];
      if (p[0] == o.background.r && p[1] == o.background.g && p[2] == o.background.b) continue;
      ++ink.pixels;
      ink.minX = std::min(ink.minX, x - x0), ink.maxX = std::max(ink.maxX, x - x0);
      ink.minY = std::min(ink.minY, y - y0), ink.maxY = std::max(ink.maxY, y - y0);
    }
  }
  return ink;
}

}  // namespace

TEST(IconsCli, theContactSheetShowsEveryIconAtEveryLevelFramedInItsCell) {
  TempDir t("sheet");
  const auto r = runCli({"icons", std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", t / "out", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["contact_sheets"].size(), 1u);
  const auto img = readPng(j["contact_sheets"][0].get<std::string>());
  // Layout (docs/ICONS.md 6.3): 11 icons of at most 3 levels, 200 px cells.
  using namespace sandtable::render;
  const IconSheetOptions o;
  ASSERT_EQ(j["icons"].size(), 11u);
  ASSERT_EQ(img.width, 2 * kIconSheetMargin + 3 * (o.cell + kIconSheetMargin));
  ASSERT_EQ(img.height, kIconSheetMargin + 11 * (kIconSheetHeader + o.cell + kIconSheetFooter));
  for (std::uint32_t icon = 0; icon < 11; ++icon) {
    for (std::uint32_t level = 0; level < j["icons"][icon]["levels"].size(); ++level) {
      const std::uint32_t x = kIconSheetMargin + level * (o.cell + kIconSheetMargin);
      const std::uint32_t y = kIconSheetMargin + icon * (kIconSheetHeader + o.cell + kIconSheetFooter) +
                              kIconSheetHeader;
      const CellInk ink = inkOf(img, x, y, o.cell);
      SCOPED_TRACE("icon " + std::to_string(icon) + " level " + std::to_string(level));
      // Framed on the bounding sphere: visible, inside the cell, not clipped at its edges, about centred.
      EXPECT_GT(ink.pixels, std::size_t(o.cell) * o.cell / 40);
      EXPECT_GT(ink.minX, 0u);
      EXPECT_LT(ink.maxX, o.cell - 1);
      EXPECT_GT(ink.minY, 0u);
      EXPECT_LT(ink.maxY, o.cell - 1);
      EXPECT_NEAR(0.5 * (ink.minX + ink.maxX), 0.5 * o.cell, 0.15 * o.cell);
    }
  }
  // One model alone: one row with one cell per level of detail.
  const std::string model = data("models/assimp/jeep1.3ds");
  SANDTABLE_REQUIRE(std::filesystem::exists(model), "the models of ../shared/data: " << model);
  const auto m = runCli({"icons", "--model", model, "-o", t / "jeep", "--json"});
  ASSERT_EQ(m.exitCode, 0) << m.err;
  const auto mj = nlohmann::json::parse(m.out);
  const auto jeep = readPng(mj["contact_sheets"][0].get<std::string>());
  // The pack's levels: the report's, less any the build drops as no lighter than the one before.
  ASSERT_EQ((jeep.width - 2 * kIconSheetMargin) % (o.cell + kIconSheetMargin), 0u);
  const std::size_t columns = (jeep.width - 2 * kIconSheetMargin) / (o.cell + kIconSheetMargin);
  EXPECT_GE(columns, 2u);
  EXPECT_LE(columns, mj["levels"].size());
  EXPECT_EQ(jeep.height, kIconSheetMargin + kIconSheetHeader + o.cell + kIconSheetFooter);
  EXPECT_GT(inkOf(jeep, kIconSheetMargin, kIconSheetMargin + kIconSheetHeader, o.cell).pixels, 1000u);
}

TEST(IconsCli, theContactSheetDrawsTheModelsTextures) {
  const std::string defs = std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons-models.txt";
  SANDTABLE_REQUIRE(std::filesystem::exists(data("models/kenney-racing/vehicle-truck-red.glb")),
                    "the models of ../shared/data: " << data("models/kenney-racing/vehicle-truck-red.glb"));
  TempDir t("sheettex");
  const auto r = runCli({"icons", defs, "-o", t / "out", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["icons"][1]["name"], "truck");
  const auto img = readPng(j["contact_sheets"][0].get<std::string>());
  using namespace sandtable::render;
  const IconSheetOptions o;
  // The Kenney truck is white geometry coloured red by its palette texture.
  const std::uint32_t x0 = kIconSheetMargin, y0 = kIconSheetMargin + (kIconSheetHeader + o.cell + kIconSheetFooter) +
                                                  kIconSheetHeader;
  std::size_t red = 0;
  for (std::uint32_t y = y0; y < y0 + o.cell; ++y) {
    for (std::uint32_t x = x0; x < x0 + o.cell; ++x) {
      const std::uint8_t* p = &img.rgba[(std::size_t(y) * img.width + x) * 4];
      red += p[0] > 100 && p[0] > 2 * p[1] && p[0] > 2 * p[2];
    }
  }
  EXPECT_GT(red, 1500u) << "the truck is not red: its texture was not drawn";
}
