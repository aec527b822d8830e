// Full builds (elevation, culture, load modules) from real OSM extracts
// over real SRTM cells, through the CLI as a user runs them: each must pass
// validate, and info must report the culture it decaled. Bayreuth also
// crosses the N49E011/N50E011 tile edge, so its roads cross a mosaic seam,
// module boundaries and, at coarse levels, level boundaries.
#include <ostream>

#include <nlohmann/json.hpp>

#include "test_support.h"

namespace sandtable::test {
namespace {

struct RealCase {
  const char* name;
  std::vector<std::string> elevation;  ///< relative to ../shared/data
  const char* culture;
  const char* extent[4];
  double minRoadKm;
};

// gtest prints a parameter's bytes unless told how to name it.
void PrintTo(const RealCase& c, std::ostream* os) { *os << c.name; }

class RealCultureBuild : public ::testing::TestWithParam<RealCase> {};

double roadKm(const nlohmann::json& classes) {
  double km = 0;
  for (const char* road : {"motorway", "trunk", "primary", "secondary", "tertiary", "street", "service", "track"}) {
    if (classes.contains(road)) km += classes[road].value("length_km", 0.0);
  }
  return km;
}

TEST_P(RealCultureBuild, buildsValidatesAndReportsCulture) {
  SANDTABLE_REQUIRE_DATA();
  const RealCase& c = GetParam();
  TempDir tmp(c.name);
  const std::string db = tmp / "db";
  std::vector<std::string> args = {"build", "--elevation"};
  for (const auto& e : c.elevation) args.push_back(data(e));
  args.insert(args.end(), {"--culture", data(c.culture), "--extent", c.extent[0], c.extent[1], c.extent[2],
                           c.extent[3], "--spacing", "30", "--json", "-o", db});
  const auto b = runCli(args);
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto built = nlohmann::json::parse(b.out);
  ASSERT_TRUE(built.contains("culture")) << b.out;
  EXPECT_GT(roadKm(built["culture"]["classes"]), c.minRoadKm);

  const auto v = runCli({"validate", db, "--json"});
  EXPECT_EQ(v.exitCode, 0) << v.out << v.err;
  const auto report = nlohmann::json::parse(v.out);
  EXPECT_TRUE(report["ok"].get<bool>()) << v.out;
  EXPECT_TRUE(report["problems"].empty()) << v.out;

  const auto i = runCli({"info", db});
  ASSERT_EQ(i.exitCode, 0) << i.err;
  EXPECT_NE(i.out.find("culture"), std::string::npos) << i.out;
  EXPECT_NE(i.out.find("decal polygons"), std::string::npos) << i.out;

  // One module exported as glTF, as a user would inspect it.
  const auto x = runCli({"export", db, "--module", "1", "1", "--format", "gltf", "-o", tmp / "m.gltf"});
  EXPECT_EQ(x.exitCode, 0) << x.err;
  EXPECT_GT(slurpFile(tmp / "m.gltf").size(), 1000u);
}

INSTANTIATE_TEST_SUITE_P(
    OsmOverSrtm, RealCultureBuild,
    ::testing::Values(RealCase{"monaco", {"elevation/srtm/N43E007.hgt.zip"}, "culture/osm/monaco.osm.gz",
                               {"7.38", "43.70", "7.50", "43.76"}, 20.0},
                      RealCase{"bayreuth",
                               {"elevation/srtm/N49E011.hgt.zip", "elevation/srtm/N50E011.hgt.zip"},
                               "culture/osm/north-bayreuth.osm.gz",
                               {"11.48", "49.97", "11.61", "50.05"},
                               200.0}),
    [](const auto& p) { return std::string(p.param.name); });

}  // namespace
}  // namespace sandtable::test
