// Issue 9 item 2: a sea stored as nodata became interpolated land. Voids the
// grid's edge reaches at sea level are now sea (0 m, water); inland voids
// are filled as before, and the two are counted apart.
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>

#include "sandtable/converters/crs.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/formats/database.h"
#include "sandtable/world/terrain.h"
#include "source_raster.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

constexpr std::uint8_t kWater = 1, kFilledVoid = 2;

// ---- a constructed coast: what each post is, by construction

constexpr int kSize = 240;        // posts per side, 30 m apart, UTM 32N
constexpr float kNoData = -9999;

enum class Truth { land, sea, inlandHole, lowHole, highNotch };

/// West: sea as nodata (columns < 40, touching the edge). A coastal plain at
/// 1 m (columns 40..79), then a slope up to 81 m. A nodata hole in the
/// slope (~56 m around it), a nodata hole in the 1 m plain (inland, at sea
/// level, enclosed by land) and a nodata notch in the east edge at ~75 m.
Truth truthAt(double c, double r) {
  if (c < 40) return Truth::sea;
  if (std::hypot(c - 190, r - 120) < 15) return Truth::inlandHole;
  if (std::hypot(c - 60, r - 200) < 6) return Truth::lowHole;
  if (c >= 220 && r >= 20 && r < 40) return Truth::highNotch;
  return Truth::land;
}

double landAt(double c) { return c < 80 ? 1.0 : 1.0 + (c - 80) * 0.5; }

std::string writeCoast(const std::string& path) {
  GDALAllRegister();
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  std::unique_ptr<GDALDataset> ds(gtiff->Create(path.c_str(), kSize, kSize, 1, GDT_Float32, nullptr));
  double g[6] = {500000, 30, 0, 5000000, 0, -30};
  ds->SetGeoTransform(g);
  OGRSpatialReference srs;
  srs.importFromEPSG(32632);
  ds->SetSpatialRef(&srs);
  ds->GetRasterBand(1)->SetNoDataValue(kNoData);
  std::vector<float> v(kSize * kSize);
  for (int r = 0; r < kSize; ++r) {
    for (int c = 0; c < kSize; ++c) {
      v[r * kSize + c] = truthAt(c, r) == Truth::land ? static_cast<float>(landAt(c)) : kNoData;
    }
  }
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, kSize, kSize, v.data(), kSize, kSize, GDT_Float32, 0, 0),
            CE_None);
  return path;
}

struct Counts {
  std::uint64_t seaOk = 0, seaBad = 0, holeOk = 0, holeBad = 0;
};

/// Checks each grid post well inside a constructed region (2 posts from
/// its border) against what it must be.
Counts checkCoast(const Database& db, bool seaExpected) {
  Counts n;
  const auto& m = db.manifest;
  const auto& g = *db.grid;
  for (std::uint32_t j = 0; j < g.postsZ(); ++j) {
    for (std::uint32_t i = 0; i < g.postsX(); ++i) {
      // Source post index (post k at pixel centre k + 0.5).
      const double c = (m.originEasting + i * m.spacing - 500000) / 30 - 0.5;
      const double r = (5000000 - (m.originNorthing - j * m.spacing)) / 30 - 0.5;
      const Truth t = truthAt(c, r);
      bool deep = true;
      for (const double dc : {-2.0, 2.0}) {
        for (const double dr : {-2.0, 2.0}) deep = deep && truthAt(c + dc, r + dr) == t;
      }
      if (!deep || t == Truth::land) continue;
      const float z = g.elevation(i, j);
      const std::uint8_t mat = g.material(i, j);
      if (t == Truth::sea && seaExpected) {
        (z == 0.0f && mat == kWater ? n.seaOk : n.seaBad)++;
      } else if (t == Truth::sea) {
        (mat == kFilledVoid ? n.seaOk : n.seaBad)++;
      } else {
        // Filled from the land around: not flattened to the sea.
        const double around = t == Truth::inlandHole ? landAt(190) : t == Truth::lowHole ? 1.0 : landAt(230);
        (mat == kFilledVoid && std::fabs(z - around) < 8.0 ? n.holeOk : n.holeBad)++;
      }
    }
  }
  return n;
}

TEST(Sea, edgeVoidAtSeaLevelIsSeaAndInlandVoidsAreFilled) {
  TempDir tmp("coast");
  const std::string tif = writeCoast(tmp / "coast.tif");
  for (const bool sea : {true, false}) {
    convert::ElevationOptions o;
    o.sources = {tif};
    o.output = tmp / (sea ? "sea" : "nosea");
    o.crs = "EPSG:32632";
    o.modules = false;
    o.seaFromVoids = sea;
    auto r = convert::buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    auto db = openDatabase(o.output);
    ASSERT_TRUE(db.ok()) << db.error();
    const Counts n = checkCoast(db.value(), sea);
    std::printf("[ sea ] seaFromVoids=%d: %llu sea posts, %llu voids filled; deep sea %llu ok %llu bad, holes %llu ok "
                "%llu bad\n",
                int(sea), static_cast<unsigned long long>(r->seaPosts), static_cast<unsigned long long>(r->voidsFilled),
                static_cast<unsigned long long>(n.seaOk), static_cast<unsigned long long>(n.seaBad),
                static_cast<unsigned long long>(n.holeOk), static_cast<unsigned long long>(n.holeBad));
    EXPECT_GT(n.seaOk, 5000u);
    EXPECT_EQ(n.seaBad, 0u);
    EXPECT_GT(n.holeOk, 600u);  // the three holes, less their 2-post rims
    EXPECT_EQ(n.holeBad, 0u);
    // The counts are the posts of each kind: about 40 columns of sea, and
    // the holes' areas (pi 15^2 + pi 6^2 + 20 x 20 posts).
    const double seaArea = 40.0 * db->grid->postsZ(), holeArea = M_PI * 225 + M_PI * 36 + 400;
    if (sea) {
      EXPECT_NEAR(double(r->seaPosts), seaArea, 0.1 * seaArea);
      EXPECT_NEAR(double(r->voidsFilled), holeArea, 0.2 * holeArea);
      EXPECT_EQ(db->manifest.build.value("sea_posts", std::uint64_t{0}), r->seaPosts);
    } else {
      EXPECT_EQ(r->seaPosts, 0u);
      EXPECT_NEAR(double(r->voidsFilled), seaArea + holeArea, 0.1 * (seaArea + holeArea));
    }
    EXPECT_EQ(db->manifest.build.value("voids_filled", std::uint64_t{0}), r->voidsFilled);
    EXPECT_TRUE(validateDatabase(o.output).ok());
  }
}

// ---- the Danish DHM cells, where the sea is stored as nodata

TEST(Sea, danishCellSeaIsWaterAtZeroAndCountedApart) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("dksea");
  const std::string cell = data("elevation/dted/denmark-dhm/e010/n55.dt1");
  const std::string db = tmp / "db";
  auto b = runCli({"build", "--elevation", cell, "--no-modules", "--json", "-o", db});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto built = nlohmann::json::parse(b.out);
  const auto sea = built["sea_posts"].get<std::uint64_t>(), filled = built["voids_filled"].get<std::uint64_t>();
  std::printf("[ sea ] e010/n55: %llu sea posts, %llu voids filled of %llu posts\n",
              static_cast<unsigned long long>(sea), static_cast<unsigned long long>(filled),
              static_cast<unsigned long long>(built["posts"].get<std::uint64_t>()));
  EXPECT_GT(sea, built["posts"].get<std::uint64_t>() / 5);  // the Kattegat, the Belts, the Baltic
  EXPECT_LT(filled, sea / 50);

  auto i = runCli({"info", db, "--json"});
  ASSERT_EQ(i.exitCode, 0) << i.err;
  const auto info = nlohmann::json::parse(i.out);
  EXPECT_EQ(info["sea_posts"].get<std::uint64_t>(), sea);
  EXPECT_EQ(info["voids_filled"].get<std::uint64_t>(), filled);
  auto human = runCli({"info", db});
  EXPECT_NE(human.out.find(std::to_string(sea) + " sea posts"), std::string::npos) << human.out;

  // Known sea: the Kattegat west of Samsoe, and the Great Belt.
  spit(tmp / "pts.txt", "10.40 55.70\n10.85 55.60\n");
  auto s = runCli({"sample", db, "--points", tmp / "pts.txt", "--json"});
  ASSERT_EQ(s.exitCode, 0) << s.err;
  for (const auto& p : nlohmann::json::parse(s.out)) {
    EXPECT_EQ(p["elevation"].get<double>(), 0.0) << p.dump();
    EXPECT_EQ(p["material"].get<int>(), kWater) << p.dump();
  }

  // Independently, through GDAL: source posts deep in nodata (none valid
  // within 2 posts) are water at 0 m in the grid, bar enclosed sea-level
  // voids that the rule fills as inland.
  auto dbo = openDatabase(db);
  ASSERT_TRUE(dbo.ok()) << dbo.error();
  SourceRaster src(cell);
  ASSERT_TRUE(src.ok());
  world::Terrain terrain(dbo->grid);
  auto geo = geodesy::Projection::create(dbo->manifest.crsWkt);
  std::uint64_t deep = 0, water = 0;
  for (int r = 2; r + 2 < src.height(); r += 5) {
    for (int c = 2; c + 2 < src.width(); c += 5) {
      bool allVoid = true;
      for (int dr = -2; dr <= 2 && allVoid; ++dr) {
        for (int dc = -2; dc <= 2 && allVoid; ++dc) allVoid = !src.post(c + dc, r + dr);
      }
      if (!allVoid) continue;
      const auto xy = src.postXY(c, r);
      const auto en = geo->toProjected({xy[0], xy[1]});
      if (!en) continue;
      const auto got = terrain.sampleEN(en->easting, en->northing);
      if (!got) continue;
      ++deep;
      water += got->material == kWater && got->elevation == 0.0;
    }
  }
  std::printf("[ sea ] e010/n55: %llu of %llu deep-nodata source posts are water at 0 m\n",
              static_cast<unsigned long long>(water), static_cast<unsigned long long>(deep));
  EXPECT_GT(deep, 5000u);
  EXPECT_GE(double(water), 0.98 * double(deep));

  // The rule can be turned off: then the sea is filled as before.
  auto off = runCli({"build", "--elevation", cell, "--no-modules", "--no-sea-from-voids", "--json", "-o", tmp / "off"});
  ASSERT_EQ(off.exitCode, 0) << off.err;
  const auto offJson = nlohmann::json::parse(off.out);
  EXPECT_EQ(offJson["sea_posts"].get<std::uint64_t>(), 0u);
  EXPECT_EQ(offJson["voids_filled"].get<std::uint64_t>(), sea + filled);
}

}  // namespace
}  // namespace sandtable::test
