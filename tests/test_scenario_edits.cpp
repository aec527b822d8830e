// A scenario's crater, berm, ditch and flatten lines on real data (north of
// Bayreuth, SRTM at 30 m): every point makeTerrainEdits places, through the
// database's CRS as `sim` does (tools/sandtable/sim_setup.cpp), lands where
// `sandtable sample --lonlat` says that lon/lat is, and where OGR projects
// it independently. `sim` takes the lines, and refuses an edit wholly off the
// database with its line.
#include <gtest/gtest.h>

#include <memory>

#include <nlohmann/json.hpp>
#include <ogr_spatialref.h>

#include "sandtable/formats/database.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/sim/scenario.h"
#include "sandtable/sim/scenario_load.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

const char* const kScenario =
    "sandtable-scenario 1\n"
    "crater  at=11.585,49.965 size=large\n"
    "berm    line=11.57,49.95;11.58,49.96;11.60,49.962 width=3 height=2\n"
    "ditch   line=11.561,49.975;11.612,49.9755 width=2 depth=2.5 slope=1\n"
    "flatten polygon=11.59,49.97;11.595,49.97;11.595,49.973;11.59,49.973 height=420 slope=0.3\n"
    "crater  at=11.553,49.9425 radius=5 depth=2   # near the south-west corner\n";

TEST(ScenarioEdits, pointsLandWhereSampleAndOgrPutTheirLonLat) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("scenedits");
  const std::string db = t / "db";
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.55", "49.94",
                         "11.62", "49.99", "--spacing", "30", "-o", db});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  spit(t / "s.scenario", kScenario);

  // The conversion `sim` makes: the manifest's CRS through geodesy.
  auto opened = openDatabase(db);
  ASSERT_TRUE(opened.ok()) << opened.error();
  const manifest::Manifest& m = opened->manifest;
  auto geo = geodesy::Projection::create(m.crsWkt);
  ASSERT_TRUE(geo.ok()) << geo.error();
  const world::ToProjectedFn toProjected = [&](double lon, double lat, double& e, double& n) -> std::string {
    const auto en = geo->toProjected({lon, lat});
    if (!en) return en.error();
    e = en->easting, n = en->northing;
    return {};
  };
  auto scen = sim::readScenarioFile(t / "s.scenario");
  ASSERT_TRUE(scen.ok()) << scen.error();
  const grid::GridHeightField field(*opened->grid);
  const auto edits = sim::makeTerrainEdits(scen.value(), toProjected, field.layout());
  ASSERT_TRUE(edits.ok()) << edits.error();
  ASSERT_EQ(edits->size(), 5u);

  // OGR, independently of geodesy: WGS 84 lon/lat to the manifest's CRS.
  OGRSpatialReference wgs, frame;
  wgs.SetWellKnownGeogCS("WGS84");
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  ASSERT_EQ(frame.importFromWkt(m.crsWkt.c_str()), OGRERR_NONE);
  frame.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs, &frame));
  ASSERT_TRUE(ct);

  std::size_t checked = 0;
  for (std::size_t k = 0; k < edits->size(); ++k) {
    const auto& e = edits.value()[k];
    const auto& spec = scen->terrainEdits[k];
    EXPECT_EQ(e.id, k + 1);
    EXPECT_EQ(e.kind, spec.kind);
    ASSERT_EQ(e.points.size(), spec.points.size());
    for (std::size_t p = 0; p < e.points.size(); ++p) {
      const double lon = spec.points[p][0], lat = spec.points[p][1];
      SCOPED_TRACE("line " + std::to_string(spec.line) + " point " + std::to_string(p + 1));
      const auto s = runCli({"sample", db, "--lonlat", std::to_string(lon), std::to_string(lat), "--json"});
      ASSERT_EQ(s.exitCode, 0) << s.err;
      const auto j = nlohmann::json::parse(s.out);
      EXPECT_NEAR(e.points[p][0], j["easting"].get<double>() - m.originEasting, 1e-6);
      EXPECT_NEAR(e.points[p][1], m.originNorthing - j["northing"].get<double>(), 1e-6);
      double x = lon, y = lat;
      ASSERT_TRUE(ct->Transform(1, &x, &y));
      EXPECT_NEAR(e.points[p][0], x - m.originEasting, 1e-3);
      EXPECT_NEAR(e.points[p][1], m.originNorthing - y, 1e-3);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 1u + 3 + 2 + 4 + 1);

  // `sim` takes the lines (sim_setup converts them), and names the line of
  // an edit that lies wholly off the database.
  const auto run = runCli({"sim", db, "--scenario", t / "s.scenario", "--duration", "1"});
  EXPECT_EQ(run.exitCode, 0) << run.err;
  spit(t / "off.scenario", "sandtable-scenario 1\ncrater at=11.585,49.965 size=small\ncrater at=11.70,49.965 "
                           "size=small\n");
  const auto off = runCli({"sim", db, "--scenario", t / "off.scenario", "--duration", "1"});
  EXPECT_EQ(off.exitCode, 2);
  EXPECT_NE(off.err.find("scenario: line 3: crater: lies wholly outside the database"), std::string::npos) << off.err;
}

}  // namespace
}  // namespace sandtable::test
