// `sandtable synth`: real formats, terrain that looks like terrain, culture
// that agrees with it, determinism and the atomic output directory.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <vector>

#include <gdal.h>
#include <nlohmann/json.hpp>
#include <ogr_api.h>
#include <ogr_srs_api.h>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"

namespace fs = std::filesystem;
using sandtable::convert::SynthOptions;
using sandtable::convert::SynthTerrain;
using sandtable::convert::synthesize;

namespace {

/// A fresh directory under the system temp dir, removed at scope exit.
struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name)
      : dir(fs::temp_directory_path() / ("sandtable_synth_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

SynthOptions small(const fs::path& out) {
  SynthOptions o;
  o.outDir = out.string();
  o.sizeKm = 10;
  return o;
}

std::vector<std::int16_t> readInt16(GDALDatasetH ds) {
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  std::vector<std::int16_t> v(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  EXPECT_EQ(GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Read, 0, 0, w, h, v.data(), w, h, GDT_Int16, 0, 0), CE_None);
  return v;
}

std::string bytesOf(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Field name -> type for an OGR layer.
std::vector<std::pair<std::string, OGRFieldType>> fieldsOf(OGRLayerH layer) {
  std::vector<std::pair<std::string, OGRFieldType>> out;
  OGRFeatureDefnH defn = OGR_L_GetLayerDefn(layer);
  for (int k = 0; k < OGR_FD_GetFieldCount(defn); ++k) {
    OGRFieldDefnH f = OGR_FD_GetFieldDefn(defn, k);
    out.emplace_back(OGR_Fld_GetNameRef(f), OGR_Fld_GetType(f));
  }
  return out;
}

bool hasField(OGRLayerH layer, const std::string& name, OGRFieldType type) {
  for (const auto& [n, t] : fieldsOf(layer)) {
    if (n == name && t == type) return true;
  }
  return false;
}

}  // namespace

// One full run: every file in its real format, the terrain has sea and
// relief, and the three elevation products agree where they overlap.
TEST(Synth, WritesRealFormatsThatAgree) {
  sandtable::convert::initGdal();
  Scratch s("formats");
  const fs::path out = s.dir / "data";
  auto r = synthesize(small(out));
  ASSERT_TRUE(r) << r.error();
  EXPECT_FALSE(fs::exists(out.string() + ".partial." + std::to_string(::getpid())));

  // 10 km around 13.30E 42.30N lies inside one cell.
  EXPECT_EQ(r->dted1Cells, 1);
  EXPECT_EQ(r->dted2Cells, 1);
  const fs::path dt1 = out / "dted1/e013/n42.dt1", dt2 = out / "dted2/e013/n42.dt2";
  GDALDatasetH d1 = GDALOpen(dt1.c_str(), GA_ReadOnly);
  GDALDatasetH d2 = GDALOpen(dt2.c_str(), GA_ReadOnly);
  ASSERT_NE(d1, nullptr);
  ASSERT_NE(d2, nullptr);
  EXPECT_STREQ(GDALGetDriverShortName(GDALGetDatasetDriver(d1)), "DTED");
  EXPECT_STREQ(GDALGetDriverShortName(GDALGetDatasetDriver(d2)), "DTED");
  EXPECT_EQ(GDALGetRasterXSize(d1), 1201);
  EXPECT_EQ(GDALGetRasterYSize(d1), 1201);
  EXPECT_EQ(GDALGetRasterXSize(d2), 3601);
  EXPECT_EQ(GDALGetRasterYSize(d2), 3601);
  double gt[6];
  ASSERT_EQ(GDALGetGeoTransform(d1, gt), CE_None);
  EXPECT_NEAR(gt[0], 13.0 - 0.5 / 1200.0, 1e-9);
  EXPECT_NEAR(gt[3], 43.0 + 0.5 / 1200.0, 1e-9);

  const auto e1 = readInt16(d1), e2 = readInt16(d2);
  GDALClose(d1);
  GDALClose(d2);
  // Sea (DTED holds 0 there) and real relief.
  const auto sea = std::count_if(e2.begin(), e2.end(), [](std::int16_t v) { return v <= 0; });
  EXPECT_GT(sea, 10000);
  EXPECT_GT(*std::max_element(e2.begin(), e2.end()), 500);
  EXPECT_LT(*std::max_element(e2.begin(), e2.end()), 3500);
  EXPECT_GE(*std::min_element(e2.begin(), e2.end()), 0);
  // Every DTED1 post is a DTED2 post.
  int worst = 0;
  for (std::size_t row = 0; row < 1201; ++row) {
    for (std::size_t col = 0; col < 1201; ++col) {
      worst = std::max(worst, std::abs(e1[row * 1201 + col] - e2[3 * row * 3601 + 3 * col]));
    }
  }
  EXPECT_LE(worst, 1);

  // The DEM: 1" pixels centred on DTED2 posts, covering the square.
  GDALDatasetH dem = GDALOpen((out / "dem.tif").c_str(), GA_ReadOnly);
  ASSERT_NE(dem, nullptr);
  EXPECT_STREQ(GDALGetDriverShortName(GDALGetDatasetDriver(dem)), "GTiff");
  EXPECT_EQ(GDALGetRasterDataType(GDALGetRasterBand(dem, 1)), GDT_Float32);
  ASSERT_EQ(GDALGetGeoTransform(dem, gt), CE_None);
  const int w = GDALGetRasterXSize(dem), h = GDALGetRasterYSize(dem);
  EXPECT_NEAR(gt[1], 1.0 / 3600.0, 1e-12);
  EXPECT_LE(gt[0], r->west);
  EXPECT_GE(gt[0] + w * gt[1], r->east);
  EXPECT_GE(gt[3], r->north);
  EXPECT_LE(gt[3] + h * gt[5], r->south);
  std::vector<float> z(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(dem, 1), GF_Read, 0, 0, w, h, z.data(), w, h, GDT_Float32, 0, 0), CE_None);
  const char* wkt = GDALGetProjectionRef(dem);
  EXPECT_NE(std::string(wkt).find("WGS"), std::string::npos);
  GDALClose(dem);
  double demWorst = 0;
  int compared = 0;
  for (int row = 0; row < h; ++row) {
    for (int col = 0; col < w; ++col) {
      const double lon = gt[0] + (col + 0.5) * gt[1], lat = gt[3] + (row + 0.5) * gt[5];
      const long i = std::lround((lon - 13.0) * 3600.0), j = std::lround((43.0 - lat) * 3600.0);
      const float v = z[static_cast<std::size_t>(row) * static_cast<std::size_t>(w) + static_cast<std::size_t>(col)];
      if (v <= 0.5f) continue;  // sea: the DEM keeps the sea floor, DTED holds 0
      demWorst = std::max(demWorst, std::fabs(static_cast<double>(v) - e2[static_cast<std::size_t>(j) * 3601 + static_cast<std::size_t>(i)]));
      ++compared;
    }
  }
  EXPECT_GT(compared, 1000);
  EXPECT_LE(demWorst, 1.0);

  // The culture GeoPackage: five layers in EPSG:4326, with their fields.
  GDALDatasetH gpkg = GDALOpenEx((out / "culture.gpkg").c_str(), GDAL_OF_VECTOR, nullptr, nullptr, nullptr);
  ASSERT_NE(gpkg, nullptr);
  EXPECT_STREQ(GDALGetDriverShortName(GDALGetDatasetDriver(gpkg)), "GPKG");
  const std::pair<const char*, OGRwkbGeometryType> layers[] = {
      {"roads", wkbLineString}, {"rivers", wkbLineString}, {"lakes", wkbPolygon}, {"forest", wkbPolygon},
      {"buildings", wkbPolygon}};
  for (const auto& [name, type] : layers) {
    OGRLayerH layer = GDALDatasetGetLayerByName(gpkg, name);
    ASSERT_NE(layer, nullptr) << name;
    EXPECT_EQ(wkbFlatten(OGR_L_GetGeomType(layer)), type) << name;
    EXPECT_GT(OGR_L_GetFeatureCount(layer, TRUE), 0) << name;
    OGRSpatialReferenceH srs = OGR_L_GetSpatialRef(layer);
    ASSERT_NE(srs, nullptr);
    EXPECT_STREQ(OSRGetAuthorityCode(srs, nullptr), "4326");
  }
  OGRLayerH roads = GDALDatasetGetLayerByName(gpkg, "roads");
  EXPECT_TRUE(hasField(roads, "type", OFTString));
  EXPECT_TRUE(hasField(roads, "width", OFTReal));
  // Buildings: rectangles 8 to 20 m a side, 3 to 12 m high, clear of each other.
  OGRLayerH houses = GDALDatasetGetLayerByName(gpkg, "buildings");
  EXPECT_TRUE(hasField(houses, "height", OFTReal));
  OGR_L_ResetReading(houses);
  while (OGRFeatureH f = OGR_L_GetNextFeature(houses)) {
    const double height = OGR_F_GetFieldAsDouble(f, 0);
    EXPECT_GE(height, 3.0);
    EXPECT_LE(height, 12.0);
    OGRGeometryH ring = OGR_G_GetGeometryRef(OGR_F_GetGeometryRef(f), 0);
    EXPECT_EQ(OGR_G_GetPointCount(ring), 5);
    OGR_F_Destroy(f);
  }
  OGRLayerH rivers = GDALDatasetGetLayerByName(gpkg, "rivers");
  EXPECT_TRUE(hasField(rivers, "name", OFTString));
  EXPECT_TRUE(hasField(rivers, "width", OFTReal));
  std::set<std::string> types;
  OGR_L_ResetReading(roads);
  while (OGRFeatureH f = OGR_L_GetNextFeature(roads)) {
    const std::string type = OGR_F_GetFieldAsString(f, 0);
    const double width = OGR_F_GetFieldAsDouble(f, 1);
    types.insert(type);
    if (type == "motorway") {
      EXPECT_DOUBLE_EQ(width, 25.0);
    }
    if (type == "track") {
      EXPECT_DOUBLE_EQ(width, 3.5);
    }
    if (type == "primary" || type == "secondary") {
      EXPECT_GE(width, 7.0);
      EXPECT_LE(width, 12.0);
    }
    OGR_F_Destroy(f);
  }
  for (const auto& t : types) {
    EXPECT_TRUE(t == "motorway" || t == "primary" || t == "secondary" || t == "track") << t;
  }
  EXPECT_TRUE(types.count("track"));
  GDALClose(gpkg);

  // synth.json describes it all.
  std::ifstream js(out / "synth.json");
  const auto j = nlohmann::ordered_json::parse(js);
  EXPECT_EQ(j["seed"], 1);
  EXPECT_EQ(j["size_km"], 10.0);
  EXPECT_NEAR(j["center"]["lon"].get<double>(), 13.30, 1e-12);
  EXPECT_NEAR(j["bounds"]["west"].get<double>(), r->west, 1e-12);
  const auto files = j["files"].get<std::vector<std::string>>();
  for (const char* f : {"dted1/e013/n42.dt1", "dted2/e013/n42.dt2", "dem.tif", "culture.gpkg"}) {
    EXPECT_NE(std::find(files.begin(), files.end(), f), files.end()) << f;
  }
  EXPECT_EQ(j.dump(2) + "\n", r->json);
}

// The same seed gives the same bytes; another seed, other terrain.
TEST(Synth, IsDeterministic) {
  Scratch s("determinism");
  auto dtedOnly = [&](const std::string& name, std::uint64_t seed) {
    SynthOptions o = small(s.dir / name);
    o.seed = seed;
    o.dted2 = o.dem = o.culture = false;
    auto r = synthesize(o);
    EXPECT_TRUE(r) << r.error();
    return bytesOf(s.dir / name / "dted1/e013/n42.dt1");
  };
  const std::string a = dtedOnly("a", 7), b = dtedOnly("b", 7), c = dtedOnly("c", 8);
  ASSERT_GT(a.size(), 1000000u);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
}

// Rivers run downhill to the sea, roads stay on land, lakes are level.
TEST(Synth, CultureAgreesWithTerrain) {
  sandtable::convert::initGdal();
  Scratch s("culture");
  SynthOptions o = small(s.dir / "data");
  o.dted1 = o.dted2 = o.dem = false;
  auto r = synthesize(o);
  ASSERT_TRUE(r) << r.error();
  auto terrain = SynthTerrain::create(o);
  ASSERT_TRUE(terrain) << terrain.error();
  const SynthTerrain& t = *terrain.value();

  GDALDatasetH gpkg = GDALOpenEx((s.dir / "data/culture.gpkg").c_str(), GDAL_OF_VECTOR, nullptr, nullptr, nullptr);
  ASSERT_NE(gpkg, nullptr);
  auto eachPoint = [](OGRFeatureH f, auto fn) {
    OGRGeometryH g = OGR_F_GetGeometryRef(f);
    for (int k = 0; k < OGR_G_GetPointCount(g); ++k) fn(k, OGR_G_GetPointCount(g), OGR_G_GetX(g, k), OGR_G_GetY(g, k));
  };

  OGRLayerH rivers = GDALDatasetGetLayerByName(gpkg, "rivers");
  int toSea = 0, count = 0;
  OGR_L_ResetReading(rivers);
  while (OGRFeatureH f = OGR_L_GetNextFeature(rivers)) {
    double first = 0, last = 0, maxGap = 0, prevX = 0, prevY = 0;
    eachPoint(f, [&](int k, int n, double x, double y) {
      if (k == 0) first = t.elevation(x, y);
      if (k == n - 1) last = t.elevation(x, y);
      if (k > 0) maxGap = std::max(maxGap, std::hypot((x - prevX) * 82000.0, (y - prevY) * 111000.0));
      prevX = x, prevY = y;
    });
    EXPECT_LE(last, first + 2.0) << OGR_F_GetFieldAsString(f, 0);
    EXPECT_LE(maxGap, 200.0);  // dense vertices
    if (last <= 0.5) ++toSea;
    ++count;
    OGR_F_Destroy(f);
  }
  EXPECT_GT(count, 3);
  EXPECT_GT(toSea, 0);

  OGRLayerH roads = GDALDatasetGetLayerByName(gpkg, "roads");
  OGR_L_ResetReading(roads);
  while (OGRFeatureH f = OGR_L_GetNextFeature(roads)) {
    eachPoint(f, [&](int, int, double x, double y) { EXPECT_GT(t.elevation(x, y), 0.5) << x << " " << y; });
    OGR_F_Destroy(f);
  }

  OGRLayerH lakes = GDALDatasetGetLayerByName(gpkg, "lakes");
  OGR_L_ResetReading(lakes);
  while (OGRFeatureH f = OGR_L_GetNextFeature(lakes)) {
    const double level = OGR_F_GetFieldAsDouble(f, 0);
    OGRGeometryH c = OGR_G_CreateGeometry(wkbPoint);
    ASSERT_EQ(OGR_G_Centroid(OGR_F_GetGeometryRef(f), c), OGRERR_NONE);
    EXPECT_DOUBLE_EQ(t.elevation(OGR_G_GetX(c, 0), OGR_G_GetY(c, 0)), level);
    EXPECT_GT(level, 0.0);
    OGR_G_DestroyGeometry(c);
    OGR_F_Destroy(f);
  }
  GDALClose(gpkg);
}

TEST(Synth, RefusesAnExistingDirectoryUnlessForced) {
  Scratch s("atomic");
  SynthOptions o = small(s.dir / "data");
  o.dted1 = o.dted2 = o.dem = o.culture = false;  // just synth.json: fast
  ASSERT_TRUE(synthesize(o));
  std::ofstream(s.dir / "data/marker") << "old";
  auto again = synthesize(o);
  ASSERT_FALSE(again);
  EXPECT_NE(again.error().find("SynthOptions::force"), std::string::npos) << again.error();
  EXPECT_EQ(again.error().find("--"), std::string::npos) << again.error();
  EXPECT_TRUE(fs::exists(s.dir / "data/marker"));
  o.force = true;
  ASSERT_TRUE(synthesize(o));
  EXPECT_FALSE(fs::exists(s.dir / "data/marker"));
  EXPECT_TRUE(fs::exists(s.dir / "data/synth.json"));
  for (const auto& e : fs::directory_iterator(s.dir)) {
    EXPECT_EQ(e.path().filename(), "data") << "left behind: " << e.path();
  }
}

TEST(Synth, ValidatesOptions) {
  using sandtable::convert::validateSynthOptions;
  SynthOptions o;
  o.outDir = "x";
  EXPECT_TRUE(validateSynthOptions(o).ok());
  SynthOptions bad = o;
  bad.sizeKm = 0;
  EXPECT_FALSE(validateSynthOptions(bad).ok());
  bad.sizeKm = 1001;
  EXPECT_FALSE(validateSynthOptions(bad).ok());
  bad = o;
  bad.centerLat = 85;
  EXPECT_FALSE(validateSynthOptions(bad).ok());
  bad = o;
  bad.outDir.clear();
  EXPECT_FALSE(validateSynthOptions(bad).ok());
  // A 1000 km square is allowed and spans many cells.
  bad = o;
  bad.sizeKm = 1000;
  EXPECT_TRUE(validateSynthOptions(bad).ok());
}

// One Status holds every finding, and each names its option field (file
// and message), never a CLI flag: the CLI maps fields to flags.
TEST(Synth, OptionProblemsNameTheFieldNotAFlag) {
  using sandtable::convert::validateSynthOptions;
  SynthOptions bad;
  bad.sizeKm = 0;
  bad.threads = -1;
  const sandtable::Status st = validateSynthOptions(bad);
  ASSERT_EQ(st.problems().size(), 3u) << st.error();
  const char* fields[] = {"SynthOptions::outDir", "SynthOptions::sizeKm", "SynthOptions::threads"};
  for (std::size_t k = 0; k < 3; ++k) {
    const sandtable::Problem& p = st.problems()[k];
    EXPECT_EQ(p.file, fields[k]);
    EXPECT_NE(p.message.find(fields[k]), std::string::npos) << p.message;
    EXPECT_EQ(p.message.find("--"), std::string::npos) << p.message;
  }
}

TEST(Elevation, OptionProblemsNameTheFieldNotAFlag) {
  Scratch s("fields");
  sandtable::convert::ElevationOptions o;
  o.sources = {(s.dir / "none.dt1").string()};
  o.output = (s.dir / "db").string();
  o.spacing = -30;
  auto r = sandtable::convert::buildElevation(o, {});
  ASSERT_FALSE(r);
  EXPECT_EQ(r.problems().front().file, "ElevationOptions::spacing");
  EXPECT_EQ(r.problems().front().message, "build: ElevationOptions::spacing must be positive");
  o.spacing = 0;
  o.modules = false;
  o.culture = {"roads.gpkg"};
  r = sandtable::convert::buildElevation(o, {});
  ASSERT_FALSE(r);
  EXPECT_EQ(r.problems().front().message,
            "build: ElevationOptions::culture, ElevationOptions::materials, ElevationOptions::icons and "
            "ElevationOptions::objects need load modules; drop ElevationOptions::modules = false");
  EXPECT_FALSE(fs::exists(s.dir / "db"));
}
