// The pager (docs/PAGER.md): the pure strip logic in every direction,
// diagonals, hysteresis, lead strips and jumps; the needed set; and the
// threaded pager on small hand-made databases (a GridWriter grid plus a
// PackWriter pack of tiny modules, no converter): strips loaded and freed,
// no thrashing, nearest-first refills, cancellation, flat memory, corrupt
// and missing modules, the budget, demand and mmap modes, and a lock-free
// reader hammering resident() while the viewer moves.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <new>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "sandtable/formats/bytes.h"
#include "sandtable/paging/pager.h"
#include "sandtable/testing/fixtures.h"

// Counting allocations: every operator new in the binary goes through here
// (not under ThreadSanitizer, which has its own allocator hooks).
#if defined(__SANITIZE_THREAD__)
#define SANDTABLE_COUNT_ALLOCATIONS 0
#else
#define SANDTABLE_COUNT_ALLOCATIONS 1
namespace {
thread_local std::uint64_t tAllocations = 0;
std::atomic<std::uint64_t> gAllocations{0};
}  // namespace
void* operator new(std::size_t n) {
  ++tAllocations;
  gAllocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
// GCC pairs the builtin operator new with this free() when it inlines.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop
#endif

namespace sandtable::paging {
namespace {

namespace fs = std::filesystem;

// ------------------------------------------------------------ test data

constexpr double kSpacing = 125.0;  // seed: 125 m posts, 1 km load modules
constexpr std::uint32_t kSquares = 8;
constexpr double kEdge = kSpacing * kSquares;

float gridElevation(std::uint32_t i, std::uint32_t j) { return float(100.0 + 0.25 * i + 0.5 * j); }

/// A module whose every vertex names it: s = kx, t = kz, y = 1000 kx + kz.
module::Module makeModule(std::uint32_t kx, std::uint32_t kz, std::uint32_t squares,
                          std::uint32_t levels) {
  module::Module m;
  m.kx = kx;
  m.kz = kz;
  for (std::uint32_t l = 0; l < levels; ++l) {
    const std::uint32_t n = std::max(1u, squares >> l);
    module::Level lv;
    lv.spacing = kSpacing * double(squares / n);
    lv.squaresX = lv.squaresZ = n;
    lv.skirtDepth = 10;
    const float y = float(1000.0 * kx + kz);
    for (std::uint32_t b = 0; b <= n; ++b) {
      for (std::uint32_t a = 0; a <= n; ++a) {
        lv.vertices.push_back({float(a * lv.spacing), y, float(b * lv.spacing), float(kx), float(kz)});
      }
    }
    fixtures::addLatticeSkin(lv, n);
    m.levels.push_back(std::move(lv));
  }
  return m;
}

struct TestDb {
  std::string dir;
  std::shared_ptr<const grid::GridFile> grid;
  std::shared_ptr<const pack::PackReader> pack;
};

std::string tempDir(const std::string& name) {
  const fs::path p =
      fs::temp_directory_path() / ("sandtable-pager-" + name + "." + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

/// Removes this process's test databases when the tests end.
class RemoveTempDirs : public ::testing::Environment {
 public:
  void TearDown() override {
    std::string suffix(1, '.');
    suffix += std::to_string(::getpid());
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(fs::temp_directory_path(), ec)) {
      const std::string n = e.path().filename().string();
      if (n.rfind("sandtable-pager-", 0) == 0 && n.size() > suffix.size() &&
          n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0) {
        fs::remove_all(e.path(), ec);
      }
    }
  }
};
[[maybe_unused]] ::testing::Environment* const kRemoveTempDirs =
    ::testing::AddGlobalTestEnvironment(new RemoveTempDirs);

TestDb makeDb(const std::string& name, std::uint32_t mx, std::uint32_t mz,
              std::uint32_t squares = kSquares, std::uint32_t levels = 3, const pack::PackLayout& layout = {}) {
  TestDb db;
  db.dir = tempDir(name);
  const std::uint32_t px = mx * squares + 1, pz = mz * squares + 1;
  const Status written = fixtures::writeGrid(db.dir + "/grid.stg", px, pz, kSpacing, gridElevation);
  EXPECT_TRUE(written.ok()) << written.error();
  auto g = grid::GridFile::open(db.dir + "/grid.stg");
  EXPECT_TRUE(g.ok()) << g.error();
  db.grid = g.value();

  pack::IndexHeader h;
  h.modulesX = mx;
  h.modulesZ = mz;
  h.levels = levels;
  h.moduleSquares = squares;
  h.moduleSize = squares * kSpacing;
  auto pw = pack::PackWriter::create(db.dir, h, 1, layout);
  EXPECT_TRUE(pw.ok()) << pw.error();
  for (std::uint32_t kz = 0; kz < mz; ++kz) {
    for (std::uint32_t kx = 0; kx < mx; ++kx) {
      EXPECT_EQ(pw.value()->add(makeModule(kx, kz, squares, levels)).message(), "");
    }
  }
  EXPECT_EQ(pw.value()->finish().message(), "");
  auto pr = pack::PackReader::open(db.dir);
  EXPECT_TRUE(pr.ok()) << pr.error();
  db.pack = pr.value();
  return db;
}

std::vector<std::byte> readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> c((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> v(c.size());
  std::memcpy(v.data(), c.data(), c.size());
  return v;
}

void writeAll(const std::string& path, std::span<const std::byte> bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

/// Flips bytes in the middle of module (kx, kz)'s record.
void corruptRecord(const TestDb& db, std::uint32_t kx, std::uint32_t kz) {
  const pack::Entry e = db.pack->entry(kx, kz);
  const std::string path = db.dir + "/" + pack::kPackFileName;
  std::vector<std::byte> bytes = readAll(path);
  for (std::uint64_t o = e.offset + e.compressedBytes / 3; o < e.offset + e.compressedBytes / 3 + 8; ++o) {
    bytes[o] ^= std::byte{0x5a};
  }
  writeAll(path, bytes);
}

/// Rewrites the index so that module (kx, kz) has no record (table CRC and
/// header CRC recomputed), and reopens the pack.
void dropEntry(TestDb& db, std::uint32_t kx, std::uint32_t kz) {
  const std::string path = db.dir + "/" + pack::kIndexFileName;
  std::vector<std::byte> bytes = readAll(path);
  pack::IndexHeader h = db.pack->header();
  pack::Entry e = db.pack->entry(kx, kz);
  e.compressedBytes = 0;
  const std::size_t at = pack::kIndexHeaderBytes + pack::kEntryBytes * (std::size_t(kz) * h.modulesX + kx);
  pack::encodeEntry(e, std::span(bytes).subspan(at, pack::kEntryBytes));
  h.tableCrc = crc32(std::span<const std::byte>(bytes).subspan(pack::kIndexHeaderBytes));
  const std::vector<std::byte> page = pack::encodeIndexHeader(h);
  std::copy(page.begin(), page.end(), bytes.begin());
  writeAll(path, bytes);
  auto pr = pack::PackReader::open(db.dir);
  ASSERT_TRUE(pr.ok()) << pr.error();
  db.pack = pr.value();
}

PagingGeometry geometry40() {
  PagingGeometry g;
  g.moduleSize = 1000;
  g.modulesX = g.modulesZ = 40;
  g.viewDistance = 3000;
  g.hysteresis = 100;
  g.maxLeadStrips = 3;
  return g;
}

std::set<std::pair<std::uint32_t, std::uint32_t>> keys(const std::vector<ModuleKey>& v) {
  std::set<std::pair<std::uint32_t, std::uint32_t>> s;
  for (const ModuleKey& k : v) s.insert({k.kx, k.kz});
  return s;
}

std::set<std::pair<std::uint32_t, std::uint32_t>> column(std::uint32_t kx, std::uint32_t z0,
                                                         std::uint32_t z1) {
  std::set<std::pair<std::uint32_t, std::uint32_t>> s;
  for (std::uint32_t z = z0; z < z1; ++z) s.insert({kx, z});
  return s;
}

std::set<std::pair<std::uint32_t, std::uint32_t>> row(std::uint32_t kz, std::uint32_t x0,
                                                      std::uint32_t x1) {
  std::set<std::pair<std::uint32_t, std::uint32_t>> s;
  for (std::uint32_t x = x0; x < x1; ++x) s.insert({x, kz});
  return s;
}

std::uint32_t signalled(const PlanStep& s) {
  std::uint32_t mask = 0;
  for (std::size_t d = 0; d < kDirections; ++d) mask |= s.jobs[d].signalled() ? 1u << d : 0u;
  return mask;
}

constexpr std::uint32_t bit(Direction d) { return 1u << std::uint32_t(d); }

// ----------------------------------------------------------- strip logic

TEST(StripPlanner, geometryFollowsSeedFigure28) {
  PagingGeometry g = geometry40();
  EXPECT_EQ(g.radius(), 4);  // ceil((3000 + 100) / 1000)
  EXPECT_EQ(g.side(), 9);
  EXPECT_EQ(g.ringX(), 15u);  // side + 3 lead strips on one side + 3 guard strips on the other
  g.viewDistance = 2900;
  EXPECT_EQ(g.radius(), 3);  // exactly 3 modules: no rounding up
  g.modulesX = 5;
  EXPECT_EQ(g.ringX(), 5u);  // never more slots than modules
}

TEST(StripPlanner, firstUpdateRefillsTheActiveAreaNearestFirst) {
  StripPlanner p(geometry40());
  const PlanStep& s = p.update(20500, 20500, 0, 0, 0);
  EXPECT_TRUE(s.refill);
  EXPECT_TRUE(s.changed);
  EXPECT_EQ(s.after, (ModuleRect{16, 16, 25, 25}));
  std::size_t total = 0;
  for (const StripJob& j : s.jobs) total += j.load.size();
  EXPECT_EQ(total, 81u);
  // Dealt round robin from one nearest-first list: the centre, then its
  // four edge neighbours, one per loader.
  EXPECT_EQ(s.jobs[0].load[0], (ModuleKey{20, 20}));
  std::set<std::pair<std::uint32_t, std::uint32_t>> ring1;
  for (std::size_t d = 1; d < 4; ++d) ring1.insert({s.jobs[d].load[0].kx, s.jobs[d].load[0].kz});
  ring1.insert({s.jobs[0].load[1].kx, s.jobs[0].load[1].kz});
  EXPECT_EQ(ring1, (std::set<std::pair<std::uint32_t, std::uint32_t>>{
                       {20, 19}, {19, 20}, {21, 20}, {20, 21}}));
}

TEST(StripPlanner, crossingTheBoxInEachDirectionSignalsThatLoader) {
  struct Case {
    Direction d;
    double x, z;
    std::set<std::pair<std::uint32_t, std::uint32_t>> load, free;
  };
  // Centre module (20, 20), box [19900, 21100]^2, window [16, 25)^2.
  const std::vector<Case> cases = {
      {Direction::east, 21101, 20500, column(25, 16, 25), column(16, 16, 25)},
      {Direction::west, 19899, 20500, column(15, 16, 25), column(24, 16, 25)},
      {Direction::north, 20500, 19899, row(15, 16, 25), row(24, 16, 25)},
      {Direction::south, 20500, 21101, row(25, 16, 25), row(16, 16, 25)},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(directionName(c.d));
    StripPlanner p(geometry40());
    p.update(20500, 20500, 0, 0, 0);
    // Just inside the margin: nothing.
    const PlanStep& inside = p.update(c.x + (c.x > 20500 ? -2 : c.x < 20500 ? 2 : 0),
                                      c.z + (c.z > 20500 ? -2 : c.z < 20500 ? 2 : 0), 0, 0, 0);
    EXPECT_FALSE(inside.changed);
    const PlanStep& s = p.update(c.x, c.z, 0, 0, 0);
    EXPECT_TRUE(s.crossed);
    EXPECT_FALSE(s.refill);
    EXPECT_EQ(signalled(s), bit(c.d));
    EXPECT_EQ(keys(s.jobs[std::size_t(c.d)].load), c.load);
    EXPECT_EQ(keys(s.jobs[std::size_t(c.d)].free), c.free);
  }
}

TEST(StripPlanner, diagonalMoveSignalsTwoLoaders) {
  StripPlanner p(geometry40());
  p.update(20500, 20500, 0, 0, 0);
  const PlanStep& s = p.update(21101, 19899, 0, 0, 0);  // north-east
  EXPECT_EQ(signalled(s), bit(Direction::east) | bit(Direction::north));
  EXPECT_EQ(s.after, (ModuleRect{17, 15, 26, 24}));
  // The new corner (25, 15) goes to the east loader.
  EXPECT_EQ(keys(s.jobs[std::size_t(Direction::east)].load), column(25, 15, 24));
  EXPECT_EQ(keys(s.jobs[std::size_t(Direction::north)].load), row(15, 17, 25));
  EXPECT_EQ(keys(s.jobs[std::size_t(Direction::east)].free), column(16, 16, 25));
  EXPECT_EQ(keys(s.jobs[std::size_t(Direction::north)].free), row(24, 17, 25));
}

TEST(StripPlanner, backAndForthInsideTheMarginPagesNothing) {
  StripPlanner p(geometry40());
  p.update(20500, 20500, 0, 0, 0);
  // Cross east once, then swing across the module edge at 21000 m inside
  // the 100 m margin, at speed, with the lead strips on.
  ASSERT_TRUE(p.update(21101, 20500, 50, 0, 2.0).changed);
  const ModuleRect w = p.window();
  for (int i = 0; i < 200; ++i) {
    const double x = (i % 2) ? 20905 : 21095;
    const double vx = (i % 2) ? -50 : 50;
    const PlanStep& s = p.update(x, 20500 + (i % 7) * 10.0, vx, 0, 2.0);
    EXPECT_FALSE(s.changed) << "swing " << i;
  }
  EXPECT_EQ(p.window(), w);
  EXPECT_EQ(p.centreX(), 21);
}

TEST(StripPlanner, leadStripsScaleWithSpeedAndOnlyGrowInsideTheBox) {
  StripPlanner p(geometry40());
  p.update(20500, 20500, 0, 0, 0);
  // 600 m/s with a 2 s lead time: 1200 m ahead, two strips east.
  const PlanStep& s = p.update(20600, 20500, 600, 0, 2.0);
  EXPECT_EQ(p.lead()[std::size_t(Direction::east)], 2u);
  EXPECT_EQ(signalled(s), bit(Direction::east));
  EXPECT_EQ(keys(s.jobs[std::size_t(Direction::east)].load).size(), 18u);
  EXPECT_TRUE(s.jobs[std::size_t(Direction::east)].free.empty());
  // Faster: clamped to maxLeadStrips.
  p.update(20650, 20500, 5000, 0, 2.0);
  EXPECT_EQ(p.lead()[std::size_t(Direction::east)], 3u);
  // Slower or reversed inside the box: kept.
  EXPECT_FALSE(p.update(20700, 20500, 10, 0, 2.0).changed);
  EXPECT_FALSE(p.update(20600, 20500, -600, 0, 2.0).changed);
  // Leaving the box westwards: the lead switches sides.
  p.update(19899, 20500, -600, 0, 2.0);
  EXPECT_EQ(p.lead()[std::size_t(Direction::east)], 0u);
  EXPECT_EQ(p.lead()[std::size_t(Direction::west)], 2u);
  EXPECT_EQ(p.window(), (ModuleRect{13, 16, 24, 25}));
}

// The window moves only at updates; within one the eye may turn anywhere.
// At 2500 m/s and one update a second, a 90-degree turn puts the eye 2.5 km
// down an axis that had no lead: the guard keeps what it then sees resident.
TEST(StripPlanner, theGuardCoversOneUpdateOfTravelOnEverySide) {
  StripPlanner slow(geometry40());
  slow.update(20500, 20500, 50, 0, 0, 1.0);  // 50 m in an update: inside the hysteresis
  EXPECT_EQ(slow.guard(), 0u);
  EXPECT_EQ(slow.window(), (ModuleRect{16, 16, 25, 25}));

  StripPlanner fast(geometry40());
  fast.update(20500, 20500, 2500, 0, 0, 1.0);  // ceil((2500 - 100) / 1000) = 3 strips
  EXPECT_EQ(fast.guard(), 3u);
  EXPECT_EQ(fast.window(), (ModuleRect{13, 13, 28, 28}));
  // The turn south: everything within the view distance of the new eye was
  // already in the window, where the window without a guard misses row 25.
  const double eyeX = 20500, eyeZ = 23000;
  for (std::int64_t z = 0; z < 40; ++z) {
    for (std::int64_t x = 0; x < 40; ++x) {
      const double x0 = double(x) * 1000.0, z0 = double(z) * 1000.0;  // the module's nearest point
      const double dx = std::max({x0 - eyeX, 0.0, eyeX - x0 - 1000.0});
      const double dz = std::max({z0 - eyeZ, 0.0, eyeZ - z0 - 1000.0});
      if (std::hypot(dx, dz) < 3000) {
        EXPECT_TRUE(fast.window().contains(x, z)) << x << ", " << z;
      }
    }
  }
  EXPECT_FALSE(slow.window().contains(20, 25));
  // Slower inside the box: the guard is kept; at the next crossing it follows the speed.
  EXPECT_FALSE(fast.update(20550, 20500, 50, 0, 0, 1.0).changed);
  EXPECT_EQ(fast.guard(), 3u);
  fast.update(21200, 20500, 50, 0, 0, 1.0);
  EXPECT_EQ(fast.guard(), 0u);
  EXPECT_EQ(fast.window(), (ModuleRect{17, 16, 26, 25}));
}

TEST(StripPlanner, jumpRefillsNearestFirstAndFreesTheOldArea) {
  StripPlanner p(geometry40());
  p.update(10500, 10500, 0, 0, 0);
  const PlanStep& s = p.update(30200, 29700, 0, 0, 0);
  EXPECT_TRUE(s.refill);
  EXPECT_EQ(s.after, (ModuleRect{26, 25, 35, 34}));
  std::size_t loads = 0, frees = 0;
  for (const StripJob& j : s.jobs) {
    loads += j.load.size();
    frees += j.free.size();
    // Each loader's share is nearest first.
    for (std::size_t i = 1; i < j.load.size(); ++i) {
      auto d = [](ModuleKey k) {
        return std::hypot((k.kx + 0.5) * 1000 - 30200, (k.kz + 0.5) * 1000 - 29700);
      };
      EXPECT_LE(d(j.load[i - 1]), d(j.load[i]));
    }
  }
  EXPECT_EQ(loads, 81u);
  EXPECT_EQ(frees, 81u);
  EXPECT_EQ(s.jobs[0].load[0], (ModuleKey{30, 29}));
}

TEST(StripPlanner, clipsToTheDatabase) {
  StripPlanner p(geometry40());
  const PlanStep& s = p.update(500, 39500, 0, 0, 0);  // south-west corner module
  EXPECT_EQ(s.after, (ModuleRect{0, 35, 5, 40}));
  p.update(-5000, 60000, 0, 0, 0);  // off the database: nothing to page
  EXPECT_TRUE(p.window().empty());
}

// ------------------------------------------------------------ needed set

TEST(NeededSet, levelsFollowSeedTable8) {
  // Four levels over 6 km: 0-1500, 1500-3000, 3000-4500, 4500-6000.
  EXPECT_EQ(levelForDistance(0, 6000, 4), 0u);
  EXPECT_EQ(levelForDistance(1500, 6000, 4), 0u);
  EXPECT_EQ(levelForDistance(1501, 6000, 4), 1u);
  EXPECT_EQ(levelForDistance(4500, 6000, 4), 2u);
  EXPECT_EQ(levelForDistance(6000, 6000, 4), 3u);
  EXPECT_EQ(levelForDistance(9000, 6000, 4), 3u);
  const std::vector<double> edges = {1000, 2000};
  EXPECT_EQ(levelForDistance(1500, 6000, 4, edges), 1u);
  EXPECT_EQ(levelForDistance(2500, 6000, 4, edges), 3u);
}

TEST(NeededSet, modulesUnderTheViewTriangleWithTheirLevels) {
  NeedParams p;
  p.eyeX = 20500;
  p.eyeZ = 20500;
  p.headingDeg = 0;  // north
  p.halfAngleDeg = 30;
  p.viewDistance = 4000;
  const auto need = neededModules(p, 1000, 40, 40, 4);
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> level;
  for (const NeededModule& n : need) level[{n.kx, n.kz}] = n.level;
  EXPECT_EQ(level.at({20, 20}), 0u);  // the eye's module
  EXPECT_EQ(level.at({20, 18}), 1u);  // 1500 m ahead: bin 1000-2000
  EXPECT_EQ(level.at({20, 16}), 3u);  // 3500 m ahead
  EXPECT_EQ(level.count({20, 22}), 0u);  // behind
  EXPECT_EQ(level.count({14, 20}), 0u);  // outside the 30 degree half angle
  for (std::size_t i = 1; i < need.size(); ++i) EXPECT_LE(need[i - 1].kz, need[i].kz);
}

// ------------------------------------------------------------- the pager

PagerOptions baseOptions() {
  PagerOptions o;
  o.viewDistance = 3000;
  o.lookAheadScale = 0;  // deterministic windows unless a test turns it on
  o.log = [](const std::string&) {};
  return o;
}

std::unique_ptr<Pager> openPager(const TestDb& db, const PagerOptions& o) {
  auto p = Pager::open(db.grid, db.pack, o);
  EXPECT_TRUE(p.ok()) << p.error();
  return p.ok() ? std::move(p.value()) : nullptr;
}

bool residentNow(const Pager& p, std::uint32_t kx, std::uint32_t kz) {
  return bool(p.resident(kx, kz));
}

TEST(Pager, fillsTheAreaThenPagesStripsAndFreesTheOppositeSide) {
  const TestDb db = makeDb("strips", 40, 40);
  auto p = openPager(db, baseOptions());
  ASSERT_TRUE(p);
  p->update(20500, 20500, 0, 0, 0);
  ASSERT_TRUE(p->waitIdle(30));
  PagerMetrics m = p->metrics();
  EXPECT_EQ(m.windowModules, 81u);
  EXPECT_EQ(m.holesInWindow, 0u);
  EXPECT_EQ(m.loaded, 81u);
  EXPECT_EQ(m.refills, 1u);
  {
    const ResidentRef r = p->resident(20, 20, 0);
    ASSERT_TRUE(r);
    EXPECT_EQ(r.finestLevel(), 0u);
    EXPECT_FALSE(r.placeholder());
    EXPECT_EQ(r.level().vertices.front().s, 20.0f);
    EXPECT_EQ(r.level(2).squaresX, 2u);
    const ResidentRef coarse = p->resident(20, 20, 2);
    EXPECT_EQ(coarse.levelIndex(), 2u);
  }
  EXPECT_FALSE(residentNow(*p, 25, 20));

  // East, then north, west, south: one loader each; then a diagonal.
  struct Step {
    double x, z;
    std::uint32_t mask;
  };
  const std::vector<Step> steps = {{21101, 20500, bit(Direction::east)},
                                   {21101, 19899, bit(Direction::north)},
                                   {19899, 19899, bit(Direction::west)},
                                   {19899, 20501 + 100, bit(Direction::south)},
                                   {21200, 19700, bit(Direction::east) | bit(Direction::north)}};
  std::array<std::uint64_t, 4> before = m.stripSignals;
  for (const Step& s : steps) {
    p->update(s.x, s.z, 0, 0, 0);
    ASSERT_TRUE(p->waitIdle(30));
    m = p->metrics();
    std::uint32_t mask = 0;
    for (std::size_t d = 0; d < 4; ++d) mask |= m.stripSignals[d] != before[d] ? 1u << d : 0u;
    EXPECT_EQ(mask, s.mask) << "at " << s.x << ", " << s.z;
    before = m.stripSignals;
    EXPECT_EQ(m.holesInWindow, 0u);
  }
  // After the diagonal the centre is (21, 19): window [17, 26) x [15, 24).
  EXPECT_EQ(p->window(), (ModuleRect{17, 15, 26, 24}));
  EXPECT_TRUE(residentNow(*p, 25, 15));
  EXPECT_FALSE(residentNow(*p, 16, 20));  // freed with the west strip
  EXPECT_FALSE(residentNow(*p, 20, 24));  // freed with the south strip
  EXPECT_EQ(m.freed + 81, m.loaded + 0u);  // every module loaded but the window's was freed
  EXPECT_EQ(m.cancelledQueued + m.cancelledInFlight, 0u);
  EXPECT_EQ(m.latency.count, m.loaded);
  EXPECT_GT(m.bytesRead, 0u);
}

// The window moves only at updates, so the lead also covers one update's
// travel: at 300 km/s and 60 updates a second that is 5 km, where a 1 ms
// latency alone would ask for one strip.
TEST(Pager, leadCoversTheLatencyAndOneUpdateOfTravel) {
  const TestDb db = makeDb("lead", 40, 40);
  for (const double scale : {2.0, 0.0}) {
    PagerOptions o = baseOptions();
    o.lookAheadScale = scale;
    o.initialLatencySeconds = 0.001;
    o.maxLeadStrips = 16;
    // Slow reads: the refill's 81 loads (which leave the latency estimate
    // alone) come before any lead strip's, so no strip load lands and moves
    // the estimate before the metrics are taken.
    o.simulatedReadSeconds = 0.05;
    auto p = openPager(db, o);
    ASSERT_TRUE(p);
    p->update(20500, 20500, 0, 0, 0);
    for (int k = 1; k <= 120; ++k) p->update(20500, 20500, 300000, 0, k / 60.0);
    const PagerMetrics m = p->metrics();
    if (scale > 0) {
      EXPECT_NEAR(m.leadSeconds, 2 * 0.001 + 1.0 / 60, 1e-9);
      // ceil(300 km/s * 18.67 ms / 1 km)
      EXPECT_EQ(m.leadStrips[std::size_t(Direction::east)], 6u);
    } else {
      EXPECT_EQ(m.leadSeconds, 0.0);  // 0 still turns prediction off
      EXPECT_EQ(m.leadStrips[std::size_t(Direction::east)], 0u);
    }
    EXPECT_EQ(m.leadStrips[std::size_t(Direction::west)], 0u);
  }
}

TEST(Pager, backAndForthInsideTheMarginLoadsNothing) {
  const TestDb db = makeDb("swing", 40, 40);
  PagerOptions o = baseOptions();
  o.lookAheadScale = 2;
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  p->update(20500, 20500, 0, 0, 0);
  p->update(20990, 20500, 50, 0, 0.1);
  ASSERT_TRUE(p->waitIdle(30));
  const PagerMetrics m0 = p->metrics();
  for (int i = 0; i < 500; ++i) {
    const double x = (i % 2) ? 20910 : 21090;
    p->update(x, 20500, (i % 2) ? -50 : 50, 0, 0.2 + i * 0.1);
  }
  ASSERT_TRUE(p->waitIdle(30));
  const PagerMetrics m1 = p->metrics();
  EXPECT_EQ(m1.requested, m0.requested);
  EXPECT_EQ(m1.freed, m0.freed);
  EXPECT_EQ(m1.boxCrossings, m0.boxCrossings);
  EXPECT_EQ(m1.holesInWindow, 0u);
}

/// Jumps from (8500, 8500) to (30200, 29700) and returns the order in which
/// the 81 new modules arrived, per loader and overall. With `holdSlot`, a
/// reader guard on the old module in the slot of (30, 29) is held across
/// the jump, so the loader that claims it waits for the reader until
/// update() has queued everything.
struct Arrivals {
  std::vector<std::vector<ModuleKey>> byLoader = std::vector<std::vector<ModuleKey>>(4);
  std::vector<ModuleKey> all;
  PagerMetrics metrics;
};

Arrivals jumpAndRecord(const TestDb& db, std::uint32_t loaders, bool holdSlot) {
  PagerOptions o = baseOptions();
  o.loaderThreads = loaders;
  o.simulatedReadSeconds = 0.002;
  o.workStealing = false;  // the deal itself is under test
  std::mutex mu;
  Arrivals a;
  bool recording = false;
  o.onResident = [&](std::uint32_t loader, ModuleKey k, bool) {
    const std::lock_guard lock(mu);
    if (!recording) return;
    a.byLoader[loader].push_back(k);
    a.all.push_back(k);
  };
  auto p = openPager(db, o);
  EXPECT_TRUE(p);
  if (!p) return a;
  p->update(8500, 8500, 0, 0, 0);
  EXPECT_TRUE(p->waitIdle(30));
  {
    const std::lock_guard lock(mu);
    recording = true;
  }
  {
    // (6, 5) is in the old window and shares the slot of (30, 29) (ring 12).
    ResidentRef guard = holdSlot ? p->resident(6, 5) : ResidentRef();
    EXPECT_EQ(bool(guard), holdSlot);
    // update() deals the whole refill, sorted, before it returns, so the
    // order does not depend on how soon the loader starts (there was a
    // 50 ms sleep here). The guard only shows that a reader of the slot's
    // old occupant does not disturb the load: double buffering keeps the
    // fresh load out of the guarded buffer.
    p->update(30200, 29700, 0, 0, 1);
  }
  EXPECT_TRUE(p->waitIdle(30));
  a.metrics = p->metrics();
  p->stop();
  return a;
}

double distanceTo(ModuleKey k, double x, double z) {
  return std::hypot((k.kx + 0.5) * 1000 - x, (k.kz + 0.5) * 1000 - z);
}

TEST(Pager, jumpRefillsNearestFirstOnEveryLoader) {
  const TestDb db = makeDb("jump4", 40, 40);
  const Arrivals a = jumpAndRecord(db, 4, false);
  ASSERT_EQ(a.all.size(), 81u);
  for (const auto& v : a.byLoader) {
    EXPECT_GE(v.size(), 20u);  // dealt round robin: 21, 20, 20, 20
    for (std::size_t i = 1; i < v.size(); ++i) {
      EXPECT_LE(distanceTo(v[i - 1], 30200, 29700), distanceTo(v[i], 30200, 29700));
    }
  }
  EXPECT_EQ(a.metrics.refills, 2u);
  EXPECT_EQ(a.metrics.freed, 81u);
}

TEST(Pager, jumpRefillsNearestFirstOverall) {
  // One loader, and everything queued (by update() itself) before its
  // first read: the arrival order is sorted, with a reader holding the old
  // occupant of the first module's slot.
  const TestDb db = makeDb("jump1", 40, 40);
  const Arrivals a = jumpAndRecord(db, 1, true);
  ASSERT_EQ(a.all.size(), 81u);
  EXPECT_EQ(a.all.front(), (ModuleKey{30, 29}));
  for (std::size_t i = 1; i < a.all.size(); ++i) {
    EXPECT_LE(distanceTo(a.all[i - 1], 30200, 29700), distanceTo(a.all[i], 30200, 29700)) << i;
  }
  EXPECT_EQ(a.metrics.holesInWindow, 0u);
}

/// Loads of one east strip per loader. With stealing, the east loader is
/// held in its first publication until another loader has published, so
/// the strip completes only if idle loaders take its pending modules.
struct StripLoads {
  std::array<std::uint64_t, 4> byLoader{};
  std::uint64_t stolen = 0;
  PagerMetrics metrics;
};

StripLoads eastStripByLoader(const TestDb& db, bool stealing) {
  PagerOptions o = baseOptions();
  o.workStealing = stealing;
  std::mutex mu;
  std::condition_variable cv;
  StripLoads r;
  bool recording = false, held = false;
  const auto east = std::uint32_t(Direction::east);
  o.onResident = [&](std::uint32_t loader, ModuleKey, bool) {
    std::unique_lock lock(mu);
    if (!recording) return;
    ++r.byLoader[loader];
    cv.notify_all();
    if (stealing && loader == east && !held) {
      held = true;
      // A guard against a hang, not a timing threshold: the wait ends as
      // soon as another loader publishes.
      cv.wait_for(lock, std::chrono::seconds(30), [&] {
        return r.byLoader[0] + r.byLoader[2] + r.byLoader[3] > 0;
      });
    }
  };
  auto p = openPager(db, o);
  EXPECT_TRUE(p);
  if (!p) return r;
  p->update(20500, 20500, 0, 0, 0);
  EXPECT_TRUE(p->waitIdle(30));
  const std::uint64_t stolen0 = p->metrics().stolen;
  {
    const std::lock_guard lock(mu);
    recording = true;
  }
  p->update(21101, 20500, 0, 0, 1);
  EXPECT_TRUE(p->waitIdle(60));
  r.metrics = p->metrics();
  r.stolen = r.metrics.stolen - stolen0;
  p->stop();
  return r;
}

TEST(Pager, idleLoadersStealFromTheBusyDirection) {
  const TestDb db = makeDb("steal", 40, 40);
  const StripLoads off = eastStripByLoader(db, false);
  EXPECT_EQ(off.byLoader[std::size_t(Direction::east)], 9u);  // the whole strip, by its own loader
  EXPECT_EQ(off.byLoader[0] + off.byLoader[2] + off.byLoader[3], 0u);
  EXPECT_EQ(off.stolen, 0u);

  const StripLoads on = eastStripByLoader(db, true);
  const std::uint64_t others = on.byLoader[0] + on.byLoader[2] + on.byLoader[3];
  EXPECT_EQ(on.byLoader[1] + others, 9u);
  EXPECT_GE(others, 1u);
  EXPECT_EQ(on.stolen, others);
  EXPECT_EQ(on.metrics.holesInWindow, 0u);
  EXPECT_EQ(on.metrics.stripSignals[std::size_t(Direction::east)], 1u);
}

/// A pack source whose reads, once armed, wait at a gate until the test
/// opens it: loads stay in flight for exactly as long as a test needs,
/// with no sleep (Pager::open's preallocation reads before arming).
class GatedSource final : public ModuleSource {
 public:
  explicit GatedSource(std::shared_ptr<const pack::PackReader> p) : pack_(std::move(p)) {}
  const pack::IndexHeader& header() const override { return pack_.header(); }
  ModuleInfo info(std::uint32_t kx, std::uint32_t kz) const override { return pack_.info(kx, kz); }
  std::uint64_t generation(std::uint32_t, std::uint32_t) const override { return 0; }
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    pass();
    return pack_.read(kx, kz, into);
  }
  std::uint32_t coarseLevel() const override { return pack_.coarseLevel(); }
  Result<std::uint64_t> readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    pass();
    return pack_.readCoarse(kx, kz, into);
  }
  Status readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    return pack_.readFine(kx, kz, into);
  }
  bool missing(std::uint32_t kx, std::uint32_t kz) const override { return pack_.missing(kx, kz); }
  std::uint64_t changes() const override { return 0; }
  std::uint64_t changedSince(std::uint64_t since, std::vector<ModuleKey>&) const override { return since; }

  void arm() { armed_.store(true); }
  void open() {
    const std::lock_guard lock(mu_);
    armed_.store(false);
    cv_.notify_all();
  }
  /// Blocks until `n` reads wait at the gate.
  void waitForWaiting(std::uint32_t n) const {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [&] { return waiting_ >= n; });
  }

 private:
  void pass() const {
    if (!armed_.load()) return;
    std::unique_lock lock(mu_);
    ++waiting_;
    cv_.notify_all();
    cv_.wait(lock, [&] { return !armed_.load(); });
  }
  PackSource pack_;
  std::atomic<bool> armed_{false};
  mutable std::mutex mu_;
  mutable std::condition_variable cv_;
  mutable std::uint32_t waiting_ = 0;
};

TEST(Pager, loadsThatLeaveTheAreaAreCancelled) {
  // Every loader's first read of the 81-module area is held at the gate
  // while the viewer jumps away: the rest of that refill is still queued
  // and must be cancelled, not read.
  const TestDb db = makeDb("cancel", 40, 40);
  auto src = std::make_shared<GatedSource>(db.pack);
  PagerOptions o = baseOptions();
  o.workStealing = false;
  auto opened = Pager::open(db.grid, src, o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  src->arm();
  p.update(8500, 8500, 0, 0, 0);
  src->waitForWaiting(o.loaderThreads);  // one read in flight per loader, the rest queued
  p.update(30500, 30500, 0, 0, 0.05);    // far away before the first area is in
  src->open();
  ASSERT_TRUE(p.waitIdle(30));
  const PagerMetrics m = p.metrics();
  EXPECT_GE(m.cancelledQueued, 81u - o.loaderThreads);
  EXPECT_EQ(m.cancelledInFlight, std::uint64_t(o.loaderThreads));
  EXPECT_EQ(m.loaded, 81u);  // only the new area
  EXPECT_EQ(m.holesInWindow, 0u);
  for (std::uint32_t kz = 4; kz < 13; ++kz) {
    for (std::uint32_t kx = 4; kx < 13; ++kx) EXPECT_FALSE(residentNow(p, kx, kz));
  }
  EXPECT_TRUE(residentNow(p, 30, 30));
}

long residentPages() {
  std::ifstream in("/proc/self/statm");
  long size = 0, res = 0;
  in >> size >> res;
  return res;
}

TEST(Pager, memoryStaysFlatOverALongFlight) {
  const TestDb db = makeDb("flat", 40, 40, 16, 3);
  PagerOptions o = baseOptions();
  o.lookAheadScale = 2;
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  // Laps of a 20 km square, 100 m per tick (at 50 m/s).
  auto fly = [&](int laps, double& t) {
    for (int lap = 0; lap < laps; ++lap) {
      for (int side = 0; side < 4; ++side) {
        for (int k = 0; k < 200; ++k) {
          const double s = k * 100.0;
          const double x = side == 0 ? 10000 + s : side == 1 ? 30000 : side == 2 ? 30000 - s : 10000;
          const double z = side == 0 ? 10000 : side == 1 ? 10000 + s : side == 2 ? 30000 : 30000 - s;
          const double vx = side == 0 ? 50 : side == 2 ? -50 : 0;
          const double vz = side == 1 ? 50 : side == 3 ? -50 : 0;
          p->update(x, z, vx, vz, t);
          t += 2;
          if (k % 10 == 0) {
            ASSERT_TRUE(p->waitIdle(30));
          }
        }
      }
    }
  };
  double t = 0;
  fly(1, t);  // warm-up
  ASSERT_TRUE(p->waitIdle(30));
  const PagerMetrics warm = p->metrics();
  const long rssWarm = residentPages();
  fly(3, t);
  ASSERT_TRUE(p->waitIdle(30));
  const PagerMetrics end = p->metrics();
  const long rssEnd = residentPages();
  EXPECT_GT(end.loaded, warm.loaded + 500);
  EXPECT_EQ(end.poolBytes, warm.poolBytes) << "the pool never grows after warm-up";
  EXPECT_LE(end.poolBytes, o.memoryBudgetBytes);
  EXPECT_LE(double(rssEnd), 1.10 * double(rssWarm)) << rssWarm << " -> " << rssEnd << " pages";
  EXPECT_EQ(end.holesInWindow, 0u);
  EXPECT_EQ(end.budgetRefusals, 0u);
}

#if SANDTABLE_COUNT_ALLOCATIONS
void expectNoSteadyStateAllocations(const pack::PackLayout& layout) {
  const TestDb db = makeDb("alloc", 40, 40, kSquares, 3, layout);
  PagerOptions o = baseOptions();
  o.lookAheadScale = 2;
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  auto fly = [&](double t0, std::uint64_t& mainAllocs) {
    double t = t0;
    for (int lap = 0; lap < 2; ++lap) {
      for (int k = 0; k < 400; ++k) {  // east 20 km, back west, with strips every 1 km
        const double x = 10000 + (k < 200 ? k : 400 - k) * 100.0;
        const double vx = k < 200 ? 50 : -50;
        const std::uint64_t before = tAllocations;
        p->update(x, 20500 + (k % 2) * 150.0, vx, 0, t);
        for (std::uint32_t kx = 5; kx < 35; ++kx) (void)p->resident(kx, 20, 1);
        mainAllocs += tAllocations - before;
        t += 2;
        if (k % 5 == 0) {
          ASSERT_TRUE(p->waitIdle(30));
        }
      }
    }
  };
  std::uint64_t warmAllocs = 0, allocs = 0;
  // Each loader thread grows its own reusable buffers (thread_local) on its
  // first loads; under a loaded machine one loader can get little of the
  // first flight, so the warm-up flies the laps twice before counting.
  fly(0, warmAllocs);
  fly(2000, warmAllocs);
  ASSERT_TRUE(p->waitIdle(30));
  const std::uint64_t loaded0 = p->metrics().loaded, global0 = gAllocations.load();
  fly(4000, allocs);
  ASSERT_TRUE(p->waitIdle(30));
  EXPECT_EQ(allocs, 0u) << "update() and resident() on the main thread";
  const std::uint64_t loads = p->metrics().loaded - loaded0;
  ASSERT_GT(loads, 100u);
  // The loaders too: each reads into its own module and buffers
  // (PackReader::readInto), whose capacity the warm-up flight grew.
  EXPECT_EQ(gAllocations.load() - global0, 0u) << "allocations on any thread over " << loads << " loads";
}

TEST(Pager, nothingIsAllocatedInSteadyState) { expectNoSteadyStateAllocations({}); }

// Coarse-first with a v2 pack: two reads per module (the coarse record,
// then the fine one) and the capacity-swapping readers still allocate
// nothing once warm.
TEST(Pager, nothingIsAllocatedInSteadyStateCoarseFirst) { expectNoSteadyStateAllocations(pack::PackLayout::split(3)); }
#endif

/// A pack source that logs every coarse and fine read, in order, and holds
/// the first read until released (so a test can queue a whole refill first).
class LoggingSource final : public ModuleSource {
 public:
  explicit LoggingSource(std::shared_ptr<const pack::PackReader> p) : pack_(std::move(p)) {}
  const pack::IndexHeader& header() const override { return pack_.header(); }
  ModuleInfo info(std::uint32_t kx, std::uint32_t kz) const override { return pack_.info(kx, kz); }
  std::uint64_t generation(std::uint32_t, std::uint32_t) const override { return 0; }
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    note('w', kx, kz);
    return pack_.read(kx, kz, into);
  }
  std::uint32_t coarseLevel() const override { return pack_.coarseLevel(); }
  Result<std::uint64_t> readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    note('c', kx, kz);
    while (!released.load()) std::this_thread::yield();
    return pack_.readCoarse(kx, kz, into);
  }
  Status readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    note('f', kx, kz);
    return pack_.readFine(kx, kz, into);
  }
  void willNeed(std::span<const ModuleKey> keys, bool fine) const override {
    hinted.fetch_add(keys.size());
    pack_.willNeed(keys, fine);
  }
  bool missing(std::uint32_t kx, std::uint32_t kz) const override { return pack_.missing(kx, kz); }
  std::uint64_t changes() const override { return 0; }
  std::uint64_t changedSince(std::uint64_t since, std::vector<ModuleKey>&) const override { return since; }

  std::vector<std::tuple<char, std::uint32_t, std::uint32_t>> log() const {
    const std::lock_guard lock(mu_);
    return log_;
  }
  mutable std::atomic<bool> released{false};
  mutable std::atomic<std::uint64_t> hinted{0};

 private:
  void note(char what, std::uint32_t kx, std::uint32_t kz) const {
    const std::lock_guard lock(mu_);
    log_.emplace_back(what, kx, kz);
  }
  PackSource pack_;
  mutable std::mutex mu_;
  mutable std::vector<std::tuple<char, std::uint32_t, std::uint32_t>> log_;
};

// A refill from a v2 pack on one loader: every coarse record is read,
// nearest first, before any fine record, the fine ones follow nearest
// first, and in the end every module is resident at every level with the
// right vertices (tagged with its kx, kz). Readahead hints covered the
// refill. The loader's first read waits until update() has queued the
// whole refill, so the order does not depend on timing.
TEST(Pager, coarseFirstReadsEveryCoarseRecordBeforeAnyFineOne) {
  const TestDb db = makeDb("coarse-first", 20, 20, kSquares, 3, pack::PackLayout::split(3));
  ASSERT_EQ(db.pack->coarseLevel(), 1u);
  auto src = std::make_shared<LoggingSource>(db.pack);
  PagerOptions o = baseOptions();
  o.loaderThreads = 1;
  o.workStealing = false;
  auto opened = Pager::open(db.grid, src, o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  // preallocate read the median module whole ('w'): left out below.
  const std::size_t skip = src->log().size();
  const double x = 10500, z = 10500;
  p.update(x, z, 0, 0, 0);
  src->released.store(true);
  ASSERT_TRUE(p.waitIdle(30));
  const auto all = src->log();
  const std::vector<std::tuple<char, std::uint32_t, std::uint32_t>> log(all.begin() + std::ptrdiff_t(skip), all.end());
  const std::size_t n = std::size_t(p.window().count());
  ASSERT_EQ(n, 81u);  // R = 4 at 3 km
  ASSERT_EQ(log.size(), 2 * n);
  auto dist = [&](std::uint32_t kx, std::uint32_t kz) {
    return std::hypot((kx + 0.5) * kEdge - x, (kz + 0.5) * kEdge - z);
  };
  std::set<std::pair<std::uint32_t, std::uint32_t>> coarse, fine;
  for (std::size_t i = 0; i < log.size(); ++i) {
    const auto [what, kx, kz] = log[i];
    EXPECT_EQ(what, i < n ? 'c' : 'f') << "read " << i;
    (i < n ? coarse : fine).insert({kx, kz});
    if (i > 0 && i != n) {
      const auto [w0, px, pz] = log[i - 1];
      EXPECT_LE(dist(px, pz), dist(kx, kz) + 1e-9) << "read " << i << " is not nearest first";
    }
  }
  EXPECT_EQ(coarse.size(), n);
  EXPECT_EQ(coarse, fine);
  for (const auto& [kx, kz] : coarse) {
    const ResidentRef r = p.resident(kx, kz, 0);
    ASSERT_TRUE(r) << kx << "," << kz;
    EXPECT_EQ(r.finestLevel(), 0u);
    for (std::uint32_t l = 0; l < 3; ++l) {
      ASSERT_FALSE(r.level(l).vertices.empty());
      EXPECT_EQ(r.level(l).vertices.front().s, float(kx));
      EXPECT_EQ(r.level(l).vertices.back().t, float(kz));
      EXPECT_EQ(r.level(l).squaresX, kSquares >> l);  // each level at its own number
    }
  }
  const PagerMetrics m = p.metrics();
  EXPECT_EQ(m.loaded, n);
  EXPECT_EQ(m.fineLoaded, n);
  EXPECT_EQ(m.fineFailed, 0u);
  std::uint64_t bytes = 0;
  for (const auto& [kx, kz] : coarse) bytes += db.pack->entry(kx, kz).storedBytes();
  EXPECT_EQ(m.bytesRead, bytes);
  EXPECT_GE(m.readaheadHints, 1u);
  EXPECT_EQ(src->hinted.load(), n);
}

// PagerOptions::prepareLevel runs on the loader for every level it
// publishes, coarsest first, before readers can see the level: each
// prepared level a reader finds was made from that module's own level, and
// the call for level 0 comes with every level written. Without a hook
// nothing is prepared.
TEST(Pager, everyPublishedLevelIsPreparedFirstCoarsestFirst) {
  const TestDb db = makeDb("prepare-hook", 20, 20, kSquares, 3, pack::PackLayout::split(3));
  struct Tag final : LevelExtra {
    std::uint32_t kx = 0, kz = 0, level = 0;
    float s = -1;  ///< the level's first vertex's s when prepared (makeDb tags it kx)
  };
  std::mutex mutex;
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<std::uint32_t>> calls;
  std::atomic<std::uint32_t> wholeAtLevel0{0}, notWhole{0};
  PagerOptions o = baseOptions();
  o.loaderThreads = 2;
  o.prepareLevel = [&](ResidentModule& m, std::uint32_t level) {
    ASSERT_EQ(m.prepared.size(), m.levels.size());
    auto tag = std::make_unique<Tag>();
    tag->kx = m.kx, tag->kz = m.kz, tag->level = level;
    if (!m.levels[level].vertices.empty()) tag->s = m.levels[level].vertices.front().s;
    m.prepared[level] = std::move(tag);
    if (level == 0 && !m.placeholder) {
      bool whole = true;
      for (const module::Level& l : m.levels) whole = whole && !l.vertices.empty() && l.vertices.front().s == float(m.kx);
      (whole ? wholeAtLevel0 : notWhole).fetch_add(1);
    }
    const std::lock_guard lock(mutex);
    calls[{m.kx, m.kz}].push_back(level);
  };
  auto opened = Pager::open(db.grid, db.pack, o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  p.update(10500, 10500, 0, 0, 0);
  ASSERT_TRUE(p.waitIdle(30));
  const std::size_t n = std::size_t(p.window().count());
  ASSERT_EQ(calls.size(), n);
  for (const auto& [key, levels] : calls) {
    EXPECT_EQ(levels, (std::vector<std::uint32_t>{2, 1, 0})) << key.first << "," << key.second;
    const ResidentRef r = p.resident(key.first, key.second, 0);
    ASSERT_TRUE(r);
    ASSERT_EQ(r.finestLevel(), 0u);
    for (std::uint32_t l = 0; l < 3; ++l) {
      const auto* tag = dynamic_cast<const Tag*>(r.module().prepared[l].get());
      ASSERT_NE(tag, nullptr);
      EXPECT_EQ(tag->kx, key.first);
      EXPECT_EQ(tag->kz, key.second);
      EXPECT_EQ(tag->level, l);
      EXPECT_EQ(tag->s, float(key.first));
    }
  }
  EXPECT_EQ(wholeAtLevel0.load(), n);
  EXPECT_EQ(notWhole.load(), 0u);
  p.stop();

  auto plain = Pager::open(db.grid, db.pack, baseOptions());
  ASSERT_TRUE(plain.ok()) << plain.error();
  plain.value()->update(10500, 10500, 0, 0, 0);
  ASSERT_TRUE(plain.value()->waitIdle(30));
  const ResidentRef r = plain.value()->resident(10, 10, 0);
  ASSERT_TRUE(r);
  EXPECT_TRUE(r.module().prepared.empty());
}

// The same pack with coarseFirst off reads each module whole, once.
TEST(Pager, coarseFirstOffReadsWholeModules) {
  const TestDb db = makeDb("coarse-off", 20, 20, kSquares, 3, pack::PackLayout::split(3));
  auto src = std::make_shared<LoggingSource>(db.pack);
  src->released.store(true);
  PagerOptions o = baseOptions();
  o.coarseFirst = false;
  auto opened = Pager::open(db.grid, src, o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  p.update(10500, 10500, 0, 0, 0);
  ASSERT_TRUE(p.waitIdle(30));
  for (const auto& [what, kx, kz] : src->log()) EXPECT_EQ(what, 'w') << kx << "," << kz;
  EXPECT_EQ(p.metrics().fineLoaded, 0u);
  const ResidentRef r = p.resident(10, 10, 0);
  ASSERT_TRUE(r);
  EXPECT_EQ(r.finestLevel(), 0u);
}

// A damaged fine record: the module stays drawn at its coarse levels, the
// failure is counted and logged, and nothing is a hole.
TEST(Pager, aCorruptFineRecordLeavesTheCoarseLevels) {
  const TestDb db = makeDb("fine-bad", 20, 20, kSquares, 3, pack::PackLayout::split(3));
  const pack::Entry e = db.pack->entry(10, 10);
  auto bytes = readAll(db.dir + "/modules.pack");
  bytes[e.fine.offset + e.fine.compressedBytes / 2] ^= std::byte{0x5a};
  writeAll(db.dir + "/modules.pack", bytes);
  auto pr = pack::PackReader::open(db.dir);
  ASSERT_TRUE(pr.ok()) << pr.error();
  std::vector<std::string> logged;
  std::mutex mu;
  PagerOptions o = baseOptions();
  o.log = [&](const std::string& m) {
    const std::lock_guard lock(mu);
    logged.push_back(m);
  };
  auto opened = Pager::open(db.grid, pr.value(), o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  p.update(10500, 10500, 0, 0, 0);
  ASSERT_TRUE(p.waitIdle(30));
  const ResidentRef r = p.resident(10, 10, 0);
  ASSERT_TRUE(r);
  EXPECT_EQ(r.finestLevel(), 1u);
  EXPECT_TRUE(r.coarser());
  EXPECT_FALSE(r.placeholder());
  EXPECT_EQ(p.metrics().fineFailed, 1u);
  EXPECT_EQ(p.metrics().holesInWindow, 0u);
  const std::lock_guard lock(mu);
  ASSERT_EQ(logged.size(), 1u);
  EXPECT_NE(logged[0].find("fine module (10,10) record checksum mismatch"), std::string::npos) << logged[0];
  EXPECT_NE(logged[0].find("the coarse levels stay drawn"), std::string::npos) << logged[0];
}

TEST(Pager, windowFollowsTheViewDistanceBothWays) {
  TestDb db = makeDb("grow", 40, 40);
  PagerOptions o = baseOptions();
  o.viewDistance = 3000;
  o.maxViewDistance = 6000;
  o.simulatedReadSeconds = 0.002;  // so the new ring is still coming in right after the update
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  const double x = 20500, z = 20500;
  p->update(x, z, 0, 0, 0);
  ASSERT_TRUE(p->waitIdle(30));
  // R = ceil((vd + 100 m) / 1 km): 4 at 3 km, 7 at 6 km.
  EXPECT_EQ(p->window().count(), 9 * 9);
  EXPECT_DOUBLE_EQ(p->residentDistance(x, z), 3000);

  EXPECT_DOUBLE_EQ(p->setViewDistance(9000), 6000);  // clamped to the most
  p->update(x, z, 0, 0, 0.1);
  EXPECT_EQ(p->window().count(), 15 * 15);
  // The new ring starts 3.5 km out (module edges at 20 +- 3.5 km): nothing
  // nearer is missing, and something of the ring is, for now.
  const double covered = p->residentDistance(x, z);
  EXPECT_GE(covered, 3500);
  EXPECT_LT(covered, 6000);
  ASSERT_TRUE(p->waitIdle(30));
  EXPECT_DOUBLE_EQ(p->residentDistance(x, z), 6000);
  PagerMetrics m = p->metrics();
  EXPECT_EQ(m.holesInWindow, 0u);
  EXPECT_EQ(m.loaded, 15u * 15u);

  EXPECT_DOUBLE_EQ(p->setViewDistance(2000), 2000);
  p->update(x, z, 0, 0, 0.2);
  ASSERT_TRUE(p->waitIdle(30));
  EXPECT_EQ(p->window().count(), 7 * 7);
  m = p->metrics();
  EXPECT_EQ(m.freed, 15u * 15u - 7u * 7u);
  EXPECT_FALSE(p->resident(13, 13, 0));  // the old outer ring is gone
  EXPECT_TRUE(p->resident(17, 17, 0));
}

TEST(Pager, maxViewDistanceBelowTheViewDistanceIsRefused) {
  TestDb db = makeDb("maxvd", 10, 10);
  PagerOptions o = baseOptions();
  o.maxViewDistance = 1000;
  auto p = Pager::open(db.grid, db.pack, o);
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.error().find("maxViewDistance"), std::string::npos) << p.error();
}

TEST(Pager, corruptAndMissingModulesBecomeCoarsePlaceholdersThatFollowTheGrid) {
  TestDb db = makeDb("damage", 40, 40);
  corruptRecord(db, 20, 20);
  dropEntry(db, 21, 20);
  PagerOptions o = baseOptions();
  std::mutex mu;
  std::vector<std::string> logged;
  o.log = [&](const std::string& s) {
    const std::lock_guard lock(mu);
    logged.push_back(s);
  };
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  p->update(20500, 20500, 0, 0, 0);
  ASSERT_TRUE(p->waitIdle(30));
  PagerMetrics m = p->metrics();
  EXPECT_EQ(m.corruptModules, 1u);
  EXPECT_EQ(m.missingModules, 1u);
  EXPECT_EQ(m.placeholders, 2u);
  EXPECT_EQ(m.holesInWindow, 0u);  // placeholders are resident
  EXPECT_EQ(m.loaded, 79u);
  {
    const ResidentRef r = p->resident(20, 20, 0);
    ASSERT_TRUE(r);
    EXPECT_TRUE(r.placeholder());
    EXPECT_EQ(r.finestLevel(), 2u);
    EXPECT_TRUE(r.coarser());
    const module::Level& l = r.level();
    EXPECT_EQ(l.squaresX, 2u);  // the coarse lattice: 8 squares / 4
    // The coarse lattice carries the grid's own heights (a flat stand-in
    // drew as a plain with walls round it); skirt vertices hang below.
    const double sp = l.spacing / 4;  // grid posts every 4 at the coarsest of 3 levels
    std::uint32_t onLattice = 0;
    for (const module::Vertex& v : l.vertices) {
      const auto i = std::uint32_t(20 * 8 + std::lround(v.x / sp));
      const auto j = std::uint32_t(20 * 8 + std::lround(v.z / sp));
      const float y = gridElevation(i, j);
      EXPECT_TRUE(v.y == y || v.y < y - 0.5f) << v.x << " " << v.z << " " << v.y << " vs " << y;
      onLattice += v.y == y;
    }
    EXPECT_GE(onLattice, 9u);  // the 3 x 3 posts of 2 x 2 squares
    // The square's highest post: its south-east corner on this sloping grid.
    EXPECT_EQ(l.maxHeight, (std::vector<float>{gridElevation(164, 164), gridElevation(168, 164),
                                               gridElevation(164, 168), gridElevation(168, 168)}));
    EXPECT_GT(l.groups.size(), 8u);  // upper, lower and skirts
  }
  {
    const std::lock_guard lock(mu);
    ASSERT_EQ(logged.size(), 2u);
    const std::string both = logged[0] + "\n" + logged[1];
    EXPECT_NE(both.find("record checksum mismatch"), std::string::npos) << both;
    EXPECT_NE(both.find("module (21, 20) is missing"), std::string::npos) << both;
  }
  // Away and back: placeholders again, no second log, no second read.
  const std::uint64_t bytes = m.bytesRead;
  p->update(35500, 35500, 0, 0, 1);
  ASSERT_TRUE(p->waitIdle(30));
  const std::uint64_t bytesAway = p->metrics().bytesRead;
  p->update(20500, 20500, 0, 0, 2);
  ASSERT_TRUE(p->waitIdle(30));
  m = p->metrics();
  EXPECT_EQ(m.placeholders, 4u);
  EXPECT_EQ(m.corruptModules, 1u);
  EXPECT_EQ(m.missingModules, 1u);
  EXPECT_GT(bytesAway, bytes);
  // Home again: the 79 sound modules are read, the known-bad ones are not.
  EXPECT_EQ(m.bytesRead - bytesAway, bytes - db.pack->entry(20, 20).compressedBytes);
  const std::lock_guard lock(mu);
  EXPECT_EQ(logged.size(), 2u);
}

TEST(Pager, aTruncatedPackGivesMissingModules) {
  TestDb db = makeDb("truncated", 20, 20);
  // The last record added is (19, 19); cut the pack in its middle.
  const pack::Entry e = db.pack->entry(19, 19);
  fs::resize_file(db.dir + "/" + pack::kPackFileName, e.offset + e.compressedBytes / 2);
  PagerOptions o = baseOptions();
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  p->update(19500, 19500, 0, 0, 0);
  ASSERT_TRUE(p->waitIdle(30));
  const PagerMetrics m = p->metrics();
  EXPECT_EQ(m.missingModules, 1u);
  EXPECT_EQ(m.corruptModules, 0u);
  const ResidentRef r = p->resident(19, 19);
  ASSERT_TRUE(r);
  EXPECT_TRUE(r.placeholder());
}

TEST(Pager, theBudgetIsNeverExceeded) {
  const TestDb db = makeDb("budget", 40, 40);
  PagerOptions o = baseOptions();
  o.preallocate = false;
  o.memoryBudgetBytes = 1000;
  auto tooSmall = Pager::open(db.grid, db.pack, o);
  ASSERT_FALSE(tooSmall.ok());
  EXPECT_NE(tooSmall.error().find("pager: the placeholders of 225 slots need"), std::string::npos)
      << tooSmall.error();
  // Room for the placeholders (measured) and about 30 full modules.
  std::uint64_t placeholderBytes = 0;
  {
    PagerOptions big = o;
    big.memoryBudgetBytes = 1ull << 30;
    placeholderBytes = openPager(db, big)->metrics().poolBytes;
  }
  o.memoryBudgetBytes = placeholderBytes + 30 * 6000;
  std::atomic<int> budgetLogs{0};
  o.log = [&](const std::string& s) {
    if (s.find("memory budget") != std::string::npos) ++budgetLogs;
  };
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  p->update(20500, 20500, 0, 0, 0);
  ASSERT_TRUE(p->waitIdle(30));
  const PagerMetrics m = p->metrics();
  EXPECT_LE(m.poolBytes, o.memoryBudgetBytes);
  EXPECT_GT(m.budgetRefusals + m.budgetTrimmedLevels, 0u);
  EXPECT_EQ(m.holesInWindow, 0u);  // refused modules show as placeholders
  EXPECT_EQ(budgetLogs.load(), 1);
}

TEST(Pager, demandModeLoadsOnlyWhatIsAskedFor) {
  const TestDb db = makeDb("demand", 40, 40);
  PagerOptions o = baseOptions();
  o.mode = PagerMode::demand;
  o.loaderThreads = 1;
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  p->update(20500, 20500, 0, 0, 0);
  ASSERT_TRUE(p->waitIdle(30));
  EXPECT_EQ(p->metrics().loaded, 0u);
  EXPECT_FALSE(p->resident(20, 20));  // a fault
  EXPECT_FALSE(p->resident(21, 20));
  ASSERT_TRUE(p->waitIdle(30));
  EXPECT_TRUE(p->resident(20, 20));
  EXPECT_TRUE(p->resident(21, 20));
  // Outside the window: the fault is dropped.
  EXPECT_FALSE(p->resident(2, 2));
  ASSERT_TRUE(p->waitIdle(30));
  EXPECT_FALSE(p->resident(2, 2));
  const PagerMetrics m = p->metrics();
  EXPECT_EQ(m.loaded, 2u);
  EXPECT_EQ(m.demandFaults, 4u);  // (2, 2) faulted twice
  EXPECT_EQ(m.latency.count, 2u);
  // Moving pages nothing in demand mode.
  p->update(25500, 20500, 100, 0, 10);
  ASSERT_TRUE(p->waitIdle(30));
  EXPECT_EQ(p->metrics().loaded, 2u);
}

TEST(Pager, mmapModeTouchesTheGridAndSleepsLongerWhenSlow) {
  const TestDb db = makeDb("mmap", 40, 40);
  PagerOptions o = baseOptions();
  o.mode = PagerMode::mmap;
  o.lookAheadScale = 2;
  auto opened = Pager::open(db.grid, nullptr, o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  auto waitPasses = [&](std::uint64_t n) {
    for (int i = 0; i < 4000 && p.metrics().prefetchPasses < n; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return p.metrics().prefetchPasses >= n;
  };
  p.update(20500, 20500, 20000, 0, 0);  // fast: 8 km blocks pass in 0.4 s
  ASSERT_TRUE(waitPasses(2));
  const PagerMetrics fast = p.metrics();
  EXPECT_GT(fast.prefetchBlocks, 0u);
  EXPECT_EQ(fast.prefetchPages, fast.prefetchBlocks * 11);
  p.update(20500, 20500, 10, 0, 1);  // slow
  ASSERT_TRUE(waitPasses(fast.prefetchPasses + 2));
  const PagerMetrics slow = p.metrics();
  EXPECT_LT(fast.lastSleepSeconds, slow.lastSleepSeconds);
  EXPECT_EQ(slow.lastSleepSeconds, o.maxSleepSeconds);
  EXPECT_FALSE(p.resident(20, 20));  // no modules in mmap mode
}

TEST(Pager, badOptionsAndMissingPackAreRefused) {
  const TestDb db = makeDb("options", 10, 10);
  PagerOptions o = baseOptions();
  o.hysteresis = 600;
  auto a = Pager::open(db.grid, db.pack, o);
  ASSERT_FALSE(a.ok());
  EXPECT_EQ(a.problems().front().message,
            "pager options: hysteresis must be >= 0 and below half a module (500 m)");
  o = baseOptions();
  o.loaderThreads = 0;
  EXPECT_FALSE(Pager::open(db.grid, db.pack, o).ok());
  auto b = Pager::open(db.grid, nullptr, baseOptions());
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.error().find("pager: the database has no load modules"), std::string::npos);
}

/// A reader thread checks every module it gets against its key (each vertex
/// carries kx, kz) while the main thread flies a fast random walk with
/// jumps: a reused or half-written buffer would show as a wrong key (and
/// as a data race under ThreadSanitizer).
void hammer(const TestDb& db, int ticks, double simulatedRead) {
  PagerOptions o = baseOptions();
  o.lookAheadScale = 2;
  o.simulatedReadSeconds = simulatedRead;
  o.initialLatencySeconds = 0.01;
  auto p = openPager(db, o);
  ASSERT_TRUE(p);
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> hits{0}, bad{0};
  std::atomic<double> eyeX{20500}, eyeZ{20500};
  auto reader = [&](unsigned seed) {
    std::mt19937 rng(seed);
    while (!done.load(std::memory_order_relaxed)) {
      const auto cx = std::int64_t(eyeX.load(std::memory_order_relaxed) / 1000);
      const auto cz = std::int64_t(eyeZ.load(std::memory_order_relaxed) / 1000);
      const std::int64_t kx = std::clamp<std::int64_t>(cx + std::int64_t(rng() % 11) - 5, 0, 39);
      const std::int64_t kz = std::clamp<std::int64_t>(cz + std::int64_t(rng() % 11) - 5, 0, 39);
      const ResidentRef r = p->resident(std::uint32_t(kx), std::uint32_t(kz), std::uint32_t(rng() % 3));
      if (!r) continue;
      hits.fetch_add(1, std::memory_order_relaxed);
      bool ok = r.module().kx == kx && r.module().kz == kz && !r.placeholder();
      for (std::uint32_t l = r.finestLevel(); l < 3 && ok; ++l) {
        const module::Level& lv = r.level(l);
        ok = lv.squaresX == (8u >> l) && !lv.vertices.empty();
        for (const module::Vertex& v : lv.vertices) ok = ok && v.s == float(kx) && v.t == float(kz);
      }
      if (!ok) bad.fetch_add(1, std::memory_order_relaxed);
    }
  };
  std::thread r1(reader, 1u), r2(reader, 2u);
  std::mt19937 rng(7);
  double x = 20500, z = 20500, vx = 0, vz = 0, t = 0;
  for (int i = 0; i < ticks; ++i) {
    if (rng() % 200 == 0) {  // a jump
      x = 3000 + double(rng() % 34000);
      z = 3000 + double(rng() % 34000);
    } else {
      vx = std::clamp(vx + (double(rng() % 201) - 100) * 4, -800.0, 800.0);
      vz = std::clamp(vz + (double(rng() % 201) - 100) * 4, -800.0, 800.0);
      x = std::clamp(x + vx * 0.1, 0.0, 39999.0);
      z = std::clamp(z + vz * 0.1, 0.0, 39999.0);
    }
    t += 0.1;
    eyeX.store(x, std::memory_order_relaxed);
    eyeZ.store(z, std::memory_order_relaxed);
    p->update(x, z, vx, vz, t);
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  ASSERT_TRUE(p->waitIdle(60));
  done = true;
  r1.join();
  r2.join();
  const PagerMetrics m = p->metrics();
  EXPECT_EQ(bad.load(), 0u);
  EXPECT_GT(hits.load(), 1000u);
  EXPECT_EQ(m.holesInWindow, 0u);
  EXPECT_LE(m.poolBytes, o.memoryBudgetBytes);
  p->stop();
}

TEST(Pager, lockFreeReadersSeeWholeModulesWhileTheViewerMoves) {
  const TestDb db = makeDb("readers", 40, 40);
  hammer(db, 1500, 0);
}

TEST(PagerStress, fastRandomWalkWithSlowReads) {
  const TestDb db = makeDb("stress", 40, 40);
  hammer(db, 3000, 0.0005);
}

// ------------------------------------------------------- module sources

/// An in-memory source over makeModule's modules in which a module's
/// generation can be bumped: generation g lifts every vertex by 100 km * g,
/// so a reader can tell the generations apart (and a torn copy) from y.
class GenerationSource final : public ModuleSource {
 public:
  explicit GenerationSource(const pack::IndexHeader& h)
      : header_(h), generations_(std::size_t(h.modulesX) * h.modulesZ) {}
  const pack::IndexHeader& header() const override { return header_; }
  ModuleInfo info(std::uint32_t, std::uint32_t) const override { return {1000, 1000, 0}; }
  std::uint64_t generation(std::uint32_t kx, std::uint32_t kz) const override {
    return generations_[index(kx, kz)].load();
  }
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override {
    const std::uint64_t g = generation(kx, kz);
    if (held_.load() == index(kx, kz) + 1) {
      // The held module's read waits until the test has seen what it
      // wanted meanwhile (no sleep: as long as the test needs, no longer).
      entered_.store(true);
      while (held_.load() == index(kx, kz) + 1) std::this_thread::yield();
    }
    into = makeModule(kx, kz, header_.moduleSquares, header_.levels);
    for (module::Level& l : into.levels) {
      for (module::Vertex& v : l.vertices) v.y += float(100000.0 * double(g));
      for (float& y : l.maxHeight) y += float(100000.0 * double(g));
    }
    return g;
  }
  bool missing(std::uint32_t, std::uint32_t) const override { return false; }
  std::uint64_t changes() const override { return changes_.load(); }
  std::uint64_t changedSince(std::uint64_t since, std::vector<ModuleKey>& out) const override {
    const std::lock_guard lock(mu_);
    out.insert(out.end(), log_.begin() + std::ptrdiff_t(since), log_.end());
    return log_.size();
  }

  /// A newer generation of module (kx, kz); with `hold`, its reads wait
  /// (entered() turns true) until release().
  void bump(std::uint32_t kx, std::uint32_t kz, bool hold) {
    entered_.store(false);
    held_.store(hold ? index(kx, kz) + 1 : 0);
    generations_[index(kx, kz)].fetch_add(1);
    const std::lock_guard lock(mu_);
    log_.push_back({kx, kz});
    changes_.store(log_.size());
  }
  bool entered() const { return entered_.load(); }
  void release() { held_.store(0); }

 private:
  std::size_t index(std::uint32_t kx, std::uint32_t kz) const { return std::size_t(kz) * header_.modulesX + kx; }
  pack::IndexHeader header_;
  std::vector<std::atomic<std::uint64_t>> generations_;
  std::atomic<std::size_t> held_{0};
  mutable std::atomic<bool> entered_{false};
  mutable std::mutex mu_;
  std::vector<ModuleKey> log_;
  std::atomic<std::uint64_t> changes_{0};
};

/// y of every vertex of makeModule(kx, kz) at source generation g.
float generationY(std::uint32_t kx, std::uint32_t kz, std::uint64_t g) {
  return float(1000.0 * kx + kz) + float(100000.0 * double(g));
}

TEST(Pager, aNewerGenerationReplacesTheResidentModuleWithNoHoleMeanwhile) {
  const TestDb db = makeDb("generations", 10, 10);
  const auto source = std::make_shared<GenerationSource>(db.pack->header());
  auto opened = Pager::open(db.grid, std::shared_ptr<const ModuleSource>(source), baseOptions());
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  p.update(5500, 5500, 0, 0, 0);
  ASSERT_TRUE(p.waitIdle(30));
  std::uint64_t slotGeneration = 0;
  {
    const ResidentRef r = p.resident(5, 5);
    ASSERT_TRUE(r);
    EXPECT_EQ(r.module().generation, 0u);
    EXPECT_EQ(r.level(0).vertices[0].y, generationY(5, 5, 0));
    slotGeneration = r.generation();
  }
  // A reader draws module (5, 5) all along: it must never miss it, and
  // every guard it takes must show one whole generation.
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> holes{0}, torn{0}, seenOld{0}, seenNew{0};
  std::thread reader([&] {
    while (!done.load()) {
      const ResidentRef r = p.resident(5, 5, 0);
      if (!r) {
        ++holes;
        continue;
      }
      const std::uint64_t g = r.module().generation;
      for (std::uint32_t l = r.finestLevel(); l < p.levels(); ++l) {
        for (const module::Vertex& v : r.level(l).vertices) {
          if (v.y != generationY(5, 5, g)) ++torn;
        }
      }
      ++(g == 0 ? seenOld : seenNew);
    }
  });
  while (seenOld.load() == 0 && holes.load() == 0) std::this_thread::yield();
  source->bump(5, 5, true);  // its read waits until released
  p.update(5500, 5500, 0, 0, 1);
  while (!source->entered()) std::this_thread::yield();
  // While the newer generation is being read, the older one is still drawn.
  const std::uint64_t oldAtRead = seenOld.load();
  while (seenOld.load() < oldAtRead + 2 && holes.load() == 0 && torn.load() == 0) std::this_thread::yield();
  source->release();
  ASSERT_TRUE(p.waitIdle(30));
  const std::uint64_t oldBeforeNew = seenOld.load();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (seenNew.load() == 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
  done.store(true);
  reader.join();
  EXPECT_EQ(holes.load(), 0u);
  EXPECT_EQ(torn.load(), 0u);
  EXPECT_GT(oldBeforeNew, 1u);  // the older generation was drawn during the slow read
  EXPECT_GT(seenNew.load(), 0u);
  {
    const ResidentRef r = p.resident(5, 5);
    ASSERT_TRUE(r);
    EXPECT_EQ(r.module().generation, 1u);
    EXPECT_EQ(r.level(0).vertices[0].y, generationY(5, 5, 1));
    EXPECT_EQ(r.finestLevel(), 0u);
    EXPECT_NE(r.generation(), slotGeneration);  // the GPU cache's key moved on
  }
  PagerMetrics m = p.metrics();
  EXPECT_EQ(m.reloaded, 1u);
  EXPECT_EQ(m.placeholders, 0u);
  EXPECT_EQ(m.holesInWindow, 0u);
  // A change outside the window reloads nothing now; the module comes in
  // at its newest generation when the window reaches it.
  source->bump(0, 0, false);
  p.update(5500, 5500, 0, 0, 2);
  ASSERT_TRUE(p.waitIdle(30));
  EXPECT_EQ(p.metrics().reloaded, 1u);
  p.update(500, 500, 0, 0, 3);
  ASSERT_TRUE(p.waitIdle(30));
  const ResidentRef r = p.resident(0, 0);
  ASSERT_TRUE(r);
  EXPECT_EQ(r.module().generation, 1u);
  EXPECT_EQ(r.level(0).vertices[0].y, generationY(0, 0, 1));
  // Twice more for the same module: each generation replaces the last
  // (the reload alternates between the slot's two buffers).
  for (std::uint64_t g = 2; g <= 3; ++g) {
    source->bump(1, 1, false);
    p.update(500, 500, 0, 0, double(g + 2));
    ASSERT_TRUE(p.waitIdle(30));
    const ResidentRef q = p.resident(1, 1);
    ASSERT_TRUE(q);
    EXPECT_EQ(q.module().generation, g - 1);
    EXPECT_EQ(q.level(0).vertices[0].y, generationY(1, 1, g - 1));
  }
}

TEST(Pager, demandModeReloadsAChangedModuleToo) {
  const TestDb db = makeDb("generations-demand", 10, 10);
  const auto source = std::make_shared<GenerationSource>(db.pack->header());
  PagerOptions o = baseOptions();
  o.mode = PagerMode::demand;
  auto opened = Pager::open(db.grid, std::shared_ptr<const ModuleSource>(source), o);
  ASSERT_TRUE(opened.ok()) << opened.error();
  Pager& p = *opened.value();
  p.update(5500, 5500, 0, 0, 0);
  EXPECT_FALSE(p.resident(5, 5));  // the fault
  ASSERT_TRUE(p.waitIdle(30));
  ASSERT_TRUE(p.resident(5, 5));
  source->bump(5, 5, false);
  p.update(5500, 5500, 0, 0, 1);
  ASSERT_TRUE(p.waitIdle(30));
  const ResidentRef r = p.resident(5, 5);
  ASSERT_TRUE(r);
  EXPECT_EQ(r.module().generation, 1u);
  EXPECT_EQ(r.level(0).vertices[0].y, generationY(5, 5, 1));
  EXPECT_EQ(p.metrics().reloaded, 1u);
}

TEST(Pager, thePackIsASourceOfOneGeneration) {
  const TestDb db = makeDb("packsource", 4, 4);
  const PackSource src(db.pack);
  EXPECT_EQ(src.generation(1, 2), 0u);
  EXPECT_EQ(src.changes(), 0u);
  EXPECT_EQ(src.info(1, 2).storedBytes, db.pack->entry(1, 2).compressedBytes);
  module::Module m;
  const Result<std::uint64_t> r = src.read(1, 2, m);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value(), 0u);
  EXPECT_EQ(m.levels[0].vertices[0].y, generationY(1, 2, 0));
  EXPECT_FALSE(src.missing(1, 2));
}

}  // namespace
}  // namespace sandtable::paging
