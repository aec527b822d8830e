// Icon textures: an image's bytes decoded through GDAL into RGBA layers,
// bottom row first, as GL samples them with the icons' texture
// coordinates; bytes that are no image fail with their name.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "../src/icon_textures.h"
#include "sandtable/render/image.h"

namespace sandtable::runtime::detail {
namespace {

namespace fs = std::filesystem;

std::vector<std::byte> pngOf(const Image& img) {
  const fs::path file = fs::temp_directory_path() / ("sandtable-tex." + std::to_string(::getpid()) + ".png");
  EXPECT_TRUE(writePng(file.string(), img).ok());
  std::ifstream in(file, std::ios::binary);
  const std::string s((std::istreambuf_iterator<char>(in)), {});
  fs::remove(file);
  const auto* b = reinterpret_cast<const std::byte*>(s.data());
  return {b, b + s.size()};
}

TEST(IconTextures, aPngDecodesBottomRowFirst) {
  // Top row red, green; bottom row blue, white (image order: top first).
  Image img{2, 2, {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 255}};
  auto rgba = decodeIconTexture(pngOf(img), "quad.png", 2);
  ASSERT_TRUE(rgba) << rgba.error();
  ASSERT_EQ(rgba->size(), 16u);
  const std::vector<std::uint8_t> want = {0, 0, 255, 255, 255, 255, 255, 255,   // t = 0: the image's bottom row
                                          255, 0, 0, 255, 0, 255, 0, 255};       // t = 1: its top row
  EXPECT_EQ(rgba.value(), want);
  // Resampled to 8 texels a side: the corners keep their colours.
  auto big = decodeIconTexture(pngOf(img), "quad.png", 8);
  ASSERT_TRUE(big);
  EXPECT_EQ(big.value()[0], 0);     // bottom-left: blue
  EXPECT_EQ(big.value()[2], 255);
  EXPECT_EQ(big.value()[(7 * 8 + 0) * 4], 255);  // top-left: red
  EXPECT_EQ(big.value()[(7 * 8 + 0) * 4 + 1], 0);
}

TEST(IconTextures, bytesThatAreNoImageFailWithTheirName) {
  const std::string junk = "not an image at all";
  auto r = decodeIconTexture(std::as_bytes(std::span(junk.data(), junk.size())), "colormap.png");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("colormap.png"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("base colour"), std::string::npos) << r.error();
  EXPECT_FALSE(decodeIconTexture({}, "empty.png"));
}

}  // namespace
}  // namespace sandtable::runtime::detail
