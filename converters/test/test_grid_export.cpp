// exportGridGeoTiff (grid_export.h): read back through GDAL, every post's
// float bits, the point georeferencing (GDAL's geotransform and the file's
// own PixelIsPoint tie point), the CRS, the creation options, the atomic
// replace, the cancel that leaves nothing and a directory that cannot be
// written. The end-to-end test on a real database is tests/test_grid_export.cpp.
#include "sandtable/converters/grid_export.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <bit>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <cpl_conv.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include "sandtable/base/hash.h"
#include "sandtable/converters/crs.h"

namespace sandtable::convert {
namespace {

namespace fs = std::filesystem;

/// A field of odd floats (fractions, negatives, -0, a subnormal), none of
/// them on a smooth surface, so a predictor that lost a bit would show.
class OddField final : public grid::HeightField {
 public:
  OddField(std::uint32_t nx, std::uint32_t nz) { layout_ = {nx, nz, 12.5, 512345.25, 4812000.75}; }
  const grid::PostLayout& layout() const override { return layout_; }
  float elevation(std::uint32_t i, std::uint32_t j) const override {
    if (i == 1 && j == 0) return -0.0f;
    if (i == 2 && j == 0) return 1e-40f;  // subnormal
    const std::uint64_t h = hash::mix(std::uint64_t(i) << 32 | j);
    return float(double(h % 2000000) / 1000.0 - 400.0) + float(h >> 60) * 1e-4f;
  }
  std::array<float, 3> normal(std::uint32_t, std::uint32_t) const override { return {0, 1, 0}; }
  std::uint8_t material(std::uint32_t, std::uint32_t) const override { return 0; }
  std::pair<float, float> elevationBounds() const override { return {-400, 1600}; }
  std::uint64_t generation() const override { return 0; }
  std::uint64_t regionGeneration(const grid::PostRect&) const override { return 0; }

 private:
  grid::PostLayout layout_;
};

/// WKT2 of EPSG:32632 (WGS 84 / UTM 32N), as a manifest holds it.
std::string utm32Wkt() {
  OGRSpatialReferenceH s = OSRNewSpatialReference(nullptr);
  EXPECT_EQ(OSRImportFromEPSG(s, 32632), OGRERR_NONE);
  char* wkt = nullptr;
  const char* opts[] = {"FORMAT=WKT2_2019", nullptr};
  OSRExportToWktEx(s, &wkt, opts);
  std::string out = wkt ? wkt : "";
  CPLFree(wkt);
  OSRDestroySpatialReference(s);
  return out;
}

struct Scratch {
  fs::path dir = fs::temp_directory_path() / ("sandtable_grid_export_" + std::to_string(::getpid()));
  Scratch() {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::vector<std::string> names() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
    return out;
  }
};

std::vector<float> readAll(GDALDatasetH ds) {
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  std::vector<float> v(std::size_t(w) * h);
  EXPECT_EQ(GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Read, 0, 0, w, h, v.data(), w, h, GDT_Float32, 0, 0), CE_None);
  return v;
}

TEST(GridExport, everyPostReadsBackBitForBitAtItsPoint) {
  Scratch s;
  // 300 x 270: a second row and column of 256-post tiles, partly filled.
  const OddField field(300, 270);
  const std::string out = (s.dir / "ground.tif").string();
  const std::string wkt = utm32Wkt();
  double lastFraction = 0;
  Work work;
  work.progress = [&](double f, const std::string& stage) {
    EXPECT_EQ(stage, "writing grid");
    EXPECT_GE(f, lastFraction);
    lastFraction = f;
  };
  const auto r = exportGridGeoTiff(field, wkt, out, work);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(lastFraction, 1.0);
  EXPECT_EQ(r->path, out);
  EXPECT_EQ(r->postsX, 300u);
  EXPECT_EQ(r->postsZ, 270u);
  EXPECT_EQ(r->posts, 81000u);
  EXPECT_EQ(r->bytes, fs::file_size(out));
  EXPECT_EQ(s.names(), std::vector<std::string>{"ground.tif"});  // no temporary, no .aux.xml

  GDALDatasetH ds = GDALOpen(out.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  EXPECT_STREQ(GDALGetDriverShortName(GDALGetDatasetDriver(ds)), "GTiff");
  ASSERT_EQ(GDALGetRasterCount(ds), 1);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  EXPECT_EQ(GDALGetRasterDataType(band), GDT_Float32);
  int bx = 0, by = 0;
  GDALGetBlockSize(band, &bx, &by);
  EXPECT_EQ(bx, 256);
  EXPECT_EQ(by, 256);
  int hasNoData = 1;
  GDALGetRasterNoDataValue(band, &hasNoData);
  EXPECT_FALSE(hasNoData);
  EXPECT_STREQ(GDALGetRasterUnitType(band), "m");
  EXPECT_STREQ(GDALGetMetadataItem(ds, "AREA_OR_POINT", nullptr), "Point");
  EXPECT_STREQ(GDALGetMetadataItem(ds, "COMPRESSION", "IMAGE_STRUCTURE"), "DEFLATE");
  EXPECT_STREQ(GDALGetMetadataItem(ds, "PREDICTOR", "IMAGE_STRUCTURE"), "3");

  // GDAL's model: the corner of pixel (0, 0), half a spacing outside the
  // north-west post; pixel (i, j)'s centre is post (i, j).
  double gt[6];
  ASSERT_EQ(GDALGetGeoTransform(ds, gt), CE_None);
  EXPECT_EQ(gt[0], 512345.25 - 6.25);
  EXPECT_EQ(gt[1], 12.5);
  EXPECT_EQ(gt[2], 0);
  EXPECT_EQ(gt[3], 4812000.75 + 6.25);
  EXPECT_EQ(gt[4], 0);
  EXPECT_EQ(gt[5], -12.5);
  for (const auto& [i, j] : {std::pair{0, 0}, std::pair{299, 0}, std::pair{0, 269}, std::pair{137, 211}}) {
    EXPECT_EQ(gt[0] + (i + 0.5) * gt[1], 512345.25 + i * 12.5);
    EXPECT_EQ(gt[3] + (j + 0.5) * gt[5], 4812000.75 - j * 12.5);
  }

  OGRSpatialReferenceH want = OSRNewSpatialReference(wkt.c_str());
  OGRSpatialReferenceH got = OSRNewSpatialReference(GDALGetProjectionRef(ds));
  EXPECT_TRUE(OSRIsSame(want, got)) << GDALGetProjectionRef(ds);
  EXPECT_EQ(std::string(OSRGetAuthorityCode(got, nullptr) ? OSRGetAuthorityCode(got, nullptr) : ""), "32632");
  OSRDestroySpatialReference(want);
  OSRDestroySpatialReference(got);

  const std::vector<float> v = readAll(ds);
  GDALClose(ds);
  std::uint64_t differ = 0;
  for (std::uint32_t j = 0; j < 270; ++j) {
    for (std::uint32_t i = 0; i < 300; ++i) {
      differ += std::bit_cast<std::uint32_t>(v[std::size_t(j) * 300 + i]) !=
                std::bit_cast<std::uint32_t>(field.elevation(i, j));
    }
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_TRUE(std::signbit(v[1]));

  // The file's own tie point (GDAL told not to shift it) is the north-west
  // post itself: the raster is PixelIsPoint in GeoTIFF terms too.
  CPLSetThreadLocalConfigOption("GTIFF_POINT_GEO_IGNORE", "TRUE");
  GDALDatasetH raw = GDALOpen(out.c_str(), GA_ReadOnly);
  CPLSetThreadLocalConfigOption("GTIFF_POINT_GEO_IGNORE", nullptr);
  ASSERT_NE(raw, nullptr);
  ASSERT_EQ(GDALGetGeoTransform(raw, gt), CE_None);
  EXPECT_EQ(gt[0], 512345.25);
  EXPECT_EQ(gt[3], 4812000.75);
  GDALClose(raw);
}

TEST(GridExport, replacesAtomicallyAndCancelLeavesTheOldFile) {
  Scratch s;
  const std::string out = (s.dir / "g.tif").string();
  { std::ofstream(out) << "old"; }
  const OddField big(64, 600);  // three bands of rows
  std::atomic<bool> cancel{false};
  Work work;
  work.cancel = &cancel;
  work.progress = [&](double, const std::string&) { cancel = true; };  // after the first band
  const auto c = exportGridGeoTiff(big, utm32Wkt(), out, work);
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.message(), kGridExportCancelled);
  EXPECT_EQ(s.names(), std::vector<std::string>{"g.tif"});
  std::ifstream in(out);
  std::string text;
  in >> text;
  EXPECT_EQ(text, "old");

  const auto r = exportGridGeoTiff(big, utm32Wkt(), out);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(s.names(), std::vector<std::string>{"g.tif"});
  GDALDatasetH ds = GDALOpen(out.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(GDALGetRasterXSize(ds), 64);
  EXPECT_EQ(GDALGetRasterYSize(ds), 600);
  GDALClose(ds);
}

TEST(GridExport, problemsNameThePathAndSayWhy) {
  Scratch s;
  const OddField field(10, 10);
  const std::string missing = (s.dir / "no" / "such" / "g.tif").string();
  const auto r = exportGridGeoTiff(field, utm32Wkt(), missing);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.problems()[0].file, missing);
  EXPECT_NE(r.message().find("export: cannot create"), std::string::npos) << r.message();

  const auto bad = exportGridGeoTiff(field, "not a CRS", (s.dir / "g.tif").string());
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("CRS does not read"), std::string::npos) << bad.message();
  EXPECT_TRUE(s.names().empty());

  const OddField line(1, 10);
  const auto thin = exportGridGeoTiff(line, utm32Wkt(), (s.dir / "g.tif").string());
  ASSERT_FALSE(thin.ok());
  EXPECT_NE(thin.message().find("1 x 10 posts"), std::string::npos) << thin.message();
}

}  // namespace
}  // namespace sandtable::convert
