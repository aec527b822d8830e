// Static objects in a real build (docs/ICONS.md §8): forests scattered at
// the material table's density, OSM point features, explicit points files,
// every base on its level's surface (validate checks it against the grid).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <ogrsf_frmts.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <unordered_map>

#include "sandtable/formats/database.h"
#include "sandtable/formats/pack.h"
#include "test_support.h"

using namespace sandtable::test;
namespace fs = std::filesystem;

namespace {

std::vector<std::string> bayreuthBuild(const std::string& db) {
  return {"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.55", "49.94", "11.62",
          "49.99", "--spacing", "30", "--culture", data("culture/osm/north-bayreuth.osm.gz"), "-o", db, "--force"};
}

/// Every object of the database in its CRS: easting, northing.
std::vector<std::array<double, 2>> objectsOf(const sandtable::Database& db) {
  std::vector<std::array<double, 2>> out;
  const auto& h = db.modules->header();
  const double edge = double(h.moduleSquares) * db.grid->spacing();
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto m = db.modules->read(kx, kz);
      EXPECT_TRUE(m.ok());
      if (!m) continue;
      for (const auto& o : m->objects) {
        out.push_back({db.manifest.originEasting + kx * edge + o.x, db.manifest.originNorthing - (kz * edge + o.z)});
      }
    }
  }
  return out;
}

/// Line segments in 50 m buckets, for a nearest-centreline search.
class SegmentIndex {
 public:
  void add(double ax, double ay, double bx, double by, double halfWidth) {
    const std::size_t id = segments_.size();
    segments_.push_back({ax, ay, bx, by, halfWidth});
    for (long cx = cell(std::min(ax, bx)) - 1; cx <= cell(std::max(ax, bx)) + 1; ++cx) {
      for (long cy = cell(std::min(ay, by)) - 1; cy <= cell(std::max(ay, by)) + 1; ++cy) cells_[key(cx, cy)].push_back(id);
    }
  }
  /// The segment whose widened band reaches deepest over (x, y): its
  /// distance minus its half width (negative: on it).
  double clearance(double x, double y) const {
    double best = INFINITY;
    const auto it = cells_.find(key(cell(x), cell(y)));
    if (it == cells_.end()) return best;
    for (const std::size_t id : it->second) {
      const auto& s = segments_[id];
      const double dx = s[2] - s[0], dy = s[3] - s[1], len2 = dx * dx + dy * dy;
      const double t = len2 > 0 ? std::clamp(((x - s[0]) * dx + (y - s[1]) * dy) / len2, 0.0, 1.0) : 0.0;
      best = std::min(best, std::hypot(x - s[0] - t * dx, y - s[1] - t * dy) - s[4]);
    }
    return best;
  }

 private:
  static constexpr double kCell = 50;
  static long cell(double v) { return long(std::floor(v / kCell)); }
  static std::int64_t key(long x, long y) { return std::int64_t(x) * 1000003 + y; }
  std::vector<std::array<double, 5>> segments_;
  std::unordered_map<std::int64_t, std::vector<std::size_t>> cells_;
};

/// The half width the sample material table gives an OSM line, metres;
/// 0 for lines it does not draw (default-line none). A line with its own
/// width tag gets the narrowest (a path's 2 m).
double halfWidth(OGRFeature& f) {
  static const std::map<std::string, double> widths = {
      {"motorway", 25}, {"motorway_link", 12}, {"trunk", 12}, {"trunk_link", 9}, {"primary", 9},
      {"primary_link", 8}, {"secondary", 8}, {"secondary_link", 7}, {"tertiary", 7}, {"tertiary_link", 6},
      {"residential", 6}, {"living_street", 6}, {"unclassified", 6}, {"road", 6}, {"service", 4},
      {"track", 3.5}, {"path", 2}, {"footway", 2}, {"cycleway", 2}, {"bridleway", 2}, {"pedestrian", 2},
      {"steps", 2}, {"river", 20}, {"canal", 12}, {"stream", 4}, {"ditch", 2}, {"drain", 2}, {"rail", 5}};
  const char* other = f.GetFieldAsString("other_tags");
  const std::string tags = other ? other : "";
  for (const char* hidden : {"\"tunnel\"", "\"covered\"=>\"yes\"", "\"location\"=>\"underground\""}) {
    if (tags.find(hidden) != std::string::npos) return 0;
  }
  std::string type;
  for (const char* field : {"highway", "waterway", "railway"}) {
    const int i = f.GetFieldIndex(field);
    if (i >= 0 && f.IsFieldSetAndNotNull(i)) type = f.GetFieldAsString(i);
  }
  if (tags.find("\"railway\"=>\"rail\"") != std::string::npos) type = "rail";
  if (type.empty()) return 0;
  const auto it = widths.find(type);
  if (it == widths.end()) return 0;
  if (tags.find("\"width\"") != std::string::npos) return 0.5;
  return 0.5 * it->second;
}

TEST(ObjectsBuild, noTreeStandsOnARoadInWaterOrInABuildingByTheOsmGeometryItself) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("objclear");
  const auto b = runCli(bayreuthBuild(t / "db"));
  ASSERT_EQ(b.exitCode, 0) << b.err;
  auto db = sandtable::openDatabase(t / "db");
  ASSERT_TRUE(db.ok());
  const auto trees = objectsOf(db.value());
  ASSERT_GT(trees.size(), 5000u);

  // The OSM extract read with OGR here, projected into the database's CRS.
  GDALAllRegister();
  std::unique_ptr<GDALDataset> osm(
      GDALDataset::Open(("/vsigzip/" + data("culture/osm/north-bayreuth.osm.gz")).c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  ASSERT_TRUE(osm);
  OGRSpatialReference wgs84, frame;
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  frame.importFromWkt(db->manifest.crsWkt.c_str());
  frame.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> toFrame(OGRCreateCoordinateTransformation(&wgs84, &frame));
  ASSERT_TRUE(toFrame);

  SegmentIndex lines;
  std::size_t lineCount = 0;
  for (auto& f : osm->GetLayerByName("lines")) {
    const double half = halfWidth(*f);
    OGRGeometry* g = f->GetGeometryRef();
    if (half <= 0 || !g || wkbFlatten(g->getGeometryType()) != wkbLineString) continue;
    if (g->transform(toFrame.get()) != OGRERR_NONE) continue;
    const auto* ls = g->toLineString();
    for (int k = 0; k + 1 < ls->getNumPoints(); ++k) {
      lines.add(ls->getX(k), ls->getY(k), ls->getX(k + 1), ls->getY(k + 1), half);
    }
    ++lineCount;
  }
  ASSERT_GT(lineCount, 100u);

  std::vector<std::unique_ptr<OGRGeometry>> areas;  // water and building footprints
  std::vector<std::string> kinds;
  for (auto& f : osm->GetLayerByName("multipolygons")) {
    const auto tag = [&](const char* field) {
      const int i = f->GetFieldIndex(field);
      return i >= 0 && f->IsFieldSetAndNotNull(i) ? std::string(f->GetFieldAsString(i)) : std::string();
    };
    const bool water = tag("natural") == "water" || tag("landuse") == "reservoir" || tag("landuse") == "basin";
    const bool building = !tag("building").empty();
    if (!water && !building) continue;
    std::unique_ptr<OGRGeometry> g(f->StealGeometry());
    if (g && g->transform(toFrame.get()) == OGRERR_NONE) {
      areas.push_back(std::move(g));
      kinds.push_back(std::string(water ? "water" : "building") + " " + f->GetFieldAsString("osm_way_id") +
                      f->GetFieldAsString("osm_id"));
    }
  }
  ASSERT_GT(areas.size(), 100u);
  std::vector<OGREnvelope> boxes(areas.size());
  for (std::size_t k = 0; k < areas.size(); ++k) areas[k]->getEnvelope(&boxes[k]);

  // The decals are the widened lines clipped to float32 module triangles: 5 cm of slack.
  std::size_t onLine = 0, inArea = 0;
  std::string where;
  double worst = INFINITY;
  for (const auto& [e, n] : trees) {
    const double c = lines.clearance(e, n);
    worst = std::min(worst, c);
    if (c < -0.05) ++onLine;
    OGRPoint p(e, n);
    for (std::size_t k = 0; k < areas.size(); ++k) {
      const auto& box = boxes[k];
      if (e < box.MinX || e > box.MaxX || n < box.MinY || n > box.MaxY) continue;
      if (areas[k]->Contains(&p) && ++inArea <= 5) where += "\n  " + kinds[k] + " at E " + std::to_string(e) + " N " + std::to_string(n);
    }
  }
  EXPECT_EQ(onLine, 0u) << "deepest tree into a road or stream: " << -worst << " m";
  EXPECT_EQ(inArea, 0u) << "trees in water or in a building footprint:" << where;
}

TEST(ObjectsBuild, validateFindsACoarseRecordWhoseObjectsDifferFromTheFineRecords) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("objrecords");
  const auto b = runCli(bayreuthBuild(t / "db"));
  ASSERT_EQ(b.exitCode, 0) << b.err;
  // The pack written again, one module's fine record made from the module
  // less its last object: every CRC is right, only the lists differ.
  std::uint32_t badX = 0, badZ = 0;
  bool done = false;
  {
    auto reader = sandtable::pack::PackReader::open(t / "db");
    ASSERT_TRUE(reader.ok()) << reader.error();
    const auto h = reader.value()->header();
    ASSERT_GT(h.coarseLevel, 0u);
    const std::string copy = t / "copy";
    fs::create_directories(copy);
    auto w = sandtable::pack::PackWriter::create(copy, h, 3, sandtable::pack::PackLayout::split(h.levels));
    ASSERT_TRUE(w.ok()) << w.error();
    for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
      for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
        auto m = reader.value()->read(kx, kz);
        ASSERT_TRUE(m.ok()) << m.error();
        auto rec = w.value()->compress(m.value());
        ASSERT_TRUE(rec.ok()) << rec.error();
        if (!done && m->objects.size() > 1) {
          m->objects.pop_back();
          for (auto& l : m->levels) l.objectY.pop_back();
          auto less = w.value()->compress(m.value());
          ASSERT_TRUE(less.ok()) << less.error();
          rec->fineBytes = less->fineBytes;
          rec->entry.fine = less->entry.fine;
          badX = kx, badZ = kz, done = true;
        }
        ASSERT_EQ(w.value()->append(std::move(rec.value())).message(), "");
      }
    }
    ASSERT_EQ(w.value()->finish().message(), "");
  }
  ASSERT_TRUE(done);
  for (const char* f : {"modules.pack", "modules.idx"}) fs::rename(t / ("copy/" + std::string(f)), t / ("db/" + std::string(f)));
  resealFiles(t / "db");
  const auto v = runCli({"validate", t / "db"});
  EXPECT_EQ(v.exitCode, 1) << v.out;
  const std::string want = "module (" + std::to_string(badX) + "," + std::to_string(badZ) +
                           "): its coarse record holds ";
  EXPECT_NE(v.out.find(want), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("both must carry the same list"), std::string::npos) << v.out;
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

  // Export (docs/EXPORT.md, "Objects"): the module holding the first point,
  // its objects instanced in glTF and flattened in OBJ; the tree alone.
  auto db = sandtable::openDatabase(t / "db");
  ASSERT_TRUE(db.ok());
  const auto gl = runCli({"export", t / "db", "--lonlat", "11.58", "49.96", "-o", t / "m.glb", "--json"});
  ASSERT_EQ(gl.exitCode, 0) << gl.err;
  const auto gj = nlohmann::json::parse(gl.out);
  auto mod = db->modules->read(gj["modules"]["from"][0], gj["modules"]["from"][1]);
  ASSERT_TRUE(mod.ok());
  ASSERT_GT(mod->objects.size(), 0u);
  EXPECT_EQ(gj["objects"]["mode"], "instanced");
  EXPECT_EQ(gj["objects"]["count"], mod->objects.size());
  std::uint64_t iconTriangles = 0;
  for (const auto& o : mod->objects) iconTriangles += sandtable::iconpack::triangleCount(db->icons->icons[o.icon], 0);
  const auto flat = runCli({"export", t / "db", "--lonlat", "11.58", "49.96", "-o", t / "m.obj", "--json"});
  ASSERT_EQ(flat.exitCode, 0) << flat.err;
  const auto fj = nlohmann::json::parse(flat.out);
  EXPECT_EQ(fj["objects"]["mode"], "flatten");
  EXPECT_EQ(fj["triangles"].get<std::uint64_t>(), gj["triangles"].get<std::uint64_t>() + iconTriangles);
  const auto none = runCli({"export", t / "db", "--lonlat", "11.58", "49.96", "--objects", "none", "-o", t / "n.obj",
                            "--json"});
  EXPECT_EQ(nlohmann::json::parse(none.out)["triangles"], gj["triangles"]);
  const auto tree = runCli({"export", t / "db", "--icon", "tree", "-o", t / "tree.glb", "--json"});
  ASSERT_EQ(tree.exitCode, 0) << tree.err;
  EXPECT_EQ(nlohmann::json::parse(tree.out)["triangles"], 80);  // the built-in tree (docs/ICONS.md section 4)
  const auto unknown = runCli({"export", t / "db", "--icon", "tank", "-o", t / "tank.glb"});
  EXPECT_EQ(unknown.exitCode, 2);
  EXPECT_NE(unknown.err.find("--icon tank is not in icons.pack; it has tree"), std::string::npos) << unknown.err;
  const auto objInstanced = runCli({"export", t / "db", "--module", "0", "0", "--objects", "instanced", "-o", t / "x.obj"});
  EXPECT_EQ(objInstanced.exitCode, 2);

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

namespace {

struct Built {
  std::vector<std::vector<sandtable::module::Object>> objects;  ///< per module
  std::vector<std::vector<std::vector<float>>> y;                ///< per module, level, object
  nlohmann::json info;
};

Built readBack(const std::string& db) {
  Built b;
  auto d = sandtable::openDatabase(db);
  EXPECT_TRUE(d.ok());
  if (!d) return b;
  const auto& h = d->modules->header();
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto m = d->modules->read(kx, kz);
      EXPECT_TRUE(m.ok());
      if (!m) continue;
      b.objects.push_back(m->objects);
      b.y.emplace_back();
      for (const auto& l : m->levels) b.y.back().push_back(l.objectY);
    }
  }
  const auto info = runCli({"info", db, "--json"});
  EXPECT_EQ(info.exitCode, 0) << info.err;
  b.info = nlohmann::json::parse(info.out);
  return b;
}

}  // namespace

// Module version 6 stores the scatter rules, not the trees (docs/FORMAT.md
// §9.11): the same database built as version 5 and as version 6 has the
// same objects, the scattered ones bit for bit (position, scale, heading,
// cylinder; with exact heights the bases too), the explicit ones within
// the documented quantisation; info and validate agree.
TEST(ObjectsBuild, version6RegeneratesTheTreesVersion5Stored) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("objv6");
  for (const char* step : {"0.01", "0"}) {
    auto v5 = bayreuthBuild(t / "v5"), v6 = bayreuthBuild(t / "v6");
    v5.insert(v5.end(), {"--module-version", "5", "--height-step", step});
    v6.insert(v6.end(), {"--height-step", step});
    ASSERT_EQ(runCli(v5).exitCode, 0);
    ASSERT_EQ(runCli(v6).exitCode, 0);
    EXPECT_EQ(runCli({"validate", t / "v6"}).exitCode, 0);
    const Built a = readBack(t / "v5"), b = readBack(t / "v6");
    EXPECT_EQ(a.info["objects"], b.info["objects"]);
    EXPECT_EQ(a.info["objects_by_class"], b.info["objects_by_class"]);
    ASSERT_EQ(a.objects.size(), b.objects.size());
    const bool exact = std::string(step) == "0";
    std::uint64_t trees = 0, points = 0;
    for (std::size_t k = 0; k < a.objects.size(); ++k) {
      ASSERT_EQ(a.objects[k].size(), b.objects[k].size()) << "module " << k;
      // Both lists are sorted by (icon, z, x): trees line up one to one;
      // an explicit point may swap with a tree of equal icon at its place.
      for (std::size_t o = 0; o < a.objects[k].size(); ++o) {
        const auto& p = a.objects[k][o];
        const auto& q = b.objects[k][o];
        ASSERT_EQ(p.icon, q.icon);
        ASSERT_EQ(p.cls, q.cls) << "module " << k << " object " << o;
        if (sandtable::module::isScattered(q.id)) {
          ++trees;
          ASSERT_TRUE(p.x == q.x && p.z == q.z && p.scale == q.scale && p.heading == q.heading && p.radius == q.radius &&
                      p.height == q.height)
              << "module " << k << " tree " << o;
        } else {
          ++points;
          EXPECT_NEAR(p.x, q.x, 0.02);
          EXPECT_NEAR(p.z, q.z, 0.02);
        }
        for (std::size_t l = 0; l < a.y[k].size(); ++l) {
          if (exact && sandtable::module::isScattered(q.id)) {
            ASSERT_EQ(a.y[k][l][o], b.y[k][l][o]) << "module " << k << " level " << l << " tree " << o;
          } else if (sandtable::module::isScattered(q.id)) {
            ASSERT_NEAR(a.y[k][l][o], b.y[k][l][o], 0.0051) << "module " << k << " level " << l << " tree " << o;
          }
        }
      }
    }
    EXPECT_GT(trees, 1000u);
    EXPECT_EQ(trees + points, b.info["objects"].get<std::uint64_t>());
    const auto size = [&](const char* db) { return fs::file_size(t / (std::string(db) + "/modules.pack")); };
    std::printf("height step %s: modules.pack v5 %ju bytes, v6 %ju bytes, %ju trees\n", step, std::uintmax_t(size("v5")),
                std::uintmax_t(size("v6")), std::uintmax_t(trees));
    if (exact) continue;
    // `upgrade` turns the version 5 database into version 6 with every
    // object explicit: the same objects within the quantisation, validated.
    const auto up = runCli({"upgrade", t / "v5"});
    ASSERT_EQ(up.exitCode, 0) << up.err;
    EXPECT_EQ(runCli({"validate", t / "v5"}).exitCode, 0);
    const Built c = readBack(t / "v5");
    EXPECT_EQ(c.info["objects_by_class"], a.info["objects_by_class"]);
    ASSERT_EQ(c.objects.size(), a.objects.size());
    for (std::size_t k = 0; k < a.objects.size(); ++k) {
      ASSERT_EQ(c.objects[k].size(), a.objects[k].size()) << "module " << k;
      // Quantised positions may swap neighbours in the (icon, z, x) order:
      // each version 5 object has its own within a step (1.5 cm).
      std::vector<bool> used(c.objects[k].size(), false);
      for (const auto& p : a.objects[k]) {
        bool found = false;
        for (std::size_t o = 0; o < c.objects[k].size() && !found; ++o) {
          const auto& q = c.objects[k][o];
          if (used[o] || q.icon != p.icon || std::fabs(p.x - q.x) > 0.015 || std::fabs(p.z - q.z) > 0.015) continue;
          EXPECT_FALSE(sandtable::module::isScattered(q.id));
          used[o] = found = true;
        }
        ASSERT_TRUE(found) << "module " << k << " object at " << p.x << ", " << p.z;
      }
    }
    std::printf("upgraded v5 -> v6 (objects explicit): modules.pack %ju bytes\n", std::uintmax_t(size("v5")));
  }
}
