// The elevation stage's own bilinear kernel against GDAL's, and the banded
// stage against the whole-grid one, on real data (../shared/data).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include <gdal_priv.h>
#include <gdal_utils.h>

#include "sandtable/converters/elevation.h"
#include "sandtable/formats/grid.h"
#include "sandtable/testing/require.h"

namespace sandtable::convert {
namespace {

namespace fs = std::filesystem;

std::string dataFile(const std::string& rel) { return std::string(SANDTABLE_SOURCE_DIR) + "/../shared/data/" + rel; }

#define REQUIRE_FILE(path) SANDTABLE_REQUIRE(fs::exists(path), "real data at " << (path))

struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& tag) {
    path = fs::temp_directory_path() / ("sandtable-" + tag + "-" + std::to_string(::getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  std::string operator/(const std::string& s) const { return (path / s).string(); }
};

ElevationOptions gridOnly(const std::string& file, const std::string& out) {
  ElevationOptions o;
  o.sources = {file};
  o.output = out;
  o.modules = false;
  return o;
}

std::vector<char> slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

/// GDAL's own bilinear warp of `file` onto the build's grid, with exact
/// transforms (-et 0), an independent computation of what our kernel does.
std::vector<float> gdalBilinear(const std::string& file, const manifest::Manifest& m) {
  GDALAllRegister();
  std::vector<float> out(std::size_t(m.postsX) * m.postsZ, NAN);
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> dst(mem->Create("", int(m.postsX), int(m.postsZ), 1, GDT_Float32, nullptr));
  const double s = m.spacing;
  double g[6] = {m.originEasting - s / 2, s, 0, m.originNorthing + s / 2, 0, -s};
  dst->SetGeoTransform(g);
  dst->SetProjection(m.crsWkt.c_str());
  dst->GetRasterBand(1)->SetNoDataValue(NAN);
  dst->GetRasterBand(1)->Fill(NAN);
  GDALDatasetH src = GDALOpen(file.c_str(), GA_ReadOnly);
  EXPECT_NE(src, nullptr);
  const char* args[] = {"-r", "bilinear", "-et", "0", "-q", nullptr};
  GDALWarpAppOptions* opts = GDALWarpAppOptionsNew(const_cast<char**>(args), nullptr);
  int usage = 0;
  GDALDatasetH res = GDALWarp(nullptr, GDALDataset::ToHandle(dst.get()), 1, &src, opts, &usage);
  GDALWarpAppOptionsFree(opts);
  EXPECT_NE(res, nullptr);
  GDALClose(src);
  EXPECT_EQ(dst->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, int(m.postsX), int(m.postsZ), out.data(), int(m.postsX),
                                            int(m.postsZ), GDT_Float32, 0, 0),
            CE_None);
  return out;
}

struct Case {
  const char* file;
  std::array<double, 4> extent;  ///< west south east north; all 0 = whole file
  double spacing;                ///< 0 = native
  double maxM, rmsM;             ///< tolerances (docs/ARCHITECTURE.md, stage 6)
};

class BilinearAgainstGdal : public ::testing::TestWithParam<Case> {};

TEST_P(BilinearAgainstGdal, postsMatchGdalWarpBilinear) {
  const Case c = GetParam();
  const std::string file = dataFile(c.file);
  REQUIRE_FILE(file);
  TempDir tmp("bilinear");
  ElevationOptions o = gridOnly(file, tmp / "db");
  o.resample = "bilinear";
  o.fit = "posts";
  o.spacing = c.spacing;
  o.seaFromVoids = false;
  if (c.extent[2] != c.extent[0]) o.extent = c.extent;
  auto r = buildElevation(o, nullptr);
  ASSERT_TRUE(r.ok()) << r.error();
  auto grid = grid::GridFile::open(o.output + "/grid.stg");
  ASSERT_TRUE(grid.ok()) << grid.error();
  const auto& m = r->manifest;
  const std::vector<float> ref = gdalBilinear(file, m);
  std::size_t n = 0, onlyOurs = 0, onlyGdal = 0;
  double sum2 = 0, maxAbs = 0;
  for (std::uint32_t j = 0; j < m.postsZ; ++j) {
    for (std::uint32_t i = 0; i < m.postsX; ++i) {
      const float want = ref[std::size_t(j) * m.postsX + i];
      const bool filled = grid.value()->material(i, j) == 2;  // a void ours filled
      const bool gdalValid = std::isfinite(want) && want > -12000 && want < 9000;
      if (!gdalValid || filled) {
        if (gdalValid && filled) ++onlyGdal;
        if (!gdalValid && !filled) ++onlyOurs;
        continue;
      }
      const double e = double(grid.value()->elevation(i, j)) - want;
      sum2 += e * e;
      maxAbs = std::max(maxAbs, std::fabs(e));
      ++n;
    }
  }
  const double rms = n ? std::sqrt(sum2 / double(n)) : 0;
  std::printf("[ bilinear ] %s at %.2f m: %zu posts, RMS %.5f m, max %.4f m; valid only in ours %zu, only in GDAL's "
              "%zu\n",
              c.file, m.spacing, n, rms, maxAbs, onlyOurs, onlyGdal);
  ASSERT_GT(n, 10000u);
  EXPECT_LE(rms, c.rmsM);
  EXPECT_LE(maxAbs, c.maxM);
  // Coverage agrees except along the edge of the source.
  EXPECT_LE(onlyOurs + onlyGdal, std::size_t(m.postsX + m.postsZ) * 2);
}

INSTANTIATE_TEST_SUITE_P(
    RealData, BilinearAgainstGdal,
    ::testing::Values(
        // SRTM3 at native spacing (60 m): the four-post formula. Measured: RMS
        // 0.00025 m, max 0.0019 m.
        Case{"elevation/srtm/N49E011.hgt.zip", {11.50, 49.90, 11.62, 50.00}, 0, 0.05, 0.005},
        // 90 m, 1.5 times coarser along x: GDAL widens the tent by the scale,
        // per warp chunk where ours takes the frame's. Measured: RMS 0.0165 m,
        // max 0.13 m.
        Case{"elevation/srtm/N49E011.hgt.zip", {11.40, 49.80, 11.70, 50.00}, 90, 0.5, 0.05},
        // DTED0 over a whole cell at native spacing (674 m: a lattice cell is
        // 5.4 km). Measured: RMS 0.0047 m, max 0.059 m.
        Case{"elevation/dted/n43.dt0", {0, 0, 0, 0}, 0, 0.1, 0.01}));

// A build under a budget of one byte (64-row bands) writes the same
// grid.stg, byte for byte, as the whole-grid build, for every kernel whose
// bands are fixed strips.
TEST(ElevationBands, tinyBudgetWritesTheSameGrid) {
  const std::string file = dataFile("elevation/srtm/N49E011.hgt.zip");
  REQUIRE_FILE(file);
  TempDir tmp("bands");
  struct K {
    const char* resample;
    const char* fit;
  };
  for (const K k : {K{"bilinear", "triangles"}, K{"bilinear", "posts"}, K{"weighted", "posts"}}) {
    SCOPED_TRACE(std::string(k.resample) + " " + k.fit);
    std::vector<char> bytes[2];
    for (int t = 0; t < 2; ++t) {
      ElevationOptions o = gridOnly(file, tmp / (std::string(k.resample) + k.fit + std::to_string(t)));
      o.resample = k.resample;
      o.fit = k.fit;
      o.extent = std::array<double, 4>{11.50, 49.85, 11.60, 50.00};
      if (t == 1) o.memoryBudgetBytes = 1;
      auto r = buildElevation(o, nullptr);
      ASSERT_TRUE(r.ok()) << r.error();
      if (t == 0) {
        EXPECT_EQ(r->bands, 1u);
        EXPECT_FALSE(r->banded);
      } else {
        EXPECT_EQ(r->bandRows, kMinBandRows);
        EXPECT_GE(r->bands, 4u);  // 254 rows of SRTM3
        EXPECT_TRUE(r->banded) << "a void made the build hold the whole grid; pick a cell without voids";
      }
      bytes[t] = slurp(o.output + "/grid.stg");
      ASSERT_TRUE(grid::validateGrid(o.output + "/grid.stg").ok());
    }
    ASSERT_GT(bytes[0].size(), 1000u);
    EXPECT_TRUE(bytes[0] == bytes[1]) << "banded grid.stg differs";
  }
}

// With voids left after resampling the build holds the whole grid (sea and
// void fill are global), and says so; the grid is still the same.
TEST(ElevationBands, voidsFallBackToTheWholeGrid) {
  const std::string file = dataFile("elevation/srtm/N22W160.hgt.zip");  // Kauai: sea stored as voids
  REQUIRE_FILE(file);
  TempDir tmp("bands-voids");
  std::vector<char> bytes[2];
  for (int t = 0; t < 2; ++t) {
    ElevationOptions o = gridOnly(file, tmp / ("db" + std::to_string(t)));
    o.resample = "bilinear";
    o.fit = "posts";
    o.spacing = 90;
    if (t == 1) o.memoryBudgetBytes = 1;
    auto r = buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    EXPECT_FALSE(r->banded);
    EXPECT_GT(r->seaPosts + r->voidsFilled, 0u);
    if (t == 1) {
      EXPECT_GT(r->bands, 1u);
    }
    bytes[t] = slurp(o.output + "/grid.stg");
  }
  EXPECT_TRUE(bytes[0] == bytes[1]);
}

}  // namespace
}  // namespace sandtable::convert
