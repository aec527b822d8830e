// The stealth viewer on real data (SRTM N43E007 round Monaco with its OSM
// culture): no cracks in any LoD configuration, decals with the right area
// and no skin showing through them, triangle counts falling as Table 8
// describes, and the screen-space mode within its pixel budget.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>

#include "sandtable/converters/crs.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/formats/database.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/image.h"
#include "sandtable/render/renderer.h"
#include "sandtable/paging/view_triangle.h"
#include "test_support.h"
#include "viewer_support.h"

namespace sandtable::test {
namespace {

using viewer::FlightOptions;
using render::Image;
using scene::LodMode;

constexpr double kPi = 3.14159265358979323846;
constexpr double kRoadWidth = 40;  // metres, the GeoJSON's width attribute
constexpr double kRoadLat = 43.712, kRoadLon0 = 7.425, kRoadLon1 = 7.440;

std::string buildDb(const TempDir& tmp, const std::string& name, std::vector<std::string> culture,
                    std::array<double, 4> extent) {
  convert::ElevationOptions o;
  o.sources = {data("elevation/srtm/N43E007.hgt.zip")};
  o.culture = std::move(culture);
  o.extent = extent;
  o.spacing = 30;
  o.output = tmp / name;
  auto r = convert::buildElevation(o, nullptr);
  EXPECT_TRUE(r.ok()) << r.error();
  return o.output;
}

class Viewer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    std::string why;
    if (!render::headlessGlAvailable(why)) {
      noGl_ = why;
      return;
    }
    tmp_ = new TempDir("viewer");
    monaco_ = buildDb(*tmp_, "monaco", {data("culture/osm/monaco.osm.gz")},
                      {7.38, 43.72, 7.46, 43.77});
    // One straight primary road of known width over the flat sea off Monaco.
    std::ofstream(*tmp_ / "road.geojson")
        << R"({"type":"FeatureCollection","features":[{"type":"Feature",)"
        << R"("properties":{"highway":"primary","width":")" << kRoadWidth << R"("},)"
        << R"("geometry":{"type":"LineString","coordinates":[[)" << kRoadLon0 << "," << kRoadLat
        << "],[" << kRoadLon1 << "," << kRoadLat << "]]}}]}";
    road_ = buildDb(*tmp_, "road", {*tmp_ / "road.geojson"}, {7.41, 43.70, 7.45, 43.725});
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override {
    SANDTABLE_REQUIRE_DATA();
    SANDTABLE_REQUIRE(noGl_.empty(), "headless GL (EGL, Mesa): " << noGl_);
  }

  /// Renders one frame of `db` at lon/lat with the options; fog, sky and
  /// panel off, the pager settled, so the frame shows exactly the modules.
  static std::pair<Image, viewer::FrameStats> frame(const std::string& dir, FlightOptions o,
                                                     double lon, double lat,
                                                     const std::string& name = "") {
    auto db = openAt(dir, lon, lat, o);
    if (!db) return {};
    // Two frames: the second is drawn after the pager has surely published
    // every level of every module (the first waits for its queue to drain).
    o.output.frames = 2;
    o.motion.speedKmh = 0;
    o.view.fog = false;
    o.view.sky = false;
    o.view.hud = false;
    o.pager.sync = true;
    o.render.mode = viewer::TerrainMode::modules;
    Image img;
    viewer::FlightHooks hooks(o);
    hooks.onFrame = [&](std::uint32_t, const Image& i) { img = i; };
    auto r = viewer::fly(db.value(), o, &hooks);
    EXPECT_TRUE(r.ok()) << r.error();
    viewer::FrameStats s;
    if (r.ok() && !r->frames.empty()) s = r->frames.back();
    // SANDTABLE_KEEP_TEST_OUTPUT=DIR keeps the frames for a look.
    if (const char* keep = std::getenv("SANDTABLE_KEEP_TEST_OUTPUT"); keep && !name.empty()) {
      render::writePng(std::string(keep) + "/" + name + ".png", img);
    }
    return {img, s};
  }

  static inline TempDir* tmp_ = nullptr;
  static inline std::string monaco_, road_, noGl_;
};

std::uint64_t cracks(const Image& img) { return holesBelowTheSilhouette(img); }

struct LodCase {
  const char* name;
  LodMode mode;
  std::vector<double> rings;
  double pixelError;
  bool morph;
  bool shareMorph = true;
};

std::vector<LodCase> lodCases() {
  return {{"rings Table 8", LodMode::rings, {}, 2, true},
          {"rings no morph", LodMode::rings, {}, 2, false},
          {"rings tight", LodMode::rings, {400, 800, 1600}, 2, true},
          {"rings tight no morph", LodMode::rings, {400, 800, 1600}, 2, false},
          {"sse 1 px", LodMode::sse, {}, 1, true},
          {"sse 1 px node morph", LodMode::sse, {}, 1, true, false},
          {"sse 16 px", LodMode::sse, {}, 16, true},
          {"sse 16 px no morph", LodMode::sse, {}, 16, false},
          {"full", LodMode::full, {}, 2, false}};
}

TEST_F(Viewer, NoCracksBelowTheHorizonInAnyLodConfiguration) {
  struct View {
    const char* name;
    double lon, lat, height, heading, pitch;
  };
  // Low over the harbour towards the hills, along the ridge, and steeply
  // down from high over the town.
  const View views[] = {{"low north", 7.425, 43.728, 40, 340, -4},
                        {"low west", 7.445, 43.745, 60, 260, -6},
                        {"high", 7.42, 43.735, 1500, 45, -60}};
  for (const LodCase& c : lodCases()) {
    for (const View& v : views) {
      FlightOptions o;
      o.view.width = 320;
      o.view.height = 180;
      o.motion.heightAgl = v.height;
      o.motion.headingDeg = v.heading;
      o.motion.pitchDeg = v.pitch;
      o.view.viewDistance = 6000;
      o.render.lod = {c.mode, c.rings, c.pixelError, c.morph, c.shareMorph};
      auto [img, s] = frame(monaco_, o, v.lon, v.lat, std::string(c.name) + " " + v.name);
      ASSERT_EQ(img.width, 320u);
      EXPECT_GT(s.modulesDrawn, 0u) << c.name << ", " << v.name;
      EXPECT_EQ(s.modulesMissing, 0u) << c.name << ", " << v.name;
      EXPECT_EQ(cracks(img), 0u) << c.name << ", " << v.name;
      // Everything is resident (pagerSync): nothing is drawn coarser than
      // the mode asks, and full draws every node at level 0 (issue 9).
      EXPECT_EQ(s.nodesCoarser, 0u) << c.name << ", " << v.name;
      EXPECT_EQ(s.nodesPlaceholder, 0u) << c.name << ", " << v.name;
      if (c.mode == LodMode::full) {
        ASSERT_FALSE(s.levelCounts.empty());
        EXPECT_EQ(s.levelCounts[0], s.nodesDrawn) << v.name;
      }
    }
  }
}

/// A 320 x 180 view at 6 km view distance, `agl` metres above the ground,
/// looking along `heading` with `pitch`, drawn with `lod`.
FlightOptions smallView(double agl, double heading, double pitch, const scene::LodOptions& lod) {
  FlightOptions o;
  o.view.width = 320;
  o.view.height = 180;
  o.motion.heightAgl = agl;
  o.motion.headingDeg = heading;
  o.motion.pitchDeg = pitch;
  o.view.viewDistance = 6000;
  o.render.lod = lod;
  return o;
}

/// 80 m over Monaco's harbour looking along the coast (7.415, 43.725).
FlightOptions lowOverMonaco(const scene::LodOptions& lod) { return smallView(80, 20, -6, lod); }

TEST_F(Viewer, TrianglesFallAsRangeBinsAreAdded) {
  // Table 8: 0-6000 all fine, then two, three and four bins.
  const std::vector<std::vector<double>> bins = {
      {6000}, {3000, 6000}, {2000, 4000, 6000}, {1500, 3000, 4500, 6000}};
  std::vector<std::uint64_t> triangles;
  for (const auto& b : bins) {
    const FlightOptions o = smallView(150, 70, -5, {LodMode::rings, b, 2, false});
    auto [img, s] = frame(monaco_, o, 7.39, 43.73);
    EXPECT_EQ(cracks(img), 0u);
    triangles.push_back(s.triangles);
  }
  for (std::size_t k = 1; k < triangles.size(); ++k) {
    EXPECT_LT(triangles[k], triangles[k - 1]) << "bins " << k + 1;
  }
  // One bin out to the view distance is what the finest level draws.
  scene::LodOptions fullLod;
  fullLod.mode = LodMode::full;
  const FlightOptions full = smallView(150, 70, -5, fullLod);
  EXPECT_EQ(frame(monaco_, full, 7.39, 43.73).second.triangles, triangles.front());
}

// One morph per module and level lets same-level neighbours share their
// edges: the renderer then leaves out the skirts between them and the
// selection merges their runs, with no crack opening.
TEST_F(Viewer, SharedMorphDrawsFewerTrianglesAndCommandsWithNoCracks) {
  std::uint64_t drawn[2] = {}, draws[2] = {};
  for (const bool share : {false, true}) {
    const FlightOptions o = lowOverMonaco({LodMode::sse, {}, 1, true, share});
    auto [img, s] = frame(monaco_, o, 7.415, 43.725, share ? "shared morph" : "node morph");
    EXPECT_EQ(cracks(img), 0u) << "share " << share;
    EXPECT_LE(s.maxErrorPx, 1 + 1e-6) << "share " << share;
    drawn[share] = s.trianglesDrawn;
    draws[share] = s.draws;
  }
  std::printf("[ morph    ] node: %llu triangles in %llu commands; shared: %llu in %llu\n",
              (unsigned long long)drawn[0], (unsigned long long)draws[0], (unsigned long long)drawn[1],
              (unsigned long long)draws[1]);
  EXPECT_LT(drawn[1], drawn[0]);
  EXPECT_LT(draws[1], draws[0]);
}

TEST_F(Viewer, ScreenSpaceErrorStaysWithinThePixelsRequested) {
  std::uint64_t previous = 0;
  for (const double px : {8.0, 4.0, 2.0, 1.0, 0.5}) {
    for (const bool morph : {false, true}) {
      const FlightOptions o = lowOverMonaco({LodMode::sse, {}, px, morph});
      auto [img, s] = frame(monaco_, o, 7.415, 43.725, "sse " + std::to_string(px) + (morph ? " morph" : ""));
      // The morph factor is the largest the budget allows: equal up to rounding.
      EXPECT_LE(s.maxErrorPx, px * (1 + 1e-6)) << px << " px, morph " << morph;
      EXPECT_EQ(s.nodesCoarser, 0u) << px << " px, morph " << morph;
      EXPECT_EQ(cracks(img), 0u) << px << " px, morph " << morph;
      if (!morph) {
        // A tighter budget never draws fewer triangles.
        EXPECT_GE(s.triangles, previous) << px << " px";
        previous = s.triangles;
      }
    }
  }
}

/// Screen position of a world point (X east, Y up, Z south, metres) for the
/// viewer's camera; the same projection as the renderer, written out here.
std::array<double, 2> project(const FlightOptions& o, const std::array<double, 3>& eye,
                              const std::array<double, 3>& p) {
  const double h = o.motion.headingDeg * kPi / 180, t = o.motion.pitchDeg * kPi / 180;
  const std::array<double, 3> f{std::cos(t) * std::sin(h), std::sin(t), -std::cos(t) * std::cos(h)};
  const std::array<double, 3> r{std::cos(h), 0, std::sin(h)};
  const std::array<double, 3> u{r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2],
                                r[0] * f[1] - r[1] * f[0]};
  const std::array<double, 3> d{p[0] - eye[0], p[1] - eye[1], p[2] - eye[2]};
  const auto dot = [](const auto& a, const auto& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  const double aspect = double(o.view.width) / o.view.height;
  const double k = 1 / std::tan(paging::verticalFovDeg(o.view.hfovDeg, aspect) * kPi / 360);
  const double depth = dot(f, d);
  const double nx = k / aspect * dot(r, d) / depth, ny = k * dot(u, d) / depth;
  return {(nx + 1) / 2 * o.view.width, (1 - ny) / 2 * o.view.height};
}

TEST_F(Viewer, StraightRoadCoversItsAreaWithNoSkinShowingThrough) {
  auto db = openDatabase(road_);
  ASSERT_TRUE(db.ok()) << db.error();
  auto geo = geodesy::Projection::create(db->manifest.crsWkt);
  ASSERT_TRUE(geo.ok());
  const auto& gh = db->grid->header();
  const auto world = [&](double lon, double lat) {
    const auto en = geo->toProjected({lon, lat});
    EXPECT_TRUE(en);
    if (!en) return std::array<double, 2>{0, 0};
    return std::array<double, 2>{en->easting - gh.originEasting, gh.originNorthing - en->northing};
  };
  const auto a = world(kRoadLon0, kRoadLat), b = world(kRoadLon1, kRoadLat);
  const double length = std::hypot(b[0] - a[0], b[1] - a[1]);
  const std::array<double, 2> across{-(b[1] - a[1]) / length * kRoadWidth / 2,
                                     (b[0] - a[0]) / length * kRoadWidth / 2};
  const double midLon = (kRoadLon0 + kRoadLon1) / 2;
  struct Shot {
    double height;
    std::uint32_t msaa;
  };
  for (const auto [height, msaa] : {Shot{500, 0}, Shot{1500, 0}, Shot{3000, 0}, Shot{1500, 4}}) {
    FlightOptions o;
    o.render.samples = msaa;
    o.view.width = 480;
    o.view.height = 270;
    o.motion.heightAgl = height;
    o.motion.headingDeg = 0;
    o.motion.pitchDeg = -89;
    o.view.viewDistance = 8000;
    auto [img, s] = frame(road_, o, midLon, kRoadLat, "road " + std::to_string(int(height)));
    ASSERT_EQ(img.width, 480u);
    const auto mid = world(midLon, kRoadLat);
    const std::array<double, 3> eye{mid[0], s.eyeElevation, mid[1]};
    // The road's corners on screen (the sea under it is flat at 0 m).
    std::array<std::array<double, 2>, 4> q;
    const std::array<std::array<double, 2>, 4> corners = {
        {{a[0] + across[0], a[1] + across[1]}, {b[0] + across[0], b[1] + across[1]},
         {b[0] - across[0], b[1] - across[1]}, {a[0] - across[0], a[1] - across[1]}}};
    for (int k = 0; k < 4; ++k) q[k] = project(o, eye, {corners[k][0], 0, corners[k][1]});
    double area = 0;
    for (int k = 0; k < 4; ++k) {
      area += q[k][0] * q[(k + 1) % 4][1] - q[(k + 1) % 4][0] * q[k][1];
    }
    area = std::abs(area) / 2;
    const auto centre = project(o, eye, {mid[0], 0, mid[1]});
    // The sea under the road is water blue and the land beside it green;
    // the road's colour (primary: F0B060), its darker shoulders and its
    // white markings are neither.
    // (Nor the magenta clear colour past the database's east edge.)
    const auto isRoad = [](render::Rgb c) {
      return int(c.r) + 20 > int(c.b) && int(c.r) + 20 > int(c.g) && c.g > 60;
    };
    ASSERT_TRUE(isRoad(img.at(std::uint32_t(centre[0]), std::uint32_t(centre[1]))))
        << "no road at the centre, height " << height;
    double winding = 0;
    for (int k = 0; k < 4; ++k) winding += q[k][0] * q[(k + 1) % 4][1] - q[(k + 1) % 4][0] * q[k][1];
    const double orient = winding > 0 ? 1 : -1;
    // Distance (pixels) from a point to the quad's nearest edge, positive inside.
    const auto inset = [&](double x, double y) {
      double d = 1e9;
      for (int k = 0; k < 4; ++k) {
        const auto& p0 = q[k];
        const auto& p1 = q[(k + 1) % 4];
        const double ex = p1[0] - p0[0], ey = p1[1] - p0[1];
        d = std::min(d, orient * (ex * (y - p0[1]) - ey * (x - p0[0])) / std::hypot(ex, ey));
      }
      return d;
    };
    ASSERT_GT(inset(centre[0], centre[1]), 1.5);
    std::uint64_t roadPixels = 0, skinInside = 0;
    for (std::uint32_t y = 0; y < img.height; ++y) {
      for (std::uint32_t x = 0; x < img.width; ++x) {
        const bool r = isRoad(img.at(x, y));
        roadPixels += r;
        if (!r && inset(x + 0.5, y + 0.5) > 1.5) ++skinInside;
      }
    }
    const bool wholeRoadOnScreen = std::all_of(q.begin(), q.end(), [&](const auto& p) {
      return p[0] >= 0 && p[0] < o.view.width && p[1] >= 0 && p[1] < o.view.height;
    });
    if (height >= 1500) {
      EXPECT_TRUE(wholeRoadOnScreen) << "height " << height;
    }
    // Multisampled edges blend road and skin: only the interior is checked then.
    if (wholeRoadOnScreen && msaa == 0) {
      EXPECT_NEAR(double(roadPixels), area, 0.05 * area)
          << "height " << height << " centre " << centre[0] << "," << centre[1] << " corners "
          << q[0][0] << "," << q[0][1] << " " << q[2][0] << "," << q[2][1];
    }
    EXPECT_EQ(skinInside, 0u) << "height " << height << ", msaa " << msaa;
  }
}

TEST_F(Viewer, StraightRoadHoldsAtGrazingAnglesFarAway) {
  // Looking along the road from beyond its west end, low: the decal must
  // cover its centreline from near to far (no z-fighting with the skin).
  auto db = openDatabase(road_);
  ASSERT_TRUE(db.ok()) << db.error();
  auto geo = geodesy::Projection::create(db->manifest.crsWkt);
  ASSERT_TRUE(geo.ok());
  const auto& gh = db->grid->header();
  const auto roadA = geo->toProjected({kRoadLon0, kRoadLat}), roadB = geo->toProjected({kRoadLon1, kRoadLat});
  ASSERT_TRUE(roadA && roadB);
  const double ea = roadA->easting, na = roadA->northing, eb = roadB->easting, nb = roadB->northing;
  const double length = std::hypot(eb - ea, nb - na);
  const double ue = (eb - ea) / length, un = (nb - na) / length;
  for (const double back : {300.0, 900.0}) {
    FlightOptions o;
    o.view.width = 320;
    o.view.height = 180;
    o.motion.heightAgl = 60;
    o.motion.headingDeg = std::atan2(ue, un) * 180 / kPi;
    o.motion.pitchDeg = -3;
    o.view.viewDistance = 8000;
    const auto ll = geo->toLonLat({ea - back * ue, na - back * un});
    ASSERT_TRUE(ll);
    auto [img, s] = frame(road_, o, ll->lon, ll->lat, "road along " + std::to_string(int(back)));
    ASSERT_EQ(img.width, 320u);
    const std::array<double, 3> eye{ea - back * ue - gh.originEasting, s.eyeElevation,
                                    gh.originNorthing - (na - back * un)};
    render::Rgb road{};
    int checked = 0;
    for (double f = 0.1; f <= 0.9; f += 0.02) {
      const double e = ea + f * length * ue, n = na + f * length * un;
      const auto p = project(o, eye, {e - gh.originEasting, 0, gh.originNorthing - n});
      ASSERT_TRUE(p[0] >= 0 && p[0] < o.view.width && p[1] >= 0 && p[1] < o.view.height) << f;
      const render::Rgb c = img.at(std::uint32_t(p[0]), std::uint32_t(p[1]));
      if (checked++ == 0) road = c;
      EXPECT_GT(int(c.r) - int(c.b), 60) << "back " << back << " at " << f;  // road, not grass
      EXPECT_LE(std::abs(int(c.r) - int(road.r)) + std::abs(int(c.g) - int(road.g)), 24)
          << "back " << back << " at " << f;
    }
  }
}

TEST_F(Viewer, GpuCopiesFollowThePager) {
  // Across the database fast with a short view: modules enter and leave
  // the pager's window, and the render thread's copies with them.
  FlightOptions o;
  auto db = openAt(monaco_, 7.385, 43.745, o);
  ASSERT_TRUE(db);
  o.view.width = 160;
  o.view.height = 90;
  o.output.frames = 45;
  o.motion.headingDeg = 90;
  o.motion.heightAgl = 300;
  o.motion.speedKmh = 12000;  // 111 m a frame: 5 km in 45 frames
  o.view.viewDistance = 1200;
  o.view.hud = false;
  o.pager.sync = true;
  auto r = viewer::fly(db.value(), o);
  ASSERT_TRUE(r.ok()) << r.error();
  std::uint64_t uploads = 0, released = 0;
  for (const auto& f : r->frames) {
    uploads += f.uploads;
    released += f.released;
    EXPECT_GT(f.modulesDrawn, 0u);
    // Only modules of the pager's window keep GPU copies, one per level at most.
    EXPECT_LE(f.cachedLevels, f.windowModules * 4) << "frame " << f.frame;
  }
  EXPECT_GT(uploads, r->frames.front().uploads);  // new modules came in on the way
  EXPECT_GT(released, 0u);                         // and old ones went
}

TEST_F(Viewer, ClearErrorsForBadViewerOptions) {
  const auto fly = [](std::vector<std::string> extra) {
    std::vector<std::string> args = {"fly", monaco_, "--png", *tmp_ / "bad", "--frames", "1"};
    args.insert(args.end(), extra.begin(), extra.end());
    return runCli(args);
  };
  EXPECT_EQ(fly({"--lod", "bogus"}).exitCode, 2);
  EXPECT_EQ(fly({"--rings", "3000,1000"}).exitCode, 2);
  EXPECT_EQ(fly({"--rings", "a,b"}).exitCode, 2);
  EXPECT_EQ(fly({"--mode", "sideways"}).exitCode, 2);
  EXPECT_EQ(fly({"--pixel-error", "0"}).exitCode, 2);
  EXPECT_EQ(fly({"--msaa", "64"}).exitCode, 2);
  // A grid without load modules flies as a mesh, and refuses --mode modules.
  convert::ElevationOptions o;
  o.sources = {data("elevation/srtm/N43E007.hgt.zip")};
  o.extent = std::array<double, 4>{7.40, 43.72, 7.42, 43.735};
  o.spacing = 30;
  o.modules = false;
  o.output = *tmp_ / "nomodules";
  ASSERT_TRUE(convert::buildElevation(o, nullptr).ok());
  const auto bare = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {"fly", o.output, "--png", *tmp_ / "bare", "--frames", "1",
                                     "--size", "64x36"};
    args.insert(args.end(), extra.begin(), extra.end());
    return runCli(args);
  };
  const auto modules = bare({"--mode", "modules"});
  EXPECT_EQ(modules.exitCode, 2);
  EXPECT_NE(modules.err.find("--mode mesh"), std::string::npos) << modules.err;
  const auto mesh = bare({});
  EXPECT_EQ(mesh.exitCode, 0) << mesh.err;
  EXPECT_NE(mesh.out.find("terrain:  mesh"), std::string::npos) << mesh.out;
  EXPECT_EQ(runCli({"bench", "render", o.output, "--frames", "1"}).exitCode, 2);
  // The library names the option field; the CLI shows the user the flag.
  const auto pitch = fly({"--pitch", "95"});
  EXPECT_EQ(pitch.exitCode, 2);
  EXPECT_NE(pitch.err.find("--pitch must be between -89 and 89 degrees"), std::string::npos) << pitch.err;
  EXPECT_EQ(pitch.err.find("MotionOptions::"), std::string::npos) << pitch.err;
  viewer::FlightOptions bad;
  bad.motion.pitchDeg = 95;
  const auto problems = viewer::checkFlightOptions(openDatabase(monaco_).value().grid, bad);
  ASSERT_FALSE(problems.empty());
  EXPECT_NE(problems.front().message.find("MotionOptions::pitchDeg"), std::string::npos);
}

TEST_F(Viewer, HeadlessFlightShowsFramesFpsAndTimeLeft) {
  // Not a TTY here: plain lines at 25 % steps, the last one at 100 %.
  const auto r = runCli({"fly", monaco_, "--png", *tmp_ / "progress", "--frames", "8", "--size", "64x36"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("fly: 100% ("), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("frame 8/8"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(" fps  0 s left"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("fly:  25% ("), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sandtable::test
