// The 2-D map (seed Figures 40 and 41) over a small synthetic grid: sea in
// blue, a grey ramp that rises with elevation, scales that halve the
// ground shown, windows clamped to the database, and the viewer's marker.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "sandtable/render/map_view.h"

namespace sandtable::render {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kPostsX = 130, kPostsZ = 100;  // not square, not whole blocks
constexpr double kSpacing = 10;
constexpr std::uint32_t kCoast = 20;  // posts west of this are sea

/// Sea (-5 m, water) in the west, then ground rising 2 m per post east; a
/// lake (water material at 50 m) around post (100, 80).
void post(std::uint32_t i, std::uint32_t j, float& e, std::uint8_t& m) {
  e = i < kCoast ? -5.0f : float(i - kCoast) * 2.0f + 1.0f;
  m = i < kCoast ? 1 : 0;
  if (i >= 98 && i <= 102 && j >= 78 && j <= 82) m = 1;
}

std::shared_ptr<const grid::GridFile> writeGrid() {
  const fs::path path = fs::temp_directory_path() / ("sandtable-map-" + std::to_string(::getpid()) + ".stg");
  const auto h = grid::makeHeader(kPostsX, kPostsZ, kSpacing, 500000, 4000000);
  auto w = grid::GridWriter::create(path.string(), h);
  EXPECT_TRUE(w.ok()) << w.error();
  auto b = std::make_unique<grid::BlockData>();
  for (std::uint32_t bz = 0; bz < h.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < h.blocksX; ++bx) {
      for (std::uint32_t z = 0; z < grid::kBlockPosts; ++z) {
        for (std::uint32_t x = 0; x < grid::kBlockPosts; ++x) {
          // Padding repeats the edge post (docs/FORMAT.md 4.6).
          const std::uint32_t i = std::min(bx * grid::kBlockPosts + x, kPostsX - 1);
          const std::uint32_t j = std::min(bz * grid::kBlockPosts + z, kPostsZ - 1);
          const std::size_t k = z * grid::kBlockPosts + x;
          post(i, j, b->elevation[k], b->material[k]);
          b->normalX[k] = 0;
          b->normalY[k] = grid::toSnorm(1.0f);
          b->normalZ[k] = 0;
        }
      }
      EXPECT_EQ(w.value()->writeBlock(bx, bz, *b).message(), "");
    }
  }
  EXPECT_EQ(w.value()->finish().message(), "");
  auto g = grid::GridFile::open(path.string());
  EXPECT_TRUE(g.ok()) << g.error();
  fs::remove(path);  // the mapping stays valid
  return g.value();
}

MapOptions pureRamp() {
  MapOptions o;
  o.hillshade = 0;
  return o;
}

Image filled(std::uint32_t w, std::uint32_t h, Rgb c) {
  Image img;
  img.width = w;
  img.height = h;
  img.rgba.resize(std::size_t(w) * h * 4);
  for (std::size_t k = 0; k < img.rgba.size(); k += 4) {
    img.rgba[k] = c.r;
    img.rgba[k + 1] = c.g;
    img.rgba[k + 2] = c.b;
    img.rgba[k + 3] = 255;
  }
  return img;
}

bool same(Rgb a, Rgb b) { return a.r == b.r && a.g == b.g && a.b == b.b; }

class MapViewTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { grid_ = writeGrid(); }
  static void TearDownTestSuite() { grid_.reset(); }
  static std::shared_ptr<const grid::GridFile> grid_;
};
std::shared_ptr<const grid::GridFile> MapViewTest::grid_;

TEST_F(MapViewTest, SeaIsBlueAndTheGreyRampRisesWithElevation) {
  MapView map(grid_, pureRamp());
  EXPECT_FLOAT_EQ(map.landMin(), 1);
  EXPECT_FLOAT_EQ(map.landMax(), float(kPostsX - 1 - kCoast) * 2 + 1);
  EXPECT_TRUE(same(map.rampColor(-5, 1), kMapSeaBlue));
  EXPECT_TRUE(same(map.rampColor(0, 0), kMapSeaBlue));   // sea level
  EXPECT_TRUE(same(map.rampColor(50, 1), kMapSeaBlue));  // water material above sea level
  const Rgb low = map.rampColor(map.landMin(), 0), high = map.rampColor(map.landMax(), 0);
  EXPECT_EQ(high.r, 255);
  EXPECT_LT(low.r, 32);
  int last = -1;
  for (float e = map.landMin(); e <= map.landMax(); e += 0.5f) {
    const Rgb c = map.rampColor(e, 0);
    EXPECT_TRUE(c.r == c.g && c.g == c.b) << "grey at " << e;
    EXPECT_GE(int(c.r), last) << "ramp falls at " << e;
    last = c.r;
  }
  // The overview shows the same: sea pixels blue, the land row rising.
  const Image& ov = map.overview();
  ASSERT_EQ(ov.width, kPostsX);
  ASSERT_EQ(ov.height, kPostsZ);
  EXPECT_TRUE(same(ov.at(3, 10), kMapSeaBlue));
  EXPECT_TRUE(same(ov.at(100, 80), kMapSeaBlue));  // the lake
  last = -1;
  for (std::uint32_t x = kCoast; x < kPostsX; ++x) {
    EXPECT_GE(int(ov.at(x, 10).r), last);
    last = ov.at(x, 10).r;
  }
  EXPECT_GT(int(ov.at(kPostsX - 1, 10).r), int(ov.at(kCoast, 10).r));
}

TEST_F(MapViewTest, OverviewIsDownsampled) {
  MapOptions o = pureRamp();
  o.overviewMaxSide = 50;
  MapView map(grid_, o);
  EXPECT_LE(map.overview().width, 50u);
  EXPECT_LE(map.overview().height, 50u);
}

TEST_F(MapViewTest, EachScaleHalvesTheGroundAndStaysOnTheDatabase) {
  MapView map(grid_, pureRamp());
  const double W = map.worldWidth(), D = map.worldDepth();
  EXPECT_DOUBLE_EQ(W, 1290);
  EXPECT_DOUBLE_EQ(D, 990);
  const MapWindow full = map.centredWindow(300, 200, 0);
  EXPECT_DOUBLE_EQ(full.left, 0);
  EXPECT_DOUBLE_EQ(full.right, W);
  EXPECT_DOUBLE_EQ(full.top, 0);
  EXPECT_DOUBLE_EQ(full.bottom, D);
  for (int s = 1; s < 5; ++s) {
    const MapWindow a = map.centredWindow(640, 500, s - 1), b = map.centredWindow(640, 500, s);
    EXPECT_NEAR(b.width(), a.width() / 2, 1e-9) << MapView::scaleName(s);
    EXPECT_NEAR(b.depth(), a.depth() / 2, 1e-9);
  }
  // Centred in the middle; shifted, not shrunk, at the edges (Figure 40).
  const MapWindow mid = map.centredWindow(640, 500, 2);
  EXPECT_NEAR((mid.left + mid.right) / 2, 640, 1e-9);
  EXPECT_NEAR((mid.top + mid.bottom) / 2, 500, 1e-9);
  const MapWindow nw = map.centredWindow(10, 10, 2);
  EXPECT_DOUBLE_EQ(nw.left, 0);
  EXPECT_DOUBLE_EQ(nw.top, 0);
  EXPECT_NEAR(nw.width(), W / 4, 1e-9);
  const MapWindow se = map.centredWindow(W - 1, D + 500, 3);
  EXPECT_DOUBLE_EQ(se.right, W);
  EXPECT_DOUBLE_EQ(se.bottom, D);
  EXPECT_NEAR(se.depth(), D / 8, 1e-9);
  EXPECT_STREQ(MapView::scaleName(4), "SIXTEENTH");
}

TEST_F(MapViewTest, HiddenMapTouchesNothing) {
  MapView map(grid_, pureRamp());
  Image frame = filled(320, 240, {10, 200, 10});
  const Image before = frame;
  EXPECT_FALSE(map.compose(frame, 100, 100, 0).drawn);
  EXPECT_EQ(frame.rgba, before.rgba);
  map.toggle();
  EXPECT_TRUE(map.compose(frame, 100, 100, 0).drawn);
  EXPECT_NE(frame.rgba, before.rgba);
}

TEST_F(MapViewTest, ComposeDrawsTheMapInTheCornerWithTheViewerAtHisPixel) {
  MapView map(grid_, pureRamp());
  map.setVisible(true);
  const Rgb bg{10, 200, 10};
  Image frame = filled(640, 480, bg);
  const double eyeX = 900, eyeZ = 300;
  const MapLayout l = map.compose(frame, eyeX, eyeZ, 90);  // heading east
  ASSERT_TRUE(l.drawn);
  // Top-right corner, the box a fraction of the shorter side, aspect kept.
  EXPECT_EQ(l.width, 192);  // 0.4 * 480
  EXPECT_EQ(l.height, int(std::lround(192 * 990.0 / 1290.0)));
  EXPECT_EQ(l.x + l.width + 1 + 8, 640);
  EXPECT_EQ(l.y, 9);
  EXPECT_TRUE(same(frame.at(5, 300), bg));  // outside the map: untouched
  // The viewer's pixel, from the database's extent (full scale).
  ASSERT_TRUE(l.markerVisible);
  EXPECT_EQ(l.markerX, l.x + int(eyeX / 1290.0 * l.width));
  EXPECT_EQ(l.markerY, l.y + int(eyeZ / 990.0 * l.height));
  const Rgb red{255, 40, 40};
  EXPECT_TRUE(same(frame.at(std::uint32_t(l.markerX), std::uint32_t(l.markerY)), red));
  // The arrow points east: red ahead of the viewer, not as far behind.
  const int size = std::max(4, l.width / 24);
  EXPECT_TRUE(same(frame.at(std::uint32_t(l.markerX + size - 2), std::uint32_t(l.markerY)), red));
  EXPECT_FALSE(same(frame.at(std::uint32_t(l.markerX - size + 1), std::uint32_t(l.markerY)), red));
  // Sea in the west of the map is blue; land east of the coast is grey.
  EXPECT_TRUE(same(frame.at(std::uint32_t(l.x + 3), std::uint32_t(l.y + 10)), kMapSeaBlue));
  const Rgb land = frame.at(std::uint32_t(l.x + l.width / 2), std::uint32_t(l.y + 10));
  EXPECT_TRUE(land.r == land.g && land.g == land.b);
}

TEST_F(MapViewTest, LabelAndMarkerStayInsideTheMapAtEveryScaleAndSize) {
  // The label was clipped ("1/8 EIGHT", "1/1 FUL") and the arrow could hang
  // over the map's edge. Nothing the map draws may fall outside its box.
  const Rgb bg{10, 200, 10};
  for (auto [w, h] : {std::pair{320u, 180u}, {640u, 360u}, {1280u, 720u}, {1920u, 1080u}}) {
    for (int scale = 0; scale < 5; ++scale) {
      // At the database's corners and centre, heading every way.
      for (auto [x, z] : {std::pair{0.0, 0.0}, {1290.0, 990.0}, {645.0, 495.0}, {1290.0, 0.0}}) {
        for (double heading : {0.0, 45.0, 135.0, 270.0}) {
          MapView map(grid_, pureRamp());
          map.setVisible(true);
          map.setScale(scale);
          Image frame = filled(w, h, bg);
          const MapLayout l = map.compose(frame, x, z, heading);
          ASSERT_TRUE(l.drawn);
          for (std::uint32_t py = 0; py < h; ++py) {
            for (std::uint32_t px = 0; px < w; ++px) {
              const bool inBox = int(px) >= l.x - 1 && int(px) <= l.x + l.width &&
                                 int(py) >= l.y - 1 && int(py) <= l.y + l.height;
              if (!inBox) {
                ASSERT_TRUE(same(frame.at(px, py), bg))
                    << w << "x" << h << " scale " << scale << " at " << px << "," << py;
              }
            }
          }
          // The label is whole: its last glyph column ends inside the box.
          const int labelRow = l.y + l.height - 4;
          int rightmost = -1;
          for (int px = l.x; px < l.x + l.width; ++px) {
            const Rgb c = frame.at(std::uint32_t(px), std::uint32_t(labelRow));
            if (c.r == 255 && c.g == 255 && c.b == 0) rightmost = px;  // the label colour
          }
          EXPECT_LT(rightmost, l.x + l.width - 1) << w << "x" << h << " scale " << scale;
        }
      }
    }
  }
}

TEST_F(MapViewTest, ZoomedMapFollowsTheViewerOnlyOutOfTheInnerBox) {
  MapView map(grid_, pureRamp());
  map.setVisible(true);
  map.setScale(2);  // a quarter: 322.5 m wide
  Image frame = filled(640, 480, {0, 0, 0});
  const MapLayout a = map.compose(frame, 640, 500, 0);
  EXPECT_NEAR((a.window.left + a.window.right) / 2, 640, 1e-9);
  EXPECT_NEAR(a.window.width(), 1290.0 / 4, 1e-9);
  // 50 m east is inside the inner box (a quarter of the width either way):
  // the map stays, the marker moves.
  const MapLayout b = map.compose(frame, 690, 500, 0);
  EXPECT_DOUBLE_EQ(b.window.left, a.window.left);
  EXPECT_GT(b.markerX, a.markerX);
  // 100 m east is out of it: the map re-centres on the viewer.
  const MapLayout c = map.compose(frame, 740, 500, 0);
  EXPECT_NEAR((c.window.left + c.window.right) / 2, 740, 1e-9);
  EXPECT_EQ(c.markerX, c.x + c.width / 2);
}

TEST_F(MapViewTest, EntitiesAreArrowsInTheirForcesColoursTheDeadDimmedUnderTheViewer) {
  MapView map(grid_, pureRamp());
  map.setVisible(true);
  Image frame = filled(640, 480, Rgb{10, 200, 10});
  // The database is 1290 x 990 m; the map shows all of it (full scale).
  const std::vector<MapMark> marks = {
      {300, 200, 90, 2, true, false, false, std::nullopt},   // red, alive, heading east
      {600, 700, 0, 1, true, false, false, std::nullopt},    // blue
      {1000, 500, 0, 3, false, false, false, std::nullopt},  // green, dead
      {200, 800, 0, 0, true, false, false, std::nullopt},    // neutral
  };
  const MapLayout l = map.compose(frame, 900, 300, 0, marks);
  ASSERT_TRUE(l.drawn);
  const auto at = [&](double x, double z) {
    int px = 0, py = 0;
    EXPECT_TRUE(MapView::pixelOf(l, x, z, px, py));
    // pixelOf follows the layout: the full-scale map maps metres linearly.
    EXPECT_EQ(px, l.x + int(x / 1290.0 * l.width));
    EXPECT_EQ(py, l.y + int(z / 990.0 * l.height));
    return frame.at(std::uint32_t(px), std::uint32_t(py));
  };
  const Rgb red{235, 30, 30}, blue{40, 110, 255}, green{40, 200, 60}, grey{170, 170, 170};
  EXPECT_TRUE(same(forceColour(2), red));
  EXPECT_TRUE(same(forceColour(3), green));
  EXPECT_TRUE(same(forceColour(9), grey));
  EXPECT_TRUE(same(at(300, 200), red));
  EXPECT_TRUE(same(at(600, 700), blue));
  EXPECT_TRUE(same(at(200, 800), grey));
  // The dead: half the force's colour, no heading.
  EXPECT_TRUE(same(at(1000, 500), Rgb{20, 100, 30}));
  EXPECT_TRUE(same(deadColour(3), Rgb{20, 100, 30}));
  // The red arrow points east: red two pixels ahead, not two behind it.
  int px = 0, py = 0;
  ASSERT_TRUE(MapView::pixelOf(l, 300, 200, px, py));
  EXPECT_TRUE(same(frame.at(std::uint32_t(px + 2), std::uint32_t(py)), red));
  EXPECT_FALSE(same(frame.at(std::uint32_t(px - 3), std::uint32_t(py)), red));
  // Off the map: nothing to find.
  EXPECT_FALSE(MapView::pixelOf(l, -10, 200, px, py));
  // The viewer's arrow goes over an entity at his own place.
  Image again = filled(640, 480, Rgb{10, 200, 10});
  MapOptions o = pureRamp();
  o.markerFill = {255, 220, 0};
  MapView yellow(grid_, o);
  yellow.setVisible(true);
  const MapLayout m = yellow.compose(again, 300, 200, 0, {marks[0]});
  EXPECT_TRUE(same(again.at(std::uint32_t(m.markerX), std::uint32_t(m.markerY)), o.markerFill));
}

TEST_F(MapViewTest, ToWorldFromProjected) {
  double x = 0, z = 0;
  MapView::toWorld(grid_->header(), 500120, 3999700, x, z);
  EXPECT_DOUBLE_EQ(x, 120);
  EXPECT_DOUBLE_EQ(z, 300);
}

}  // namespace
}  // namespace sandtable::render
