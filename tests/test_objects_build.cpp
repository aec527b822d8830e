// Static objects in a real build (docs/ICONS.md §8): forests scattered at
// the material table's density, OSM point features, explicit points files,
// every base on its level's surface (validate checks it against the grid).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "test_support.h"

using namespace sandtable::test;
namespace fs = std::filesystem;

namespace {

std::vector<std::string> bayreuthBuild(const std::string& db) {
  return {"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.55", "49.94", "11.62",
          "49.99", "--spacing", "30", "--culture", data("culture/osm/north-bayreuth.osm.gz"), "-o", db, "--force"};
}

TEST(ObjectsBuild, forestsGetTreesAtTheTablesDensityAndEveryBaseIsOnItsLevel) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("objforest");
  const auto b = runCli(bayreuthBuild(t / "db"));
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto v = runCli({"validate", t / "db"});
  EXPECT_EQ(v.exitCode, 0) << v.out;  // includes every object's base against the grid lattice, every level
  const auto info = runCli({"info", t / "db", "--json"});
  ASSERT_EQ(info.exitCode, 0) << info.err;
  const auto j = nlohmann::json::parse(info.out);
  const auto forest = j["objects_by_class"].value("forest", std::uint64_t(0));
  // samples/materials.txt: scatter forest density=20 per hectare, on the
  // forest area the culture load measured (roads and streams over it take
  // a little: trees never stand under a decal).
  const double areaHa = j["culture"]["classes"]["forest"]["area_km2"].get<double>() * 100.0;
  ASSERT_GT(areaHa, 100.0);
  EXPECT_NEAR(double(forest), 20.0 * areaHa, 0.05 * 20.0 * areaHa);
  EXPECT_LT(double(forest), 20.0 * areaHa);
  EXPECT_EQ(j["objects"].get<std::uint64_t>(), forest + j["objects_by_class"].value("natural=tree", std::uint64_t(0)));
}

TEST(ObjectsBuild, aPointsFilePlacesItsIconsAndRefusesUnknownOnes) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("objpoints");
  const std::string good = t / "points.geojson", bad = t / "bad.geojson";
  std::ofstream(good) << R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"icon": "tree", "heading": 90, "scale": 2},
     "geometry": {"type": "Point", "coordinates": [11.58, 49.96]}},
    {"type": "Feature", "properties": {"icon": "tree"},
     "geometry": {"type": "Point", "coordinates": [11.60, 49.97]}},
    {"type": "Feature", "properties": {"icon": "tree"},
     "geometry": {"type": "Point", "coordinates": [12.5, 49.97]}}]})";
  std::ofstream(bad) << R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"icon": "tank"},
     "geometry": {"type": "Point", "coordinates": [11.58, 49.96]}}]})";
  auto args = bayreuthBuild(t / "db");
  args.insert(args.end(), {"--objects", good, "--json"});
  const auto b = runCli(args);
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto j = nlohmann::json::parse(b.out);
  EXPECT_EQ(j["objects"]["by_class"]["explicit"], 2);  // the third lies outside
  ASSERT_EQ(j["objects"]["warnings"].size(), 1u);
  EXPECT_NE(j["objects"]["warnings"][0].get<std::string>().find("1 of 3 points lie outside"), std::string::npos);
  EXPECT_EQ(runCli({"validate", t / "db"}).exitCode, 0);

  auto badArgs = bayreuthBuild(t / "db2");
  badArgs.insert(badArgs.end(), {"--objects", bad});
  const auto r = runCli(badArgs);
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("names icon \"tank\", which the icon database lacks"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(t / "db2"));
  const auto missing = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.55",
                               "49.94", "11.62", "49.99", "--objects", t / "none.csv", "-o", t / "db3"});
  EXPECT_EQ(missing.exitCode, 2);
  EXPECT_NE(missing.err.find("check the --objects path"), std::string::npos) << missing.err;
}

}  // namespace
