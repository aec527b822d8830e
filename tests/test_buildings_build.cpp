// Buildings in a real build (docs/CULTURE.md, "Buildings"): footprints of
// the extruded class become walls and a flat roof at priority 99, at the
// height their attributes give, standing on the grid's own surface, with
// courtyards open, and no longer in the skin. Footprints are written here
// in lon/lat and projected by the test itself (OGR), and the ground comes
// from the grid's posts, not from the builder's modules.
#include <gtest/gtest.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <fstream>
#include <memory>
#include <optional>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/pack.h"
#include "test_support.h"

using namespace sandtable;
using namespace sandtable::test;

namespace {

// A square footprint of `side` metres (about: degrees at 49.96 N) centred
// at (lon, lat), optionally with a square hole of `hole` metres.
constexpr double kLatM = 1.0 / 111200.0, kLonM = 1.0 / 71600.0;
std::string square(double lon, double lat, double side, double hole) {
  const auto ring = [&](double s, bool reverse) {
    const double dx = s / 2 * kLonM, dy = s / 2 * kLatM;
    std::array<std::array<double, 2>, 5> p{{{lon - dx, lat - dy}, {lon + dx, lat - dy}, {lon + dx, lat + dy},
                                            {lon - dx, lat + dy}, {lon - dx, lat - dy}}};
    if (reverse) std::reverse(p.begin(), p.end());
    std::string out = "[";
    for (std::size_t k = 0; k < p.size(); ++k) {
      out += k ? ", [" : "[";
      out += std::to_string(p[k][0]);
      out += ", ";
      out += std::to_string(p[k][1]);
      out += "]";
    }
    return out + "]";
  };
  std::string out = "[";
  out += ring(side, false);
  if (hole > 0) {
    out += ", ";
    out += ring(hole, true);
  }
  out += "]";
  return out;
}

struct Footprint {
  double lon, lat, side, hole;
  std::string properties;
  double height;  ///< what the attributes ask for
};

const std::array<Footprint, 4> kFootprints{{
    {11.5800, 49.9600, 20, 0, R"("building": "yes", "height": "20 m")", 20},
    {11.5830, 49.9600, 20, 0, R"("building": "house", "building:levels": "4")", 12},  // 4 x storey 3
    {11.5800, 49.9580, 20, 0, R"("building": "yes")", 8},                             // the class's extrude=8
    {11.5830, 49.9580, 40, 16, R"("building": "yes")", 8},                            // a courtyard
}};

std::string footprintsJson() {
  std::string s = R"({"type": "FeatureCollection", "features": [)";
  for (std::size_t k = 0; k < kFootprints.size(); ++k) {
    const Footprint& f = kFootprints[k];
    if (k) s += ",";
    s += R"({"type": "Feature", "properties": {)";
    s += f.properties;
    s += R"(}, "geometry": {"type": "Polygon", "coordinates": )";
    s += square(f.lon, f.lat, f.side, f.hole);
    s += "}}";
  }
  return s + "]}";
}

/// lon/lat to UTM 32N easting/northing through OGR (the database's CRS).
std::array<double, 2> utm(double lon, double lat) {
  OGRSpatialReference wgs, zone;
  wgs.SetWellKnownGeogCS("WGS84");
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  zone.importFromEPSG(32632);
  zone.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  auto* ct = OGRCreateCoordinateTransformation(&wgs, &zone);
  double x = lon, y = lat;
  EXPECT_TRUE(ct && ct->Transform(1, &x, &y));
  OGRCoordinateTransformation::DestroyCT(ct);
  return {x, y};
}

/// The grid's surface at world (x, z): posts split along SW-NE (docs/FORMAT.md).
double gridHeight(const grid::GridFile& g, double x, double z) {
  const double s = g.spacing();
  const auto i = std::uint32_t(std::floor(x / s)), j = std::uint32_t(std::floor(z / s));
  const double u = x / s - i, v = z / s - j;
  const double nw = g.elevation(i, j), ne = g.elevation(i + 1, j), sw = g.elevation(i, j + 1),
               se = g.elevation(i + 1, j + 1);
  if (u + v <= 1) return nw + u * (ne - nw) + v * (sw - nw);
  return se + (1 - u) * (sw - se) + (1 - v) * (ne - se);
}

struct Roofs {
  std::vector<std::array<module::Vertex, 3>> triangles;  ///< world x, z; y as stored
  bool skinHasBuildingClass = false;
};

/// Level `level`'s horizontal priority-99 triangles of every module, in world metres.
Roofs roofs(const std::string& db, std::uint32_t level, std::uint16_t buildingClass) {
  Roofs out;
  auto r = pack::PackReader::open(db);
  EXPECT_TRUE(r.ok()) << r.error();
  const pack::IndexHeader h = r.value()->header();
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto m = r.value()->read(kx, kz);
      EXPECT_TRUE(m.ok()) << m.error();
      const module::Level& l = m->levels[level];
      for (const module::Group& g : l.groups) {
        if (g.priority == module::kPrioritySkin && g.material == buildingClass) out.skinHasBuildingClass = true;
        if (g.priority != module::kPriorityObject) continue;
        for (std::uint32_t k = g.firstIndex; k + 3 <= g.firstIndex + g.indexCount; k += 3) {
          std::array<module::Vertex, 3> t{};
          for (int q = 0; q < 3; ++q) {
            t[std::size_t(q)] = l.vertices[l.indices[k + std::uint32_t(q)]];
            t[std::size_t(q)].x += float(kx * h.moduleSize);
            t[std::size_t(q)].z += float(kz * h.moduleSize);
          }
          // Heights are stored to 1 cm (FORMAT.md 9.9): a roof is level within that.
          if (std::fabs(t[0].y - t[1].y) < 0.02f && std::fabs(t[0].y - t[2].y) < 0.02f) out.triangles.push_back(t);
        }
      }
    }
  }
  return out;
}

/// The roof height over world (x, z); nullopt where no roof covers it.
std::optional<double> roofAt(const Roofs& r, double x, double z) {
  for (const auto& t : r.triangles) {
    const auto side = [&](const module::Vertex& a, const module::Vertex& b) {
      return (double(b.x) - a.x) * (z - a.z) - (double(b.z) - a.z) * (x - a.x);
    };
    const double s0 = side(t[0], t[1]), s1 = side(t[1], t[2]), s2 = side(t[2], t[0]);
    if ((s0 >= 0 && s1 >= 0 && s2 >= 0) || (s0 <= 0 && s1 <= 0 && s2 <= 0)) return t[0].y;
  }
  return std::nullopt;
}

double roofArea(const Roofs& r, double x0, double z0, double x1, double z1) {
  double a = 0;
  for (const auto& t : r.triangles) {
    const double cx = (t[0].x + t[1].x + t[2].x) / 3, cz = (t[0].z + t[1].z + t[2].z) / 3;
    if (cx < x0 || cx > x1 || cz < z0 || cz > z1) continue;
    a += std::fabs((double(t[1].x) - t[0].x) * (double(t[2].z) - t[0].z) -
                   (double(t[2].x) - t[0].x) * (double(t[1].z) - t[0].z)) / 2;
  }
  return a;
}

TEST(BuildingsBuild, footprintsStandOnTheGridAtTheirAttributesHeightWithCourtyardsOpen) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("buildings");
  const std::string fp = t / "footprints.geojson";
  std::ofstream(fp) << footprintsJson();
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.575", "49.955",
                         "11.59", "49.965", "--spacing", "30", "--culture", fp, "-o", t / "db", "--json"});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto j = nlohmann::json::parse(b.out);
  EXPECT_EQ(j["culture"]["buildings"], 4);
  // Level l > 0 keeps footprints of at least (spacing_l / 4)^2: 20 m squares
  // (400 m^2) to level 1 (60 m), the courtyard block (1,344 m^2) to level 2.
  const auto& perLevel = j["modules"]["per_level"];
  ASSERT_EQ(perLevel.size(), 4u);
  const std::array<int, 4> expected{4, 4, 1, 0};
  for (std::size_t l = 0; l < 4; ++l) EXPECT_EQ(perLevel[l]["buildings"], expected[l]) << "level " << l;
  EXPECT_EQ(runCli({"validate", t / "db"}).exitCode, 0);

  auto g = grid::GridFile::open(t / "db/grid.stg");
  ASSERT_TRUE(g.ok()) << g.error();
  const grid::Header& h = g.value()->header();
  const Roofs level0 = roofs(t / "db", 0, 11);
  EXPECT_FALSE(level0.skinHasBuildingClass) << "footprints must leave the skin";
  const auto world = [&](double lon, double lat) {
    const auto en = utm(lon, lat);
    return std::array<double, 2>{en[0] - h.originEasting, h.originNorthing - en[1]};
  };
  for (const Footprint& f : kFootprints) {
    const double half = f.side / 2;
    double ground = INFINITY;
    for (const double sx : {-1.0, 1.0}) {
      for (const double sy : {-1.0, 1.0}) {
        const auto c = world(f.lon + sx * half * kLonM, f.lat + sy * half * kLatM);
        ground = std::min(ground, gridHeight(*g.value(), c[0], c[1]));
      }
    }
    const auto c = world(f.lon, f.lat);
    // A point on the solid part: the centre, or for the courtyard block
    // halfway between the hole and the outer wall.
    const double solidDx = f.hole > 0 ? (f.side + f.hole) / 4 : 0;
    const auto solid = world(f.lon + solidDx * kLonM, f.lat);
    const auto y = roofAt(level0, solid[0], solid[1]);
    ASSERT_TRUE(y.has_value()) << f.properties << ": no roof";
    EXPECT_NEAR(*y - ground, f.height, 0.02) << f.properties;
    if (f.hole > 0) {
      EXPECT_FALSE(roofAt(level0, c[0], c[1]).has_value()) << "the courtyard is roofed over";
      const double area = roofArea(level0, c[0] - half - 2, c[1] - half - 2, c[0] + half + 2, c[1] + half + 2);
      const double want = f.side * f.side - f.hole * f.hole;
      EXPECT_NEAR(area, want, 0.02 * want);
    }
  }
}

}  // namespace

namespace {

/// Building polygons of an OSM extract that lie (by their envelope) on the
/// database's rectangle, counted with OGR here: `building` set, and none of
/// the sample table's ignore rules (tunnel, covered, underground) on them.
std::uint64_t osmBuildingsOn(const std::string& osm, const std::string& db) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(("/vsigzip/" + osm).c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  EXPECT_TRUE(ds);
  if (!ds) return 0;
  const auto m = nlohmann::json::parse(slurpFile(db + "/manifest.json"));
  OGRSpatialReference wgs, frame;
  wgs.SetWellKnownGeogCS("WGS84");
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  frame.importFromWkt(m["crs"]["wkt"].get<std::string>().c_str());
  frame.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs, &frame));
  const auto& grid = m["grid"];
  const double west = grid["origin_easting"], north = grid["origin_northing"];
  const double east = west + grid["spacing_m"].get<double>() * (grid["posts_x"].get<double>() - 1);
  const double south = north - grid["spacing_m"].get<double>() * (grid["posts_z"].get<double>() - 1);
  std::uint64_t n = 0;
  for (auto& f : ds->GetLayerByName("multipolygons")) {
    const int b = f->GetFieldIndex("building");
    if (b < 0 || !f->IsFieldSetAndNotNull(b)) continue;
    const int o = f->GetFieldIndex("other_tags");
    const std::string tags = o >= 0 && f->IsFieldSetAndNotNull(o) ? f->GetFieldAsString(o) : "";
    bool ignored = false;
    for (const char* t : {"\"tunnel\"=>\"yes\"", "\"tunnel\"=>\"culvert\"", "\"tunnel\"=>\"building_passage\"",
                          "\"covered\"=>\"yes\"", "\"location\"=>\"underground\""}) {
      ignored = ignored || tags.find(t) != std::string::npos;
    }
    OGRGeometry* g = f->GetGeometryRef();
    if (ignored || !g || g->transform(ct.get()) != OGRERR_NONE) continue;
    OGREnvelope e;
    g->getEnvelope(&e);
    n += e.MaxX >= west && e.MinX <= east && e.MaxY >= south && e.MinY <= north;
  }
  return n;
}

}  // namespace

TEST(BuildingsBuild, realOsmBuildingsAreTheExtractsFootprintsLessTheDroppedOnes) {
  SANDTABLE_REQUIRE_DATA();
  struct Case {
    const char* name;
    std::string elevation, osm;
    std::vector<std::string> extent;
  };
  const Case cases[] = {
      {"monaco", data("elevation/srtm/N43E007.hgt.zip"), data("culture/osm/monaco.osm.gz"),
       {"7.405", "43.72", "7.44", "43.75"}},
      {"bayreuth", data("elevation/srtm/N49E011.hgt.zip"), data("culture/osm/north-bayreuth.osm.gz"),
       {"11.55", "49.94", "11.62", "49.99"}}};
  TempDir t("osmbuildings");
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<std::string> args = {"build", "--elevation", c.elevation, "--extent"};
    args.insert(args.end(), c.extent.begin(), c.extent.end());
    args.insert(args.end(), {"--spacing", "10", "--culture", c.osm, "--json", "-o", t / c.name});
    const auto b = runCli(args);
    ASSERT_EQ(b.exitCode, 0) << b.err;
    const auto j = nlohmann::json::parse(b.out);
    const auto& cls = j["culture"]["classes"]["building"];
    const std::uint64_t read = cls["read"], dropped = cls["dropped"], built = j["culture"]["buildings"];
    const std::uint64_t gdal = osmBuildingsOn(c.osm, t / c.name);
    ASSERT_GT(gdal, 100u);
    // Every footprint GDAL finds on the database is extruded; every other
    // building the extract holds is read and dropped, with its reason
    // (wholly outside the database).
    EXPECT_EQ(built, gdal);
    EXPECT_EQ(built, read - dropped);
    std::uint64_t explained = 0;
    for (const auto& [reason, r] : j["culture"]["reasons"].items()) {
      if (r["action"] == "dropped") explained += r["count"].get<std::uint64_t>();
    }
    EXPECT_GE(explained, dropped);
    std::printf("%s: %llu building polygons on the database (OGR), %llu extruded, %llu read, %llu dropped\n",
                c.name, static_cast<unsigned long long>(gdal), static_cast<unsigned long long>(built),
                static_cast<unsigned long long>(read), static_cast<unsigned long long>(dropped));
  }
}
