// SimWorld reads its modules through the world's ModuleSource, and a newer
// generation of one module replaces exactly that module's soil classes,
// object bases and collision squares (issue 34 item 4). The source is a
// hand-made one whose modules are plain skins of one material each, with
// one object each; the expectations are worked from those by hand.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <limits>
#include <mutex>

#include "sandtable/formats/database.h"
#include "sandtable/formats/grid.h"
#include "sandtable/paging/world.h"
#include "sandtable/sim/sim_world.h"
#include "sandtable/testing/fixtures.h"

namespace sandtable::sim {
namespace {

constexpr std::uint32_t kSquares = 16, kModules = 4, kPosts = kSquares * kModules + 1;
constexpr double kSpacing = 10, kModuleSize = kSquares * kSpacing;

/// A module of one level: the plain skin in `material`, one object at
/// module-local (x, z) standing on `baseY`, `height` tall.
module::Module makeModule(std::uint32_t kx, std::uint32_t kz, std::uint16_t material, float x, float z,
                          float baseY, float height) {
  module::Module m;
  m.kx = kx;
  m.kz = kz;
  m.levels.resize(1);
  module::Level& lv = m.levels[0];
  lv.spacing = kSpacing;
  lv.squaresX = lv.squaresZ = kSquares;
  for (std::uint32_t b = 0; b <= kSquares; ++b) {
    for (std::uint32_t a = 0; a <= kSquares; ++a) lv.vertices.push_back({float(a * kSpacing), 0, float(b * kSpacing), 0, 0});
  }
  fixtures::addLatticeSkin(lv, kSquares);
  for (module::Group& g : lv.groups) g.material = material;
  module::Object o;
  o.x = x;
  o.z = z;
  o.radius = 2;
  o.height = height;
  m.objects.push_back(o);
  lv.objectY.push_back(baseY);
  return m;
}

std::uint16_t materialOf(std::uint32_t kx, std::uint32_t kz) { return std::uint16_t(10 + kz * kModules + kx); }

/// Modules in memory with generations; replace() is the dynamic-terrain
/// overlay's job in miniature.
class MemorySource final : public paging::ModuleSource {
 public:
  MemorySource() {
    header_.modulesX = header_.modulesZ = kModules;
    header_.levels = 1;
    header_.moduleSquares = kSquares;
    header_.moduleSize = kModuleSize;
    for (std::uint32_t kz = 0; kz < kModules; ++kz) {
      for (std::uint32_t kx = 0; kx < kModules; ++kx) {
        modules_.push_back(makeModule(kx, kz, materialOf(kx, kz), 80, 80, 1, 5));
        generations_.push_back(0);
      }
    }
  }
  void replace(std::uint32_t kx, std::uint32_t kz, module::Module m) {
    std::lock_guard lock(m_);
    modules_[kz * kModules + kx] = std::move(m);
    ++generations_[kz * kModules + kx];
    log_.push_back({kx, kz});
    changes_.store(log_.size(), std::memory_order_release);
  }
  /// A change notice for a module whose generation did not move.
  void noticeOnly(std::uint32_t kx, std::uint32_t kz) {
    std::lock_guard lock(m_);
    log_.push_back({kx, kz});
    changes_.store(log_.size(), std::memory_order_release);
  }
  mutable std::atomic<int> reads{0};

  const pack::IndexHeader& header() const override { return header_; }
  paging::ModuleInfo info(std::uint32_t, std::uint32_t) const override { return {1, 1, 0}; }
  std::uint64_t generation(std::uint32_t kx, std::uint32_t kz) const override {
    std::lock_guard lock(m_);
    return generations_[kz * kModules + kx];
  }
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    std::lock_guard lock(m_);
    ++reads;
    into = modules_[kz * kModules + kx];
    return generations_[kz * kModules + kx];
  }
  bool missing(std::uint32_t, std::uint32_t) const override { return false; }
  std::uint64_t changes() const override { return changes_.load(std::memory_order_acquire); }
  std::uint64_t changedSince(std::uint64_t since, std::vector<paging::ModuleKey>& out) const override {
    std::lock_guard lock(m_);
    for (std::size_t k = since; k < log_.size(); ++k) out.push_back(log_[k]);
    return log_.size();
  }

 private:
  pack::IndexHeader header_;
  mutable std::mutex m_;
  std::vector<module::Module> modules_;
  std::vector<std::uint64_t> generations_;
  std::vector<paging::ModuleKey> log_;
  std::atomic<std::uint64_t> changes_{0};
};

std::shared_ptr<const grid::GridFile> flatGrid() {
  const std::string path = std::filesystem::temp_directory_path().string() + "/sandtable_simworld_modules_" +
                           std::to_string(::getpid()) + ".grid";
  const Status st = fixtures::writeGrid(path, kPosts, kPosts, kSpacing, [](std::uint32_t, std::uint32_t) { return 1.0f; });
  EXPECT_TRUE(st) << st.error();
  auto g = grid::GridFile::open(path);
  EXPECT_TRUE(g) << g.error();
  std::filesystem::remove(path);
  return g.value();
}

struct Opened {
  std::shared_ptr<MemorySource> source;
  std::shared_ptr<SimWorld> world;
};

Opened openOverMemory() {
  Opened o;
  o.source = std::make_shared<MemorySource>();
  Database db;
  db.grid = flatGrid();
  const paging::World w(db, grid::heightField(db.grid), o.source);
  auto sw = SimWorld::open(w);
  EXPECT_TRUE(sw) << sw.error();
  o.world = sw.value();
  return o;
}

/// The centre of square (sx, sz)'s upper triangle, world metres.
std::pair<double, double> upperCentroid(std::uint32_t sx, std::uint32_t sz) {
  return {(sx + 1.0 / 3.0) * kSpacing, (sz + 1.0 / 3.0) * kSpacing};
}

TEST(SimWorldModules, theWorldReadsEveryModuleThroughItsSourceOnce) {
  const Opened o = openOverMemory();
  EXPECT_EQ(o.source->reads.load(), int(kModules * kModules));
  ASSERT_EQ(o.world->objects().size(), std::size_t(kModules * kModules));
  for (std::uint32_t kz = 0; kz < kModules; ++kz) {
    for (std::uint32_t kx = 0; kx < kModules; ++kx) {
      const auto [x, z] = upperCentroid(kx * kSquares + 3, kz * kSquares + 7);
      EXPECT_EQ(o.world->classAt(x, z), materialOf(kx, kz));
      const StaticObject& ob = o.world->objects()[kz * kModules + kx];
      EXPECT_DOUBLE_EQ(ob.x, kx * kModuleSize + 80);
      EXPECT_DOUBLE_EQ(ob.z, kz * kModuleSize + 80);
      EXPECT_DOUBLE_EQ(ob.baseY, 1);
    }
  }
  // Nothing changed: refresh reads nothing.
  auto r = o.world->refresh();
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r.value(), 0u);
  EXPECT_EQ(o.source->reads.load(), int(kModules * kModules));
}

TEST(SimWorldModules, aNewGenerationReplacesExactlyThatModulesSoilObjectsAndSquares) {
  const Opened o = openOverMemory();
  SimWorld& w = *o.world;
  // An object of another module was knocked over: that must survive.
  w.setObjectState(0, ObjectState::knockedOver);
  const std::vector<StaticObject> before = w.objects();
  // Module (1, 2): new soil 99, its object moved to (40, 120) local on a
  // 7 m berm, 12 m tall.
  o.source->replace(1, 2, makeModule(1, 2, 99, 40, 120, 7, 12));
  auto r = w.refresh();
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r.value(), 1u);
  EXPECT_EQ(o.source->reads.load(), int(kModules * kModules) + 1);  // that module only

  // Soil: every level-0 triangle of (1, 2) is 99, every other as it was.
  for (std::uint32_t sz = 0; sz < kPosts - 1; ++sz) {
    for (std::uint32_t sx = 0; sx < kPosts - 1; ++sx) {
      const std::uint32_t kx = sx / kSquares, kz = sz / kSquares;
      const std::uint16_t want = kx == 1 && kz == 2 ? 99 : materialOf(kx, kz);
      const auto [x, z] = upperCentroid(sx, sz);
      ASSERT_EQ(w.classAt(x, z), want) << sx << "," << sz;
      ASSERT_EQ(w.classAt(x + kSpacing / 3, z + kSpacing / 3), want) << "lower " << sx << "," << sz;
    }
  }
  // Objects: the old ones keep index and state; (1, 2)'s is retired and its
  // new one appended with the new base.
  ASSERT_EQ(w.objects().size(), before.size() + 1);
  for (std::size_t i = 0; i < before.size(); ++i) {
    const StaticObject& a = before[i];
    const StaticObject& b = w.objects()[i];
    EXPECT_EQ(b.x, a.x);
    EXPECT_EQ(b.z, a.z);
    EXPECT_EQ(b.baseY, a.baseY);
    EXPECT_EQ(b.state, a.state);
    EXPECT_EQ(b.current, !(a.moduleX == 1 && a.moduleZ == 2)) << i;
  }
  EXPECT_EQ(w.objects()[0].state, ObjectState::knockedOver);
  const StaticObject& added = w.objects().back();
  EXPECT_DOUBLE_EQ(added.x, kModuleSize + 40);
  EXPECT_DOUBLE_EQ(added.z, 2 * kModuleSize + 120);
  EXPECT_DOUBLE_EQ(added.baseY, 7);
  EXPECT_TRUE(added.current);

  // Collision squares: the new object is found where it stands, the old
  // one no longer where it stood; everywhere the grid agrees with testing
  // every object.
  std::vector<std::uint32_t> near;
  w.objectsNear(added.x, added.z, 1, 10, near);
  EXPECT_EQ(near, std::vector<std::uint32_t>{std::uint32_t(w.objects().size() - 1)});
  near.clear();
  w.objectsNear(kModuleSize + 80, 2 * kModuleSize + 80, 1, 2, near);
  EXPECT_TRUE(near.empty());
  for (double z = 5; z < (kPosts - 1) * kSpacing; z += 20) {
    for (double x = 5; x < (kPosts - 1) * kSpacing; x += 20) {
      std::vector<std::uint32_t> a, b;
      w.objectsNear(x, z, 3, 2, a);
      w.objectsNearBruteForce(x, z, 3, 2, b);
      ASSERT_EQ(a, b) << x << "," << z;
    }
  }
  const auto sq = [&](double x, double z) {
    return std::pair<std::uint32_t, std::uint32_t>{std::uint32_t(x / w.squareM()), std::uint32_t(z / w.squareM())};
  };
  const auto [nx, nz] = sq(added.x, added.z);
  EXPECT_DOUBLE_EQ(w.tallestTopIn(nx, nz), 19);  // the berm's 7 m + 12 m

  // A notice for a module whose generation did not move reads nothing.
  o.source->noticeOnly(3, 3);
  auto again = w.refresh();
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(again.value(), 0u);
  EXPECT_EQ(o.source->reads.load(), int(kModules * kModules) + 1);
}

TEST(SimWorldModules, anObjectKeepsItsStateInItsModulesNewGeneration) {
  const Opened o = openOverMemory();
  SimWorld& w = *o.world;
  std::uint32_t old = UINT32_MAX;
  for (std::uint32_t k = 0; k < w.objects().size(); ++k) {
    if (w.objects()[k].moduleX == 1 && w.objects()[k].moduleZ == 2) old = k;
  }
  ASSERT_NE(old, UINT32_MAX);
  w.setObjectState(old, ObjectState::knockedOver);
  // A crater re-meshes the module: same object (same id), new base.
  o.source->replace(1, 2, makeModule(1, 2, 99, 40, 120, 7, 12));
  ASSERT_TRUE(w.refresh());
  const std::uint32_t now = w.currentIndex(old);
  ASSERT_EQ(now, std::uint32_t(w.objects().size() - 1));
  EXPECT_FALSE(w.objects()[old].current);
  EXPECT_EQ(w.objects()[old].successor, now);
  EXPECT_EQ(w.objects()[now].state, ObjectState::knockedOver);
  EXPECT_EQ(w.currentIndex(now), now);
}

}  // namespace
}  // namespace sandtable::sim
