// The heights overlay on real data (../shared/data: Monaco's SRTM at 30 m,
// built in the suite) and against independent computations:
//  - a medium crater on a steep slope (steep in the SRTM source itself, read
//    through GDAL): Terrain::sampleXZ at its centre is the unedited grid's
//    ground there minus the depth; the volume it removes is the profile's
//    closed form; the ground clamp's level 0 agrees with Terrain;
//  - 200 random edits applied twice give one hash and bit-identical posts
//    and fine posts; two overlapping edits swapped give another hash;
//  - readers on many threads while one writer applies edits see only the
//    values the thread contract allows (a reference run gives each
//    generation's values), generations never go back;
//  - no step across a refined square's edges or its patch's border;
//  - normals are the build's central differences, recomputed here.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <thread>

#include "sandtable/base/hash.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/edits/heights.h"
#include "sandtable/edits/profile.h"
#include "sandtable/formats/database.h"
#include "sandtable/testing/fixtures.h"
#include "sandtable/testing/require.h"
#include "sandtable/world/ground.h"
#include "sandtable/world/terrain.h"

namespace sandtable::edits {
namespace {

namespace fs = std::filesystem;

std::string dataDir() { return std::string(SANDTABLE_SOURCE_DIR) + "/../shared/data"; }
std::string srtmPath() { return dataDir() + "/elevation/srtm/N43E007.hgt.zip"; }
bool haveData() { return fs::exists(srtmPath()); }

edit::Edit crater(double x, double z, double radius, double depth, std::uint64_t id = 1) {
  edit::Edit e;
  e.id = id;
  e.kind = edit::Kind::crater;
  e.points = {{x, z}};
  e.radius = radius;
  e.depth = depth;
  return e;
}

edit::Edit line(edit::Kind kind, std::vector<std::array<double, 2>> pts, double width, double height, double slope,
                std::uint64_t id = 1) {
  edit::Edit e;
  e.id = id;
  e.kind = kind;
  e.points = std::move(pts);
  e.width = width;
  e.height = height;
  e.sideSlope = slope;
  return e;
}

/// The position of fine post a of square k (cells c): the overlay's own
/// numbers (a dyadic fraction of a square), so a centre put there is a post.
double finePos(std::uint32_t k, std::uint32_t a, std::uint32_t c, double s) {
  return (double(k) + double(a) / double(c)) * s;
}

/// The SRTM tile's posts through GDAL, bilinear at lon/lat (as test_sim).
class Srtm {
 public:
  Srtm() {
    GDALAllRegister();
    const std::string vsi = "/vsizip/" + srtmPath() + "/N43E007.hgt";
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
  /// NaN where a post it needs is a void.
  double at(double lon, double lat) const {
    const double u = (lon - gt_[0]) / gt_[1] - 0.5, v = (lat - gt_[3]) / gt_[5] - 0.5;
    const int i = int(std::floor(u)), j = int(std::floor(v));
    const double fu = u - i, fv = v - j;
    auto p = [&](int a, int b) {
      const float post = posts_[std::size_t(b) * std::size_t(w_) + std::size_t(a)];
      return post < -1000.0f ? std::nan("") : double(post);
    };
    return (1 - fv) * ((1 - fu) * p(i, j) + fu * p(i + 1, j)) + fv * ((1 - fu) * p(i, j + 1) + fu * p(i + 1, j + 1));
  }

 private:
  int w_ = 0, h_ = 0;
  double gt_[6] = {};
  std::vector<float> posts_;
};

/// Monaco at 30 m, grid only, built once for the suite with the converters
/// (the build `sandtable build --no-modules` runs).
class MonacoHeights : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    dir_ = new fs::path(fs::temp_directory_path() / ("sandtable-heights." + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    convert::ElevationOptions o;
    o.sources = {srtmPath()};
    o.output = (*dir_ / "db").string();
    o.extent = std::array<double, 4>{7.38, 43.70, 7.47, 43.78};
    o.spacing = 30;
    o.modules = false;
    const auto built = convert::buildElevation(o, {});
    ASSERT_TRUE(built) << built.error();
    auto db = openDatabase(o.output);
    ASSERT_TRUE(db) << db.error();
    db_ = new Database(std::move(db.value()));
  }
  static void TearDownTestSuite() {
    delete db_;
    db_ = nullptr;
    if (dir_) fs::remove_all(*dir_);
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    SANDTABLE_REQUIRE(haveData(), "../shared/data at " << dataDir());
    ASSERT_TRUE(db_);
  }
  /// A fresh overlay over the database's grid.
  static std::shared_ptr<EditedHeights> overlay() {
    return std::make_shared<EditedHeights>(grid::heightField(db_->grid));
  }
  /// The unedited ground, opened again from the file (not through the
  /// overlay or its base).
  static std::shared_ptr<const grid::GridFile> original() {
    auto g = grid::GridFile::open(db_->directory + "/grid.stg");
    EXPECT_TRUE(g) << g.error();
    return g ? g.value() : nullptr;
  }
  /// The post with the steepest central-difference slope, 40 posts or more
  /// from the edges (the random edits' window fits around it).
  static std::array<std::uint32_t, 2> steepestPost(const grid::GridFile& g) {
    double best = -1;
    std::array<std::uint32_t, 2> at{};
    const double s = g.spacing();
    for (std::uint32_t j = 40; j + 40 < g.postsZ(); ++j) {
      for (std::uint32_t i = 40; i + 40 < g.postsX(); ++i) {
        const double dx = (g.elevation(i + 1, j) - g.elevation(i - 1, j)) / (2 * s);
        const double dz = (g.elevation(i, j + 1) - g.elevation(i, j - 1)) / (2 * s);
        if (std::hypot(dx, dz) > best) best = std::hypot(dx, dz), at = {i, j};
      }
    }
    return at;
  }
  static Database* db_;
  static fs::path* dir_;
};
Database* MonacoHeights::db_ = nullptr;
fs::path* MonacoHeights::dir_ = nullptr;

/// World (x, z) of the database to lon/lat, through GDAL/PROJ.
class ToLonLat {
 public:
  ToLonLat(const Database& db) : db_(db) {
    src_.importFromWkt(db.manifest.crsWkt.c_str());
    dst_.importFromEPSG(4326);
    dst_.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    src_.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    ct_.reset(OGRCreateCoordinateTransformation(&src_, &dst_));
  }
  std::array<double, 2> operator()(double x, double z) const {
    double e = db_.grid->header().originEasting + x, n = db_.grid->header().originNorthing - z;
    EXPECT_TRUE(ct_ && ct_->Transform(1, &e, &n));
    return {e, n};
  }

 private:
  const Database& db_;
  OGRSpatialReference src_, dst_;
  std::unique_ptr<OGRCoordinateTransformation> ct_;
};

TEST_F(MonacoHeights, aMediumCraterOnASteepSlopeDigsItsDepthAndRemovesItsVolume) {
  const auto orig = original();
  ASSERT_TRUE(orig);
  const world::Terrain before(orig);
  const auto heights = overlay();
  const world::Terrain after{std::shared_ptr<const grid::HeightField>(heights)};
  const double s = heights->spacing();

  const edit::Edit probe = crater(0, 0, kCraterMedium.radius, kCraterMedium.depth);
  const std::uint32_t c = refineCells(probe, s);
  ASSERT_EQ(c, 64u) << "a medium crater on 30 m posts is refined 64 cells a square";

  // The site: the steepest square of the grid where the SRTM source has no
  // void (the steepest cliffs of Monaco are voids the build filled). The
  // crater's centre is on a fine post (the drawn surface is linear between
  // fine posts, and the bowl is not).
  const Srtm srtm;
  ASSERT_TRUE(srtm.ok());
  const ToLonLat lonlat(*db_);
  const auto src = [&](double x, double z) {
    const auto ll = lonlat(x, z);
    return srtm.at(ll[0], ll[1]);
  };
  const auto centre = [&](std::uint32_t i, std::uint32_t j) {
    return std::array<double, 2>{finePos(i, c / 2, c, s), finePos(j, 3 * c / 8, c, s)};
  };
  /// The slope over 30 m across (x, z) of a surface.
  const auto slope = [](const auto& f, double x, double z) {
    return std::hypot((f(x + 15, z) - f(x - 15, z)) / 30, (f(x, z + 15) - f(x, z - 15)) / 30);
  };
  const auto ground = [&](double x, double z) { return before.sampleXZ(x, z)->elevation; };
  std::vector<std::pair<double, SquareIndex>> squares;
  for (std::uint32_t j = 2; j + 3 < orig->postsZ(); ++j) {
    for (std::uint32_t i = 2; i + 3 < orig->postsX(); ++i) {
      const auto [x, z] = centre(i, j);
      squares.push_back({-slope(ground, x, z), {i, j}});
    }
  }
  std::sort(squares.begin(), squares.end());
  const auto site = std::find_if(squares.begin(), squares.end(), [&](const auto& sq) {
    const auto [x, z] = centre(sq.second.i, sq.second.j);
    return std::isfinite(slope(src, x, z)) && std::isfinite(slope(src, x + 30, z + 30)) &&
           std::isfinite(slope(src, x - 30, z - 30));
  });
  ASSERT_NE(site, squares.end());
  const auto [pi, pj] = site->second;
  const auto [cx, cz] = centre(pi, pj);
  // Steep in the source itself (the SRTM posts through GDAL), and the grid
  // agrees with it there.
  EXPECT_GT(slope(src, cx, cz), std::tan(30.0 * M_PI / 180)) << "the SRTM slope at the crater is over 30 degrees";
  EXPECT_NEAR(slope(ground, cx, cz), slope(src, cx, cz), 0.25 * slope(src, cx, cz));

  const auto changed = heights->apply(crater(cx, cz, kCraterMedium.radius, kCraterMedium.depth));
  ASSERT_TRUE(changed) << changed.error();
  EXPECT_TRUE(changed->posts.empty()) << "a 12 m crater inside a 30 m square moves no post";
  ASSERT_EQ(changed->squares.size(), 1u);
  EXPECT_EQ(changed->squares[0], (SquareIndex{pi, pj}));
  EXPECT_EQ(changed->region, (grid::PostRect{pi, pj, pi + 2, pj + 2}));
  EXPECT_EQ(heights->regionGeneration({pi, pj, pi + 1, pj + 1}), changed->generation);

  // The centre: the original ground minus the depth.
  const auto o = before.sampleXZ(cx, cz), n = after.sampleXZ(cx, cz);
  ASSERT_TRUE(o && n);
  EXPECT_NEAR(n->elevation, o->elevation - kCraterMedium.depth, 1e-3);

  // The volume removed: at every fine post (the patch's lattice, h apart),
  // old minus new where positive, times h^2.
  const auto patch = heights->refined(pi, pj);
  ASSERT_TRUE(patch);
  EXPECT_EQ(patch->cells, c);
  const double h = s / c;
  double removed = 0;
  for (std::uint32_t b = patch->b0; b <= patch->b1; ++b) {
    for (std::uint32_t a = patch->a0; a <= patch->a1; ++a) {
      const double x = finePos(pi, a, c, s), z = finePos(pj, b, c, s);
      removed += std::max(0.0, before.sampleXZ(x, z)->elevation - after.sampleXZ(x, z)->elevation) * h * h;
    }
  }
  const double exact = craterVolumeRemoved(kCraterMedium.radius, kCraterMedium.depth);
  EXPECT_NEAR(removed / exact, 1.0, 0.01) << removed << " m3 against " << exact;
  // The drawn surface (linear between fine posts, integrated at the
  // midpoints of a lattice 4 times finer) holds a little less: the bowl is
  // a paraboloid and its chords lie above it, by about 2 % at h = 0.47 m.
  double drawn = 0;
  const double q = h / 4;
  for (double z = finePos(pj, patch->b0, c, s) + q / 2; z < finePos(pj, patch->b1, c, s); z += q) {
    for (double x = finePos(pi, patch->a0, c, s) + q / 2; x < finePos(pi, patch->a1, c, s); x += q) {
      drawn += std::max(0.0, before.sampleXZ(x, z)->elevation - after.sampleXZ(x, z)->elevation) * q * q;
    }
  }
  EXPECT_NEAR(drawn / exact, 0.98, 0.01) << drawn << " m3 against " << exact;

  // The ground clamp's level 0 (the grid mesh) is Terrain's surface.
  const world::GroundClamp clamp{std::shared_ptr<const grid::HeightField>(heights)};
  for (double z = cz - 8; z <= cz + 8; z += 0.37) {
    for (double x = cx - 8; x <= cx + 8; x += 0.41) {
      EXPECT_NEAR(*clamp.surfaceXZ(x, z, {0, 0}), after.sampleXZ(x, z)->elevation, 1e-6) << x << " " << z;
    }
  }
  // Outside the support nothing moved.
  EXPECT_EQ(after.sampleXZ(cx + 6.5, cz)->elevation, before.sampleXZ(cx + 6.5, cz)->elevation);
  const HeightsStats st = heights->stats();
  EXPECT_EQ(st.tiles, 0u);
  EXPECT_EQ(st.refinedSquares, 1u);
  EXPECT_EQ(st.finePosts, patch->heights.size());
  EXPECT_GT(st.bytes, patch->heights.size() * sizeof(float));
}

/// `n` random height edits over a 20 x 20 square window at (i0, j0): craters
/// of every size (the seed's three and one the posts carry), berms and
/// ditches (narrow and wide), flattens (a pad and a field). A fixed hash
/// stream, not <random>'s distributions, so every library gives the same.
std::vector<edit::Edit> randomEdits(std::uint32_t n, const grid::HeightField& g, std::uint32_t i0, std::uint32_t j0) {
  const double s = g.spacing(), span = 20 * s, x0 = i0 * s, z0 = j0 * s;
  std::uint64_t k = 0;
  const auto u = [&k] { return hash::unit(hash::mix(0x5eed0000ull + k++)); };
  const auto point = [&] { return std::array<double, 2>{x0 + u() * span, z0 + u() * span}; };
  std::vector<edit::Edit> out;
  for (std::uint32_t id = 1; id <= n; ++id) {
    edit::Edit e;
    const double kind = u();
    if (kind < 0.45) {
      const CraterSize sizes[] = {kCraterSmall, kCraterMedium, kCraterLarge, {70.0, 6.0}};
      const CraterSize c = sizes[std::size_t(u() * 4) % 4];
      const auto p = point();
      e = crater(p[0], p[1], c.radius * (0.8 + 0.4 * u()), c.depth * (0.8 + 0.4 * u()), id);
    } else if (kind < 0.75) {
      std::vector<std::array<double, 2>> pts{point()};
      for (int m = 0, len = 1 + int(u() * 3); m < len; ++m) {
        pts.push_back({pts.back()[0] + (u() - 0.5) * 200, pts.back()[1] + (u() - 0.5) * 200});
      }
      const bool wide = u() < 0.2;
      e = line(u() < 0.5 ? edit::Kind::berm : edit::Kind::ditch, pts, wide ? 100 + 40 * u() : 1 + 5 * u(),
               0.5 + 2.5 * u(), 0.4 + 1.2 * u(), id);
    } else {
      const auto c = point();
      const double r = u() < 0.6 ? 4 + 8 * u() : 60 + 60 * u(), turn = u() * 3.14;
      e.id = id;
      e.kind = edit::Kind::flatten;
      for (int m = 0; m < 5; ++m) {
        const double a = turn + m * 2 * 3.14159 / 5;
        e.points.push_back({c[0] + r * std::cos(a), c[1] + r * std::sin(a)});
      }
      const double ground = g.elevation(std::uint32_t(c[0] / s), std::uint32_t(c[1] / s));
      e.height = ground + (u() - 0.5) * 6;
      e.sideSlope = 0.5 + u();
    }
    out.push_back(std::move(e));
  }
  return out;
}

/// Every post whose elevation or normal changed and every refined square, over a run.
struct Touched {
  std::set<SquareIndex> posts;
  std::set<SquareIndex> squares;
  void add(const HeightsChange& c) {
    for (std::uint32_t j = c.posts.j0; j < c.posts.j1; ++j) {
      for (std::uint32_t i = c.posts.i0; i < c.posts.i1; ++i) posts.insert({i, j});
    }
    squares.insert(c.squares.begin(), c.squares.end());
  }
};

std::uint32_t bitsOf(float v) {
  std::uint32_t b;
  std::memcpy(&b, &v, 4);
  return b;
}

TEST_F(MonacoHeights, theSameEditsInTheSameOrderGiveBitIdenticalHeights) {
  const auto orig = original();
  const auto [pi, pj] = steepestPost(*orig);
  const auto a = overlay(), b = overlay();
  const auto edits = randomEdits(200, *a, pi - 10, pj - 10);
  Touched touched;
  std::uint32_t refinedEdits = 0, postEdits = 0;
  for (const edit::Edit& e : edits) {
    const auto ca = a->apply(e);
    const auto cb = b->apply(e);
    ASSERT_TRUE(ca && cb) << ca.error() << cb.error();
    EXPECT_EQ(ca->generation, cb->generation);
    EXPECT_EQ(ca->region, cb->region);
    touched.add(ca.value());
    refinedEdits += !ca->squares.empty();
    postEdits += !ca->posts.empty();
  }
  EXPECT_GT(refinedEdits, 80u);
  EXPECT_GT(postEdits, 50u);
  EXPECT_EQ(a->contentHash(), b->contentHash());
  EXPECT_NE(a->contentHash(), overlay()->contentHash());
  for (const SquareIndex& p : touched.posts) {
    ASSERT_EQ(bitsOf(a->elevation(p.i, p.j)), bitsOf(b->elevation(p.i, p.j))) << p.i << " " << p.j;
    ASSERT_EQ(a->normal(p.i, p.j), b->normal(p.i, p.j));
  }
  std::uint64_t fine = 0;
  for (const SquareIndex& q : touched.squares) {
    const auto pa = a->refined(q.i, q.j), pb = b->refined(q.i, q.j);
    ASSERT_TRUE(pa && pb);
    ASSERT_EQ(std::tie(pa->cells, pa->a0, pa->b0, pa->a1, pa->b1), std::tie(pb->cells, pb->a0, pb->b0, pb->a1, pb->b1));
    ASSERT_EQ(std::memcmp(pa->heights.data(), pb->heights.data(), pa->heights.size() * sizeof(float)), 0);
    fine += pa->heights.size();
  }
  EXPECT_EQ(a->stats().finePosts, fine);
  EXPECT_EQ(a->stats().refinedSquares, touched.squares.size());

  // Two overlapping edits that do not commute, swapped: another ground.
  const double x = (pi + 0.4) * a->spacing(), z = (pj + 0.4) * a->spacing();
  edit::Edit pad;
  pad.kind = edit::Kind::flatten;
  pad.points = {{x - 5, z - 5}, {x + 5, z - 5}, {x + 5, z + 5}, {x - 5, z + 5}};
  pad.height = orig->elevation(pi, pj);
  pad.sideSlope = 1;
  const edit::Edit hole = crater(x + 3, z + 1, kCraterMedium.radius, kCraterMedium.depth);
  const auto one = overlay(), two = overlay();
  ASSERT_TRUE(one->apply(pad) && one->apply(hole));
  ASSERT_TRUE(two->apply(hole) && two->apply(pad));
  EXPECT_NE(one->contentHash(), two->contentHash());
}

TEST_F(MonacoHeights, resetReturnsToTheBaseAndTheSameEditsAgainGiveTheSameGround) {
  const auto orig = original();
  const auto [pi, pj] = steepestPost(*orig);
  const auto a = overlay();
  const auto edits = randomEdits(60, *a, pi - 10, pj - 10);
  for (const edit::Edit& e : edits) ASSERT_TRUE(a->apply(e));
  const std::uint64_t edited = a->contentHash();
  const std::uint64_t g = a->generation();
  const HeightsChange cleared = a->reset();
  EXPECT_GT(cleared.generation, g);
  EXPECT_FALSE(cleared.region.empty());
  EXPECT_EQ(a->contentHash(), overlay()->contentHash());
  for (std::uint32_t j = pj - 12; j < pj + 12; ++j) {
    for (std::uint32_t i = pi - 12; i < pi + 12; ++i) {
      ASSERT_EQ(bitsOf(a->elevation(i, j)), bitsOf(orig->elevation(i, j)));
      ASSERT_EQ(a->refined(i, j), nullptr);
    }
  }
  for (const edit::Edit& e : edits) ASSERT_TRUE(a->apply(e));
  EXPECT_EQ(a->contentHash(), edited);
  EXPECT_TRUE(a->reset().generation > 0);
  EXPECT_TRUE(a->reset().empty());  // nothing left to clear
}

TEST_F(MonacoHeights, readersOnManyThreadsSeeOnlyWhatTheContractAllows) {
  const auto orig = original();
  const auto [pi, pj] = steepestPost(*orig);
  const auto reference = overlay();
  const auto edits = randomEdits(60, *reference, pi - 10, pj - 10);
  // The reference run: each generation's values at the probe posts, and
  // each patch's content by the generation that made it.
  std::vector<SquareIndex> probes;
  for (std::uint32_t j = pj - 10; j < pj + 10; j += 2) {
    for (std::uint32_t i = pi - 10; i < pi + 10; i += 2) probes.push_back({i, j});
  }
  const auto patchHash = [](const grid::RefinedSquare& p) {
    std::uint64_t h = hash::mix(std::uint64_t(p.cells) << 32 | p.a0) ^ hash::mix(std::uint64_t(p.b0) << 32 | p.a1);
    for (const float v : p.heights) h = hash::mix(h ^ bitsOf(v));
    return h ^ p.b1;
  };
  std::vector<std::vector<float>> expected;
  std::vector<std::vector<std::array<float, 3>>> expectedNormals;
  std::map<std::tuple<std::uint32_t, std::uint32_t, std::uint64_t>, std::uint64_t> expectedPatches;
  const auto record = [&](const EditedHeights& x) {
    expected.emplace_back();
    expectedNormals.emplace_back();
    for (const SquareIndex& p : probes) {
      expected.back().push_back(x.elevation(p.i, p.j));
      expectedNormals.back().push_back(x.normal(p.i, p.j));
    }
  };
  record(*reference);
  for (const edit::Edit& e : edits) {
    const auto c = reference->apply(e);
    ASSERT_TRUE(c) << c.error();
    if (c->empty()) continue;
    ASSERT_EQ(c->generation, expected.size());
    record(*reference);
    for (const SquareIndex& q : c->squares) {
      expectedPatches[{q.i, q.j, c->generation}] = patchHash(*reference->refined(q.i, q.j));
    }
  }
  const std::uint64_t last = expected.size() - 1;

  const auto heights = overlay();
  const world::Terrain terrain{std::shared_ptr<const grid::HeightField>(heights)};
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> notified{0}, reads{0}, failures{0};
  heights->subscribe([&](const grid::HeightChange& c) {
    if (c.generation != notified.load() + 1) ++failures;  // one at a time, in order
    notified.store(c.generation);
  });
  std::thread writer([&] {
    for (const edit::Edit& e : edits) {
      if (!heights->apply(e)) ++failures;
    }
    done.store(true);
  });
  const grid::PostRect window{pi - 10, pj - 10, pi + 10, pj + 10};
  tbb::parallel_for(0, 8, [&](int reader) {
    std::uint64_t seen = 0, seenRegion = 0;
    for (std::uint64_t k = reader;; k += 7) {
      const bool finished = done.load();
      const std::size_t m = k % probes.size();
      const SquareIndex p = probes[m];
      const std::uint64_t g1 = heights->generation();
      const float v = heights->elevation(p.i, p.j);
      const std::array<float, 3> n = heights->normal(p.i, p.j);
      const std::uint64_t g2 = heights->generation();
      // Within one generation: that generation's value, or the next one's
      // (a change's posts are written before its generation is bumped).
      if (g1 == g2) {
        const bool ok = v == expected[g1][m] || (g1 < last && v == expected[g1 + 1][m]);
        const bool okN = n == expectedNormals[g1][m] || (g1 < last && n == expectedNormals[g1 + 1][m]);
        if (!ok || !okN) ++failures;
      }
      if (g1 < seen || g2 < g1) ++failures;
      seen = g2;
      const std::uint64_t rg = heights->regionGeneration(window);
      if (rg < seenRegion || rg > heights->generation()) ++failures;
      seenRegion = rg;
      // A patch is a whole snapshot of the change that made it.
      const SquareIndex q{p.i + std::uint32_t(k % 3), p.j + std::uint32_t(k % 2)};
      if (const auto patch = heights->refined(q.i, q.j)) {
        const auto it = expectedPatches.find({q.i, q.j, patch->generation});
        // Published before its generation is: at most one ahead.
        if (it == expectedPatches.end() || it->second != patchHash(*patch) ||
            patch->generation > heights->generation() + 1) {
          ++failures;
        }
      }
      // Samples stay finite and inside the bounds.
      const auto t = terrain.sampleXZ((p.i + 0.3) * heights->spacing(), (p.j + 0.6) * heights->spacing());
      const auto [lo, hi] = heights->elevationBounds();
      if (!t || !std::isfinite(t->elevation) || v < lo || v > hi) ++failures;
      ++reads;
      if (finished && k > 20000) break;
    }
  });
  writer.join();
  EXPECT_EQ(failures.load(), 0u);
  EXPECT_EQ(notified.load(), last);
  EXPECT_EQ(heights->contentHash(), reference->contentHash());
  EXPECT_GT(reads.load(), 8u * 2000u);
}

/// Samples across the line from (x0, z0) to (x1, z1) at `n` points, a
/// micrometre to each side; the largest difference.
double worstStep(const world::Terrain& t, double x0, double z0, double x1, double z1, int n) {
  const double len = std::hypot(x1 - x0, z1 - z0), nx = -(z1 - z0) / len, nz = (x1 - x0) / len;
  constexpr double eps = 1e-6;
  double worst = 0;
  for (int k = 0; k <= n; ++k) {
    const double f = double(k) / n, x = x0 + f * (x1 - x0), z = z0 + f * (z1 - z0);
    const auto a = t.sampleXZ(x - eps * nx, z - eps * nz), b = t.sampleXZ(x + eps * nx, z + eps * nz);
    if (a && b) worst = std::max(worst, std::abs(a->elevation - b->elevation));
  }
  return worst;
}

TEST_F(MonacoHeights, noStepAtARefinedSquaresEdgesOrItsPatchBorder) {
  const auto orig = original();
  const auto [pi, pj] = steepestPost(*orig);
  const auto heights = overlay();
  const double s = heights->spacing();
  const double x = pi * s, z = pj * s;
  // Each path of the overlay: a crater inside a square, one by a post (its
  // squares' planes move), one on a square edge, a berm refined 16 cells a
  // square, then a crater over it (64 cells: the berm's squares resampled),
  // a pad, a diagonal ditch, and a crater the posts carry (the fine posts
  // ride on the planes), and random edits on top.
  std::vector<edit::Edit> edits = {
      crater(x + 15.3, z + 11.1, 3, 1.2),
      crater(x + 31.5, z + 29.0, 3, 1.2),
      crater(x + 60.0, z + 44.0, 1, 0.5),
      line(edit::Kind::berm, {{x - 40, z + 70}, {x + 130, z + 95}}, 6, 2, 0.4),
      crater(x + 50, z + 80, 3, 1.2),
      line(edit::Kind::ditch, {{x - 30, z - 30}, {x + 100, z + 120}}, 2, 1.5, 1),
      crater(x + 40, z + 40, 70, 5),
  };
  edit::Edit pad;
  pad.kind = edit::Kind::flatten;
  pad.points = {{x + 70, z + 10}, {x + 82, z + 12}, {x + 80, z + 24}, {x + 68, z + 21}};
  pad.height = orig->elevation(pi + 2, pj);
  pad.sideSlope = 1;
  edits.insert(edits.begin() + 5, pad);
  EXPECT_EQ(refineCells(edits[3], s), 16u);
  EXPECT_EQ(refineCells(edits.back(), s), 0u);
  const auto more = randomEdits(40, *heights, pi - 5, pj - 5);
  edits.insert(edits.end(), more.begin(), more.end());
  Touched touched;
  for (const edit::Edit& e : edits) {
    const auto c = heights->apply(e);
    ASSERT_TRUE(c) << c.error();
    touched.add(c.value());
  }
  ASSERT_GT(touched.squares.size(), 20u);
  const world::Terrain t{std::shared_ptr<const grid::HeightField>(heights)};
  std::set<std::uint32_t> cells;
  for (const SquareIndex& q : touched.squares) {
    const auto p = heights->refined(q.i, q.j);
    ASSERT_TRUE(p);
    cells.insert(p->cells);
    const double x0 = q.i * s, z0 = q.j * s, x1 = x0 + s, z1 = z0 + s;
    // The square's four edges, then the patch's border inside the square.
    for (const auto& [a, b, c, d] : {std::array<double, 4>{x0, z0, x1, z0}, std::array<double, 4>{x1, z0, x1, z1},
                                     std::array<double, 4>{x0, z1, x1, z1}, std::array<double, 4>{x0, z0, x0, z1}}) {
      EXPECT_LT(worstStep(t, a, b, c, d, 2000), 1e-4) << "square " << q.i << " " << q.j << " edge " << a << " " << b;
    }
    const double h = s / p->cells;
    const double pa0 = x0 + p->a0 * h, pa1 = x0 + p->a1 * h, pb0 = z0 + p->b0 * h, pb1 = z0 + p->b1 * h;
    for (const auto& [a, b, c, d] : {std::array<double, 4>{pa0, pb0, pa1, pb0}, std::array<double, 4>{pa1, pb0, pa1, pb1},
                                     std::array<double, 4>{pa0, pb1, pa1, pb1}, std::array<double, 4>{pa0, pb0, pa0, pb1}}) {
      EXPECT_LT(worstStep(t, a, b, c, d, 1000), 1e-4) << "square " << q.i << " " << q.j << " patch border";
    }
  }
  EXPECT_GE(cells.size(), 2u) << "patches of more than one lattice";
}

TEST_F(MonacoHeights, normalsAreTheBuildsCentralDifferencesOfTheEditedPosts) {
  const auto orig = original();
  const auto [pi, pj] = steepestPost(*orig);
  const auto heights = overlay();
  Touched touched;
  for (const edit::Edit& e : randomEdits(100, *heights, pi - 10, pj - 10)) {
    const auto c = heights->apply(e);
    ASSERT_TRUE(c) << c.error();
    touched.add(c.value());
  }
  ASSERT_GT(touched.posts.size(), 100u);
  // Recomputed here: central differences of the edited elevations,
  // one-sided at the grid's edge; the grid stores snorm16, so within a step.
  const double s = heights->spacing();
  const std::uint32_t W = heights->postsX(), H = heights->postsZ();
  const auto E = [&](std::uint32_t i, std::uint32_t j) { return double(heights->elevation(i, j)); };
  std::uint32_t differ = 0;
  for (std::uint32_t j = pj - 14; j < pj + 14; ++j) {
    for (std::uint32_t i = pi - 14; i < pi + 14; ++i) {
      const double dx = i == 0 ? (E(1, j) - E(0, j)) / s
                        : i == W - 1 ? (E(i, j) - E(i - 1, j)) / s
                                     : (E(i + 1, j) - E(i - 1, j)) / (2 * s);
      const double dz = j == 0 ? (E(i, 1) - E(i, 0)) / s
                        : j == H - 1 ? (E(i, j) - E(i, j - 1)) / s
                                     : (E(i, j + 1) - E(i, j - 1)) / (2 * s);
      const double len = std::sqrt(dx * dx + 1 + dz * dz);
      const std::array<double, 3> want{-dx / len, 1 / len, -dz / len};
      const auto got = heights->normal(i, j);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(got[k], want[k], 1.0 / 32767) << i << " " << j;
      differ += got != orig->normal(i, j);
    }
  }
  EXPECT_GT(differ, 50u) << "the edits changed normals";
}

// ------------------------------------------------- small synthetic grids

class SmallGrid : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sandtable-heights-small." + std::to_string(::getpid()));
    fs::create_directories(dir_);
    const std::string path = (dir_ / "grid.stg").string();
    const Status st = fixtures::writeGrid(path, 150, 90, 10.0, [](std::uint32_t i, std::uint32_t j) {
      return float(100.0 + 0.5 * i - 0.25 * j);
    });
    ASSERT_TRUE(st.ok()) << st.error();
    auto g = grid::GridFile::open(path);
    ASSERT_TRUE(g) << g.error();
    heights_ = std::make_shared<EditedHeights>(grid::heightField(g.value()));
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  std::shared_ptr<EditedHeights> heights_;
};

TEST_F(SmallGrid, refusesBadEditsAndEditsOutsideTheGridWithClearMessages) {
  auto r = heights_->apply(crater(50, 50, -1, 1));
  ASSERT_FALSE(r);
  EXPECT_NE(r.message().find("edits: EditedHeights::apply: edit: crater: Edit::radius"), std::string::npos) << r.message();
  edit::Edit obj;
  obj.kind = edit::Kind::removeObject;
  obj.id = 4;
  r = heights_->apply(obj);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.message(), "edits: EditedHeights::apply: remove-object 4 does not change heights (crater, berm, ditch and flatten do)");
  r = heights_->apply(crater(-50, 300, 3, 1, 9));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.message(),
            "edits: EditedHeights::apply: crater 9 changes x -56.00..-44.00, z 294.00..306.00 m: wholly outside the grid "
            "(x 0..1490.00, z 0..890.00 m)");
  EXPECT_EQ(heights_->generation(), 0u);
  // Partly outside is applied to the part inside.
  r = heights_->apply(crater(1, 1, 3, 1));
  ASSERT_TRUE(r) << r.error();
  EXPECT_FALSE(r->empty());
}

TEST_F(SmallGrid, aChangeBumpsGenerationsTellsListenersAndWidensTheBounds) {
  std::vector<grid::HeightChange> heard;
  heights_->subscribe([&](const grid::HeightChange& c) { heard.push_back(c); });
  const auto [lo0, hi0] = heights_->elevationBounds();
  EXPECT_EQ(lo0, heights_->base().elevationBounds().first);
  // A crater the posts carry (radius 40 m on 10 m posts).
  const auto c = heights_->apply(crater(705, 405, 40, 60));
  ASSERT_TRUE(c) << c.error();
  EXPECT_TRUE(c->squares.empty());
  EXPECT_EQ(c->generation, 1u);
  ASSERT_EQ(heard.size(), 1u);
  EXPECT_EQ(heard[0].posts, c->region);
  EXPECT_EQ(c->region, c->posts);
  // Posts strictly inside the support (x 625..785, z 325..485), and one
  // ring of neighbours whose normals follow.
  EXPECT_EQ(c->posts, (grid::PostRect{62, 32, 80, 50}));
  EXPECT_EQ(heights_->elevation(62, 40), heights_->base().elevation(62, 40));  // outside the support
  EXPECT_FLOAT_EQ(heights_->elevation(71, 41), float(double(heights_->base().elevation(71, 41)) +
                                                     craterDelta(40, 60, std::hypot(5.0, 5.0))));
  EXPECT_LE(heights_->elevationBounds().first, heights_->elevation(71, 41));
  EXPECT_LT(heights_->elevationBounds().first, lo0);
  EXPECT_EQ(heights_->regionGeneration({0, 70, 10, 80}), 0u) << "another tile";
  EXPECT_EQ(heights_->regionGeneration({70, 40, 71, 41}), 1u);
  EXPECT_EQ(heights_->stats().tiles, 2u) << "posts 62..79 lie in two tiles of 64";
  // Untouched posts read as the base, bit for bit.
  EXPECT_EQ(heights_->normal(10, 10), heights_->base().normal(10, 10));
  EXPECT_EQ(heights_->material(70, 40), heights_->base().material(70, 40));
}

TEST_F(SmallGrid, aSmallCraterOverAnotherIsResampledFinerAndGrows) {
  // A large crater (7.5 m on 10 m posts: 8 cells a square; it moves posts,
  // so the squares round them are refined whole), then a small one (32
  // cells) in one of those squares.
  const auto big = heights_->apply(crater(15.0, 15.0, 7.5, 2.5));
  ASSERT_TRUE(big) << big.error();
  EXPECT_EQ(big->squares.size(), 9u);
  const auto p0 = heights_->refined(1, 1);
  ASSERT_TRUE(p0);
  EXPECT_EQ(p0->cells, 8u);
  EXPECT_EQ(std::tie(p0->a0, p0->b0, p0->a1, p0->b1), std::make_tuple(0u, 0u, 8u, 8u));
  const auto small = heights_->apply(crater(12.5, 12.5, 1, 0.5));
  ASSERT_TRUE(small) << small.error();
  EXPECT_EQ(small->squares, (std::vector<SquareIndex>{{1, 1}}));
  EXPECT_TRUE(small->posts.empty());
  const auto p1 = heights_->refined(1, 1);
  ASSERT_TRUE(p1);
  EXPECT_EQ(p1->cells, 32u);
  EXPECT_NE(p1, p0);
  EXPECT_EQ(p0->cells, 8u) << "the old snapshot stays valid";
  EXPECT_EQ(heights_->refined(0, 1)->cells, 8u) << "a square the small crater did not reach keeps its lattice";
  // The big crater's fine posts are kept where the small one did not reach.
  EXPECT_EQ(p1->at(28, 28), p0->at(7, 7));
  // The small crater's centre (a fine post of both) is at its depth below
  // the big one's bowl.
  bool inside = false;
  const double bowl = grid::refinedHeight(*p0, 0.25, 0.25, inside);
  ASSERT_TRUE(inside);
  EXPECT_NEAR(grid::refinedHeight(*p1, 0.25, 0.25, inside), bowl - 0.5, 1e-4);
}

}  // namespace
}  // namespace sandtable::edits
