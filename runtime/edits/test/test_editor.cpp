// The editor (editor.h) over a small synthetic database: a GeoTIFF of
// smooth hills written here through GDAL, built with the converters (10 m
// posts, 320 m modules, three levels). Checked:
//  - edits applied in (time, origin, id) order give bit-identical posts and
//    fine posts whatever order they arrive in (a late overlapping edit
//    makes the editor rebuild), and a crater no other edit meets reads the
//    profile of docs/DYNAMIC.md worked here by hand over the grid file's own
//    posts;
//  - a duplicate (same origin and id) is dropped and counted;
//  - the journal replayed at open gives the heights of the run that wrote
//    it; readOnly writes nothing;
//  - meshModules=false leaves world().modules() the base's; the background
//    re-mesh, waited for, gives the modules the in-apply() re-mesh gives;
//  - nextId per origin, and the stats' counts;
//  - bake: the baked grid (exported by the CLI, read through GDAL) holds
//    the edited posts; `validate` on it (disabled: a known bug, below).
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "sandtable/converters/elevation.h"
#include "sandtable/edits/bake.h"
#include "sandtable/edits/editor.h"
#include "sandtable/edits/profile.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/formats/grid.h"

namespace sandtable::edits {
namespace {

namespace fs = std::filesystem;

constexpr int kPixels = 161;      // 1,600 m a side at 10 m
constexpr double kPixel = 10;
constexpr double kWest = 500000, kNorth = 5500000;

double hills(double x, double z) { return 300 + 20 * std::sin(x / 170.0) * std::cos(z / 230.0) + 0.02 * x; }

/// The hills as a Float32 GeoTIFF in UTM 32N, pixel centres on the posts.
void writeHills(const std::string& path) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  ASSERT_NE(drv, nullptr);
  GDALDataset* ds = drv->Create(path.c_str(), kPixels, kPixels, 1, GDT_Float32, nullptr);
  ASSERT_NE(ds, nullptr);
  double gt[6] = {kWest - kPixel / 2, kPixel, 0, kNorth + kPixel / 2, 0, -kPixel};
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.importFromEPSG(32632);
  ds->SetSpatialRef(&srs);
  std::vector<float> px(std::size_t(kPixels) * kPixels);
  for (int j = 0; j < kPixels; ++j) {
    for (int i = 0; i < kPixels; ++i) px[std::size_t(j) * kPixels + std::size_t(i)] = float(hills(i * kPixel, j * kPixel));
  }
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, kPixels, kPixels, px.data(), kPixels, kPixels, GDT_Float32,
                                           0, 0),
            CE_None);
  GDALClose(ds);
}

edit::Edit crater(std::uint64_t id, double t, double x, double z, double radius, double depth, edit::Origin origin = 0) {
  edit::Edit e;
  e.id = id, e.time = t, e.origin = origin, e.kind = edit::Kind::crater;
  e.points = {{x, z}};
  e.radius = radius, e.depth = depth;
  return e;
}

edit::Edit line(std::uint64_t id, double t, edit::Kind kind, std::vector<std::array<double, 2>> pts, double width,
                double height, double slope) {
  edit::Edit e;
  e.id = id, e.time = t, e.kind = kind;
  e.points = std::move(pts);
  e.width = width, e.height = height, e.sideSlope = slope;
  return e;
}

/// Overlapping edits of every height kind (flatten and craters do not
/// commute), a crater smaller than a post (refined squares) in the middle
/// of them, and one far crater no other edit meets.
std::vector<edit::Edit> battle() {
  std::vector<edit::Edit> v;
  v.push_back(crater(1, 1.0, 400.25, 410.5, 30, 3));
  v.push_back(crater(2, 2.0, 430, 400, 25, 2));
  edit::Edit pad = line(3, 3.0, edit::Kind::flatten, {{380, 380}, {440, 385}, {430, 430}, {385, 425}}, 0, 305, 0.5);
  v.push_back(pad);
  v.push_back(line(4, 4.0, edit::Kind::berm, {{300, 500}, {450, 420}, {600, 450}}, 6, 2, 0.5));
  v.push_back(line(5, 5.0, edit::Kind::ditch, {{420, 300}, {440, 600}}, 3, 2.5, 1));
  v.push_back(crater(6, 6.0, 405.3, 402.7, kCraterMedium.radius, kCraterMedium.depth));
  v.push_back(crater(7, 7.0, 1200.5, 1100.25, 30, 4));
  return v;
}

/// Every post's and fine post's bits, and the overlay's hash.
struct Heights {
  std::vector<std::uint32_t> posts;
  std::vector<std::uint32_t> fine;
  std::uint64_t hash = 0;
  bool operator==(const Heights&) const = default;
};

Heights snapshot(const EditedHeights& h) {
  Heights s;
  for (std::uint32_t j = 0; j < h.postsZ(); ++j) {
    for (std::uint32_t i = 0; i < h.postsX(); ++i) s.posts.push_back(std::bit_cast<std::uint32_t>(h.elevation(i, j)));
  }
  for (std::uint32_t j = 0; j + 1 < h.postsZ(); ++j) {
    for (std::uint32_t i = 0; i + 1 < h.postsX(); ++i) {
      const auto r = h.refined(i, j);
      if (!r) continue;
      s.fine.insert(s.fine.end(), {i, j, r->cells, r->a0, r->b0, r->a1, r->b1});
      for (float y : r->heights) s.fine.push_back(std::bit_cast<std::uint32_t>(y));
    }
  }
  s.hash = h.contentHash();
  return s;
}

class Editing : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("sandtable-editor." + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    writeHills((*dir_ / "hills.tif").string());
    convert::ElevationOptions o;
    o.sources = {(*dir_ / "hills.tif").string()};
    o.output = (*dir_ / "db").string();
    o.crs = "EPSG:32632";
    o.spacing = kPixel;
    o.moduleSize = 320;
    o.levels = 3;
    o.threads = 1;
    const auto built = convert::buildElevation(o, {});
    ASSERT_TRUE(built) << built.error();
    auto w = paging::World::open(o.output);
    ASSERT_TRUE(w) << w.error();
    world_ = new std::shared_ptr<const paging::World>(w.value());
  }
  static void TearDownTestSuite() {
    delete world_;
    world_ = nullptr;
    if (dir_) fs::remove_all(*dir_);
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    ASSERT_TRUE(world_);
    ASSERT_TRUE((*world_)->modules()) << "the build made no modules";
  }

  static std::unique_ptr<Editor> open(EditorOptions o = {}) {
    auto ed = Editor::open(*world_, std::move(o));
    EXPECT_TRUE(ed) << ed.error();
    return ed ? std::move(ed.value()) : nullptr;
  }
  static EditorOptions heightsOnly() {
    EditorOptions o;
    o.meshModules = false;
    return o;
  }
  /// Applies `edits` in the order given; every one must apply.
  static void applyAll(Editor& ed, const std::vector<edit::Edit>& edits) {
    for (const edit::Edit& e : edits) {
      const auto r = ed.apply(e);
      ASSERT_TRUE(r) << "edit " << e.id << ": " << r.error();
      EXPECT_FALSE(r.value().duplicate) << e.id;
    }
  }
  static std::string path(const std::string& name) { return (*dir_ / name).string(); }

  static fs::path* dir_;
  static std::shared_ptr<const paging::World>* world_;
};
fs::path* Editing::dir_ = nullptr;
std::shared_ptr<const paging::World>* Editing::world_ = nullptr;

TEST_F(Editing, anyArrivalOrderGivesTheKeyOrdersHeightsBitForBit) {
  const std::vector<edit::Edit> inOrder = battle();
  auto ref = open(heightsOnly());
  ASSERT_TRUE(ref);
  applyAll(*ref, inOrder);
  EXPECT_EQ(ref->stats().rebuilds, 0u);
  const Heights want = snapshot(*ref->heights());
  ASSERT_FALSE(want.fine.empty()) << "the medium crater should refine squares on 10 m posts";
  ASSERT_NE(want.hash, EditedHeights((*world_)->heights()).contentHash());

  // The edits do not commute: applied straight to an overlay in reverse
  // (no editor to order them), the ground differs.
  EditedHeights raw((*world_)->heights());
  for (auto it = inOrder.rbegin(); it != inOrder.rend(); ++it) ASSERT_TRUE(raw.apply(*it));
  ASSERT_FALSE(snapshot(raw) == want);

  std::vector<std::vector<edit::Edit>> orders;
  orders.push_back({inOrder.rbegin(), inOrder.rend()});
  std::mt19937 rng(37);
  for (int k = 0; k < 3; ++k) {
    orders.push_back(inOrder);
    std::shuffle(orders.back().begin(), orders.back().end(), rng);
  }
  for (const auto& order : orders) {
    auto ed = open(heightsOnly());
    ASSERT_TRUE(ed);
    applyAll(*ed, order);
    EXPECT_EQ(ed->edits(), inOrder);  // held in key order
    EXPECT_TRUE(snapshot(*ed->heights()) == want);
  }

  // Reversed, the pad (3) comes after the craters 4..7 that share its
  // squares: it, and every overlapping edit before it, rebuilds.
  auto rev = open(heightsOnly());
  ASSERT_TRUE(rev);
  std::uint64_t rebuilt = 0;
  for (auto it = inOrder.rbegin(); it != inOrder.rend(); ++it) {
    const auto r = rev->apply(*it);
    ASSERT_TRUE(r) << r.error();
    rebuilt += r.value().rebuilt;
    if (it->id == 7) {
      EXPECT_FALSE(r.value().rebuilt);  // the first
    }
  }
  EXPECT_GT(rebuilt, 0u);
  EXPECT_EQ(rev->stats().rebuilds, rebuilt);
  EXPECT_TRUE(snapshot(*rev->heights()) == want);
}

/// docs/DYNAMIC.md's crater, worked here: the bowl, the rim's outer side.
double craterByHand(double R, double d, double r) {
  const double rim = d / 4;
  if (r <= R) return -d + (d + rim) * (r / R) * (r / R);
  if (r < 2 * R) return rim * ((2 * R - r) / R) * ((2 * R - r) / R);
  return 0;
}

TEST_F(Editing, aCraterNoOtherEditMeetsIsTheProfileOverTheGridFilesPosts) {
  auto ed = open(heightsOnly());
  ASSERT_TRUE(ed);
  applyAll(*ed, battle());
  // The posts as built, from the file again (not through the editor).
  auto g = grid::GridFile::open((*world_)->directory() + "/grid.stg");
  ASSERT_TRUE(g) << g.error();
  const edit::Edit far = battle().back();
  const double cx = far.points[0][0], cz = far.points[0][1], s = g.value()->spacing();
  int inBowl = 0, onRim = 0, outside = 0;
  for (std::uint32_t j = 100; j < 120; ++j) {
    for (std::uint32_t i = 110; i < 130; ++i) {
      const double r = std::hypot(i * s - cx, j * s - cz);
      const float before = g.value()->elevation(i, j), after = ed->heights()->elevation(i, j);
      if (r >= 2 * far.radius) {
        EXPECT_EQ(std::bit_cast<std::uint32_t>(after), std::bit_cast<std::uint32_t>(before)) << i << " " << j;
        ++outside;
        continue;
      }
      EXPECT_NEAR(after, double(before) + craterByHand(far.radius, far.depth, r), 1e-4) << i << " " << j;
      ++(r <= far.radius ? inBowl : onRim);
    }
  }
  EXPECT_GT(inBowl, 20);
  EXPECT_GT(onRim, 50);
  EXPECT_GT(outside, 50);
}

TEST_F(Editing, aDuplicateIsDroppedAndCounted) {
  auto ed = open(heightsOnly());
  ASSERT_TRUE(ed);
  applyAll(*ed, battle());
  const Heights before = snapshot(*ed->heights());
  edit::Edit again = battle()[1];
  again.depth = 9;  // the same (origin, id): dropped whatever it says
  again.time = 0.5;
  const auto r = ed->apply(again);
  ASSERT_TRUE(r) << r.error();
  EXPECT_TRUE(r.value().duplicate);
  EXPECT_FALSE(r.value().rebuilt);
  EXPECT_TRUE(r.value().heights.empty());
  EXPECT_EQ(ed->stats().duplicates, 1u);
  EXPECT_EQ(ed->stats().applied, battle().size());
  EXPECT_EQ(ed->edits(), battle());
  EXPECT_TRUE(snapshot(*ed->heights()) == before);
  // Another origin with the same id is another edit.
  again.origin = 5;
  const auto other = ed->apply(again);
  ASSERT_TRUE(other) << other.error();
  EXPECT_FALSE(other.value().duplicate);
  EXPECT_EQ(ed->stats().applied, battle().size() + 1);
}

TEST_F(Editing, theJournalReplayedAtOpenGivesTheHeightsOfTheRunThatWroteIt) {
  const std::string j = path("replay.journal");
  fs::remove(j);
  std::vector<edit::Edit> arrival = battle();
  std::reverse(arrival.begin(), arrival.end());
  Heights written;
  {
    EditorOptions o = heightsOnly();
    o.journal = j;
    auto ed = open(o);
    ASSERT_TRUE(ed);
    applyAll(*ed, arrival);
    ASSERT_TRUE(ed->apply(battle()[0]).value().duplicate);  // not journalled twice
    ASSERT_TRUE(ed->flush());
    written = snapshot(*ed->heights());
  }
  // The file holds the edits in arrival order, once each.
  const auto read = journal::readJournal(j);
  ASSERT_TRUE(read) << read.error();
  EXPECT_EQ(read.value().edits, arrival);
  EXPECT_TRUE(read.value().warnings.empty());

  EditorOptions o = heightsOnly();
  o.journal = j;
  auto again = open(o);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->stats().replayed, arrival.size());
  EXPECT_EQ(again->stats().rebuilds, 0u);  // sorted before replay
  EXPECT_EQ(again->edits(), battle());
  EXPECT_TRUE(snapshot(*again->heights()) == written);
  EXPECT_TRUE(again->warnings().empty());
}

TEST_F(Editing, readOnlyWritesNothing) {
  const std::string fresh = path("never.journal");
  fs::remove(fresh);
  {
    EditorOptions o = heightsOnly();
    o.journal = fresh;
    o.readOnly = true;
    auto ed = open(o);
    ASSERT_TRUE(ed);
    applyAll(*ed, battle());
    ASSERT_TRUE(ed->flush());
  }
  EXPECT_FALSE(fs::exists(fresh));

  // Over an existing journal: replayed, never appended to.
  const std::string j = path("ro.journal");
  fs::remove(j);
  {
    EditorOptions o = heightsOnly();
    o.journal = j;
    auto ed = open(o);
    ASSERT_TRUE(ed);
    applyAll(*ed, {battle()[0]});
  }
  const auto size = fs::file_size(j);
  {
    EditorOptions o = heightsOnly();
    o.journal = j;
    o.readOnly = true;
    auto ed = open(o);
    ASSERT_TRUE(ed);
    EXPECT_EQ(ed->stats().replayed, 1u);
    applyAll(*ed, {battle()[6]});
    ASSERT_TRUE(ed->flush());
  }
  EXPECT_EQ(fs::file_size(j), size);
  EXPECT_EQ(journal::readJournal(j).value().edits.size(), 1u);
}

TEST_F(Editing, withoutMeshingTheModulesAreTheBases) {
  auto ed = open(heightsOnly());
  ASSERT_TRUE(ed);
  applyAll(*ed, battle());
  EXPECT_EQ(ed->modules(), nullptr);
  EXPECT_EQ(ed->world()->modules(), (*world_)->modules());
  EXPECT_EQ(ed->world()->heights(), std::static_pointer_cast<const grid::HeightField>(ed->heights()));
  EXPECT_EQ(ed->stats().remeshes, 0u);

  auto meshed = open();
  ASSERT_TRUE(meshed);
  ASSERT_NE(meshed->modules(), nullptr);
  EXPECT_EQ(meshed->world()->modules(), std::static_pointer_cast<const paging::ModuleSource>(meshed->modules()));
  EXPECT_NE(meshed->world()->modules(), (*world_)->modules());
}

/// Every module of `s` encoded (the same bytes mean the same module).
std::vector<std::vector<std::byte>> encodeAll(const paging::ModuleSource& s) {
  std::vector<std::vector<std::byte>> out;
  for (std::uint32_t kz = 0; kz < s.header().modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < s.header().modulesX; ++kx) {
      module::Module m;
      const auto r = s.read(kx, kz, m);
      EXPECT_TRUE(r) << r.error();
      out.push_back(module::encode(m));
    }
  }
  return out;
}

TEST_F(Editing, theBackgroundReMeshWaitedForGivesTheModulesOfTheReMeshInApply) {
  EditorOptions now;
  now.background = false;
  auto a = open(now);
  auto b = open();  // background
  ASSERT_TRUE(a && b);
  applyAll(*a, battle());
  applyAll(*b, battle());
  b->wait();
  for (Editor* ed : {a.get(), b.get()}) {
    const EditorStats s = ed->stats();
    EXPECT_EQ(s.remeshFailures, 0u) << s.lastRemeshError;
    EXPECT_GT(s.modulesRemeshed, 0u);
  }
  const auto base = encodeAll(*(*world_)->modules());
  const auto inApply = encodeAll(*a->world()->modules());
  const auto background = encodeAll(*b->world()->modules());
  ASSERT_EQ(inApply.size(), background.size());
  std::size_t changed = 0;
  for (std::size_t k = 0; k < inApply.size(); ++k) {
    EXPECT_TRUE(inApply[k] == background[k]) << "module " << k;
    changed += inApply[k] != base[k];
  }
  EXPECT_GE(changed, 2u);  // the battle near (400, 400) and the far crater
}

TEST_F(Editing, nextIdIsOnePastTheLargestOfEachOrigin) {
  auto ed = open(heightsOnly());
  ASSERT_TRUE(ed);
  EXPECT_EQ(ed->nextId(0), 1u);
  applyAll(*ed, {crater(1, 1, 200, 200, 20, 1), crater(5, 2, 800, 200, 20, 1), crater(2, 3, 200, 800, 20, 1),
                 crater(3, 1, 800, 800, 20, 1, 7), crater(9, 4, 1200, 400, 20, 1, 0x10002)});
  EXPECT_EQ(ed->nextId(0), 6u);
  EXPECT_EQ(ed->nextId(7), 4u);
  EXPECT_EQ(ed->nextId(0x10002), 10u);
  EXPECT_EQ(ed->nextId(8), 1u);
}

TEST_F(Editing, statsCountWhatHappened) {
  const std::string j = path("stats.journal");
  fs::remove(j);
  {
    EditorOptions o = heightsOnly();
    o.journal = j;
    auto ed = open(o);
    ASSERT_TRUE(ed);
    applyAll(*ed, {battle()[0], battle()[1], battle()[3]});
  }
  EditorOptions o = heightsOnly();
  o.journal = j;
  auto ed = open(o);
  ASSERT_TRUE(ed);
  const std::vector<edit::Edit> all = battle();
  applyAll(*ed, {all[4], all[2], all[5], all[6]});  // the pad (3) comes after 5: a rebuild
  ASSERT_TRUE(ed->apply(all[0]).value().duplicate);
  ASSERT_TRUE(ed->apply(all[6]).value().duplicate);
  edit::Edit bad = all[0];
  bad.id = 99;
  bad.radius = -1;
  EXPECT_FALSE(ed->apply(bad));
  const EditorStats s = ed->stats();
  EXPECT_EQ(s.replayed, 3u);
  EXPECT_EQ(s.applied, 7u);  // the replayed three and four more
  EXPECT_EQ(s.byKind[std::size_t(edit::Kind::crater)], 4u);
  EXPECT_EQ(s.byKind[std::size_t(edit::Kind::berm)], 1u);
  EXPECT_EQ(s.byKind[std::size_t(edit::Kind::ditch)], 1u);
  EXPECT_EQ(s.byKind[std::size_t(edit::Kind::flatten)], 1u);
  EXPECT_EQ(s.duplicates, 2u);
  EXPECT_EQ(s.rebuilds, 1u);
  EXPECT_EQ(s.remeshes, 0u);
  EXPECT_EQ(ed->edits().size(), 7u);
}

/// Runs the sandtable CLI; its exit code, its output in `log`.
int cli(const std::string& args, std::string& log) {
  const std::string out = (fs::temp_directory_path() / ("sandtable-editor-cli." + std::to_string(::getpid()))).string();
  const int rc = std::system(("'" + std::string(SANDTABLE_CLI) + "' " + args + " > '" + out + "' 2>&1").c_str());
  std::ifstream f(out);
  log.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  fs::remove(out);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

/// A Float32 GeoTIFF's first band, read through GDAL; empty when it does
/// not open.
std::vector<float> readTiff(const std::string& path, int& width, int& height) {
  GDALAllRegister();
  std::vector<float> px;
  auto* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  if (!ds) return px;
  width = ds->GetRasterXSize(), height = ds->GetRasterYSize();
  px.resize(std::size_t(width) * std::size_t(height));
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, width, height, px.data(), width, height, GDT_Float32, 0, 0) !=
      CE_None) {
    px.clear();
  }
  GDALClose(ds);
  return px;
}

/// A crater and a berm the posts carry (10 m posts: the crater's radius and
/// the berm's half width plus side run are at least two posts).
std::vector<edit::Edit> craterAndBerm() {
  return {battle().back(), line(8, 8.0, edit::Kind::berm, {{200, 1300}, {700, 1350}}, 20, 2, 0.2)};
}

// Baking a crater and a berm: the baked grid, exported and read back
// through GDAL, holds the edited posts (the crater's also against the
// profile by hand), and the baked database opens.
TEST_F(Editing, aBakedDatabaseHoldsTheEditedPosts) {
  const std::vector<edit::Edit> edits = craterAndBerm();
  const edit::Edit& far = edits[0];
  auto ed = open(heightsOnly());
  ASSERT_TRUE(ed);
  applyAll(*ed, edits);
  const std::string out = path("baked");
  fs::remove_all(out);
  const auto report = bake(**world_, edits, out);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report.value().edits, 2u);
  EXPECT_GT(report.value().modulesRemeshed, 0u);
  auto opened = paging::World::open(out);
  ASSERT_TRUE(opened) << opened.error();
  ASSERT_TRUE(opened.value()->modules());

  std::string log;
  ASSERT_EQ(cli("export '" + out + "' --journal none --grid -o '" + path("baked.tif") + "'", log), 0) << log;
  int w = 0, h = 0;
  const std::vector<float> baked = readTiff(path("baked.tif"), w, h);
  ASSERT_FALSE(baked.empty());
  const EditedHeights& want = *ed->heights();
  ASSERT_EQ(std::uint32_t(w), want.postsX());
  ASSERT_EQ(std::uint32_t(h), want.postsZ());
  auto g = grid::GridFile::open((*world_)->directory() + "/grid.stg");
  ASSERT_TRUE(g) << g.error();
  std::size_t moved = 0, byHand = 0;
  const double cx = far.points[0][0], cz = far.points[0][1], s = want.spacing();
  for (std::uint32_t j = 0; j < want.postsZ(); ++j) {
    for (std::uint32_t i = 0; i < want.postsX(); ++i) {
      const float y = baked[std::size_t(j) * std::size_t(w) + i];
      ASSERT_EQ(std::bit_cast<std::uint32_t>(y), std::bit_cast<std::uint32_t>(want.elevation(i, j))) << i << " " << j;
      moved += y != g.value()->elevation(i, j);
      const double r = std::hypot(i * s - cx, j * s - cz);
      if (r < 2 * far.radius) {
        EXPECT_NEAR(y, double(g.value()->elevation(i, j)) + craterByHand(far.radius, far.depth, r), 1e-4);
        ++byHand;
      }
    }
  }
  EXPECT_GT(moved, 100u);
  EXPECT_GT(byHand, 30u);
}

// Validate passes on a baked database: re-meshed vertices go exactly onto
// the edited ground, so the base pack's height rounding is not carried
// into the new encoding (it was: 83 problems, 7 mm off the lattice).
TEST_F(Editing, aBakedDatabaseValidates) {
  const std::string out = path("baked-validate");
  fs::remove_all(out);
  const auto report = bake(**world_, craterAndBerm(), out);
  ASSERT_TRUE(report) << report.error();
  std::string log;
  EXPECT_EQ(cli("validate '" + out + "'", log), 0) << log;
}

}  // namespace
}  // namespace sandtable::edits
