// Culture: loading (classification, repair, clipping), widening, and the
// decaling of skin and decals onto every level's triangles, with the
// invariants checked on every triangle: the skin tiles each grid triangle,
// every vertex lies in its triangle and its plane, no two vertices of one
// triangle's layer are closer than the merge tolerance. Synthetic scenes
// are written as GeoJSON in UTM 32N; real data comes from ../shared/data.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <ogr_api.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>

#include "sandtable/base/jobs.h"
#include "sandtable/converters/crs.h"
#include "sandtable/converters/culture.h"
#include "sandtable/converters/synth.h"
#include "sandtable/formats/materials.h"
#include "sandtable/testing/require.h"

namespace fs = std::filesystem;
using namespace sandtable;
using namespace sandtable::convert;

namespace {

constexpr double kE0 = 500000, kN0 = 5500000;  // frame origin of the synthetic scenes (UTM 32N)
constexpr double kPi = std::numbers::pi;

/// Decal areas match the exact union up to this fraction: merging moves
/// points on a triangle edge up to 0.13 m onto its corners.
constexpr double kMergeArea = 1e-3;

const std::string kRoot = SANDTABLE_SOURCE_DIR;
const std::string kData = kRoot + "/../shared/data/culture";

struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name)
      : dir(fs::temp_directory_path() / ("sandtable_culture_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

materials::Table sampleTable() {
  auto t = materials::readFile(kRoot + "/samples/materials.txt");
  EXPECT_TRUE(t) << t.error();
  return t.value();
}

std::uint16_t classId(const materials::Table& t, const std::string& name) {
  const materials::Class* c = t.findByName(name);
  EXPECT_NE(c, nullptr) << name;
  return c ? c->id : 0;
}

std::string wktOf(int epsg) {
  OGRSpatialReference s;
  s.importFromEPSG(epsg);
  char* w = nullptr;
  s.exportToWkt(&w);
  std::string out = w;
  CPLFree(w);
  return out;
}

// ------------------------------------------------------------ scenes

using Pt = std::array<double, 2>;  // world metres: x east, z south
using Path = std::vector<Pt>;

/// One GeoJSON feature in world metres.
struct Feat {
  std::string props;  // JSON object body, e.g. "\"highway\": \"primary\""
  bool polygon = false;
  std::vector<Path> parts;  // line: one path; polygon: rings (closed unless a test says not)
};

std::string coords(const Path& p) {
  std::ostringstream o;
  o.precision(17);
  o << "[";
  for (std::size_t k = 0; k < p.size(); ++k) o << (k ? "," : "") << "[" << kE0 + p[k][0] << "," << kN0 - p[k][1] << "]";
  o << "]";
  return o.str();
}

std::string writeGeoJson(const fs::path& file, const std::vector<Feat>& feats) {
  std::ofstream out(file);
  out << "{\"type\":\"FeatureCollection\",\"crs\":{\"type\":\"name\",\"properties\":{\"name\":"
         "\"urn:ogc:def:crs:EPSG::32632\"}},\"features\":[\n";
  for (std::size_t k = 0; k < feats.size(); ++k) {
    const Feat& f = feats[k];
    out << (k ? ",\n" : "") << "{\"type\":\"Feature\",\"properties\":{" << f.props << "},\"geometry\":{";
    if (f.polygon) {
      out << "\"type\":\"Polygon\",\"coordinates\":[";
      for (std::size_t r = 0; r < f.parts.size(); ++r) out << (r ? "," : "") << coords(f.parts[r]);
      out << "]";
    } else {
      out << "\"type\":\"LineString\",\"coordinates\":" << coords(f.parts[0]);
    }
    out << "}}";
  }
  out << "\n]}\n";
  return file.string();
}

Path closed(Path p) {
  p.push_back(p.front());
  return p;
}

Path circle(double cx, double cz, double r, int n, double phase = 0.1) {
  Path p;
  for (int k = 0; k < n; ++k) {
    const double a = phase + 2 * kPi * k / n;
    p.push_back({cx + r * std::cos(a), cz + r * std::sin(a)});
  }
  return closed(p);
}

double shoelace(const Path& p) {
  double a = 0;
  for (std::size_t k = 0; k + 1 < p.size(); ++k) a += p[k][0] * p[k + 1][1] - p[k + 1][0] * p[k][1];
  return std::fabs(0.5 * a);
}

Feat line(const std::string& props, Path p) { return {props, false, {std::move(p)}}; }
Feat area(const std::string& props, std::vector<Path> rings) { return {props, true, std::move(rings)}; }

std::shared_ptr<const Culture> loadScene(const Scratch& s, const std::vector<Feat>& feats, const materials::Table& t,
                                         double widthM = 1000, double heightM = 1000) {
  CultureOptions o;
  o.sources = {writeGeoJson(s.dir / "scene.geojson", feats)};
  const CultureFrame frame{wktOf(32632), kE0, kN0, widthM, heightM};
  auto c = Culture::load(o, t, frame);
  EXPECT_TRUE(c) << c.error();
  return c ? c.value() : nullptr;
}

// ------------------------------------------------------------ lattices

using HeightFn = std::function<double(double, double)>;

double flat(double, double) { return 100.0; }
double hills(double x, double z) { return 300 + 40 * std::sin(x / 170.0) * std::cos(z / 230.0) + 0.013 * x; }

/// The lattice of level `level` of the module whose north-west corner is at
/// world (mx, mz), `squares` level-0 squares of `spacing` on a side,
/// clamped to the database extent.
LevelLattice lattice(double mx, double mz, int squares, double spacing, int level, const HeightFn& h,
                     double dbW = 1e30, double dbH = 1e30) {
  LevelLattice lat;
  lat.moduleX = mx, lat.moduleZ = mz;
  lat.spacing = spacing * (1 << level);
  const int nx = int(std::min<double>(squares, std::floor((dbW - mx) / spacing + 1e-9)));
  const int nz = int(std::min<double>(squares, std::floor((dbH - mz) / spacing + 1e-9)));
  for (int i = 0; i < nx; i += 1 << level) lat.xs.push_back(i * spacing);
  lat.xs.push_back(nx * spacing);
  for (int j = 0; j < nz; j += 1 << level) lat.zs.push_back(j * spacing);
  lat.zs.push_back(nz * spacing);
  for (double z : lat.zs) {
    for (double x : lat.xs) lat.heights.push_back(float(h(mx + x, mz + z)));
  }
  return lat;
}

// ------------------------------------------------------------ invariants

struct LevelCheck {
  std::map<std::uint16_t, double> skin, decal;  // area per class, m^2
  std::size_t triangles = 0;
  std::size_t closePairs = 0;  // vertices of one triangle's layer closer than the tolerance
  double worstTiling = 0;      // relative
  double worstPlane = 0;       // metres
  double worstInside = 0;      // metres
};

double area2(const module::Vertex& a, const module::Vertex& b, const module::Vertex& c) {
  return (double(b.x) - a.x) * (double(c.z) - a.z) - (double(b.z) - a.z) * (double(c.x) - a.x);
}

/// Checks every invariant of one decaled level (EXPECTs) and sums areas.
LevelCheck checkLevel(const module::Level& lv, const LevelLattice& lat, double tol = 0.1) {
  LevelCheck r;
  const std::size_t nx = lat.xs.size() - 1, nz = lat.zs.size() - 1;
  EXPECT_EQ(lv.squaresX, nx);
  EXPECT_EQ(lv.squaresZ, nz);
  EXPECT_EQ(lv.spacing, lat.spacing);
  // The lattice posts come first, with the grid's heights bit for bit.
  EXPECT_GE(lv.vertices.size(), (nx + 1) * (nz + 1));
  for (std::size_t j = 0; j <= nz && lv.vertices.size() >= (nx + 1) * (nz + 1); ++j) {
    for (std::size_t i = 0; i <= nx; ++i) {
      const auto& v = lv.vertices[j * (nx + 1) + i];
      EXPECT_EQ(v.x, float(lat.xs[i]));
      EXPECT_EQ(v.z, float(lat.zs[j]));
      EXPECT_EQ(v.y, lat.heights[j * (nx + 1) + i]);
    }
  }
  std::uint32_t expectFirst = 0;
  std::map<std::pair<std::uint32_t, int>, double> skinSum;
  std::map<std::tuple<std::uint32_t, int, int>, std::set<std::uint32_t>> layerVerts;
  for (std::size_t g = 0; g < lv.groups.size(); ++g) {
    const module::Group& gr = lv.groups[g];
    if (g > 0) {
      const module::Group& p = lv.groups[g - 1];
      const auto ka = std::make_tuple(p.priority, p.square, int(p.half), p.material);
      const auto kb = std::make_tuple(gr.priority, gr.square, int(gr.half), gr.material);
      EXPECT_LT(ka, kb) << "group " << g << " out of order";
    }
    EXPECT_EQ(gr.firstIndex, expectFirst);
    EXPECT_GT(gr.indexCount, 0u);
    EXPECT_EQ(gr.indexCount % 3, 0u);
    expectFirst = gr.firstIndex + gr.indexCount;
    EXPECT_LT(gr.square, nx * nz);
    if (gr.square >= nx * nz) return r;
    // Buildings (priority 99) stand on the skin: walls and roofs, checked by BuildingsBuild.
    if (gr.priority == module::kPriorityObject) continue;
    const std::size_t sx = gr.square % nx, sz = gr.square / nx;
    const double x0 = lat.xs[sx], x1 = lat.xs[sx + 1], z0 = lat.zs[sz], z1 = lat.zs[sz + 1];
    const std::size_t w = nx + 1;
    const double hNW = lat.heights[sz * w + sx], hNE = lat.heights[sz * w + sx + 1];
    const double hSW = lat.heights[(sz + 1) * w + sx], hSE = lat.heights[(sz + 1) * w + sx + 1];
    const bool upper = gr.half == module::Half::upper;
    EXPECT_TRUE(gr.half != module::Half::skirt);
    for (std::uint32_t k = gr.firstIndex; k < gr.firstIndex + gr.indexCount; k += 3) {
      const auto& a = lv.vertices[lv.indices[k]];
      const auto& b = lv.vertices[lv.indices[k + 1]];
      const auto& c = lv.vertices[lv.indices[k + 2]];
      const double a2 = area2(a, b, c);
      EXPECT_LT(a2, 0) << "triangle not counter-clockwise seen from above, square " << gr.square << " half "
                       << int(gr.half) << " priority " << int(gr.priority) << " material " << gr.material << ": ("
                       << a.x << ", " << a.z << ") (" << b.x << ", " << b.z << ") (" << c.x << ", " << c.z << ")";
      ++r.triangles;
      const double area = 0.5 * std::fabs(a2);
      if (gr.priority == module::kPrioritySkin) {
        skinSum[{gr.square, int(gr.half)}] += area;
        r.skin[gr.material] += area;
      } else {
        r.decal[gr.material] += area;
      }
      for (std::uint32_t idx : {lv.indices[k], lv.indices[k + 1], lv.indices[k + 2]}) {
        layerVerts[{gr.square, int(gr.half), gr.priority}].insert(idx);
        const auto& v = lv.vertices[idx];
        const double fx = (v.x - x0) / (x1 - x0), fz = (v.z - z0) / (z1 - z0);
        const double y = upper ? hNW + fx * (hNE - hNW) + fz * (hSW - hNW)
                               : hSE + (1 - fx) * (hSW - hSE) + (1 - fz) * (hNE - hSE);
        r.worstPlane = std::max(r.worstPlane, std::fabs(v.y - y));
        // Distance outside the triangle.
        double out = 0;
        if (upper) {
          out = std::max({x0 - v.x, z0 - v.z, ((v.x - x0) / (x1 - x0) + (v.z - z0) / (z1 - z0) - 1) * std::min(x1 - x0, z1 - z0) / std::sqrt(2.0)});
        } else {
          out = std::max({v.x - x1, v.z - z1, (1 - (v.x - x0) / (x1 - x0) - (v.z - z0) / (z1 - z0)) * std::min(x1 - x0, z1 - z0) / std::sqrt(2.0)});
        }
        r.worstInside = std::max(r.worstInside, out);
      }
    }
  }
  EXPECT_EQ(expectFirst, lv.indices.size());
  // The skin tiles every grid triangle.
  for (std::size_t sq = 0; sq < nx * nz; ++sq) {
    const std::size_t sx = sq % nx, sz = sq / nx;
    const double a = 0.5 * (lat.xs[sx + 1] - lat.xs[sx]) * (lat.zs[sz + 1] - lat.zs[sz]);
    for (int half = 0; half < 2; ++half) {
      const auto it = skinSum.find({std::uint32_t(sq), half});
      const double got = it == skinSum.end() ? 0 : it->second;
      const double rel = std::fabs(got - a) / a;
      r.worstTiling = std::max(r.worstTiling, rel);
      EXPECT_LE(rel, 1e-6) << "square " << sq << " half " << half << ": skin " << got << " m2 of " << a;
    }
  }
  // No two vertices of one triangle's layer closer than the tolerance.
  for (const auto& [key, ids] : layerVerts) {
    std::vector<std::uint32_t> v(ids.begin(), ids.end());
    for (std::size_t i = 0; i < v.size(); ++i) {
      for (std::size_t j = i + 1; j < v.size(); ++j) {
        const auto& p = lv.vertices[v[i]];
        const auto& q = lv.vertices[v[j]];
        const double d = std::hypot(double(p.x) - q.x, double(p.z) - q.z);
        if (d > 0 && d < tol * 0.999) {  // equal positions: one point (layers keep their own texture coordinates)
          if (r.closePairs++ < 3) {
            std::printf("close: square %u half %d priority %d: (%.6f, %.6f) (%.6f, %.6f) d %.4f\n", std::get<0>(key),
                        std::get<1>(key), std::get<2>(key), p.x, p.z, q.x, q.z, d);
          }
        }
      }
    }
  }
  EXPECT_LE(r.worstPlane, 1e-3);
  EXPECT_LE(r.worstInside, 1e-3);
  return r;
}

struct Decaled {
  std::vector<module::Level> levels;
  std::vector<LevelCheck> checks;
  std::vector<DecalStats> stats;
  std::vector<double> ms;  // decalLevel wall time per level (level 0 builds the partition)
};

/// Decals all `levels` levels of the module at (mx, mz) and checks them.
Decaled decalModule(const Culture& c, double mx, double mz, int levels = 4, const HeightFn& h = hills,
                    double dbW = 1e30, double dbH = 1e30, int squares = 32, double spacing = 31.25) {
  Decaled d;
  for (int l = 0; l < levels; ++l) {
    const LevelLattice lat = lattice(mx, mz, squares, spacing, l, h, dbW, dbH);
    module::Level lv;
    const auto t0 = std::chrono::steady_clock::now();
    d.stats.push_back(c.decalLevel(lat, lv));
    d.ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    d.checks.push_back(checkLevel(lv, lat));
    EXPECT_EQ(d.checks.back().closePairs, 0u) << "level " << l;
    EXPECT_EQ(d.stats.back().failures, 0u) << "level " << l;
    d.levels.push_back(std::move(lv));
  }
  return d;
}

double sumOf(const std::map<std::uint16_t, double>& m) {
  double s = 0;
  for (const auto& [k, v] : m) s += v;
  return s;
}

// ------------------------------------------------------------ roads

TEST(Culture, straightRoadAreaIsLengthTimesWidth) {
  Scratch s("straight");
  const auto t = sampleTable();
  const Pt a{150, 300}, b{850, 620};
  auto c = loadScene(s, {line("\"highway\": \"secondary\", \"width\": \"10\"", {a, b})}, t);
  ASSERT_TRUE(c);
  const double want = std::hypot(b[0] - a[0], b[1] - a[1]) * 10;
  const Decaled d = decalModule(*c, 0, 0);
  for (int l = 0; l < 4; ++l) {
    const double got = d.checks[l].decal.at(classId(t, "secondary"));
    EXPECT_NEAR(got, want, 0.005 * want) << "level " << l;
    EXPECT_NEAR(got, want, kMergeArea * want) << "level " << l;
    EXPECT_NEAR(sumOf(d.checks[l].skin), 1e6, 1e-3);
  }
  EXPECT_EQ(c->stats().perClass.at("secondary").read, 1u);
  EXPECT_NEAR(c->stats().perClass.at("secondary").lengthKm, want / 10 / 1000, 1e-9);
}

TEST(Culture, partitionIsBuiltOncePerModuleAndTimedByStage) {
  // The profile's stage timers (docs/CULTURE.md, section 13): the first
  // level of a module builds its partition and counts it, with its parts
  // inside the whole; the other levels reuse it and count none; a second
  // module builds its own.
  Scratch s("stages");
  const auto t = sampleTable();
  auto c = loadScene(s, {line("\"highway\": \"secondary\", \"width\": \"10\"", {{150, 300}, {1850, 620}})}, t,
                     2000, 1000);
  ASSERT_TRUE(c);
  for (double mx : {0.0, 1000.0}) {
    const Decaled d = decalModule(*c, mx, 0, 4, hills, 2000, 1000);
    const DecalStats& first = d.stats[0];
    EXPECT_GT(first.partitionSeconds, 0.0) << mx;
    EXPECT_GT(first.arrangementSeconds, 0.0) << mx;
    EXPECT_LE(first.gatherSeconds + first.arrangementSeconds + first.piecesSeconds, first.partitionSeconds) << mx;
    for (int l = 0; l < 4; ++l) EXPECT_GT(d.stats[l].cutSeconds, 0.0) << mx << " level " << l;
    for (int l = 1; l < 4; ++l) {
      EXPECT_EQ(d.stats[l].partitionSeconds, 0.0) << mx << " level " << l;
      EXPECT_EQ(d.stats[l].arrangementSeconds, 0.0) << mx << " level " << l;
    }
  }
}

TEST(Culture, roadAcrossModuleBoundariesKeepsItsAreaAtEveryLevel) {
  Scratch s("across");
  const auto t = sampleTable();
  // Through six modules (three across, two down), crossing module edges on
  // both axes and passing a module corner's neighbourhood.
  const Pt a{150, 250}, b{2850, 1650};
  auto c = loadScene(s, {line("\"highway\": \"secondary\", \"width\": \"10\"", {a, b})}, t, 3000, 2000);
  ASSERT_TRUE(c);
  const double want = std::hypot(b[0] - a[0], b[1] - a[1]) * 10;
  std::array<double, 4> got{};
  for (double mz : {0.0, 1000.0}) {
    for (double mx : {0.0, 1000.0, 2000.0}) {
      const Decaled d = decalModule(*c, mx, mz, 4, hills, 3000, 2000);
      for (int l = 0; l < 4; ++l) {
        const auto& decal = d.checks[l].decal;
        const auto it = decal.find(classId(t, "secondary"));
        if (it != decal.end()) got[l] += it->second;
        EXPECT_NEAR(sumOf(d.checks[l].skin), 1e6, 1e-3) << mx << "," << mz << " level " << l;
      }
    }
  }
  for (int l = 0; l < 4; ++l) EXPECT_NEAR(got[l], want, kMergeArea * want) << "level " << l;
}

TEST(Culture, crossingRoadsOfOneClassAreUnited) {
  Scratch s("cross");
  const auto t = sampleTable();
  const double th = 20 * kPi / 180;
  const Pt m{500, 500};
  const Pt d1{std::cos(th), std::sin(th)}, d2{-std::sin(th), std::cos(th)};
  auto seg = [&](Pt d, double h) { return Path{{m[0] - h * d[0], m[1] - h * d[1]}, {m[0] + h * d[0], m[1] + h * d[1]}}; };
  auto c = loadScene(s,
                     {line("\"highway\": \"residential\", \"width\": \"6\"", seg(d1, 400)),
                      line("\"highway\": \"residential\", \"width\": \"8\"", seg(d2, 300))},
                     t);
  ASSERT_TRUE(c);
  const double want = 800 * 6 + 600 * 8 - 6 * 8;
  const Decaled d = decalModule(*c, 0, 0);
  for (int l = 0; l < 4; ++l) EXPECT_NEAR(d.checks[l].decal.at(classId(t, "street")), want, kMergeArea * (want)) << "level " << l;
}

TEST(Culture, tJunctionsLeaveNoGap) {
  const auto t = sampleTable();
  const double th = 35 * kPi / 180;
  const Pt d1{std::cos(th), std::sin(th)}, n1{-std::sin(th), std::cos(th)};
  const Pt m{480, 520};
  auto at = [&](double u, double v) { return Pt{m[0] + u * d1[0] + v * n1[0], m[1] + u * d1[1] + v * n1[1]}; };
  const std::string props = "\"highway\": \"residential\"";  // street, 6 m
  const double want = 800 * 6 + 300 * 6 - 3 * 6;
  {
    // B ends on A's centreline, between A's vertices.
    Scratch s("tee1");
    auto c = loadScene(s, {line(props, {at(-400, 0), at(400, 0)}), line(props, {at(0, 0), at(0, 300)})}, t);
    ASSERT_TRUE(c);
    const Decaled d = decalModule(*c, 0, 0);
    for (int l = 0; l < 4; ++l) EXPECT_NEAR(d.checks[l].decal.at(classId(t, "street")), want, kMergeArea * (want)) << l;
  }
  {
    // OSM-like: A split into two ways at the junction node, B starts there.
    Scratch s("tee2");
    auto c = loadScene(s,
                       {line(props, {at(-400, 0), at(0, 0)}), line(props, {at(0, 0), at(400, 0)}),
                        line(props, {at(0, 0), at(0, 300)})},
                       t);
    ASSERT_TRUE(c);
    const Decaled d = decalModule(*c, 0, 0);
    for (int l = 0; l < 4; ++l) EXPECT_NEAR(d.checks[l].decal.at(classId(t, "street")), want, kMergeArea * (want)) << l;
  }
  {
    // Two ways meeting end to end at an angle: the joint fills the wedge.
    Scratch s("elbow");
    auto c = loadScene(s, {line(props, {at(-400, 0), at(0, 0)}), line(props, {at(0, 0), at(0, 300)})}, t);
    ASSERT_TRUE(c);
    const Decaled d = decalModule(*c, 0, 0);
    // Rectangles, minus their overlap on the inside of the bend (h^2),
    // plus the joint outside it: a quarter of the octagon's 8 h^2 tan(pi/8).
    const double h = 3, wedge = 2 * h * h * std::tan(kPi / 8);
    const double elbow = 400 * 6 + 300 * 6 - h * h + wedge;
    for (int l = 0; l < 4; ++l) EXPECT_NEAR(d.checks[l].decal.at(classId(t, "street")), elbow, kMergeArea * (elbow)) << l;
  }
}

TEST(Culture, bendsAreMitredOrBevelled) {
  const auto t = sampleTable();
  for (const double turnDeg : {90.0, 135.0, 30.0}) {
    Scratch s("bend" + std::to_string(int(turnDeg)));
    const double a0 = 10 * kPi / 180, a1 = a0 + turnDeg * kPi / 180;
    const Pt v{500, 520};
    const Path p = {{v[0] - 300 * std::cos(a0), v[1] - 300 * std::sin(a0)}, v,
                    {v[0] + 300 * std::cos(a1), v[1] + 300 * std::sin(a1)}};
    auto c = loadScene(s, {line("\"highway\": \"secondary\", \"width\": \"10\"", p)}, t);
    ASSERT_TRUE(c);
    const double h = 5, phi = turnDeg * kPi / 180;
    // Mitre (turns up to 120 degrees): exactly centreline length x width.
    // Bevel: the mitre's tip triangle is cut off.
    const double want = turnDeg <= 120 ? 600 * 10 : 600 * 10 - h * h * std::tan(phi / 2) + 0.5 * h * h * std::sin(phi);
    const Decaled d = decalModule(*c, 0, 0);
    for (int l = 0; l < 4; ++l) {
      EXPECT_NEAR(d.checks[l].decal.at(classId(t, "secondary")), want, kMergeArea * (want)) << turnDeg << " level " << l;
    }
  }
}

TEST(Culture, loopRoadIsAPolygonWithAHole) {
  Scratch s("loop");
  const auto t = sampleTable();
  const Path ring = circle(500, 500, 200, 40);
  auto c = loadScene(s, {line("\"highway\": \"residential\", \"width\": \"6\"", ring)}, t);
  ASSERT_TRUE(c);
  // A closed polygon of n sides widened by h either side with mitres:
  // perimeter x width (the mitred outer ring and inner ring average out).
  double per = 0;
  for (std::size_t k = 0; k + 1 < ring.size(); ++k) per += std::hypot(ring[k + 1][0] - ring[k][0], ring[k + 1][1] - ring[k][1]);
  const Decaled d = decalModule(*c, 0, 0);
  for (int l = 0; l < 4; ++l) EXPECT_NEAR(d.checks[l].decal.at(classId(t, "street")), per * 6, kMergeArea * (per * 6)) << l;
}

// ------------------------------------------------------------ bounded work

/// Decal area of `cls` at level `l`, summed over the modules of a frame
/// of `w` x `h` metres.
double decalAreaOver(const Culture& c, std::uint16_t cls, int l, double w, double h) {
  double sum = 0;
  for (double mz = 0; mz < h; mz += 1000) {
    for (double mx = 0; mx < w; mx += 1000) {
      const Decaled d = decalModule(c, mx, mz, l + 1, hills, w, h);
      const auto it = d.checks[std::size_t(l)].decal.find(cls);
      if (it != d.checks[std::size_t(l)].decal.end()) sum += it->second;
    }
  }
  return sum;
}

TEST(Culture, smoothTenThousandVertexRoadIsLengthTimesWidth) {
  // The hostile test's smooth road: 10,000 vertices 0.25 m apart on a
  // gentle curve (radius >= 1.1 km). Before the size rule its widening took
  // 16 s; now the centreline is simplified first.
  Scratch s("smooth10k");
  const auto t = sampleTable();
  Path p;
  for (int k = 0; k < 10000; ++k) {
    const double x = 250 + 0.25 * k;
    p.push_back({x, 1000 + 150 * std::sin(x / 350.0)});
  }
  double length = 0;
  for (std::size_t k = 0; k + 1 < p.size(); ++k) length += std::hypot(p[k + 1][0] - p[k][0], p[k + 1][1] - p[k][1]);
  auto c = loadScene(s, {line("\"highway\": \"secondary\", \"width\": \"10\"", p)}, t, 3000, 2000);
  ASSERT_TRUE(c);
  const CultureStats& st = c->stats();
  EXPECT_EQ(st.lineVerticesRead, 10000u);
  EXPECT_LT(st.lineVerticesKept, 1000u);
  EXPECT_EQ(st.coarsened, 0u);
  EXPECT_NEAR(st.perClass.at("secondary").lengthKm, length / 1000, 1e-9);  // of the line as read
  // Simplified at 0.1 m: the area is L x W to well within 1 %.
  const double want = length * 10;
  EXPECT_NEAR(decalAreaOver(*c, classId(t, "secondary"), 0, 3000, 2000), want, 0.01 * want);
}

TEST(Culture, zigzagFoldingWithinItsWidthIsSimplifiedAndBounded) {
  // The hostile test's line: 2,000 vertices 0.33 m apart along x, +-55 m
  // across, 900 m wide: each segment's rectangle overlaps every other one.
  // Its exact union took over 5 minutes. The size rule simplifies it until
  // its vertices no longer crowd within its width.
  Scratch s("zigzag");
  const auto t = sampleTable();
  Path p;
  for (int k = 0; k < 2000; ++k) p.push_back({1170 + 0.33 * k, 1000 + (k % 2 ? 55.0 : -55.0)});
  auto c = loadScene(s, {line("\"highway\": \"primary\", \"width\": \"900\"", p)}, t, 3000, 2000);
  ASSERT_TRUE(c);
  const CultureStats& st = c->stats();
  EXPECT_EQ(st.coarsened, 1u);
  EXPECT_LT(st.lineVerticesKept, 50u);
  bool warned = false;
  for (const auto& m : st.messages) warned |= m.find("folding back on itself within its width") != std::string::npos;
  EXPECT_TRUE(warned);
  // Plausible: at least the band the zigzag sweeps (660 x 110 m), at most
  // its box grown by half the width each side.
  const double got = decalAreaOver(*c, classId(t, "primary"), 0, 3000, 2000);
  EXPECT_GT(got, 660 * 110);
  EXPECT_LT(got, (660 + 900) * (110 + 900));
}

TEST(Culture, lineVertexLimitCoarsensTheLine) {
  Scratch s("limit");
  const auto t = sampleTable();
  Path p;
  for (int k = 0; k < 2000; ++k) p.push_back({100 + 0.4 * k, 500 + 20 * std::sin(0.4 * k / 15.0)});
  CultureOptions o;
  o.sources = {writeGeoJson(s.dir / "scene.geojson", {line("\"highway\": \"secondary\", \"width\": \"10\"", p)})};
  o.maxLineVertices = 40;
  auto c = Culture::load(o, t, {wktOf(32632), kE0, kN0, 1000, 1000});
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c.value()->stats().coarsened, 1u);
  EXPECT_LE(c.value()->stats().lineVerticesKept, 40u);
  EXPECT_GE(c.value()->stats().lineVerticesKept, 2u);
}

TEST(Culture, noFeatureOnTheTerrainIsAnError) {
  const auto t = sampleTable();
  const std::string road = "\"highway\": \"secondary\", \"width\": \"10\"";
  {
    // Wholly outside: an error naming the file and both extents.
    Scratch s("miss");
    CultureOptions o;
    o.sources = {writeGeoJson(s.dir / "far.geojson", {line(road, {{5000, 5000}, {6000, 5200}}),
                                                     area("\"natural\": \"water\"", {circle(7000, 7000, 100, 12)})})};
    auto c = Culture::load(o, t, {wktOf(32632), kE0, kN0, 1000, 1000});
    ASSERT_FALSE(c);
    const Problem& p = c.problems().front();
    EXPECT_EQ(p.file, o.sources[0]);
    EXPECT_NE(p.message.find("none of its 2 line and area features lies on the terrain"), std::string::npos) << p.message;
    EXPECT_NE(p.message.find("the culture covers lon"), std::string::npos) << p.message;
    EXPECT_NE(p.message.find("the database lon"), std::string::npos) << p.message;
    // A library names option fields, never the CLI's flags.
    EXPECT_NE(p.message.find("ElevationOptions::extent"), std::string::npos) << p.message;
    EXPECT_NE(p.message.find("CultureOptions::sources"), std::string::npos) << p.message;
    EXPECT_EQ(p.message.find("--"), std::string::npos) << p.message;
  }
  {
    // An empty source: an error too.
    Scratch s("none");
    CultureOptions o;
    o.sources = {writeGeoJson(s.dir / "empty.geojson", {})};
    auto c = Culture::load(o, t, {wktOf(32632), kE0, kN0, 1000, 1000});
    ASSERT_FALSE(c);
    EXPECT_NE(c.problems().front().message.find("no line or area features"), std::string::npos);
  }
  {
    // Some inside: counted as landed, the rest as outside.
    Scratch s("some");
    CultureOptions o;
    o.sources = {writeGeoJson(s.dir / "some.geojson", {line(road, {{100, 100}, {900, 200}}),
                                                      line(road, {{5000, 5000}, {6000, 5200}}),
                                                      line(road, {{-3000, 100}, {-2000, 100}})})};
    auto c = Culture::load(o, t, {wktOf(32632), kE0, kN0, 1000, 1000});
    ASSERT_TRUE(c) << c.error();
    EXPECT_EQ(c.value()->stats().featuresRead, 3u);
    EXPECT_EQ(c.value()->stats().featuresLanded, 1u);
    EXPECT_EQ(c.value()->stats().featuresOutside, 2u);
  }
}

TEST(Culture, roadTextureCoordinatesRunAlongAndAcross) {
  Scratch s("st");
  const auto t = sampleTable();
  // West to east along z = 500.3 (not on a lattice line), 8 m wide.
  auto c = loadScene(s, {line("\"highway\": \"secondary\", \"width\": \"8\"", {{100.0, 500.3}, {900.0, 500.3}})}, t);
  ASSERT_TRUE(c);
  const LevelLattice lat = lattice(0, 0, 32, 31.25, 0, flat);
  module::Level lv;
  c->decalLevel(lat, lv);
  std::size_t seen = 0;
  for (const auto& g : lv.groups) {
    if (g.priority != 10) continue;
    for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; ++k) {
      const auto& v = lv.vertices[lv.indices[k]];
      // s and t are on steps of 1/256; t is clamped to 0..1 where the
      // vertex step moved an edge point up to half a step outside.
      const double texStep = 0.5 / 256 + 1e-6, edge = CultureOptions{}.vertexStep / 2 / 8.0;
      EXPECT_NEAR(v.s, (v.x - 100.0) / 8.0, texStep);
      // Heading east, the driver's left is north (smaller z): T = 0 there.
      EXPECT_NEAR(v.t, (v.z - (500.3 - 4)) / 8.0, texStep + edge);
      ++seen;
    }
  }
  EXPECT_GT(seen, 0u);
}

// ------------------------------------------------------------ skin

TEST(Culture, lakeWithIslandAndForestResolvedByRank) {
  Scratch s("lake");
  const auto t = sampleTable();
  const Path outer = circle(500, 500, 300, 64), island = circle(430, 480, 80, 16, 0.3);
  const Path forest = closed({{600, 300}, {950, 300}, {950, 900}, {600, 900}});
  auto c = loadScene(s, {area("\"natural\": \"water\"", {outer, island}), area("\"landuse\": \"forest\"", {forest})}, t);
  ASSERT_TRUE(c);
  // Forest where the lake is not, by GEOS as an independent check.
  auto poly = [](const Path& p) {
    OGRPolygon g;
    OGRLinearRing r;
    for (const Pt& q : p) r.addPoint(q[0], q[1]);
    g.addRing(&r);
    return g;
  };
  OGRPolygon lake = poly(outer);
  const OGRPolygon fo = poly(forest);
  std::unique_ptr<OGRGeometry> forestOnly(fo.Difference(&lake));
  const double wantForest = forestOnly->toPolygon()->get_Area();
  const double wantWater = shoelace(outer) - shoelace(island);
  const Decaled d = decalModule(*c, 0, 0);
  for (int l = 0; l < 4; ++l) {
    const auto& sk = d.checks[l].skin;
    EXPECT_NEAR(sk.at(classId(t, "water")), wantWater, 1e-5 * 1e6) << l;
    EXPECT_NEAR(sk.at(classId(t, "forest")), wantForest, 1e-5 * 1e6) << l;
    EXPECT_NEAR(sk.at(classId(t, "grass")), 1e6 - wantWater - wantForest, 1e-5 * 1e6) << l;
    EXPECT_EQ(d.checks[l].decal.size(), 0u);
  }
  // Most triangles take the fast path.
  EXPECT_LT(d.stats[0].slowTriangles, 2048u / 4);
}

TEST(Culture, featuresCrossingTheDatabaseEdgeAreClipped) {
  Scratch s("edge");
  const auto t = sampleTable();
  const Path lakeRing = circle(600, -50, 200, 48);
  auto c = loadScene(s,
                     {line("\"highway\": \"primary\", \"width\": \"10\"", {{-300, 200}, {500, 600}}),
                      area("\"natural\": \"water\"", {lakeRing})},
                     t, 2000, 1000);
  ASSERT_TRUE(c);
  const double inside = std::hypot(800, 400) * (500.0 / 800.0);
  // The lake clipped at z = 0 (north edge), by GEOS.
  OGRPolygon lake, db;
  OGRLinearRing r, dr;
  for (const Pt& q : lakeRing) r.addPoint(q[0], q[1]);
  lake.addRing(&r);
  for (const Pt& q : closed({{0, 0}, {2000, 0}, {2000, 1000}, {0, 1000}})) dr.addPoint(q[0], q[1]);
  db.addRing(&dr);
  std::unique_ptr<OGRGeometry> in(lake.Intersection(&db));
  const double wantWater = in->toPolygon()->get_Area();
  const Decaled d = decalModule(*c, 0, 0, 4, hills, 2000, 1000);
  for (int l = 0; l < 4; ++l) {
    EXPECT_NEAR(d.checks[l].decal.at(classId(t, "primary")), inside * 10, kMergeArea * (inside * 10)) << l;
    EXPECT_NEAR(d.checks[l].skin.at(classId(t, "water")), wantWater, 1e-5 * (wantWater)) << l;
  }
  EXPECT_NEAR(c->stats().perClass.at("primary").lengthKm, inside / 1000, 1e-9);
  EXPECT_NEAR(c->stats().perClass.at("water").areaKm2, wantWater / 1e6, 1e-9);
}

TEST(Culture, invalidGeometryIsRepairedOrDroppedNeverAHole) {
  Scratch s("invalid");
  const auto t = sampleTable();
  std::vector<Feat> f = {
      line("\"highway\": \"primary\"", {{500, 500}, {500, 500}, {500, 500}}),            // zero length
      area("\"natural\": \"wood\"", {closed({{100, 100}, {300, 300}, {300, 100}, {100, 300}})}),  // bow-tie
      area("\"landuse\": \"meadow\"", {{{600, 100}, {800, 100}, {800, 300}, {600, 300}}}),  // ring not closed
      line("\"highway\": \"track\"", {{100, 700}, {100, 700}, {400, 760}, {400, 760}, {700, 700}}),  // repeats
      area("\"landuse\": \"farmland\"", {closed({{100, 900}, {200, 900}, {300, 900}})}),  // no area
      area("\"landuse\": \"farmland\"", {closed({{600, 600}, {700, 600}, {700, 600}, {700, 700}, {600, 700}})}),
  };
  auto c = loadScene(s, f, t);
  ASSERT_TRUE(c);
  const CultureStats& st = c->stats();
  EXPECT_EQ(st.featuresRead, 6u);
  EXPECT_EQ(st.perClass.at("primary").dropped, 1u);
  EXPECT_EQ(st.perClass.at("forest").repaired, 1u);
  EXPECT_EQ(st.perClass.at("meadow").repaired, 1u);
  EXPECT_EQ(st.perClass.at("track").repaired, 1u);
  EXPECT_EQ(st.perClass.at("farmland").dropped, 1u);
  EXPECT_EQ(st.perClass.at("farmland").repaired, 1u);
  EXPECT_GE(st.warnings, 6u);
  EXPECT_FALSE(st.messages.empty());
  EXPECT_NEAR(st.perClass.at("forest").areaKm2, 0.02, 1e-9);  // both lobes of the bow-tie
  const Decaled d = decalModule(*c, 0, 0);
  for (int l = 0; l < 4; ++l) {
    EXPECT_NEAR(d.checks[l].skin.at(classId(t, "forest")), 20000, 1e-5 * (20000)) << l;
    EXPECT_NEAR(d.checks[l].skin.at(classId(t, "meadow")), 40000, 1e-5 * (40000)) << l;
    EXPECT_NEAR(d.checks[l].skin.at(classId(t, "farmland")), 10000, 1e-5 * (10000)) << l;
  }
}

TEST(Culture, moduleWithoutCultureIsOneTrianglePerHalf) {
  const auto t = sampleTable();
  // No sources (a build without --culture); an empty source is an error
  // (noFeatureOnTheTerrainIsAnError).
  auto loaded = Culture::load({}, t, {wktOf(32632), kE0, kN0, 3000, 1000});
  ASSERT_TRUE(loaded) << loaded.error();
  const auto c = loaded.value();
  const Decaled d = decalModule(*c, 1000, 0, 4, hills, 3000, 1000);
  EXPECT_EQ(d.levels[0].vertices.size(), 33u * 33u);
  EXPECT_EQ(d.levels[0].indices.size(), 32u * 32u * 6u);
  EXPECT_EQ(d.levels[0].groups.size(), 32u * 32u * 2u);
  EXPECT_EQ(d.stats[0].slowTriangles, 0u);
  EXPECT_EQ(d.checks[0].skin.at(t.defaultArea), 1e6);
}

TEST(Culture, irregularLatticesAtTheDatabaseEdge) {
  Scratch s("irregular");
  const auto t = sampleTable();
  // 30 m posts: a 1000 m module is not a whole number of squares; the east
  // module is narrower; levels clamp their last column.
  auto c = loadScene(s,
                     {line("\"highway\": \"primary\"", {{100, 100}, {1500, 700}, {1200, 985}}),
                      area("\"natural\": \"water\"", {circle(1400, 400, 150, 30)}),
                      area("\"landuse\": \"forest\"", {circle(500, 990, 200, 24)})},
                     t, 1710, 990);
  ASSERT_TRUE(c);
  // The south modules are one square high: their coarse squares are 60 x
  // 30, 120 x 30 and 240 x 30 m.
  for (double mz : {0.0, 960.0}) {
    for (double mx : {0.0, 960.0}) {
      const Decaled d = decalModule(*c, mx, mz, 4, hills, 1710, 990, 32, 30.0);
      EXPECT_GT(sumOf(d.checks[0].skin), 0);
    }
  }
}

// ------------------------------------------------------------ everything at once

TEST(Culture, randomScenesKeepEveryInvariant) {
  const auto t = sampleTable();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  const char* roads[] = {"motorway", "primary", "residential", "track", "footway"};
  const char* areas[] = {"\"landuse\": \"forest\"", "\"natural\": \"water\"", "\"landuse\": \"farmland\"",
                         "\"landuse\": \"meadow\"", "\"natural\": \"scrub\"", "\"building\": \"yes\""};
  for (int scene = 0; scene < 3; ++scene) {
    Scratch s("random" + std::to_string(scene));
    std::vector<Feat> f;
    for (int k = 0; k < 12; ++k) {
      // Wiggly polylines with short segments, through both modules.
      Path p;
      double x = u(rng) * 2000, z = u(rng) * 1000, a = u(rng) * 2 * kPi;
      for (int n = 0; n < 40; ++n) {
        p.push_back({x, z});
        a += (u(rng) - 0.5) * 1.2;
        const double step = 5 + 40 * u(rng);
        x += step * std::cos(a), z += step * std::sin(a);
      }
      f.push_back(line(std::string("\"highway\": \"") + roads[k % 5] + "\"", p));
    }
    for (int k = 0; k < 10; ++k) {
      Path ring;
      const double cx = u(rng) * 2000, cz = u(rng) * 1000, r = 30 + 250 * u(rng);
      const int n = 5 + int(u(rng) * 30);
      for (int i = 0; i < n; ++i) {
        const double a = 2 * kPi * i / n, rr = r * (0.6 + 0.4 * u(rng));
        ring.push_back({cx + rr * std::cos(a), cz + rr * std::sin(a)});
      }
      f.push_back(area(areas[k % 6], {closed(ring)}));
    }
    auto c = loadScene(s, f, t, 2000, 1000);
    ASSERT_TRUE(c);
    for (double mx : {0.0, 1000.0}) decalModule(*c, mx, 0);
  }
}

TEST(Culture, outputIsDeterministic) {
  // Two loads of one scene (different memory addresses, load on 1 and on
  // 2 threads) give byte-identical levels.
  Scratch s("det");
  const auto t = sampleTable();
  std::vector<Feat> f;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  for (int k = 0; k < 8; ++k) {
    Path p;
    double x = u(rng) * 1000, z = u(rng) * 1000, a = u(rng) * 2 * kPi;
    for (int n = 0; n < 30; ++n) {
      p.push_back({x, z});
      a += (u(rng) - 0.5);
      x += 30 * std::cos(a), z += 30 * std::sin(a);
    }
    f.push_back(line(k % 2 ? "\"highway\": \"primary\"" : "\"highway\": \"track\"", p));
  }
  for (int k = 0; k < 6; ++k) {
    f.push_back(area(k % 2 ? "\"landuse\": \"forest\"" : "\"natural\": \"water\"",
                     {circle(u(rng) * 1000, u(rng) * 1000, 50 + 200 * u(rng), 5 + k * 4)}));
  }
  CultureOptions o;
  o.sources = {writeGeoJson(s.dir / "scene.geojson", f)};
  const CultureFrame frame{wktOf(32632), kE0, kN0, 1000, 1000};
  std::vector<std::string> bytes;
  for (int threads : {1, 2}) {
    o.threads = threads;
    auto c = Culture::load(o, t, frame);
    ASSERT_TRUE(c) << c.error();
    std::string b;
    for (int l = 0; l < 4; ++l) {
      module::Level lv;
      c.value()->decalLevel(lattice(0, 0, 32, 31.25, l, hills), lv);
      b.append(reinterpret_cast<const char*>(lv.vertices.data()), lv.vertices.size() * sizeof(module::Vertex));
      b.append(reinterpret_cast<const char*>(lv.indices.data()), lv.indices.size() * 4);
      for (const auto& g : lv.groups) b += std::to_string(g.square) + "," + std::to_string(g.material) + ";";
    }
    bytes.push_back(std::move(b));
  }
  EXPECT_TRUE(bytes[0] == bytes[1]);
}

TEST(Culture, concurrentDecalsMatchSequentialOnes) {
  Scratch s("threads");
  const auto t = sampleTable();
  auto c = loadScene(s,
                     {line("\"highway\": \"primary\"", {{-50, 210}, {900, 300}, {1900, 800}}),
                      area("\"natural\": \"water\"", {circle(1000, 500, 300, 40)}),
                      area("\"landuse\": \"forest\"", {circle(400, 600, 250, 30)})},
                     t, 2000, 1000);
  ASSERT_TRUE(c);
  auto run = [&](double mx, int l) {
    module::Level lv;
    c->decalLevel(lattice(mx, 0, 32, 31.25, l, hills), lv);
    return lv.indices.size() * 1000003u + lv.vertices.size();
  };
  std::vector<std::size_t> want;
  for (double mx : {0.0, 1000.0}) {
    for (int l = 0; l < 4; ++l) want.push_back(run(mx, l));
  }
  // Fresh culture: the module partitions are built under contention.
  auto fresh = loadScene(s, {line("\"highway\": \"primary\"", {{-50, 210}, {900, 300}, {1900, 800}}),
                             area("\"natural\": \"water\"", {circle(1000, 500, 300, 40)}),
                             area("\"landuse\": \"forest\"", {circle(400, 600, 250, 30)})},
                         t, 2000, 1000);
  ASSERT_TRUE(fresh);
  std::vector<std::size_t> got(8 * 4);
  jobs::parallelFor(4, 4, [&](std::size_t task) {
    const int th = int(task);
    for (int k = 0; k < 8; ++k) {
      const double mx = k < 4 ? 0.0 : 1000.0;
      module::Level lv;
      fresh->decalLevel(lattice(mx, 0, 32, 31.25, (k + th) % 4, hills), lv);
      got[std::size_t(th * 8 + (k < 4 ? 0 : 4) + (k + th) % 4)] = lv.indices.size() * 1000003u + lv.vertices.size();
    }
  });
  for (int th = 0; th < 4; ++th) {
    for (int k = 0; k < 8; ++k) EXPECT_EQ(got[std::size_t(th * 8 + k)], want[std::size_t(k)]) << th << " " << k;
  }
}

// ------------------------------------------------------------ real data

/// The frame over a lon/lat box in a UTM zone, snapped to 31.25 m posts.
CultureFrame frameOver(int epsg, double west, double south, double east, double north) {
  initGdal();
  OGRSpatialReference wgs, utm;
  wgs.SetWellKnownGeogCS("WGS84");
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  utm.importFromEPSG(epsg);
  utm.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs, &utm));
  double x[4] = {west, east, east, west}, y[4] = {north, north, south, south};
  ct->Transform(4, x, y);
  const double e0 = std::ceil(std::max(x[0], x[3])), n0 = std::floor(std::min(y[0], y[1]));
  const double e1 = std::floor(std::min(x[1], x[2])), n1 = std::ceil(std::max(y[2], y[3]));
  CultureFrame f;
  f.crsWkt = wktOf(epsg);
  f.originEasting = e0;
  f.originNorthing = n0;
  f.widthM = std::floor((e1 - e0) / 31.25) * 31.25;
  f.heightM = std::floor((n0 - n1) / 31.25) * 31.25;
  return f;
}

TEST(Culture, realOsmNorthOfBayreuth) {
  const std::string src = kData + "/osm/north-bayreuth.osm.gz";
  SANDTABLE_REQUIRE(fs::exists(src), src);
  const auto t = sampleTable();
  const CultureFrame frame = frameOver(32632, 11.40, 49.88, 11.67, 50.10);
  CultureOptions o;
  o.sources = {src};
  auto c = Culture::load(o, t, frame);
  ASSERT_TRUE(c) << c.error();
  const CultureStats& st = c.value()->stats();
  std::printf("north-bayreuth: %llu features read in %.2f s, %llu ignored, %llu warnings\n",
              (unsigned long long)st.featuresRead, st.seconds, (unsigned long long)st.ignored,
              (unsigned long long)st.warnings);
  for (const auto& [name, k] : st.perClass) {
    std::printf("  %-12s read %6llu dropped %4llu repaired %4llu defaulted %5llu  %8.2f km %8.3f km2\n", name.c_str(),
                (unsigned long long)k.read, (unsigned long long)k.dropped, (unsigned long long)k.repaired,
                (unsigned long long)k.defaulted, k.lengthKm, k.areaKm2);
  }
  EXPECT_GT(st.featuresRead, 7000u);
  EXPECT_GT(st.perClass.at("track").read, 800u);
  EXPECT_GT(st.perClass.at("motorway").read, 50u);
  EXPECT_GT(st.perClass.at("stream").read, 100u);  // 192 in the extract; culverts are ignored
  EXPECT_GT(st.perClass.at("forest").read, 100u);
  EXPECT_GT(st.perClass.at("water").read, 100u);
  EXPECT_GT(st.perClass.at("motorway").lengthKm, 10.0);
  // Modules over the town: the extract's <bounds> are 11.48-11.61 E,
  // 49.97-50.05 N; the frame starts at 11.40 E, 50.10 N.
  OGRSpatialReference wgs, utm;
  wgs.SetWellKnownGeogCS("WGS84");
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  utm.importFromEPSG(32632);
  utm.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs, &utm));
  double x = 11.575, y = 49.995;
  ct->Transform(1, &x, &y);
  const double kx = std::floor((x - frame.originEasting) / 1000), kz = std::floor((frame.originNorthing - y) / 1000);
  double slowest = 0, total = 0, first = 0;
  int modules = 0;
  std::uint64_t slow = 0, unmerged = 0, tris = 0;
  for (double dz = 0; dz < 2; ++dz) {
    for (double dx = 0; dx < 2; ++dx) {
      const Decaled d = decalModule(*c.value(), (kx + dx) * 1000, (kz + dz) * 1000, 4, hills, frame.widthM, frame.heightM);
      const double ms = d.ms[0] + d.ms[1] + d.ms[2] + d.ms[3];
      slowest = std::max(slowest, ms);
      total += ms;
      first += d.ms[0];
      ++modules;
      for (const auto& s : d.stats) slow += s.slowTriangles, unmerged += s.unmerged, tris += s.triangles;
      EXPECT_GT(sumOf(d.checks[0].decal), 1000.0);  // roads in every module
      EXPECT_GT(d.checks[0].skin.size(), 2u);       // and several skin classes
    }
  }
  std::printf("north-bayreuth: %d modules x 4 levels: %.1f ms per module (slowest %.1f; level 0 with the partition "
              "%.1f), %llu triangles, %llu cut grid triangles, %llu vertices left unmerged\n",
              modules, total / modules, slowest, first / modules, (unsigned long long)tris, (unsigned long long)slow,
              (unsigned long long)unmerged);
}

TEST(Culture, realOsmZipOfSamsoe) {
  const std::string src = kData + "/osm/samsoe.osm.zip";
  SANDTABLE_REQUIRE(fs::exists(src), src);
  const auto t = sampleTable();
  const CultureFrame frame = frameOver(32632, 10.50, 55.78, 10.70, 55.98);
  CultureOptions o;
  o.sources = {src};
  auto c = Culture::load(o, t, frame);
  ASSERT_TRUE(c) << c.error();
  const CultureStats& st = c.value()->stats();
  std::printf("samsoe: %llu features read in %.2f s\n", (unsigned long long)st.featuresRead, st.seconds);
  EXPECT_GT(st.featuresRead, 5000u);
  EXPECT_GT(st.perClass.at("farmland").read, 500u);
  EXPECT_GT(st.perClass.at("water").read, 100u);
  const Decaled d = decalModule(*c.value(), 5000, 8000, 4, hills, frame.widthM, frame.heightM);
  EXPECT_GT(sumOf(d.checks[0].decal) + sumOf(d.checks[0].skin), 1e6 - 1);
}

TEST(Culture, realShapefileAndGeoJson) {
  const auto t = sampleTable();
  {
    const std::string src = kData + "/shp/BayArea.shp";
    SANDTABLE_REQUIRE(fs::exists(src), src);
    CultureOptions o;
    o.sources = {src};
    auto c = Culture::load(o, t, frameOver(32610, -122.095, 37.41, -122.075, 37.43));
    ASSERT_TRUE(c) << c.error();
    const CultureStats& st = c.value()->stats();
    EXPECT_EQ(st.featuresRead, 144u);
    EXPECT_EQ(st.perClass.at("building").read, 144u);  // footprints with a Height field
    EXPECT_EQ(st.perClass.at("building").dropped, 0u);
    EXPECT_GT(st.perClass.at("building").areaKm2, 0.01);
  }
  {
    const std::string src = kData + "/geojson/roads.geojson";
    CultureOptions o;
    o.sources = {src};
    const CultureFrame frame = frameOver(32635, 26.098, 44.428, 26.106, 44.434);
    auto c = Culture::load(o, t, frame);
    ASSERT_TRUE(c) << c.error();
    const CultureStats& st = c.value()->stats();
    EXPECT_EQ(st.featuresRead, 21u);
    EXPECT_EQ(st.perClass.at("path").read, 18u);   // footway 8, pedestrian 10
    EXPECT_EQ(st.perClass.at("street").read, 2u);  // residential
    EXPECT_EQ(st.perClass.at("primary").read, 1u);
    EXPECT_GT(st.perClass.at("path").lengthKm, 0.1);
    decalModule(*c.value(), 0, 0, 4, hills, frame.widthM, frame.heightM);
  }
}

TEST(Culture, realSynthGeoPackage) {
  Scratch s("synth");
  SynthOptions so;
  so.outDir = (s.dir / "synth").string();
  so.sizeKm = 20;
  so.dted1 = so.dted2 = so.dem = false;
  auto sum = synthesize(so);
  ASSERT_TRUE(sum) << sum.error();
  const auto t = sampleTable();
  const CultureFrame frame = frameOver(32633, sum->west + 0.005, sum->south + 0.005, sum->east - 0.005, sum->north - 0.005);
  CultureOptions o;
  o.sources = {so.outDir + "/culture.gpkg"};
  auto c = Culture::load(o, t, frame);
  ASSERT_TRUE(c) << c.error();
  const CultureStats& st = c.value()->stats();
  std::printf("synth 20 km: %llu features in %.2f s\n", (unsigned long long)st.featuresRead, st.seconds);
  EXPECT_EQ(st.featuresRead, std::uint64_t(sum->roads + sum->rivers + sum->lakes + sum->forests + sum->buildings));
  EXPECT_GT(sum->buildings, 0);
  EXPECT_EQ(st.perClass.at("building").read, std::uint64_t(sum->buildings));
  std::uint64_t roads = 0;
  for (const char* r : {"motorway", "primary", "secondary", "track"}) {
    if (st.perClass.count(r)) roads += st.perClass.at(r).read;
  }
  EXPECT_EQ(roads, std::uint64_t(sum->roads));
  EXPECT_EQ(st.perClass.at("river").read, std::uint64_t(sum->rivers));
  EXPECT_EQ(st.perClass.at("water").read, std::uint64_t(sum->lakes));
  EXPECT_EQ(st.perClass.at("forest").read, std::uint64_t(sum->forests));
  for (const auto& [name, k] : st.perClass) EXPECT_EQ(k.defaulted, 0u) << name;
  // A few modules across the square.
  for (double m : {3000.0, 9000.0, 15000.0}) decalModule(*c.value(), m, m, 4, hills, frame.widthM, frame.heightM);
}

TEST(Culture, badSourcesAndFrames) {
  const auto t = sampleTable();
  CultureOptions o;
  o.sources = {"/nonexistent/roads.shp"};
  auto c = Culture::load(o, t, {wktOf(32632), kE0, kN0, 1000, 1000});
  ASSERT_FALSE(c);
  EXPECT_EQ(c.problems().front().file, "/nonexistent/roads.shp");
  EXPECT_EQ(c.problems().front().message.rfind("culture: cannot open as a vector source", 0), 0u);
  o.sources.clear();
  auto f = Culture::load(o, t, {wktOf(32632), kE0, kN0, 0, 1000});
  ASSERT_FALSE(f);
  EXPECT_EQ(f.problems().front().message, "culture: the database frame has no extent");
}

}  // namespace
