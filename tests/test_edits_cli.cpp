// `sandtable edits` on real data (SRTM north of Bayreuth, 30 m, a small
// extent, one explicit tree), against independent computations:
//  - `edits apply DB --journal J` of every kind (crater by --lonlat and by
//    --xy, berm, ditch, flatten, remove-object), `edits list J --json`
//    listing each with its fields, the points where OGR puts the lon/lat;
//  - `sample --journal J` at a crater's centre (put on a fine post) is the
//    unedited `sample` there minus the depth within 1 mm, and the unedited
//    `sample` is the grid's plane there worked by hand from `export --grid`
//    read through GDAL;
//  - `export --journal J --grid` differs from the unedited export exactly
//    in the craters' footprints, by the profile worked by hand;
//  - bad input exits 2 naming the flag (or the object);
//  - add-object, switch-object and scale-object: the journal's modules hold
//    the added icon where OGR puts its lon/lat, and the switched and scaled
//    object as asked.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "sandtable/edits/editor.h"
#include "sandtable/formats/database.h"
#include "sandtable/formats/module.h"
#include "sandtable/paging/world.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

/// A Float32 GeoTIFF's first band through GDAL.
struct Raster {
  int width = 0, height = 0;
  std::vector<float> px;
  float at(int i, int j) const { return px[std::size_t(j) * std::size_t(width) + std::size_t(i)]; }
};

Raster readRaster(const std::string& path) {
  GDALAllRegister();
  Raster r;
  auto* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  if (!ds) return r;
  r.width = ds->GetRasterXSize(), r.height = ds->GetRasterYSize();
  r.px.resize(std::size_t(r.width) * std::size_t(r.height));
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, r.width, r.height, r.px.data(), r.width, r.height, GDT_Float32, 0,
                                     0) != CE_None) {
    r.px.clear();
  }
  GDALClose(ds);
  return r;
}

/// docs/DYNAMIC.md's crater profile, worked here.
double craterByHand(double R, double d, double r) {
  const double rim = d / 4;
  if (r <= R) return -d + (d + rim) * (r / R) * (r / R);
  if (r < 2 * R) return rim * ((2 * R - r) / R) * ((2 * R - r) / R);
  return 0;
}

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

/// Where OGR (independently of geodesy) puts WGS 84 (lon, lat) in the
/// database frame of `m` (x east, z south of its origin); false when OGR
/// cannot transform it.
bool ogrFrame(const manifest::Manifest& m, double lon, double lat, double& x, double& z) {
  OGRSpatialReference wgs, frame;
  wgs.SetWellKnownGeogCS("WGS84");
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (frame.importFromWkt(m.crsWkt.c_str()) != OGRERR_NONE) return false;
  frame.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs, &frame));
  if (!ct || !ct->Transform(1, &lon, &lat)) return false;
  x = lon - m.originEasting, z = m.originNorthing - lat;
  return true;
}

class EditsCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    dir_ = new TempDir("editscli");
    spit(*dir_ / "objects.csv", "lon,lat,icon\n11.585,49.962,tree\n");
    const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.57", "49.95",
                           "11.60", "49.97", "--spacing", "30", "--objects", *dir_ / "objects.csv", "-o", db()});
    ASSERT_EQ(b.exitCode, 0) << b.err;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    SANDTABLE_REQUIRE_DATA();
    ASSERT_TRUE(dir_);
    auto opened = openDatabase(db());
    ASSERT_TRUE(opened.ok()) << opened.error();
    originE_ = opened->manifest.originEasting;
    originN_ = opened->manifest.originNorthing;
  }
  static std::string db() { return *dir_ / "db"; }
  static std::string at(const std::string& name) { return *dir_ / name; }
  /// `edits apply DB --journal J KIND ARGS...`; must succeed.
  static void apply(const std::string& journal, std::vector<std::string> args) {
    std::vector<std::string> all = {"edits", "apply", db(), "--journal", journal};
    all.insert(all.end(), args.begin(), args.end());
    const auto r = runCli(all);
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  /// `sample DB --xy E N --journal J --json`'s elevation.
  static double sample(double e, double n, const std::string& journal) {
    const auto r = runCli({"sample", db(), "--xy", num(e), num(n), "--journal", journal, "--json"});
    EXPECT_EQ(r.exitCode, 0) << r.err;
    return r.exitCode == 0 ? nlohmann::json::parse(r.out)["elevation"].get<double>() : std::nan("");
  }
  static Raster exportGrid(const std::string& journal, const std::string& name) {
    const auto r = runCli({"export", db(), "--journal", journal, "--grid", "-o", at(name)});
    EXPECT_EQ(r.exitCode, 0) << r.err;
    return readRaster(at(name));
  }

  static TempDir* dir_;
  double originE_ = 0, originN_ = 0;
};
TempDir* EditsCli::dir_ = nullptr;

TEST_F(EditsCli, everyKindIsAppliedAndListedWithItsFields) {
  // The tree's id and module, from the pack (what remove-object names).
  auto opened = openDatabase(db());
  ASSERT_TRUE(opened.ok());
  std::uint32_t kx = 0, kz = 0;
  std::uint64_t tree = 0;
  bool found = false;
  const auto& h = opened->modules->header();
  for (std::uint32_t z = 0; z < h.modulesZ && !found; ++z) {
    for (std::uint32_t x = 0; x < h.modulesX && !found; ++x) {
      module::Module m;
      ASSERT_TRUE(opened->modules->readInto(x, z, m).ok());
      if (!m.objects.empty()) kx = x, kz = z, tree = m.objects[0].id, found = true;
    }
  }
  ASSERT_TRUE(found) << "the build placed no object";

  const std::string j = at("kinds.journal");
  const double xyE = originE_ + 1500.25, xyN = originN_ - 700.5;
  apply(j, {"crater", "--lonlat", "11.585", "49.96", "--radius", "5", "--depth", "1.5"});
  apply(j, {"berm", "--line", "11.575 49.955, 11.58 49.957", "--width", "4", "--height", "1.5"});
  apply(j, {"ditch", "--line", "11.59 49.955, 11.595 49.956, 11.596 49.958", "--width", "3", "--depth", "2", "--slope",
            "1"});
  apply(j, {"flatten", "--polygon", "11.574 49.965, 11.576 49.965, 11.576 49.966, 11.574 49.966", "--height", "380"});
  apply(j, {"remove-object", std::to_string(tree), "--module", std::to_string(kx), std::to_string(kz)});
  apply(j, {"crater", "--xy", num(xyE), num(xyN), "--radius", "3", "--depth", "1"});

  const auto l = runCli({"edits", "list", j, "--json"});
  ASSERT_EQ(l.exitCode, 0) << l.err;
  EXPECT_EQ(l.err, "");
  const auto out = nlohmann::json::parse(l.out);
  EXPECT_EQ(out["torn_tail_cut"], false);
  const auto& e = out["edits"];
  ASSERT_EQ(e.size(), 6u);
  const char* kinds[] = {"crater", "berm", "ditch", "flatten", "remove-object", "crater"};
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(e[k]["id"], k + 1);
    EXPECT_EQ(e[k]["origin"], 0);
    EXPECT_EQ(e[k]["kind"], kinds[k]) << e[k].dump();
  }
  EXPECT_EQ(e[0]["radius_m"], 5.0);
  EXPECT_EQ(e[0]["depth_m"], 1.5);
  EXPECT_EQ(e[1]["width_m"], 4.0);
  EXPECT_EQ(e[1]["height_m"], 1.5);
  EXPECT_EQ(e[1]["side_slope"], 0.5);  // the default
  EXPECT_EQ(e[1]["points_xz"].size(), 2u);
  EXPECT_EQ(e[2]["width_m"], 3.0);
  EXPECT_EQ(e[2]["depth_m"], 2.0);
  EXPECT_EQ(e[2]["side_slope"], 1.0);
  EXPECT_EQ(e[2]["points_xz"].size(), 3u);
  EXPECT_EQ(e[3]["height_m"], 380.0);
  EXPECT_EQ(e[3]["points_xz"].size(), 4u);
  EXPECT_EQ(e[4]["object"], tree);
  EXPECT_EQ(e[4]["module"], nlohmann::json::array({kx, kz}));
  EXPECT_NEAR(e[5]["points_xz"][0][0].get<double>(), 1500.25, 1e-6);
  EXPECT_NEAR(e[5]["points_xz"][0][1].get<double>(), 700.5, 1e-6);

  // The crater's lon/lat where OGR puts it in the database frame.
  double x = 0, z = 0;
  ASSERT_TRUE(ogrFrame(opened->manifest, 11.585, 49.96, x, z));
  EXPECT_NEAR(e[0]["points_xz"][0][0].get<double>(), x, 1e-3);
  EXPECT_NEAR(e[0]["points_xz"][0][1].get<double>(), z, 1e-3);

  // The plain listing names them too.
  const auto text = runCli({"edits", "list", j});
  ASSERT_EQ(text.exitCode, 0) << text.err;
  EXPECT_NE(text.out.find("6 edits"), std::string::npos) << text.out;
}

TEST_F(EditsCli, sampleAtACraterCentreIsTheGroundBeforeMinusTheDepth) {
  const Raster before = exportGrid("none", "before.tif");
  ASSERT_FALSE(before.px.empty());
  // A crater centred on a fine post: radius 12 m on 30 m posts refines its
  // squares into 16 cells (docs/DYNAMIC.md), 1.875 m, and the profile is
  // exact at a fine post. Post (i, j) plus (5, 3) fine posts.
  const int i = before.width / 2, jj = before.height / 2;
  const double fx = 5.0 / 16, fz = 3.0 / 16, s = 30;
  const double x = (i + fx) * s, z = (jj + fz) * s;
  const double e = originE_ + x, n = originN_ - z;
  const std::string j = at("sample.journal");
  apply(j, {"crater", "--xy", num(e), num(n), "--radius", "12", "--depth", "2"});

  // The ground before, by hand: the square's north-west (upper) triangle
  // (fx + fz < 1) over the posts GDAL reads from the unedited export.
  const double nw = before.at(i, jj), ne = before.at(i + 1, jj), sw = before.at(i, jj + 1);
  const double plane = nw + fx * (ne - nw) + fz * (sw - nw);
  const double unedited = sample(e, n, "none");
  EXPECT_NEAR(unedited, plane, 1e-3);
  EXPECT_NEAR(sample(e, n, j), unedited - 2, 1e-3);
  EXPECT_NEAR(sample(e, n, j), plane - 2, 1e-3);
}

TEST_F(EditsCli, anEditedExportDiffersExactlyInTheCratersFootprints) {
  const Raster before = exportGrid("none", "plain.tif");
  ASSERT_FALSE(before.px.empty());
  struct Crater {
    double x, z, radius, depth;
  };
  // Far apart, off the posts; the posts under them move by the profile.
  const Crater craters[] = {{600.5, 700.25, 40, 3}, {1400.75, 1500.5, 25, 2}};
  const std::string j = at("export.journal");
  for (const Crater& c : craters) {
    apply(j, {"crater", "--xy", num(originE_ + c.x), num(originN_ - c.z), "--radius", num(c.radius), "--depth",
              num(c.depth)});
  }
  const Raster after = exportGrid(j, "edited.tif");
  ASSERT_EQ(after.width, before.width);
  ASSERT_EQ(after.height, before.height);
  int moved = 0, inside = 0;
  for (int jj = 0; jj < before.height; ++jj) {
    for (int i = 0; i < before.width; ++i) {
      const float a = after.at(i, jj), b = before.at(i, jj);
      double delta = 0;
      bool in = false;
      for (const Crater& c : craters) {
        const double r = std::hypot(i * 30.0 - c.x, jj * 30.0 - c.z);
        if (r < 2 * c.radius) in = true, delta += craterByHand(c.radius, c.depth, r);
      }
      if (!in) {
        EXPECT_EQ(a, b) << "post " << i << " " << jj << " outside every crater changed";
        continue;
      }
      ++inside;
      EXPECT_NEAR(a, double(b) + delta, 1e-3) << "post " << i << " " << jj;
      moved += a != b;
    }
  }
  EXPECT_GE(inside, 15);
  EXPECT_EQ(moved, inside);
}

TEST_F(EditsCli, badInputExitsTwoNamingTheFlag) {
  const std::string j = at("bad.journal");
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const Case cases[] = {
      {{"--journal", j, "crater", "--lonlat", "11.585", "49.96", "--radius", "-1", "--depth", "1"}, "--radius"},
      {{"--journal", j, "crater", "--lonlat", "11.585", "49.96", "--radius", "3", "--depth", "0"}, "--depth"},
      {{"--journal", j, "berm", "--line", "11.575 49.955, 11.58", "--width", "4", "--height", "1"}, "--line"},
      {{"--journal", j, "remove-object", "987654", "--module", "1", "1"}, "object 987654"},
      {{"--journal", at("no-such-dir/j"), "crater", "--lonlat", "11.585", "49.96", "--radius", "3", "--depth", "1"},
       "--journal"},
  };
  for (const Case& c : cases) {
    std::vector<std::string> args = {"edits", "apply", db()};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, 2) << c.says << ": " << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << r.err;
  }
  // Nothing was journalled.
  EXPECT_FALSE(std::filesystem::exists(j) && runCli({"edits", "list", j, "--json"}).out.find("\"id\"") != std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(at("no-such-dir")));
}

TEST(EditsCliObjects, addedSwitchedAndScaledObjectsAreInTheJournalsModules) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("editsobjects");
  const std::string db = t / "db", j = t / "objects.journal";
  spit(t / "objects.csv", "lon,lat,icon\n11.585,49.955,tree\n");
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.57", "49.95",
                         "11.60", "49.965", "--spacing", "30", "--objects", t / "objects.csv", "--icons",
                         std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", db});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  auto opened = openDatabase(db);
  ASSERT_TRUE(opened.ok()) << opened.error();
  ASSERT_TRUE(opened->icons);
  const auto iconOf = [&](const std::string& name) {
    for (std::size_t k = 0; k < opened->icons->icons.size(); ++k) {
      if (opened->icons->icons[k].name == name) return int(k);
    }
    return -1;
  };
  const int tank = iconOf("tank"), rock = iconOf("rock"), tree = iconOf("tree");
  ASSERT_GE(tank, 0);
  ASSERT_GE(rock, 0);
  // The explicit tree: its module and id.
  const auto& h = opened->modules->header();
  std::uint32_t kx = 0, kz = 0;
  std::uint64_t id = 0;
  bool found = false;
  for (std::uint32_t z = 0; z < h.modulesZ && !found; ++z) {
    for (std::uint32_t x = 0; x < h.modulesX && !found; ++x) {
      module::Module m;
      ASSERT_TRUE(opened->modules->readInto(x, z, m).ok());
      for (const auto& o : m.objects) {
        if (o.cls == module::kObjectClassExplicit && o.icon == tree) kx = x, kz = z, id = o.id, found = true;
      }
    }
  }
  ASSERT_TRUE(found) << "the build placed no explicit tree";
  const std::vector<std::string> head = {"edits", "apply", db, "--journal", j};
  const auto apply = [&](std::vector<std::string> args) {
    args.insert(args.begin(), head.begin(), head.end());
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, 0) << r.err;
  };
  apply({"add-object", "--icon", "tank", "--lonlat", "11.58", "49.957", "--heading", "90", "--scale", "2"});
  apply({"switch-object", std::to_string(id), "--module", std::to_string(kx), std::to_string(kz), "--icon", "rock"});
  apply({"scale-object", std::to_string(id), "--module", std::to_string(kx), std::to_string(kz), "--scale", "3"});
  const auto bad = runCli({"edits", "apply", db, "--journal", j, "add-object", "--icon", "dragon", "--lonlat", "11.58",
                           "49.957"});
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.err.find("--icon dragon: no such icon"), std::string::npos) << bad.err;

  // Where OGR puts the tank's lon/lat, in the database frame.
  double fx = 0, fz = 0;
  ASSERT_TRUE(ogrFrame(opened->manifest, 11.58, 49.957, fx, fz));

  // The journal's world, as fly and sim open it.
  auto world = paging::World::open(db);
  ASSERT_TRUE(world.ok()) << world.error();
  edits::EditorOptions o;
  o.journal = j;
  o.readOnly = true;
  o.background = false;
  auto ed = edits::Editor::open(world.value(), o);
  ASSERT_TRUE(ed.ok()) << ed.error();
  const double size = h.moduleSize;
  bool tankSeen = false, treeSeen = false;
  for (std::uint32_t z = 0; z < h.modulesZ; ++z) {
    for (std::uint32_t x = 0; x < h.modulesX; ++x) {
      module::Module m;
      ASSERT_TRUE(ed.value()->world()->modules()->read(x, z, m).ok());
      for (const auto& obj : m.objects) {
        if (obj.icon == tank) {
          tankSeen = true;
          EXPECT_NEAR(x * size + obj.x, fx, 0.01);
          EXPECT_NEAR(z * size + obj.z, fz, 0.01);
          EXPECT_NEAR(obj.heading, 16384, 1);  // 90 degrees of 65536 a turn
          EXPECT_FLOAT_EQ(obj.scale, 2.0f);
        }
        if (x == kx && z == kz && obj.id == id) {
          treeSeen = true;
          EXPECT_EQ(obj.icon, rock);
          EXPECT_FLOAT_EQ(obj.scale, 3.0f);
        }
      }
    }
  }
  EXPECT_TRUE(tankSeen) << "the added tank is in no module";
  EXPECT_TRUE(treeSeen) << "the switched object is gone";
}

}  // namespace
}  // namespace sandtable::test
