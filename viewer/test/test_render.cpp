// Headless flight over a small synthetic database: display buffers, the
// flight path, the panel font, and two real frames through EGL.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/database.h"
#include "sandtable/scene/display_buffer.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/hud.h"
#include "sandtable/render/renderer.h"
#include "sandtable/world/terrain.h"
#include "sandtable/testing/require.h"

namespace sandtable::viewer {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kPosts = 256;
constexpr double kSpacing = 30;
constexpr double kOriginE = 500000, kOriginN = 5200000;

/// A hill (600 m) in the north-east and a valley (down to -40 m, under
/// sea level) in the south-west over rolling ground near 100 m.
double elevationAt(double x, double z) {
  const double w = (kPosts - 1) * kSpacing;
  auto bump = [&](double cx, double cz, double r) {
    const double dx = x - cx * w, dz = z - cz * w;
    return std::exp(-(dx * dx + dz * dz) / (r * r));
  };
  return 100 + 40 * std::sin(x / 300) * std::cos(z / 350) + 600 * bump(0.6, 0.35, 1200) -
         140 * bump(0.25, 0.75, 900);
}

std::array<float, 3> normalAt(double x, double z) {
  const double h = kSpacing;
  const double dx = (elevationAt(x + h, z) - elevationAt(x - h, z)) / (2 * h);
  const double dz = (elevationAt(x, z + h) - elevationAt(x, z - h)) / (2 * h);
  const double len = std::sqrt(dx * dx + 1 + dz * dz);
  return {float(-dx / len), float(1 / len), float(-dz / len)};
}

/// Writes a database the way `sandtable build` lays it out; returns its dir.
std::string writeSyntheticDatabase(const fs::path& dir) {
  fs::create_directories(dir);
  const std::string gridPath = (dir / manifest::kGridFileName).string();
  const auto header = grid::makeHeader(kPosts, kPosts, kSpacing, kOriginE, kOriginN);
  auto writer = grid::GridWriter::create(gridPath, header);
  EXPECT_TRUE(writer.ok()) << writer.error();
  auto block = std::make_unique<grid::BlockData>();
  for (std::uint32_t bz = 0; bz < header.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < header.blocksX; ++bx) {
      for (std::uint32_t lz = 0; lz < grid::kBlockPosts; ++lz) {
        for (std::uint32_t lx = 0; lx < grid::kBlockPosts; ++lx) {
          const double x = (bx * grid::kBlockPosts + lx) * kSpacing;
          const double z = (bz * grid::kBlockPosts + lz) * kSpacing;
          const std::size_t k = lz * grid::kBlockPosts + lx;
          const auto n = normalAt(x, z);
          block->elevation[k] = float(elevationAt(x, z));
          block->normalX[k] = grid::toSnorm(n[0]);
          block->normalY[k] = grid::toSnorm(n[1]);
          block->normalZ[k] = grid::toSnorm(n[2]);
          block->material[k] = 0;
        }
      }
      EXPECT_EQ(writer.value()->writeBlock(bx, bz, *block).message(), "");
    }
  }
  EXPECT_EQ(writer.value()->finish().message(), "");
  const auto& h = writer.value()->header();

  manifest::Manifest m;
  m.toolVersion = "test";
  m.createdUtc = "2024-01-01T00:00:00Z";
  m.crsWkt = "PROJCS[\"test\"]";  // never parsed by the runtime
  m.crsName = "test frame";
  m.originEasting = kOriginE;
  m.originNorthing = kOriginN;
  m.spacing = kSpacing;
  m.postsX = m.postsZ = kPosts;
  m.minElevation = h.minElevation;
  m.maxElevation = h.maxElevation;
  m.cornersLonLat = {{{9, 47}, {9.1, 47}, {9.1, 46.93}, {9, 46.93}}};
  const auto c = crc32File(gridPath);
  EXPECT_TRUE(c.ok()) << c.error();
  m.files.push_back({manifest::kGridFileName, c.ok() ? c->bytes : 0, c.ok() ? c->crc : 0});
  const std::string text = manifest::encode(m);
  EXPECT_EQ(writeFileAtomic((dir / manifest::kFileName).string(),
                            std::as_bytes(std::span(text.data(), text.size()))).message(),
            "");
  return dir.string();
}

class RenderTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("sandtable_render_test_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    auto db = openDatabase(writeSyntheticDatabase(root_ / "db"));
    ASSERT_TRUE(db.ok()) << db.error();
    grid_ = db->grid;
  }
  static void TearDownTestSuite() {
    grid_.reset();
    // SANDTABLE_KEEP_TEST_OUTPUT=1 keeps the frames for a look.
    if (std::getenv("SANDTABLE_KEEP_TEST_OUTPUT")) return;
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  static inline fs::path root_;
  static inline std::shared_ptr<const grid::GridFile> grid_;

  /// Flight options: south of the hill, looking north across it.
  static FlightOptions southLookingNorth() {
    FlightOptions o;
    o.view.width = 320;
    o.view.height = 240;
    o.output.frames = 2;
    o.motion.easting = kOriginE + 0.55 * (kPosts - 1) * kSpacing;
    o.motion.northing = kOriginN - 0.95 * (kPosts - 1) * kSpacing;
    o.motion.headingDeg = 0;
    o.motion.heightAgl = 150;
    o.motion.pitchDeg = -8;
    o.view.viewDistance = 8000;
    return o;
  }
};

TEST_F(RenderTest, StripsReproduceTheTerrainTriangles) {
  scene::Camera cam;
  cam.x = 3000;
  cam.z = 6000;
  cam.y = 500;
  cam.viewDistance = 2000;
  scene::DisplayBuffer buf;
  fillDisplayBuffer(grid::GridHeightField(*grid_), cam, 7, buf);
  ASSERT_FALSE(buf.spans.empty());
  EXPECT_EQ(buf.frame, 7u);
  EXPECT_EQ(buf.firsts.size(), buf.spans.size());
  EXPECT_EQ(buf.triangles, 2 * paging::countSquares(buf.spans));
  const world::Terrain terrain(grid_);
  // Every strip triangle's centroid lies on the surface Terrain samples.
  for (std::size_t s = 0; s < buf.spans.size(); s += 7) {
    for (std::int32_t k = 0; k + 2 < buf.counts[s]; ++k) {
      const auto* v = &buf.vertices[std::size_t(buf.firsts[s] + k)];
      const double x = (v[0].x + v[1].x + v[2].x) / 3.0 + buf.originX;
      const double z = (v[0].z + v[1].z + v[2].z) / 3.0 + buf.originZ;
      const double y = (v[0].y + v[1].y + v[2].y) / 3.0;
      ASSERT_NEAR(terrain.sampleXZ(x, z)->elevation, y, 1e-3) << "strip " << s << " tri " << k;
    }
  }
  // First strip vertex order: v(i,j), v(i,j+1), v(i+1,j).
  const auto& span = buf.spans.front();
  const auto& v0 = buf.vertices[0];
  const auto& v1 = buf.vertices[1];
  const auto& v2 = buf.vertices[2];
  EXPECT_NEAR(v0.x + buf.originX, span.firstI * kSpacing, 1e-2);
  EXPECT_NEAR(v0.z + buf.originZ, span.j * kSpacing, 1e-2);
  EXPECT_NEAR(v1.z - v0.z, kSpacing, 1e-3);
  EXPECT_NEAR(v2.x - v0.x, kSpacing, 1e-3);
}

TEST(FlightPath, StraightAlongHeading) {
  FlightOptions o;
  o.motion.easting = 1000;
  o.motion.northing = 2000;
  o.motion.headingDeg = 90;
  o.motion.speedKmh = 36;  // 10 m/s
  const world::Pose p = poseAt(o, 1.5);
  EXPECT_NEAR(p.easting, 1015, 1e-9);
  EXPECT_NEAR(p.northing, 2000, 1e-9);
  o.motion.headingDeg = 0;
  EXPECT_NEAR(poseAt(o, 1.0).northing, 2010, 1e-9);  // north is +northing
}

TEST(FlightPath, FollowsWaypointLegsAndStops) {
  FlightOptions o;
  o.motion.path = {{0, 0, 100, 36}, {100, 0, 300, 72}, {100, 100, 300, 10}};
  world::Pose p = poseAt(o, 5);  // half of the first leg (10 m/s)
  EXPECT_NEAR(p.easting, 50, 1e-9);
  EXPECT_NEAR(p.heightAgl, 200, 1e-9);
  EXPECT_NEAR(p.headingDeg, 90, 1e-9);
  p = poseAt(o, 12.5);  // 2.5 s into the second leg at 20 m/s
  EXPECT_NEAR(p.northing, 50, 1e-9);
  EXPECT_NEAR(p.headingDeg, 0, 1e-9);
  p = poseAt(o, 100);
  EXPECT_NEAR(p.easting, 100, 1e-9);
  EXPECT_NEAR(p.northing, 100, 1e-9);
  EXPECT_EQ(p.speedKmh, 0);
  // The left turn at the corner (t = 10 s) is spread over 2 s at 45 deg/s,
  // centred on it, not a snap from 90 to 0.
  EXPECT_NEAR(poseAt(o, 10).headingDeg, 45, 1e-9);
  EXPECT_NEAR(poseAt(o, 10).easting, 100, 1e-9);
  EXPECT_NEAR(poseAt(o, 9.5).headingDeg, 67.5, 1e-9);
  EXPECT_NEAR(poseAt(o, 0).speedKmh, 36, 1e-9);  // frame 0 is already moving
}

TEST_F(RenderTest, RejectsBadOptions) {
  FlightOptions o = southLookingNorth();
  o.view.hfovDeg = 5;
  EXPECT_FALSE(checkFlightOptions(grid_, o).empty());
  o = southLookingNorth();
  o.motion.easting = kOriginE - 100;
  EXPECT_FALSE(checkFlightOptions(grid_, o).empty());
  EXPECT_TRUE(checkFlightOptions(grid_, southLookingNorth()).empty());
}

TEST(HudFont, GlyphsAndText) {
  EXPECT_EQ(render::glyphFor(U'a'), render::glyphFor(U'A'));
  EXPECT_EQ(render::glyphFor(U'~'), render::glyphFor(U'?'));
  EXPECT_NE(render::glyphFor(U'0'), render::glyphFor(U'O'));
  EXPECT_EQ(render::decodeHudText("5\xC2\xB0").size(), 2u);
  EXPECT_EQ(render::textWidth("AB", 2), (2 * render::kGlyphAdvance - 1) * 2);
  render::Image img{40, 20, std::vector<std::uint8_t>(40 * 20 * 4, 0)};
  render::drawText(img, 1, 1, "H", 1, render::Rgb{255, 255, 255});
  EXPECT_EQ(img.at(1, 1).r, 255);  // H's top-left dot
  EXPECT_EQ(img.at(2, 1).r, 0);
  EXPECT_EQ(img.at(3, 4).r, 255);  // the crossbar
}

double distance(render::Rgb a, render::Rgb b) {
  const double dr = a.r - b.r, dg = a.g - b.g, db = a.b - b.b;
  return std::sqrt(dr * dr + dg * dg + db * db);
}

TEST_F(RenderTest, RendersSkyAboveTerrain) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  FlightOptions o = southLookingNorth();
  o.output.outDir = (root_ / "frames").string();
  std::vector<render::Image> frames;
  FlightHooks hooks(o);
  hooks.onFrame = [&](std::uint32_t, const render::Image& img) { frames.push_back(img); };
  auto r = fly(grid_, o, &hooks);
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(frames.size(), 2u);
  ASSERT_EQ(r->frames.size(), 2u);
  EXPECT_GT(r->frames[0].triangles, 1000u);
  EXPECT_FALSE(r->summary.renderer.empty());
  for (std::uint32_t k = 0; k < 2; ++k) {
    const auto png = fs::path(o.output.outDir) / frameFileName(k);
    ASSERT_TRUE(fs::exists(png));
    EXPECT_GT(fs::file_size(png), 1000u);
  }
  std::ifstream statsFile(fs::path(o.output.outDir) / "stats.json");
  const auto stats = nlohmann::json::parse(statsFile);
  EXPECT_EQ(stats["summary"]["frames"], 2);
  EXPECT_EQ(stats["frames"].size(), 2u);

  const render::Image& img = frames[1];
  ASSERT_EQ(img.width, 320u);
  ASSERT_EQ(img.height, 240u);
  const render::Rgb sky = o.view.background;
  // Top rows, right of the panel: sky, near the background colour.
  for (std::uint32_t x = 200; x < 320; x += 10) {
    const render::Rgb p = img.at(x, 2);
    EXPECT_LT(distance(p, sky), 90) << "x " << x;
    EXPECT_GT(p.b, p.r);
  }
  // Bottom rows: terrain, clearly not sky.
  double far = 0;
  for (std::uint32_t x = 0; x < 320; x += 4) far += distance(img.at(x, 236), sky);
  EXPECT_GT(far / 80, 60);
  // The lower half is shaded terrain, not one flat colour. The ground
  // there rolls gently at 60..140 m, all one stop of the elevation tint,
  // so the sun's shading alone makes the difference.
  int lo = 3 * 255, hi = 0;
  for (std::uint32_t y = 120; y < 240; y += 3) {
    for (std::uint32_t x = 0; x < 320; x += 3) {
      const render::Rgb p = img.at(x, y);
      lo = std::min(lo, p.r + p.g + p.b);
      hi = std::max(hi, p.r + p.g + p.b);
    }
  }
  EXPECT_GT(hi - lo, 15);
  // The panel darkens the top-left corner.
  EXPECT_LT(distance(img.at(1, 1), render::Rgb{0, 0, 0}), distance(img.at(300, 1), render::Rgb{0, 0, 0}));
}

TEST_F(RenderTest, ControllerAndCompositeHooksDriveTheLoop) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  FlightOptions o = southLookingNorth();
  o.output.frames = 10;
  const world::Pose start = poseAt(o, 0);
  // The controller steers three frames, then ends the flight.
  FlightHooks hooks(o);
  hooks.onPose = [&](std::uint32_t frame, double, world::GroundClamp&) -> std::optional<world::Pose> {
    if (frame == 3) return std::nullopt;
    world::Pose p = start;
    p.headingDeg = 10.0 * frame;
    p.hfovDeg = 30;
    p.viewDistance = 5000;
    return p;
  };
  std::vector<std::uint32_t> composited;
  hooks.onOverlay = [&](render::Overlay& overlay, const FrameStats& s) {
    composited.push_back(s.frame);
    render::Image& layer = overlay.layer();
    layer.rgba[0] = 255, layer.rgba[1] = 0, layer.rgba[2] = 0, layer.rgba[3] = 255;  // a map would go here
    overlay.drawn({0, 0, 1, 1});
  };
  std::vector<render::Rgb> corners;
  hooks.onFrame = [&](std::uint32_t, const render::Image& img) { corners.push_back(img.at(0, 0)); };
  auto r = fly(grid_, o, &hooks);
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r->frames.size(), 3u);
  EXPECT_EQ(composited, (std::vector<std::uint32_t>{0, 1, 2}));
  for (const render::Rgb& c : corners) EXPECT_EQ(c.r, 255);
  for (const auto& f : r->frames) {
    EXPECT_EQ(f.hfovDeg, 30);
    EXPECT_EQ(f.viewDistance, 5000);
    EXPECT_EQ(f.headingDeg, 10.0 * f.frame);
  }
  // The panel reports what was drawn, not the options.
  const auto lines = hudLines(r->frames[1], o);
  EXPECT_NE(std::find(lines.begin(), lines.end(), "FOV 30\xC2\xB0  VIEW 5000 M"), lines.end());
}

TEST_F(RenderTest, FailsCleanlyOutsideTheGrid) {
  FlightOptions o = southLookingNorth();
  o.motion.northing = kOriginN + 1000;
  auto r = fly(grid_, o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().find("outside"), std::string::npos);
}

}  // namespace
}  // namespace sandtable::viewer
