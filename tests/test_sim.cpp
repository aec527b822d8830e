// The simulator on real data (../shared/data): Monaco's SRTM and OSM.
//  - A ship on the real coastline never enters land in one simulated hour,
//    checked against the SRTM source itself (read through GDAL, not the
//    database): wherever the ship is, the source's surface is at sea level.
//  - A land vehicle driven for ten simulated minutes over the rugged hills
//    stays within 1 cm of the surface of the level drawn there (a coarse,
//    morphed level that differs from the finest grid by metres), and its
//    projected-point pitch and roll never jump at triangle edges, where the
//    polygon-normal method (seed Figure 51) jumps by degrees.
//  - `sandtable sim`: bad scenario, script and aircraft files give exit 2
//    and name the line and column; two runs with one seed print the same
//    event log.
#include <gdal_priv.h>

#include <algorithm>
#include <cmath>

#include "sandtable/converters/crs.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/formats/database.h"
#include "sandtable/sim/report.h"
#include "sandtable/sim/simulation.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

/// The Monaco database (SRTM + OSM culture, 30 m posts, 1 km modules, 4
/// levels), built once for the suite.
class SimMonaco : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    tmp_ = new TempDir("sim-monaco");
    const auto b = runCli({"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--culture",
                           data("culture/osm/monaco.osm.gz"), "--extent", "7.38", "43.70", "7.47", "43.78",
                           "--spacing", "30", "--icons", std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt",
                           "-o", *tmp_ / "db"});
    ASSERT_EQ(b.exitCode, 0) << b.err;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override { SANDTABLE_REQUIRE_DATA(); }
  static std::string db() { return *tmp_ / "db"; }
  static TempDir* tmp_;
};
TempDir* SimMonaco::tmp_ = nullptr;

/// The SRTM tile's posts, read through GDAL, sampled bilinearly at lon/lat.
class Srtm {
 public:
  explicit Srtm(const std::string& path) {
    GDALAllRegister();
    std::string vsi = "/vsizip/";
    vsi += path;
    vsi += "/N43E007.hgt";
    auto* ds = static_cast<GDALDataset*>(GDALOpen(vsi.c_str(), GA_ReadOnly));
    if (!ds) return;
    w_ = ds->GetRasterXSize();
    h_ = ds->GetRasterYSize();
    ds->GetGeoTransform(gt_);
    posts_.resize(std::size_t(w_) * std::size_t(h_));
    if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w_, h_, posts_.data(), w_, h_, GDT_Float32, 0, 0) != CE_None) {
      posts_.clear();
    }
    GDALClose(ds);
  }
  bool ok() const { return !posts_.empty(); }
  double at(double lon, double lat) const {
    // Pixel-is-area geotransform: post k's centre is at gt0 + (k + 0.5) gt1.
    const double u = (lon - gt_[0]) / gt_[1] - 0.5, v = (lat - gt_[3]) / gt_[5] - 0.5;
    const int i = int(std::floor(u)), j = int(std::floor(v));
    const double fu = u - i, fv = v - j;
    auto p = [&](int a, int b) { return double(posts_[std::size_t(b) * std::size_t(w_) + std::size_t(a)]); };
    return (1 - fv) * ((1 - fu) * p(i, j) + fu * p(i + 1, j)) + fv * ((1 - fu) * p(i, j + 1) + fu * p(i + 1, j + 1));
  }

 private:
  int w_ = 0, h_ = 0;
  double gt_[6] = {};
  std::vector<float> posts_;
};

struct Opened {
  std::shared_ptr<sim::SimWorld> world;
  std::optional<geodesy::Projection> geo;
};

Opened open(const std::string& db) {
  Opened o;
  auto w = sim::SimWorld::open(db);
  EXPECT_TRUE(w) << w.error();
  if (w) o.world = w.value();
  auto d = openDatabase(db);
  EXPECT_TRUE(d) << d.error();
  auto g = geodesy::Projection::create(d->manifest.crsWkt);
  EXPECT_TRUE(g) << g.error();
  if (g) o.geo = g.value();
  return o;
}

Eigen::Vector2d worldXZ(const Opened& o, double lon, double lat) {
  const auto en = o.geo->toProjected({lon, lat});
  EXPECT_TRUE(en) << en.error();
  if (!en) return {0, 0};
  return {en->easting - o.world->originEasting(), o.world->originNorthing() - en->northing};
}

TEST_F(SimMonaco, aShipOnTheRealCoastlineNeverEntersLandInOneSimulatedHour) {
  Opened o = open(db());
  ASSERT_TRUE(o.world && o.geo);
  Srtm srtm(data("elevation/srtm/N43E007.hgt.zip"));
  ASSERT_TRUE(srtm.ok());
  sim::Simulation s(o.world);
  const auto boat = o.world->iconIndex("boat");
  ASSERT_TRUE(boat);
  // Off the harbour, heading for the shore (north-west), zig-zagging.
  for (const auto& [lon, lat, heading] : {std::tuple{7.440, 43.725, 315.0}, std::tuple{7.455, 43.715, 300.0}}) {
    sim::Entity e;
    e.name = "patrol";
    e.icon = *boat;
    e.domain = sim::Domain::sea;
    e.mobility = sim::Mobility::ship;
    const Eigen::Vector2d p = worldXZ(o, lon, lat);
    e.position = {p.x(), 0, p.y()};
    e.headingDeg = heading;
    e.speedMs = 12;
    e.vehicle.maxSpeedMs = 15;
    e.vehicle.turnRateDegS = 3;
    e.behaviours = {true, true, true, false, false};
    e.controller = sim::Controller::behaviour;
    ASSERT_TRUE(s.add(e)) << lon << " " << lat;
  }
  double worst = -1e9, travelled = 0;
  std::vector<Eigen::Vector3d> last = {s.entity(0).position, s.entity(1).position};
  for (int k = 0; k < 60 * 3600; ++k) {
    s.step();
    if (k % 30 != 0) continue;
    for (std::size_t i = 0; i < 2; ++i) {
      const sim::Entity& e = s.entity(static_cast<std::uint32_t>(i));
      ASSERT_TRUE(e.alive);
      // The bow too: the whole hull stays on water.
      for (double reach : {0.0, e.halfLength}) {
        const Eigen::Vector3d p = e.position + sim::headingVector(e.headingDeg) * reach;
        const auto ll = o.geo->toLonLat({o.world->originEasting() + p.x(), o.world->originNorthing() - p.z()});
        ASSERT_TRUE(ll) << ll.error();
        worst = std::max(worst, srtm.at(ll->lon, ll->lat));
      }
      travelled += (e.position - last[i]).norm();
      last[i] = e.position;
    }
  }
  // SRTM holds the sea at 0 m; bilinear between a 0 post and a coastal
  // post stays under a metre only within a few metres of the water's edge.
  EXPECT_LE(worst, 1.0);
  EXPECT_GT(travelled, 2 * 20000.0);  // they sailed, not sat
  std::printf("[ coast ] 2 ships, 1 h, %.0f m sailed, %llu groundings refused; highest SRTM under a hull %.2f m\n",
              travelled, static_cast<unsigned long long>(std::count_if(s.events().begin(), s.events().end(), [](const sim::Event& ev) {
                return ev.kind == sim::EventKind::aground;
              })), worst);
}

TEST_F(SimMonaco, aLandVehicleStaysOnTheDrawnSurfaceAndItsAttitudeNeverJumpsAtTriangleEdges) {
  Opened o = open(db());
  ASSERT_TRUE(o.world && o.geo);
  // A coarse, morphed level everywhere: what a viewer draws a few km out.
  const world::DrawnLevel drawn{1, 0.25f};
  o.world->setDrawnLevel([&](double, double) { return drawn; });
  sim::SimOptions opts;
  opts.collisions = false;  // the ground, not the buildings, is under test here
  sim::Simulation s(o.world, opts);
  sim::Entity t;
  t.name = "tank";
  t.icon = *o.world->iconIndex("tank");
  t.mobility = sim::Mobility::tracked;
  const Eigen::Vector2d p = worldXZ(o, 7.405, 43.745);  // the hills above Monaco
  t.position = {p.x(), 0, p.y()};
  t.headingDeg = 20;
  t.speedMs = 6;
  t.behaviours = {true, true, true, false, false};
  t.controller = sim::Controller::behaviour;
  ASSERT_TRUE(s.add(t));
  double worstGround = 0, gridGap = 0, moved = 0;
  double worstPitch = 0, worstRoll = 0, worstNormal = 0;
  sim::Entity prev = s.entity(0);
  double prevNormalPitch = 0;
  bool first = true;
  for (int k = 0; k < 60 * 600; ++k) {
    s.step();
    const sim::Entity& e = s.entity(0);
    const double x = e.position.x(), z = e.position.z();
    const auto drawnY = o.world->clamp().surfaceXZ(x, z, drawn);
    ASSERT_TRUE(drawnY);
    worstGround = std::max(worstGround, std::abs(e.position.y() - *drawnY));
    gridGap = std::max(gridGap, std::abs(*drawnY - o.world->terrain().sampleXZ(x, z)->elevation));
    worstPitch = std::max(worstPitch, std::abs(e.pitchDeg - prev.pitchDeg));
    worstRoll = std::max(worstRoll, std::abs(e.rollDeg - prev.rollDeg));
    // Figure 51's polygon normal: the slope of the triangle under the
    // origin along the heading (1 cm differences stay inside it).
    const Eigen::Vector3d f = sim::headingVector(e.headingDeg);
    const double ahead = *o.world->clamp().surfaceXZ(x + f.x() * 0.01, z + f.z() * 0.01, drawn);
    const double normalPitch = std::atan2(ahead - *drawnY, 0.01) * sim::kRadToDeg;
    if (!first && std::abs(e.headingDeg - prev.headingDeg) < 0.01) {
      worstNormal = std::max(worstNormal, std::abs(normalPitch - prevNormalPitch));
    }
    first = false;
    prevNormalPitch = normalPitch;
    moved += (e.position - prev.position).norm();
    prev = e;
  }
  EXPECT_LT(worstGround, 0.01);
  EXPECT_GT(gridGap, 1.0);  // following the finest grid instead would fail the line above
  EXPECT_GT(moved, 1500.0);
  EXPECT_LT(worstPitch, 3.0);
  EXPECT_LT(worstRoll, 3.0);
  EXPECT_GT(worstNormal, 2 * std::max(worstPitch, worstRoll));  // the normal method jumps where the projected points glide
  std::printf("[ ground ] 10 min, %.0f m: |y - drawn| <= %.2g m, pitch/roll steps <= %.2f/%.2f deg, "
              "polygon-normal pitch steps up to %.2f deg\n",
              moved, worstGround, worstPitch, worstRoll, worstNormal);
}

TEST_F(SimMonaco, simCliRunsTheScenarioAndTwoRunsWithOneSeedGiveTheSameEventLog) {
  TempDir t("sim-cli");
  spit(t / "s.scenario",
       "sandtable-scenario 1\n"
       "frame lonlat\n"
       "entity lead icon=tank force=blue mobility=tracked at=7.405,43.745 heading=90 speed=20 driven\n"
       "group 12 name=red icon=jeep force=red mobility=wheeled area=7.40,43.74,7.41,43.75 speed=20..40 "
       "behaviour=noise,engage\n"
       "group 4 name=boats icon=boat force=red domain=sea area=7.445,43.71,7.46,43.72 speed=20..30 behaviour=noise\n");
  const auto a = runCli({"sim", db(), "--scenario", t / "s.scenario", "--duration", "120", "--seed", "3", "--json"});
  ASSERT_EQ(a.exitCode, 0) << a.err;
  const auto b = runCli({"sim", db(), "--scenario", t / "s.scenario", "--duration", "120", "--seed", "3", "--json"});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  auto ja = nlohmann::json::parse(a.out), jb = nlohmann::json::parse(b.out);
  EXPECT_EQ(ja["events"].dump(), jb["events"].dump());
  EXPECT_EQ(ja["summary"].dump(), jb["summary"].dump());
  EXPECT_EQ(ja["summary"]["entities"].get<int>(), 17);
  EXPECT_EQ(ja["summary"]["time_s"].get<double>(), 120.0);
  EXPECT_EQ(ja["summary"]["steps"].get<std::uint64_t>(), 7200u);  // 120 s at 60 Hz, as the viewer and bench step
}

TEST_F(SimMonaco, badScenarioScriptAndAircraftFilesExitTwoNamingLineAndColumn) {
  TempDir t("sim-bad");
  struct Bad {
    std::string scenario, extraFile, extraText, want;
  };
  const std::vector<Bad> cases = {
      {"sandtable-scenario 1\nentity a icon=tank at=7.405,43.745 speed=fast\n", "", "", "line 2, column"},
      {"sandtable-scenario 1\nentity a icon=tank script=bad.script script-entity=1\n", "bad.script",
       "00 00 01 1 2 10.0 0.0 10.0 0.0 0.0 0.0 0.0 5.0 0 2\n", "line 1, column"},
      {"sandtable-scenario 1\nentity a icon=jet domain=air aircraft=bad.txt at=7.405,43.745 altitude=900\n",
       "bad.txt", "sandtable-aircraft 1\nmass -5\n", "line 2, column"},
      {"sandtable-scenario 1\nentity a icon=submarine at=7.405,43.745\n", "", "", "icons.pack"},
      // 1,000 groups of 100,000 asked for 10^8 entities (10.9 GB and still loading after 60 s).
      {[] {
         std::string text = "sandtable-scenario 1\n";
         for (int k = 0; k < 1000; ++k) {
           text += "group 100000 name=g" + std::to_string(k) + " icon=tank area=7.40,43.74,7.41,43.75\n";
         }
         return text;
       }(),
       "", "", "line 3, column 7: this line brings the scenario to 200000 entities, more than the 100000"},
  };
  for (const Bad& c : cases) {
    spit(t / "s.scenario", c.scenario);
    if (!c.extraFile.empty()) spit(t / c.extraFile, c.extraText);
    const auto r = runCli({"sim", db(), "--scenario", t / "s.scenario", "--duration", "1"});
    EXPECT_EQ(r.exitCode, 2) << c.scenario;
    EXPECT_NE(r.err.find(c.want), std::string::npos) << r.err;
  }
}

// The duration is checked before the database is opened: no data needed.
TEST(SimCli, durationsPastTheMaximumNaNOrNegativeExitTwoNamingTheFlag) {
  TempDir t("sim-duration");
  spit(t / "s.scenario", "sandtable-scenario 1\n");
  for (const char* d : {"1e18", "604801", "nan", "-5", "0", "inf"}) {
    const auto r = runCli({"sim", t / "no-db", "--scenario", t / "s.scenario", "--duration", d});
    EXPECT_EQ(r.exitCode, 2) << d;
    EXPECT_NE(r.err.find("--duration"), std::string::npos) << d << ": " << r.err;
  }
  // The maximum itself passes the check and fails later, at the missing database.
  const auto max = runCli({"sim", t / "no-db", "--scenario", t / "s.scenario", "--duration", "604800"});
  EXPECT_EQ(max.exitCode, 2);
  EXPECT_EQ(max.err.find("--duration"), std::string::npos) << max.err;
}

}  // namespace
}  // namespace sandtable::test
