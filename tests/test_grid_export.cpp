// `sandtable export DB --grid -o ground.tif` on real data (Monaco's SRTM at
// 30 m): GDAL reads every post back with the grid file's float bits, puts
// pixel (i, j) on post (i, j) (gdalinfo's corners, gdallocationinfo's
// lookup, `sample` at the same easting and northing), names the manifest's
// CRS (UTM and a Cassini without an EPSG code), and agrees with the SRTM
// source warped by GDAL onto the file's own georeferencing, which a half-post
// shift would not. The difference of two exports (before and after a
// crater) computed through GDAL is the profile's change at each post, as
// docs/EXPORT.md shows with gdal_calc.py. Ctrl-C exits 130 and errors exit 2,
// and neither leaves a file behind.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <filesystem>

#include <cpl_conv.h>
#include <gdal.h>
#include <gdal_utils.h>
#include <nlohmann/json.hpp>
#include <ogr_srs_api.h>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/grid_export.h"
#include "sandtable/edits/profile.h"
#include "sandtable/formats/database.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/testing/process.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;

const char* const kMonacoExtent[] = {"7.40", "43.72", "7.44", "43.75"};

/// A Monaco database at 30 m in `crs`, built once per CRS for the suite.
std::string monaco(const std::string& crs) {
  static const TempDir tmp("gridexport");  // removed at exit
  const std::string db = tmp / ("monaco-" + crs);
  if (fs::exists(db + "/manifest.json")) return db;
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--extent", kMonacoExtent[0],
                         kMonacoExtent[1], kMonacoExtent[2], kMonacoExtent[3], "--spacing", "30", "--crs", crs, "-o",
                         db});
  EXPECT_EQ(b.exitCode, 0) << b.err;
  return db;
}

std::vector<float> readBand(GDALDatasetH ds) {
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  std::vector<float> v(std::size_t(w) * std::size_t(h));
  EXPECT_EQ(GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Read, 0, 0, w, h, v.data(), w, h, GDT_Float32, 0, 0), CE_None);
  return v;
}

bool sameCrs(const std::string& a, const std::string& b) {
  OGRSpatialReferenceH x = OSRNewSpatialReference(a.c_str()), y = OSRNewSpatialReference(b.c_str());
  const bool same = x && y && OSRIsSame(x, y);
  OSRDestroySpatialReference(x);
  OSRDestroySpatialReference(y);
  return same;
}

/// gdalinfo -json of `path`, through GDALInfo (the library side of gdalinfo).
nlohmann::json gdalinfoJson(GDALDatasetH ds) {
  const char* argv[] = {"-json", nullptr};
  GDALInfoOptions* o = GDALInfoOptionsNew(const_cast<char**>(argv), nullptr);
  char* text = GDALInfo(ds, o);
  GDALInfoOptionsFree(o);
  nlohmann::json j = nlohmann::json::parse(text ? text : "null");
  CPLFree(text);
  return j;
}

TEST(GridExport, everyPostIsTheGridsFloatOnItsPostInTheManifestsCrs) {
  SANDTABLE_REQUIRE_DATA();
  convert::initGdal();
  const std::string db = monaco("utm");
  TempDir t("gridout");
  const std::string out = t / "ground.tif";
  const auto e = runCli({"export", db, "--grid", "-o", out, "--json"});
  ASSERT_EQ(e.exitCode, 0) << e.err;
  const auto j = nlohmann::json::parse(e.out);
  auto opened = openDatabase(db);
  ASSERT_TRUE(opened.ok()) << opened.error();
  const manifest::Manifest& m = opened->manifest;
  const grid::GridFile& g = *opened->grid;
  EXPECT_EQ(j["path"], out);
  EXPECT_EQ(j["size"], nlohmann::json({g.postsX(), g.postsZ()}));
  EXPECT_EQ(j["posts"], std::uint64_t(g.postsX()) * g.postsZ());
  EXPECT_EQ(j["bytes"], fs::file_size(out));
  EXPECT_EQ(j["epsg"], m.epsg);
  EXPECT_EQ(filesUnder(t.path(), {""}).size(), 1u);  // the file alone: no temporary, no .aux.xml

  GDALDatasetH ds = GDALOpen(out.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  ASSERT_EQ(GDALGetRasterXSize(ds), int(g.postsX()));
  ASSERT_EQ(GDALGetRasterYSize(ds), int(g.postsZ()));
  const std::vector<float> v = readBand(ds);
  std::uint64_t differ = 0;
  for (std::uint32_t jz = 0; jz < g.postsZ(); ++jz) {
    for (std::uint32_t i = 0; i < g.postsX(); ++i) {
      differ += std::bit_cast<std::uint32_t>(v[std::size_t(jz) * g.postsX() + i]) !=
                std::bit_cast<std::uint32_t>(g.elevation(i, jz));
    }
  }
  EXPECT_EQ(differ, 0u) << "posts whose float differs from grid.stg";

  // gdalinfo: the manifest's CRS, a point raster, corners half a post outside
  // the outer posts (GDAL's corners are pixel edges), no NoData.
  const auto info = gdalinfoJson(ds);
  EXPECT_TRUE(sameCrs(info["coordinateSystem"]["wkt"].get<std::string>(), m.crsWkt));
  EXPECT_EQ(info["metadata"][""]["AREA_OR_POINT"], "Point");
  EXPECT_EQ(info["bands"][0]["type"], "Float32");
  EXPECT_FALSE(info["bands"][0].contains("noDataValue"));
  const double h = 0.5 * m.spacing;
  EXPECT_EQ(info["cornerCoordinates"]["upperLeft"], nlohmann::json({m.originEasting - h, m.originNorthing + h}));
  EXPECT_EQ(info["cornerCoordinates"]["lowerRight"], nlohmann::json({m.eastEasting() + h, m.southNorthing() - h}));

  // gdallocationinfo's lookup (the inverse geotransform, floored) at a post's
  // easting and northing lands in that post's pixel, at its centre; `sample`
  // there gives the same height.
  double gt[6], inv[6];
  ASSERT_EQ(GDALGetGeoTransform(ds, gt), CE_None);
  ASSERT_TRUE(GDALInvGeoTransform(gt, inv));
  const std::uint32_t lastI = g.postsX() - 1, lastJ = g.postsZ() - 1;
  for (const auto& [i, jz] : {std::pair{0u, 0u}, std::pair{lastI, lastJ}, std::pair{lastI / 3, lastJ / 2}}) {
    const double east = m.originEasting + i * m.spacing, north = m.originNorthing - jz * m.spacing;
    double px = 0, py = 0;
    GDALApplyGeoTransform(inv, east, north, &px, &py);
    EXPECT_EQ(std::floor(px), double(i));
    EXPECT_EQ(std::floor(py), double(jz));
    EXPECT_NEAR(px - i, 0.5, 1e-9);
    EXPECT_NEAR(py - jz, 0.5, 1e-9);
    const auto s = runCli({"sample", db, "--xy", std::to_string(east), std::to_string(north), "--json"});
    ASSERT_EQ(s.exitCode, 0) << s.err;
    EXPECT_NEAR(nlohmann::json::parse(s.out)["elevation"].get<double>(), v[std::size_t(jz) * g.postsX() + i], 1e-4)
        << s.out;
  }
  GDALClose(ds);
}

/// RMS of (export - SRTM warped bilinearly by GDAL onto the export's grid
/// moved by (dx, dy) pixels), over the posts the SRTM's voids (-32768, near
/// Monaco's cliffs) leave out of the warp.
double rmsAgainstSource(GDALDatasetH exported, double dx, double dy) {
  const int w = GDALGetRasterXSize(exported), h = GDALGetRasterYSize(exported);
  double gt[6];
  GDALGetGeoTransform(exported, gt);
  gt[0] += dx * gt[1];
  gt[3] += dy * gt[5];
  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", w, h, 1, GDT_Float32, nullptr);
  GDALSetGeoTransform(mem, gt);
  GDALSetProjection(mem, GDALGetProjectionRef(exported));
  constexpr double kVoid = -32768;
  GDALFillRaster(GDALGetRasterBand(mem, 1), kVoid, 0);
  const std::string src = "/vsizip/" + data("elevation/srtm/N43E007.hgt.zip") + "/N43E007.hgt";
  GDALDatasetH srtm = GDALOpen(src.c_str(), GA_ReadOnly);
  EXPECT_NE(srtm, nullptr) << src;
  if (!srtm) return NAN;
  const char* argv[] = {"-r", "bilinear", "-srcnodata", "-32768", "-dstnodata", "-32768", nullptr};
  GDALWarpAppOptions* o = GDALWarpAppOptionsNew(const_cast<char**>(argv), nullptr);
  int usage = 0;
  EXPECT_NE(GDALWarp(nullptr, mem, 1, &srtm, o, &usage), nullptr);
  GDALWarpAppOptionsFree(o);
  GDALClose(srtm);
  const std::vector<float> warped = readBand(mem), ours = readBand(exported);
  GDALClose(mem);
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < ours.size(); ++k) {
    if (warped[k] == kVoid) continue;
    sum += double(ours[k] - warped[k]) * double(ours[k] - warped[k]);
    ++n;
  }
  EXPECT_GT(n, ours.size() * 9 / 10);
  return std::sqrt(sum / double(n));
}

TEST(GridExport, theSourceWarpedOntoTheFilesGeoreferencingAgreesWithIt) {
  SANDTABLE_REQUIRE_DATA();
  convert::initGdal();
  const std::string db = monaco("utm");
  TempDir t("gridwarp");
  ASSERT_EQ(runCli({"export", db, "--grid", "-o", t / "g.tif"}).exitCode, 0);
  GDALDatasetH ds = GDALOpen((t / "g.tif").c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  // Independent of the builder: GDAL places the SRTM posts by the file's
  // geotransform and CRS alone. The build's own accuracy (`info`) is a few
  // tenths of a metre; half a post off (the area/point mix-up) is metres on
  // Monaco's slopes.
  const double onPosts = rmsAgainstSource(ds, 0, 0);
  const double halfOff = rmsAgainstSource(ds, 0.5, 0.5);
  GDALClose(ds);
  std::printf("[ grid export ] RMS against SRTM warped by GDAL: %.3f m on the posts, %.3f m half a post off\n", onPosts,
              halfOff);
  EXPECT_LT(onPosts, 0.75);
  EXPECT_GT(halfOff, 3 * onPosts);
}

TEST(GridExport, aCassiniDatabaseWithoutAnEpsgCodeKeepsItsCrs) {
  SANDTABLE_REQUIRE_DATA();
  convert::initGdal();
  const std::string db = monaco("cassini");
  TempDir t("gridcassini");
  const auto e = runCli({"export", db, "--grid", "-o", t / "c.tiff"});
  ASSERT_EQ(e.exitCode, 0) << e.err;
  EXPECT_NE(e.out.find("wrote " + (t / "c.tiff") + ": "), std::string::npos) << e.out;
  auto opened = openDatabase(db);
  ASSERT_TRUE(opened.ok()) << opened.error();
  EXPECT_EQ(opened->manifest.epsg, 0);
  GDALDatasetH ds = GDALOpen((t / "c.tiff").c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  EXPECT_TRUE(sameCrs(GDALGetProjectionRef(ds), opened->manifest.crsWkt)) << GDALGetProjectionRef(ds);
  GDALClose(ds);
}

/// The grid with one crater dug by the profile (edits/profile.h): what an
/// edited HeightField exports as.
class CraterField final : public grid::HeightField {
 public:
  CraterField(const grid::HeightField& base, edit::Edit crater) : base_(base), e_(std::move(crater)) {}
  const grid::PostLayout& layout() const override { return base_.layout(); }
  float elevation(std::uint32_t i, std::uint32_t j) const override {
    const float before = base_.elevation(i, j);
    return float(edits::newHeight(e_, i * spacing(), j * spacing(), before));
  }
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const override { return base_.normal(i, j); }
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const override { return base_.material(i, j); }
  std::pair<float, float> elevationBounds() const override { return base_.elevationBounds(); }
  std::uint64_t generation() const override { return 1; }
  std::uint64_t regionGeneration(const grid::PostRect&) const override { return 1; }

 private:
  const grid::HeightField& base_;
  edit::Edit e_;
};

TEST(GridExport, theDifferenceOfTwoExportsThroughGdalIsTheEdit) {
  SANDTABLE_REQUIRE_DATA();
  convert::initGdal();
  const std::string db = monaco("utm");
  TempDir t("griddiff");
  ASSERT_EQ(runCli({"export", db, "--grid", "-o", t / "before.tif"}).exitCode, 0);
  auto opened = openDatabase(db);
  ASSERT_TRUE(opened.ok()) << opened.error();
  const grid::GridHeightField base(*opened->grid);
  edit::Edit crater;
  crater.kind = edit::Kind::crater;
  crater.points = {{40 * base.spacing(), 50 * base.spacing()}};  // on post (40, 50)
  crater.radius = 75;
  crater.depth = 8;
  const CraterField after(base, crater);
  const auto w = convert::exportGridGeoTiff(after, opened->manifest.crsWkt, t / "after.tif");
  ASSERT_TRUE(w.ok()) << w.error();

  // docs/EXPORT.md: gdal_calc.py -A after.tif -B before.tif --calc="A-B"; here
  // through GDAL's API.
  GDALDatasetH a = GDALOpen((t / "after.tif").c_str(), GA_ReadOnly);
  GDALDatasetH b = GDALOpen((t / "before.tif").c_str(), GA_ReadOnly);
  ASSERT_TRUE(a && b);
  const std::vector<float> va = readBand(a), vb = readBand(b);
  GDALClose(a);
  GDALClose(b);
  const std::uint32_t nx = base.postsX();
  std::uint64_t changed = 0, wrong = 0;
  for (std::size_t k = 0; k < va.size(); ++k) {
    const std::uint32_t i = std::uint32_t(k % nx), jz = std::uint32_t(k / nx);
    const float want = float(edits::newHeight(crater, i * base.spacing(), jz * base.spacing(), vb[k])) - vb[k];
    wrong += std::bit_cast<std::uint32_t>(va[k] - vb[k]) != std::bit_cast<std::uint32_t>(want);
    changed += va[k] != vb[k];
  }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GT(changed, 20u);  // radius 75 m, rim to 150 m: dozens of 30 m posts
  EXPECT_FLOAT_EQ(va[50 * nx + 40] - vb[50 * nx + 40], -8.0f);
}

TEST(GridExport, ctrlCStopsABigExportAndLeavesNothing) {
  SANDTABLE_REQUIRE_DATA();
  // The whole N49E011 tile at 30 m: 8.3 M posts, 15 bands of 256 rows, with
  // progress (4 M posts or more). Ctrl-C once the first band is out.
  TempDir t("gridint");
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--spacing", "30",
                         "--no-modules", "-o", t / "db"});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const std::string script = std::string(SANDTABLE_CLI) + " export '" + (t / "db") + "' --grid -o '" + (t / "g.tif") +
                             "' 2>'" + (t / "err") + "' & p=$!; "
                             "while kill -0 $p 2>/dev/null && ! grep -q 'writing grid' '" + (t / "err") +
                             "'; do sleep 0.01; done; "
                             "kill -INT $p; wait $p; echo $?";
  const std::string rc = fixtures::commandOutput(script);
  EXPECT_EQ(rc, "130\n");
  const std::string err = slurpFile(t / "err");
  EXPECT_NE(err.find("cancelled by signal 2; nothing was written to " + (t / "g.tif")), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(t / "g.tif"));
  for (const auto& e : fs::directory_iterator(t.path())) {
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
  }
}

TEST(GridExport, badRequestsExitTwoAndLeaveNothing) {
  SANDTABLE_REQUIRE_DATA();
  const std::string db = monaco("utm");
  TempDir t("griderr");
  const auto obj = runCli({"export", db, "--grid", "-o", t / "g.obj"});
  EXPECT_EQ(obj.exitCode, 2);
  EXPECT_NE(obj.err.find("--grid writes a GeoTIFF; give an output ending in .tif or .tiff"), std::string::npos)
      << obj.err;
  const auto mixed = runCli({"export", db, "--grid", "--module", "0", "0", "-o", t / "g.tif"});
  EXPECT_EQ(mixed.exitCode, 2);
  EXPECT_NE(mixed.err.find("--grid"), std::string::npos) << mixed.err;
  const auto nowhere = runCli({"export", db, "--grid", "-o", t / "no/such/dir/g.tif"});
  EXPECT_EQ(nowhere.exitCode, 2);
  EXPECT_NE(nowhere.err.find("export: cannot create"), std::string::npos) << nowhere.err;
  const auto notDb = runCli({"export", t.path(), "--grid", "-o", t / "g.tif"});
  EXPECT_EQ(notDb.exitCode, 2);
  EXPECT_TRUE(filesUnder(t.path(), {""}).empty());
}

}  // namespace
}  // namespace sandtable::test
