// What the viewer's frames look like on real data (issue 9, items 1-3):
// `--colour height` frames of the load modules at full LoD agree with the
// grid mesh and with the grid itself; the sea is drawn as water; both
// modes colour uncovered ground alike (smooth normals, the elevation tint,
// no quilting); high mountains are not green; roads carry their markings.
//
// Every expectation is computed here from the grid (rays cast through
// pixel centres against world::Terrain), not from the renderer.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <optional>

#include "sandtable/converters/crs.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/formats/database.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/image.h"
#include "sandtable/render/renderer.h"
#include "sandtable/world/terrain.h"
#include "sandtable/paging/view_triangle.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

using render::ColourMode;
using viewer::FlightOptions;
using render::Image;
using viewer::TerrainMode;

constexpr double kPi = 3.14159265358979323846;
/// --colour height quantisation (renderer.h): 1/256 m.
constexpr double kQuantum = 1.0 / render::kHeightCodeScale;

using Vec3 = std::array<double, 3>;

std::string build(const TempDir& tmp, const std::string& name, std::vector<std::string> sources,
                  std::vector<std::string> culture, std::array<double, 4> extent, double spacing) {
  convert::ElevationOptions o;
  for (const auto& s : sources) o.sources.push_back(test::data(s));
  for (const auto& c : culture) o.culture.push_back(test::data(c));
  o.extent = extent;
  o.spacing = spacing;
  o.output = tmp / name;
  auto r = convert::buildElevation(o, nullptr);
  EXPECT_TRUE(r.ok()) << r.error();
  return o.output;
}

/// A pose: where the eye is (lon, lat), how high above the ground, where it looks.
struct View {
  const char* name;
  double lon, lat, height, heading, pitch, viewDistance;
};

/// One rendered frame and the camera that drew it (grid frame: X east,
/// Y up, Z south, metres from the grid's north-west post).
struct Shot {
  Image img;
  Vec3 eye{};
  FlightOptions o;
};

class ViewerLook : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    std::string why;
    if (!render::headlessGlAvailable(why)) {
      noGl_ = why;
      return;
    }
    tmp_ = new TempDir("viewer_look");
    monaco_ = build(*tmp_, "monaco", {"elevation/srtm/N43E007.hgt.zip"}, {"culture/osm/monaco.osm.gz"},
                    {7.38, 43.70, 7.46, 43.77}, 30);
    bayreuth_ = build(*tmp_, "bayreuth", {"elevation/srtm/N49E011.hgt.zip", "elevation/srtm/N50E011.hgt.zip"},
                      {"culture/osm/north-bayreuth.osm.gz"}, {11.50, 49.97, 11.60, 50.04}, 62.5);
    alps_ = build(*tmp_, "alps", {"elevation/geotiff/N46E008.tif"}, {}, {8.00, 46.30, 8.20, 46.58}, 90);
    samsoe_ = build(*tmp_, "samsoe", {"elevation/dted/denmark-dhm/e010/n55.dt1"}, {},
                    {10.45, 55.75, 10.75, 55.95}, 60);
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override {
    SANDTABLE_REQUIRE_DATA();
    SANDTABLE_REQUIRE(noGl_.empty(), "headless GL (EGL, Mesa): " << noGl_);
  }

  /// Renders the second frame of a still flight (the pager settled, no fog,
  /// no sky, no panel) at the view, in `mode` and `colour`.
  static Shot shoot(const Database& db, const View& v, TerrainMode mode, ColourMode colour,
                    render::Shading shading = render::Shading::smooth) {
    Shot s;
    FlightOptions& o = s.o;
    auto geo = geodesy::Projection::create(db.manifest.crsWkt);
    EXPECT_TRUE(geo.ok());
    const auto en = geo ? geo->toProjected({v.lon, v.lat}) : Result<geodesy::EastNorth>(Problem{});
    EXPECT_TRUE(en);
    if (en) o.motion.easting = en->easting, o.motion.northing = en->northing;
    o.view.width = 320;
    o.view.height = 180;
    o.output.frames = 2;
    o.motion.speedKmh = 0;
    o.motion.heightAgl = v.height;
    o.motion.headingDeg = v.heading;
    o.motion.pitchDeg = v.pitch;
    o.view.viewDistance = v.viewDistance;
    o.view.fog = false;
    o.view.sky = false;
    o.view.hud = false;
    o.pager.sync = true;
    o.render.mode = mode;
    o.render.colour = colour;
    o.render.shading = shading;
    o.render.lod.mode = scene::LodMode::full;
    viewer::FlightHooks hooks(o);
    hooks.onFrame = [&](std::uint32_t, const Image& i) { s.img = i; };
    auto r = viewer::fly(db, o, &hooks);
    EXPECT_TRUE(r.ok()) << r.error();
    if (r.ok() && !r->frames.empty()) {
      const auto& f = r->frames.back();
      const auto& h = db.grid->header();
      s.eye = {o.motion.easting - h.originEasting, f.eyeElevation, h.originNorthing - o.motion.northing};
    }
    hooks.onFrame = nullptr;
    // SANDTABLE_KEEP_TEST_OUTPUT=DIR keeps the frames for a look.
    if (const char* keep = std::getenv("SANDTABLE_KEEP_TEST_OUTPUT")) {
      const std::string name = std::string(v.name) + (mode == TerrainMode::mesh ? " mesh" : " modules") +
                               (colour == ColourMode::height ? " height" : "") +
                               (shading == render::Shading::flat ? " flat" : "");
      render::writePng(std::string(keep) + "/" + name + ".png", s.img);
    }
    return s;
  }

  static inline TempDir* tmp_ = nullptr;
  static inline std::string monaco_, bayreuth_, alps_, samsoe_, noGl_;
};

/// The view ray through the centre of pixel (px, py): unit direction in
/// the grid frame, the renderer's projection written out (camera_math.h).
Vec3 rayThrough(const FlightOptions& o, double px, double py) {
  const double h = o.motion.headingDeg * kPi / 180, t = o.motion.pitchDeg * kPi / 180;
  const Vec3 f{std::cos(t) * std::sin(h), std::sin(t), -std::cos(t) * std::cos(h)};
  const Vec3 r{std::cos(h), 0, std::sin(h)};
  const Vec3 u{r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]};
  const double aspect = double(o.view.width) / o.view.height;
  const double k = 1 / std::tan(paging::verticalFovDeg(o.view.hfovDeg, aspect) * kPi / 360);
  const double nx = (px + 0.5) / o.view.width * 2 - 1, ny = 1 - (py + 0.5) / o.view.height * 2;
  Vec3 d{};
  for (int c = 0; c < 3; ++c) d[c] = f[c] + nx * aspect / k * r[c] + ny / k * u[c];
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  for (auto& c : d) c /= n;
  return d;
}

/// The first point where the ray from `eye` meets the terrain within
/// `range` metres: marched in steps of a quarter spacing, then bisected.
std::optional<Vec3> castRay(const world::Terrain& terrain, const Vec3& eye, const Vec3& d, double range) {
  const double step = terrain.heights().spacing() / 4;
  const auto above = [&](double s) -> std::optional<double> {
    const auto g = terrain.sampleXZ(eye[0] + s * d[0], eye[2] + s * d[2]);
    if (!g) return std::nullopt;
    return eye[1] + s * d[1] - g->elevation;
  };
  double s0 = 0;
  for (double s = step; s <= range; s += step) {
    const auto a = above(s);
    if (!a) return std::nullopt;
    if (*a <= 0) {
      double lo = s0, hi = s;
      for (int k = 0; k < 50; ++k) {
        const double mid = (lo + hi) / 2;
        const auto m = above(mid);
        (m && *m > 0 ? lo : hi) = mid;
      }
      return Vec3{eye[0] + hi * d[0], eye[1] + hi * d[1], eye[2] + hi * d[2]};
    }
    s0 = s;
  }
  return std::nullopt;
}

/// Pixels whose 3 x 3 neighbourhood is terrain in `a` (and `b`) with no
/// height step over `maxStep` metres: away from silhouettes.
bool continuous(const Image& a, std::uint32_t x, std::uint32_t y, double maxStep) {
  if (x == 0 || y == 0 || x + 1 >= a.width || y + 1 >= a.height) return false;
  const auto c = render::heightAt(a, x, y);
  if (!c) return false;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const auto n = render::heightAt(a, std::uint32_t(int(x) + dx), std::uint32_t(int(y) + dy));
      if (!n || std::abs(*n - *c) > maxStep) return false;
    }
  }
  return true;
}

struct Agreement {
  std::uint64_t terrain = 0, compared = 0, agree = 0;
  double fraction() const { return compared ? double(agree) / double(compared) : 0; }
};

/// Module and mesh height frames, pixel by pixel.
Agreement compareHeights(const Image& modules, const Image& mesh, double tolerance) {
  Agreement a;
  for (std::uint32_t y = 0; y < mesh.height; ++y) {
    for (std::uint32_t x = 0; x < mesh.width; ++x) {
      const auto hm = render::heightAt(modules, x, y), hg = render::heightAt(mesh, x, y);
      if (!hm || !hg) continue;
      ++a.terrain;
      if (!continuous(mesh, x, y, 10) || !continuous(modules, x, y, 10)) continue;
      ++a.compared;
      a.agree += std::abs(*hm - *hg) <= tolerance;
    }
  }
  return a;
}

TEST_F(ViewerLook, HeightFramesOfModulesAtFullLodMatchTheGridMeshAndTheGrid) {
  struct Case {
    std::string dir;
    View view;
  };
  // Rugged ground with culture, from high and low.
  const Case cases[] = {
      {monaco_, {"monaco high", 7.40, 43.705, 1500, 20, -35, 8000}},
      {monaco_, {"monaco low", 7.445, 43.742, 60, 300, -8, 6000}},
      {bayreuth_, {"bayreuth high", 11.55, 49.975, 2500, 0, -25, 9000}},
      {bayreuth_, {"bayreuth low", 11.58, 50.00, 80, 250, -6, 6000}},
  };
  for (const Case& c : cases) {
    auto db = openDatabase(c.dir);
    ASSERT_TRUE(db.ok()) << db.error();
    const Shot modules = shoot(db.value(), c.view, TerrainMode::modules, ColourMode::height);
    const Shot mesh = shoot(db.value(), c.view, TerrainMode::mesh, ColourMode::height);
    ASSERT_EQ(modules.img.width, 320u) << c.view.name;
    // Two quantisation steps: one for the code's rounding, one for the
    // float positions the two modes hand the GPU (module-local vs eye-relative).
    const Agreement a = compareHeights(modules.img, mesh.img, 2 * kQuantum);
    std::printf("[ heights  ] %s: %llu terrain pixels, %llu compared, %.4f%% agree within %.4f m\n",
                c.view.name, (unsigned long long)a.terrain, (unsigned long long)a.compared,
                100 * a.fraction(), 2 * kQuantum);
    EXPECT_GT(a.terrain, 320u * 180u / 3) << c.view.name;
    EXPECT_GT(a.compared, a.terrain * 3 / 5) << c.view.name;
    EXPECT_GE(a.fraction(), 0.995) << c.view.name;

    // Both against the grid: a ray through each sampled pixel's centre.
    const world::Terrain terrain(db->grid);
    std::uint64_t cast = 0, onGrid = 0;
    for (std::uint32_t y = 1; y + 1 < mesh.img.height; y += 7) {
      for (std::uint32_t x = 1; x + 1 < mesh.img.width; x += 7) {
        if (!continuous(mesh.img, x, y, 2) || !continuous(modules.img, x, y, 2)) continue;
        const auto hit = castRay(terrain, mesh.eye, rayThrough(mesh.o, x, y), c.view.viewDistance);
        if (!hit) continue;
        ++cast;
        const double want = (*hit)[1];
        const bool ok = std::abs(*render::heightAt(mesh.img, x, y) - want) <= 0.05 &&
                        std::abs(*render::heightAt(modules.img, x, y) - want) <= 0.05;
        onGrid += ok;
        EXPECT_TRUE(ok) << c.view.name << " pixel " << x << "," << y << ": grid " << want << " mesh "
                        << *render::heightAt(mesh.img, x, y) << " modules "
                        << *render::heightAt(modules.img, x, y);
      }
    }
    EXPECT_GT(cast, 100u) << c.view.name;
  }
}

TEST_F(ViewerLook, UploadBudgetSpreadsTheFirstFrameAndNeverLeavesAHole) {
  // A still eye over Monaco with a budget far below what the view needs:
  // the first frames draw coarser stand-ins (never the magenta clear
  // colour), and once every level is up the frame is the very height
  // frame of an unlimited flight.
  auto db = openDatabase(monaco_);
  ASSERT_TRUE(db.ok()) << db.error();
  const View v{"monaco budget", 7.40, 43.705, 1500, 20, -35, 8000};
  const Shot want = shoot(db.value(), v, TerrainMode::modules, ColourMode::height);
  FlightOptions o = want.o;
  o.pager.sync = false;  // sync lifts the budget
  o.render.uploadBudgetBytes = 128 * 1024;
  o.output.frames = 60;
  o.view.clearColour = {0xFF, 0x00, 0xFF};
  std::vector<Image> frames;
  viewer::FlightHooks hooks(o);
  hooks.onFrame = [&](std::uint32_t, const Image& i) { frames.push_back(i); };
  auto r = viewer::fly(db.value(), o, &hooks);
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(frames.size(), 60u);
  EXPECT_GT(r->frames.front().uploadsDeferred, 0u);
  EXPECT_GT(r->frames.front().nodesFallback, 0u);
  std::uint64_t deferredFrames = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto& f = r->frames[k];
    deferredFrames += f.uploadsDeferred > 0;
    std::uint64_t holes = 0;
    for (std::uint32_t y = 0; y < frames[k].height; ++y) {
      for (std::uint32_t x = 0; x < frames[k].width; ++x) holes += !render::heightAt(frames[k], x, y).has_value();
    }
    EXPECT_EQ(holes, 0u) << "frame " << k;
  }
  std::printf("[ budget   ] %llu of 60 frames left uploads for later; frame 0: %u deferred, %u runs drawn coarser\n",
              (unsigned long long)deferredFrames, r->frames.front().uploadsDeferred, r->frames.front().nodesFallback);
  EXPECT_GT(deferredFrames, 1u);
  ASSERT_EQ(r->frames.back().uploadsDeferred, 0u);
  ASSERT_EQ(r->frames.back().nodesFallback, 0u);
  const Image& last = frames.back();
  std::uint64_t differ = 0;
  for (std::uint32_t y = 0; y < last.height; ++y) {
    for (std::uint32_t x = 0; x < last.width; ++x) {
      const auto a = render::heightAt(last, x, y), b = render::heightAt(want.img, x, y);
      differ += a.has_value() != b.has_value() || (a && std::abs(*a - *b) > 2 * kQuantum);
    }
  }
  EXPECT_EQ(differ, 0u);
}

/// Blue-ish: the water colour lit (docs/VIEWER.md, "Colours").
bool isWater(render::Rgb c) { return c.b > c.r + 40 && c.b > c.g + 15; }

TEST_F(ViewerLook, SeaIsDrawnAsWaterInBothModes) {
  struct Case {
    std::string dir;
    View view;
  };
  // Off Monaco the sea is stored as 0 m; round Samsoe (Danish DTED) the
  // grid's water posts are where the sea was kept at or below 0 m.
  const Case cases[] = {
      {monaco_, {"monaco sea", 7.42, 43.738, 200, 160, -8, 8000}},
      {samsoe_, {"samsoe sea", 10.60, 55.86, 120, 250, -10, 6000}},
  };
  for (const Case& c : cases) {
    auto db = openDatabase(c.dir);
    ASSERT_TRUE(db.ok()) << db.error();
    const grid::GridFile& g = *db->grid;
    const world::Terrain terrain(db->grid);
    for (const TerrainMode mode : {TerrainMode::modules, TerrainMode::mesh}) {
      const Shot shot = shoot(db.value(), c.view, mode, ColourMode::natural);
      std::uint64_t sea = 0, blue = 0;
      for (std::uint32_t y = 0; y < shot.img.height; ++y) {
        for (std::uint32_t x = 0; x < shot.img.width; ++x) {
          const Vec3 d = rayThrough(shot.o, x, y);
          if (d[1] >= 0) continue;
          // Where the ray meets sea level, and nothing nearer in the way.
          const double s = -shot.eye[1] / d[1];
          if (s > c.view.viewDistance * 0.95) continue;
          const auto hit = castRay(terrain, shot.eye, d, c.view.viewDistance);
          if (!hit || std::abs((*hit)[1]) > 1e-3) continue;
          const double u = (*hit)[0] / g.spacing(), v = (*hit)[2] / g.spacing();
          const auto i = std::uint32_t(u), j = std::uint32_t(v);
          if (i + 2 >= g.postsX() || j + 2 >= g.postsZ() || i == 0 || j == 0) continue;
          // Sea per the grid: the 4 x 4 posts round the point are water at 0 m.
          bool wet = true;
          for (std::uint32_t b = j - 1; b <= j + 2 && wet; ++b) {
            for (std::uint32_t a = i - 1; a <= i + 2 && wet; ++a) {
              wet = g.material(a, b) == 1 && g.elevation(a, b) <= 0.0f;
            }
          }
          if (!wet) continue;
          ++sea;
          blue += isWater(shot.img.at(x, y));
        }
      }
      const char* m = mode == TerrainMode::mesh ? "mesh" : "modules";
      std::printf("[ sea      ] %s, %s: %llu sea pixels, %llu blue\n", c.view.name, m,
                  (unsigned long long)sea, (unsigned long long)blue);
      EXPECT_GT(sea, 200u) << c.view.name << " " << m;
      EXPECT_GE(double(blue), 0.99 * double(sea)) << c.view.name << " " << m;
    }
  }
}

int channelGap(render::Rgb a, render::Rgb b) {
  return std::max({std::abs(a.r - b.r), std::abs(a.g - b.g), std::abs(a.b - b.b)});
}

TEST_F(ViewerLook, ModulesAndMeshColourUncoveredGroundAlikeAndMountainsAreNotGreen) {
  auto db = openDatabase(alps_);
  ASSERT_TRUE(db.ok()) << db.error();
  // Over the Rhone valley (700 m) north towards the Aletsch summits
  // (4,000 m and more): valley floor near, rock and snow far.
  const View views[] = {{"alps valley", 8.03, 46.335, 1500, 10, -12, 20000},
                        {"alps slopes", 8.05, 46.34, 2500, 15, -20, 20000}};
  std::uint64_t high = 0, highNeutral = 0, low = 0, lowGreen = 0;
  for (const View& v : views) {
    const Shot hm = shoot(db.value(), v, TerrainMode::mesh, ColourMode::height);
    const Shot cm = shoot(db.value(), v, TerrainMode::mesh, ColourMode::natural);
    const Shot cmod = shoot(db.value(), v, TerrainMode::modules, ColourMode::natural);
    const Shot cflat = shoot(db.value(), v, TerrainMode::modules, ColourMode::natural, render::Shading::flat);
    std::uint64_t compared = 0, same = 0, flatSame = 0;
    for (std::uint32_t y = 0; y < hm.img.height; ++y) {
      for (std::uint32_t x = 0; x < hm.img.width; ++x) {
        if (!continuous(hm.img, x, y, 60)) continue;  // steep: 90 m posts seen from afar
        ++compared;
        same += channelGap(cm.img.at(x, y), cmod.img.at(x, y)) <= 3;
        flatSame += channelGap(cm.img.at(x, y), cflat.img.at(x, y)) <= 3;
        const double h = *render::heightAt(hm.img, x, y);
        const render::Rgb c = cm.img.at(x, y);
        if (h >= 2700) {
          ++high;
          highNeutral += std::abs(c.g - c.r) <= 16 && std::abs(c.g - c.b) <= 16;
        } else if (h <= 1000) {
          ++low;
          lowGreen += c.g > c.r && c.g > c.b + 10;
        }
      }
    }
    std::printf("[ colours  ] %s: %llu compared, %.3f%% modules = mesh, %.3f%% flat = mesh\n", v.name,
                (unsigned long long)compared, 100.0 * double(same) / double(compared),
                100.0 * double(flatSame) / double(compared));
    EXPECT_GT(compared, 320u * 180u / 3) << v.name;
    // Same normals, same ramp: the two modes draw the same picture.
    EXPECT_GE(double(same), 0.99 * double(compared)) << v.name;
    // The seed's look stays available and is visibly different (quilted).
    EXPECT_LT(double(flatSame), 0.5 * double(compared)) << v.name;
  }
  std::printf("[ tint     ] %llu pixels above 2,700 m, %llu grey or white; %llu below 1,000 m, %llu green\n",
              (unsigned long long)high, (unsigned long long)highNeutral, (unsigned long long)low,
              (unsigned long long)lowGreen);
  EXPECT_GT(high, 2000u);
  EXPECT_GE(double(highNeutral), 0.99 * double(high));
  EXPECT_GT(low, 2000u);
  EXPECT_GE(double(lowGreen), 0.99 * double(low));
}

TEST_F(ViewerLook, RoadsShowTheirMarkingsFromLowAltitude) {
  // One straight primary road, 40 m wide, over the flat sea off Monaco:
  // from 150 m straight down, its dashed centre line, edge lines and lanes
  // lie where the texture layout (docs/VIEWER.md, "Roads") puts them.
  constexpr double kWidth = 40, kLat = 43.712, kLon0 = 7.425, kLon1 = 7.440;
  std::ofstream(*tmp_ / "road.geojson")
      << R"({"type":"FeatureCollection","features":[{"type":"Feature",)"
      << R"("properties":{"highway":"primary","width":")" << kWidth << R"("},)"
      << R"("geometry":{"type":"LineString","coordinates":[[)" << kLon0 << "," << kLat << "],["
      << kLon1 << "," << kLat << "]]}}]}";
  convert::ElevationOptions bo;
  bo.sources = {data("elevation/srtm/N43E007.hgt.zip")};
  bo.culture = {*tmp_ / "road.geojson"};
  bo.extent = std::array<double, 4>{7.41, 43.70, 7.45, 43.725};
  bo.spacing = 30;
  bo.output = *tmp_ / "road";
  ASSERT_TRUE(convert::buildElevation(bo, nullptr).ok());
  auto db = openDatabase(bo.output);
  ASSERT_TRUE(db.ok()) << db.error();
  auto geo = geodesy::Projection::create(db->manifest.crsWkt);
  ASSERT_TRUE(geo.ok());
  const auto& gh = db->grid->header();
  const auto roadA = geo->toProjected({kLon0, kLat}), roadB = geo->toProjected({kLon1, kLat});
  ASSERT_TRUE(roadA && roadB);
  const double ea = roadA->easting, na = roadA->northing, eb = roadB->easting, nb = roadB->northing;
  const double length = std::hypot(eb - ea, nb - na);
  const double ue = (eb - ea) / length, un = (nb - na) / length;
  // The driver's left, seen from above: T = 0 there.
  const double le = -un, ln = ue;
  const double midLon = (kLon0 + kLon1) / 2;
  const Shot shot = shoot(db.value(), {"road markings", midLon, kLat, 150, 90, -89, 4000}, TerrainMode::modules,
                          ColourMode::natural);
  ASSERT_EQ(shot.img.width, 320u);
  // Screen position of the road point at distance `s` along, `t` across (0..1).
  const auto pixel = [&](double s, double t) -> std::optional<std::array<std::uint32_t, 2>> {
    const double e = ea + s * ue + (0.5 - t) * kWidth * le, n = na + s * un + (0.5 - t) * kWidth * ln;
    const Vec3 p{e - gh.originEasting, 0, gh.originNorthing - n};
    const FlightOptions& o = shot.o;
    const double h = o.motion.headingDeg * kPi / 180, tp = o.motion.pitchDeg * kPi / 180;
    const Vec3 f{std::cos(tp) * std::sin(h), std::sin(tp), -std::cos(tp) * std::cos(h)};
    const Vec3 r{std::cos(h), 0, std::sin(h)};
    const Vec3 u{r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]};
    const Vec3 d{p[0] - shot.eye[0], p[1] - shot.eye[1], p[2] - shot.eye[2]};
    const auto dot = [](const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
    const double aspect = double(o.view.width) / o.view.height;
    const double k = 1 / std::tan(paging::verticalFovDeg(o.view.hfovDeg, aspect) * kPi / 360);
    const double x = (k / aspect * dot(r, d) / dot(f, d) + 1) / 2 * o.view.width;
    const double y = (1 - k * dot(u, d) / dot(f, d)) / 2 * o.view.height;
    if (x < 1 || y < 1 || x >= o.view.width - 1 || y >= o.view.height - 1) return std::nullopt;
    return std::array<std::uint32_t, 2>{std::uint32_t(x), std::uint32_t(y)};
  };
  // Markings are near white; the primary road's colour (F0B060) has little blue.
  const auto white = [](render::Rgb c) { return std::min({c.r, c.g, c.b}) > 150; };
  const auto asphalt = [](render::Rgb c) { return int(c.r) - int(c.b) > 60; };  // primary: F0B060
  std::uint64_t dash = 0, dashWhite = 0, gap = 0, gapRoad = 0, edge = 0, edgeWhite = 0, lane = 0, laneRoad = 0;
  for (double s = 0.3 * length; s <= 0.7 * length; s += 1.0) {
    // S runs in road widths (docs/CULTURE.md 8); dashes cover [0, 0.45) of each.
    const double f = s / kWidth - std::floor(s / kWidth);
    if (auto p = pixel(s, 0.5); p && std::min({f, std::abs(f - 0.45), 1 - f}) > 0.05) {
      const render::Rgb c = shot.img.at((*p)[0], (*p)[1]);
      if (f < 0.45) dash++, dashWhite += white(c);
      else gap++, gapRoad += asphalt(c);
    }
    for (const double t : {0.07, 0.93}) {
      if (auto p = pixel(s, t)) edge++, edgeWhite += white(shot.img.at((*p)[0], (*p)[1]));
    }
    for (const double t : {0.25, 0.75}) {
      if (auto p = pixel(s, t)) lane++, laneRoad += asphalt(shot.img.at((*p)[0], (*p)[1]));
    }
  }
  std::printf("[ road     ] dash %llu/%llu white, gap %llu/%llu road, edge %llu/%llu white, lane %llu/%llu road\n",
              (unsigned long long)dashWhite, (unsigned long long)dash, (unsigned long long)gapRoad,
              (unsigned long long)gap, (unsigned long long)edgeWhite, (unsigned long long)edge,
              (unsigned long long)laneRoad, (unsigned long long)lane);
  ASSERT_GT(dash, 20u);
  ASSERT_GT(gap, 20u);
  EXPECT_GE(double(dashWhite), 0.9 * double(dash));
  EXPECT_GE(double(gapRoad), 0.9 * double(gap));
  EXPECT_GE(double(edgeWhite), 0.9 * double(edge));
  EXPECT_GE(double(laneRoad), 0.95 * double(lane));
}

}  // namespace
}  // namespace sandtable::test
