// Icon textures: an image's bytes decoded with libpng or libjpeg into RGBA
// layers, bottom row first, as GL samples them with the icons' texture
// coordinates; bytes that are no image fail with their name. GDAL, which
// the renderer no longer links, is the independent reference: images it
// wrote decode to the pixels it reads back, and the real models' textures
// decode as it decodes them.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>

#include "sandtable/testing/require.h"
#include "../src/icon_textures.h"
#include "sandtable/render/image.h"

namespace sandtable::render::detail {
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

std::vector<std::byte> fileBytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string s((std::istreambuf_iterator<char>(in)), {});
  const auto* b = reinterpret_cast<const std::byte*>(s.data());
  return {b, b + s.size()};
}

using GdalDataset = std::unique_ptr<GDALDataset>;

/// GDAL's view of image bytes, through a /vsimem/ file.
GdalDataset gdalOpen(const std::vector<std::byte>& bytes, const std::string& path) {
  GDALAllRegister();
  auto* data = reinterpret_cast<GByte*>(const_cast<std::byte*>(bytes.data()));
  VSIFCloseL(VSIFileFromMemBuffer(path.c_str(), data, vsi_l_offset(bytes.size()), FALSE));
  GdalDataset ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  VSIUnlink(path.c_str());
  return ds;
}

/// RGBA8, top row first, `w` x `h`, as GDAL reads `ds` (resampled
/// bilinearly when the size differs from the image's): colour tables
/// expanded, grey spread to RGB, alpha from the last band of 2 or 4, else
/// 255.
std::vector<std::uint8_t> gdalRgba(GDALDataset& ds, int w, int h) {
  const int bands = ds.GetRasterCount();
  std::vector<std::uint8_t> rgba(std::size_t(w) * h * 4, 255);
  GDALRasterIOExtraArg extra;
  INIT_RASTERIO_EXTRA_ARG(extra);
  extra.eResampleAlg = GRIORA_Bilinear;
  if (const GDALColorTable* table = ds.GetRasterBand(1)->GetColorTable()) {
    std::vector<std::uint8_t> index(std::size_t(w) * h);
    EXPECT_EQ(ds.GetRasterBand(1)->RasterIO(GF_Read, 0, 0, ds.GetRasterXSize(), ds.GetRasterYSize(), index.data(), w,
                                            h, GDT_Byte, 0, 0, nullptr),
              CE_None);
    for (std::size_t p = 0; p < index.size(); ++p) {
      const GDALColorEntry* e = table->GetColorEntry(index[p]);
      const short c[4] = {e->c1, e->c2, e->c3, e->c4};
      for (int k = 0; k < 4; ++k) rgba[p * 4 + std::size_t(k)] = std::uint8_t(c[k]);
    }
    return rgba;
  }
  for (int c = 0; c < 4; ++c) {
    int band = c < 3 ? (bands >= 3 ? c + 1 : 1) : (bands == 4 ? 4 : bands == 2 ? 2 : 0);
    if (band == 0) continue;
    EXPECT_EQ(ds.GetRasterBand(band)->RasterIO(GF_Read, 0, 0, ds.GetRasterXSize(), ds.GetRasterYSize(),
                                               rgba.data() + c, w, h, GDT_Byte, 4, GSpacing(w) * 4, &extra),
              CE_None);
  }
  return rgba;
}

/// Flips RGBA rows: GDAL's top row first against GL's bottom row first.
std::vector<std::uint8_t> flipped(std::vector<std::uint8_t> rgba, std::size_t w) {
  const std::size_t row = w * 4, h = rgba.size() / row;
  for (std::size_t a = 0, b = h - 1; a < b; ++a, --b) {
    std::swap_ranges(rgba.begin() + std::ptrdiff_t(a * row), rgba.begin() + std::ptrdiff_t((a + 1) * row),
                     rgba.begin() + std::ptrdiff_t(b * row));
  }
  return rgba;
}

/// An image file GDAL writes with `driver` from `bands` bands of
/// `w` x `h` pseudo-random (but smooth enough for JPEG) texels.
std::vector<std::byte> gdalWrites(const char* driver, int bands, bool palette, int w = 37, int h = 23) {
  GDALAllRegister();
  GdalDataset mem(GetGDALDriverManager()->GetDriverByName("MEM")->Create("", w, h, bands, GDT_Byte, nullptr));
  unsigned seed = 12345;
  for (int b = 1; b <= bands; ++b) {
    std::vector<std::uint8_t> v(std::size_t(w) * h);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        seed = seed * 1103515245u + 12345u;
        v[std::size_t(y) * w + x] = std::uint8_t((x * 7 + y * 5 * b + int(seed >> 28)) & 0xFF);
      }
    }
    EXPECT_EQ(mem->GetRasterBand(b)->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Byte, 0, 0, nullptr),
              CE_None);
  }
  if (palette) {
    GDALColorTable table;
    for (int i = 0; i < 256; ++i) {
      const GDALColorEntry e{short(i), short(255 - i), short((i * 3) & 0xFF), short(i < 128 ? 255 : i)};
      table.SetColorEntry(i, &e);
    }
    mem->GetRasterBand(1)->SetColorTable(&table);
  }
  const std::string path = "/vsimem/sandtable-test-" + std::to_string(::getpid()) + "-" + driver;
  GdalDataset file(GetGDALDriverManager()->GetDriverByName(driver)->CreateCopy(path.c_str(), mem.get(), FALSE,
                                                                               nullptr, nullptr, nullptr));
  EXPECT_TRUE(file) << driver;
  file.reset();
  vsi_l_offset size = 0;
  GByte* data = VSIGetMemFileBuffer(path.c_str(), &size, FALSE);
  const auto* b = reinterpret_cast<const std::byte*>(data);
  std::vector<std::byte> bytes(b, b + size);
  VSIUnlink(path.c_str());
  return bytes;
}

void expectAsGdalDecodes(const std::vector<std::byte>& bytes, const std::string& what) {
  auto ours = decodeImage(bytes, what);
  ASSERT_TRUE(ours) << ours.error();
  auto ds = gdalOpen(bytes, "/vsimem/sandtable-ref-" + std::to_string(::getpid()));
  ASSERT_TRUE(ds) << what;
  ASSERT_EQ(ours->width, unsigned(ds->GetRasterXSize())) << what;
  ASSERT_EQ(ours->height, unsigned(ds->GetRasterYSize())) << what;
  EXPECT_TRUE(ours->rgba == gdalRgba(*ds, ds->GetRasterXSize(), ds->GetRasterYSize())) << what;
}

TEST(IconTextures, imagesGdalWroteDecodeToThePixelsGdalReads) {
  expectAsGdalDecodes(gdalWrites("PNG", 3, false), "RGB PNG");
  expectAsGdalDecodes(gdalWrites("PNG", 4, false), "RGBA PNG");
  expectAsGdalDecodes(gdalWrites("PNG", 1, false), "grey PNG");
  expectAsGdalDecodes(gdalWrites("PNG", 2, false), "grey and alpha PNG");
  expectAsGdalDecodes(gdalWrites("PNG", 1, true), "palette PNG with alpha");
  expectAsGdalDecodes(gdalWrites("JPEG", 3, false), "colour JPEG");
  expectAsGdalDecodes(gdalWrites("JPEG", 1, false), "grey JPEG");
}

fs::path sharedModels() { return fs::path(SANDTABLE_SOURCE_DIR) / ".." / "shared" / "data" / "models"; }

TEST(IconTextures, theModelsTexturesDecodeAsGdalDecodesThem) {
  // A progressive JPEG (the jeep's) and an RGBA PNG (the Kenney palette).
  for (const char* name : {"assimp/jeep1.jpg", "kenney-racing/Textures/colormap.png"}) {
    const fs::path file = sharedModels() / name;
    SANDTABLE_REQUIRE(fs::exists(file), file << " (the real models in ../shared/data/models)");
    const auto bytes = fileBytes(file);
    expectAsGdalDecodes(bytes, name);
    // Resampled to the layer size: GDAL's bilinear kernel, to rounding. GDAL
    // resamples its own decode held in memory (the JPEG driver would read a
    // DCT-scaled overview instead, another kernel).
    auto ours = decodeIconTexture(bytes, name);
    ASSERT_TRUE(ours) << ours.error();
    auto ds = gdalOpen(bytes, "/vsimem/sandtable-ref-" + std::to_string(::getpid()));
    ASSERT_TRUE(ds);
    const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
    auto full = gdalRgba(*ds, w, h);
    GdalDataset mem(GetGDALDriverManager()->GetDriverByName("MEM")->Create("", w, h, 4, GDT_Byte, nullptr));
    ASSERT_EQ(mem->RasterIO(GF_Write, 0, 0, w, h, full.data(), w, h, GDT_Byte, 4, nullptr, 4, GSpacing(w) * 4, 1,
                            nullptr),
              CE_None);
    const int n = int(kIconTextureTexels);
    const auto want = flipped(gdalRgba(*mem, n, n), kIconTextureTexels);
    ASSERT_EQ(ours->size(), want.size());
    int worst = 0;
    std::size_t off = 0;
    for (std::size_t k = 0; k < want.size(); ++k) {
      const int d = std::abs(int(ours.value()[k]) - int(want[k]));
      if (d > worst) worst = d, off = k;
    }
    RecordProperty(std::string("worst_difference_") + fs::path(name).extension().string().substr(1), worst);
    EXPECT_LE(worst, 1) << name << ": texel " << off / 4 << " channel " << off % 4;
  }
}

TEST(IconTextures, otherFormatsAndDamagedBytesFailNamingTheTexture) {
  auto bmp = decodeImage(gdalWrites("BMP", 3, false), "old.bmp");
  ASSERT_FALSE(bmp);
  EXPECT_NE(bmp.error().find("old.bmp"), std::string::npos) << bmp.error();
  EXPECT_NE(bmp.error().find("neither PNG nor JPEG"), std::string::npos) << bmp.error();
  for (const char* driver : {"PNG", "JPEG"}) {
    auto bytes = gdalWrites(driver, 3, false);
    for (std::size_t cut : {std::size_t(8), std::size_t(40), bytes.size() / 2}) {
      std::vector<std::byte> part(bytes.begin(), bytes.begin() + std::ptrdiff_t(cut));
      auto r = decodeImage(part, "cut");
      EXPECT_FALSE(r) << driver << " cut at " << cut;
      if (!r) {
        EXPECT_NE(r.error().find("base colour"), std::string::npos) << r.error();
      }
    }
  }
}

TEST(IconTextures, anImageHeaderPastTheLimitIsRefusedBeforeDecoding) {
  // A PNG header claiming 100000 x 100000 texels and nothing after it.
  auto bytes = gdalWrites("PNG", 3, false, 1, 1);
  auto put = [&](std::size_t at, std::uint32_t v) {
    for (int k = 0; k < 4; ++k) bytes[at + std::size_t(k)] = std::byte((v >> (24 - 8 * k)) & 0xFF);
  };
  put(16, 100000);  // IHDR width and height
  put(20, 100000);
  put(29, std::uint32_t(crc32(0, reinterpret_cast<const Bytef*>(bytes.data()) + 12, 17)));  // type and data
  auto r = decodeImage(bytes, "huge.png");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("huge.png"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("100000 x 100000 texels is past the limit"), std::string::npos) << r.error();
}

}  // namespace
}  // namespace sandtable::render::detail
