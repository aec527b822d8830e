// sandtable_microbench: the weighted resampling kernel, grid reads, the
// geometric module check at several module sizes (with its complexity fit)
// decaling per level, per call, and module decode / read of a built
// database. Run: build/bench/sandtable_microbench (--benchmark_filter=
// ModuleCheck, =Decal; SANDTABLE_BENCH_DB=db --benchmark_filter=Module(Decode|ReadInto)).
// Timings live here, not in unit tests.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/culture.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/modules.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/materials.h"
#include "sandtable/formats/module_check.h"
#include "sandtable/formats/pack.h"

namespace {

namespace fs = std::filesystem;
using namespace sandtable;

/// Source posts on a jittered square lattice around the target, 30 m
/// apart, on a sloping plane with noise: what the kernel sees per post.
struct Neighbourhood {
  std::vector<double> dx, dy, z;
  double radius = 0;

  explicit Neighbourhood(std::size_t points) {
    const int side = static_cast<int>(std::lround(std::sqrt(static_cast<double>(points))));
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> jitter(-3.0, 3.0), noise(-2.0, 2.0);
    constexpr double kStep = 30.0;
    for (int j = 0; j < side; ++j) {
      for (int i = 0; i < side; ++i) {
        dx.push_back((i - (side - 1) / 2.0) * kStep + jitter(rng));
        dy.push_back((j - (side - 1) / 2.0) * kStep + jitter(rng));
        z.push_back(100.0 + 0.3 * dx.back() - 0.2 * dy.back() + noise(rng));
      }
    }
    radius = kStep * side;  // every post inside, so all of them are summed
  }
};

void BM_WeightedPlaneEstimate(benchmark::State& state) {
  Neighbourhood n(static_cast<std::size_t>(state.range(0)));
  for (auto _ : state) {
    double v = convert::weightedPlaneEstimate(n.dx.data(), n.dy.data(), n.z.data(), n.z.size(), n.radius);
    benchmark::DoNotOptimize(v);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_WeightedPlaneEstimate)->ArgName("points")->Arg(9)->Arg(16)->Arg(25);

/// A 1024 x 1024 post grid (16 x 16 blocks, 11 MB) written once to a temp
/// file and memory-mapped; removed at exit.
class SmallGrid {
 public:
  static constexpr std::uint32_t kPosts = 1024;

  static const SmallGrid& get() {
    static const SmallGrid g;
    return g;
  }
  ~SmallGrid() {
    file.reset();
    std::error_code ec;
    fs::remove(path_, ec);
  }
  std::shared_ptr<const grid::GridFile> file;
  std::string error;

 private:
  SmallGrid() : path_(fs::temp_directory_path() / ("sandtable-microbench-" + std::to_string(::getpid()) + ".stg")) {
    const grid::Header h = grid::makeHeader(kPosts, kPosts, 30.0, 500000.0, 4700000.0);
    auto writer = grid::GridWriter::create(path_.string(), h);
    if (!writer) {
      error = writer.error();
      return;
    }
    auto block = std::make_unique<grid::BlockData>();
    for (std::uint32_t bz = 0; bz < h.blocksZ && error.empty(); ++bz) {
      for (std::uint32_t bx = 0; bx < h.blocksX && error.empty(); ++bx) {
        fillBlock(bx, bz, *block);
        error = writer.value()->writeBlock(bx, bz, *block).message();
      }
    }
    if (error.empty()) error = writer.value()->finish().message();
    if (!error.empty()) return;
    auto opened = grid::GridFile::open(path_.string());
    if (opened) file = opened.value();
    else error = opened.error();
  }

  static void fillBlock(std::uint32_t bx, std::uint32_t bz, grid::BlockData& b) {
    for (std::uint32_t k = 0; k < grid::kPostsPerBlock; ++k) {
      const double i = bx * grid::kBlockPosts + k % grid::kBlockPosts;
      const double j = bz * grid::kBlockPosts + k / grid::kBlockPosts;
      b.elevation[k] = static_cast<float>(500.0 + 200.0 * std::sin(i * 0.01) * std::cos(j * 0.013));
      b.normalX[k] = 0;
      b.normalY[k] = grid::toSnorm(1.0f);
      b.normalZ[k] = 0;
      b.material[k] = 0;
    }
  }

  fs::path path_;
};

/// Random posts: the viewer's ground-clamp and sample queries, cache-cold-ish.
void BM_GridElevationRandom(benchmark::State& state) {
  const SmallGrid& g = SmallGrid::get();
  if (!g.file) {
    state.SkipWithError(g.error.c_str());
    return;
  }
  constexpr std::size_t kCount = 4096;  // power of two: the index wraps with a mask
  std::mt19937 rng(2);
  std::uniform_int_distribution<std::uint32_t> post(0, SmallGrid::kPosts - 1);
  std::vector<std::uint32_t> is(kCount), js(kCount);
  for (std::size_t k = 0; k < kCount; ++k) is[k] = post(rng), js[k] = post(rng);
  std::size_t k = 0;
  for (auto _ : state) {
    float v = g.file->elevation(is[k], js[k]);
    benchmark::DoNotOptimize(v);
    k = (k + 1) & (kCount - 1);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_GridElevationRandom);

/// Along a row: the best case, for comparison with the random reads.
void BM_GridElevationRow(benchmark::State& state) {
  const SmallGrid& g = SmallGrid::get();
  if (!g.file) {
    state.SkipWithError(g.error.c_str());
    return;
  }
  std::uint32_t i = 0, j = SmallGrid::kPosts / 2;
  for (auto _ : state) {
    float v = g.file->elevation(i, j);
    benchmark::DoNotOptimize(v);
    i = (i + 1) & (SmallGrid::kPosts - 1);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_GridElevationRow);

/// The sample material table (samples/materials.txt).
const materials::Table& sampleTable() {
  static const materials::Table t = [] {
    auto r = materials::readFile(std::string(SANDTABLE_SOURCE_DIR) + "/samples/materials.txt");
    return r ? r.value() : materials::Table{};
  }();
  return t;
}

std::string utm32Wkt() {
  auto crs = convert::resolveCrs("EPSG:32632", 9.0, 45.0);
  return crs ? crs.value().wkt : std::string();
}

/// The module check (formats/module_check.h) of one module of N level-0
/// squares, 4 levels, built from SmallGrid by the converters' module builder
/// without culture. Reports triangles per second; the complexity fit over N
/// x N squares should come out O(N) in triangles (it was the
/// ModuleCheck.linearTime unit test, which may not time things).
void BM_ModuleCheck(benchmark::State& state) {
  const SmallGrid& g = SmallGrid::get();
  if (!g.file) {
    state.SkipWithError(g.error.c_str());
    return;
  }
  const auto squares = static_cast<std::uint32_t>(state.range(0));
  constexpr int kLevels = 4;
  const materials::Table& table = sampleTable();
  convert::CultureOptions co;
  const double edge = 30.0 * (SmallGrid::kPosts - 1);
  auto culture = convert::Culture::load(co, table, {utm32Wkt(), 500000.0, 4700000.0, edge, edge});
  if (!culture) {
    state.SkipWithError(culture.error().c_str());
    return;
  }
  const module::Module m = convert::buildModule(*g.file, *culture.value(), table.defaultArea, squares, kLevels, 0, 0);
  pack::IndexHeader h;
  h.modulesX = h.modulesZ = (SmallGrid::kPosts - 1 + squares - 1) / squares;
  h.levels = kLevels;
  h.moduleSquares = squares;
  h.moduleSize = 30.0 * squares;
  module::CheckOptions options;
  options.materials = &table;
  const module::ModuleChecker checker(*g.file, h, "bench/modules.pack", options);
  std::int64_t triangles = 0;
  for (const auto& lv : m.levels) triangles += static_cast<std::int64_t>(lv.indices.size() / 3);
  for (auto _ : state) {
    module::ModuleEdges e;
    const Status checked = checker.check(m, 4096, &e);
    if (!checked) {
      state.SkipWithError(checked.error().c_str());
      return;
    }
    benchmark::DoNotOptimize(e);
  }
  state.SetComplexityN(triangles);
  state.SetItemsProcessed(state.iterations() * triangles);
  state.counters["triangles"] = static_cast<double>(triangles);
}
BENCHMARK(BM_ModuleCheck)->ArgName("squares")->Arg(32)->Arg(64)->Arg(128)->Arg(256)->Complexity(benchmark::oN)
    ->Unit(benchmark::kMillisecond);

/// The scene of the former Culture.decalTimePerLevel unit test: three roads
/// and a lake through a 1 km module at 31.25 m posts (32 squares, 4
/// levels), on hills; and the same module size where there is no culture.
class DecalScene {
 public:
  static constexpr double kE0 = 500000, kN0 = 5500000, kSpacing = 31.25;
  static constexpr int kSquares = 32;

  static const DecalScene& get() {
    static const DecalScene s;
    return s;
  }
  ~DecalScene() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  /// Culture with `cacheModules` partitions kept (0 = the default).
  std::shared_ptr<const convert::Culture> load(std::size_t cacheModules, std::string& error) const {
    convert::CultureOptions o;
    o.sources = {(dir_ / "scene.geojson").string()};
    o.cacheModules = cacheModules;
    auto c = convert::Culture::load(o, sampleTable(), {utm32Wkt(), kE0, kN0, 3000, 1000});
    if (!c) {
      error = c.error();
      return nullptr;
    }
    return c.value();
  }
  /// Level `level` of the module whose north-west corner is world (mx, 0).
  static convert::LevelLattice lattice(double mx, int level) {
    convert::LevelLattice lat;
    lat.moduleX = mx;
    lat.spacing = kSpacing * (1 << level);
    for (int i = 0; i <= kSquares; i += 1 << level) lat.xs.push_back(i * kSpacing);
    lat.zs = lat.xs;
    for (double z : lat.zs) {
      for (double x : lat.xs) lat.heights.push_back(static_cast<float>(hills(mx + x, z)));
    }
    return lat;
  }

 private:
  using Path = std::vector<std::array<double, 2>>;
  static double hills(double x, double z) { return 300 + 40 * std::sin(x / 170.0) * std::cos(z / 230.0) + 0.013 * x; }

  DecalScene() : dir_(fs::temp_directory_path() / ("sandtable-microbench-decal-" + std::to_string(::getpid()))) {
    fs::create_directories(dir_);
    Path lake;
    for (int k = 0; k <= 60; ++k) {
      const double a = 0.1 + 2 * std::numbers::pi * (k % 60) / 60;
      lake.push_back({900 + 250 * std::cos(a), 700 + 250 * std::sin(a)});
    }
    std::ofstream out(dir_ / "scene.geojson");
    out.precision(17);
    out << "{\"type\":\"FeatureCollection\",\"crs\":{\"type\":\"name\",\"properties\":{\"name\":"
           "\"urn:ogc:def:crs:EPSG::32632\"}},\"features\":[\n";
    auto feature = [&](const char* props, const char* type, const Path& p, bool last) {
      out << "{\"type\":\"Feature\",\"properties\":{" << props << "},\"geometry\":{\"type\":\"" << type
          << "\",\"coordinates\":" << (type[0] == 'P' ? "[[" : "[");
      for (std::size_t k = 0; k < p.size(); ++k) out << (k ? "," : "") << "[" << kE0 + p[k][0] << "," << kN0 - p[k][1] << "]";
      out << (type[0] == 'P' ? "]]" : "]") << "}}" << (last ? "\n" : ",\n");
    };
    feature("\"highway\": \"primary\"", "LineString", {{-50, 210}, {300, 260}, {620, 410}, {1050, 450}}, false);
    feature("\"highway\": \"residential\"", "LineString", {{420, -20}, {450, 300}, {520, 700}, {480, 1020}}, false);
    feature("\"highway\": \"track\"", "LineString", {{0, 880}, {400, 820}, {1000, 900}}, false);
    feature("\"natural\": \"water\"", "Polygon", lake, true);
    out << "]}\n";
  }
  fs::path dir_;
};

/// One level of the busy module (x 0..1000 m), its partition cached: the
/// per-level cost of the module stage once the partition exists.
void BM_DecalLevel(benchmark::State& state) {
  std::string error;
  const auto c = DecalScene::get().load(0, error);
  if (!c) {
    state.SkipWithError(error.c_str());
    return;
  }
  const int level = static_cast<int>(state.range(0));
  const double mx = state.range(1) ? 0.0 : 2000.0;  // 1: roads and lake; 0: no culture
  const convert::LevelLattice lat = DecalScene::lattice(mx, level);
  module::Level lv;
  c->decalLevel(DecalScene::lattice(mx, 0), lv);  // builds and caches the module's partition
  convert::DecalStats st;
  for (auto _ : state) {
    st = c->decalLevel(lat, lv);
    benchmark::DoNotOptimize(lv);
  }
  state.counters["cut_triangles"] = static_cast<double>(st.slowTriangles);
  state.counters["triangles"] = static_cast<double>(st.triangles);
}
BENCHMARK(BM_DecalLevel)->ArgNames({"level", "culture"})->ArgsProduct({{0, 1, 2, 3}, {1, 0}})
    ->Unit(benchmark::kMillisecond);

/// Level 0 with the module's partition built each time (one partition
/// cached, two modules alternating): the first call of a module.
void BM_DecalLevelWithPartition(benchmark::State& state) {
  std::string error;
  const auto c = DecalScene::get().load(1, error);
  if (!c) {
    state.SkipWithError(error.c_str());
    return;
  }
  const convert::LevelLattice a = DecalScene::lattice(0, 0), b = DecalScene::lattice(1000, 0);
  module::Level lv;
  bool first = true;
  for (auto _ : state) {
    c->decalLevel(first ? a : b, lv);
    first = !first;
    benchmark::DoNotOptimize(lv);
  }
}
BENCHMARK(BM_DecalLevelWithPartition)->Unit(benchmark::kMillisecond);

}  // namespace

/// Every module of the database named by $SANDTABLE_BENCH_DB (a built
/// database; `sandtable build --module-version 1|2|3`), decompressed once:
/// the decode benchmark times module::decodeInto alone on each module's
/// records (both of a version 2 pack: coarse and fine), and the read
/// benchmark the reader's whole path (pread from the warm page cache, CRC,
/// zstd, decode) of the whole module. Skipped without the variable.
struct BenchDb {
  std::shared_ptr<const pack::PackReader> reader;
  std::vector<std::vector<std::byte>> raw;  ///< per module: its coarse record, then its fine one if any
  std::uint64_t compressed = 0, rawBytes = 0;
  std::string error;
  static const BenchDb& get() {
    static const BenchDb db = [] {
      BenchDb d;
      const char* dir = std::getenv("SANDTABLE_BENCH_DB");
      if (!dir) {
        d.error = "set SANDTABLE_BENCH_DB to a database directory";
        return d;
      }
      auto r = pack::PackReader::open(dir);
      if (!r) {
        d.error = r.error();
        return d;
      }
      d.reader = r.value();
      const auto& h = d.reader->header();
      for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
        for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
          for (const pack::Part part : {pack::Part::coarse, pack::Part::fine}) {
            if (part == pack::Part::fine && d.reader->coarseLevel() == 0) continue;
            auto raw = d.reader->readRaw(kx, kz, part);
            if (!raw) {
              d.error = raw.error();
              return d;
            }
            d.rawBytes += raw.value().size();
            d.raw.push_back(std::move(raw.value()));
          }
        }
      }
      return d;
    }();
    return db;
  }
};

void BM_ModuleDecode(benchmark::State& state) {
  const BenchDb& db = BenchDb::get();
  if (!db.error.empty()) {
    state.SkipWithError(db.error.c_str());
    return;
  }
  // One iteration decodes one whole module: all of its records (arg 0), or
  // only its coarse record (1) or its fine one (2), as the pager's
  // coarse-first loads and fine jobs do.
  const std::size_t records = db.reader->coarseLevel() == 0 ? 1 : 2;
  const std::size_t modules = db.raw.size() / records;
  const std::size_t first = state.range(0) == 2 && records == 2 ? 1 : 0;
  const std::size_t last = state.range(0) == 1 ? 1 : records;
  std::array<module::Module, 2> m;
  std::size_t k = 0;
  for (auto _ : state) {
    for (std::size_t r = first; r < last; ++r) {
      const Status st = module::decodeInto(db.raw[k * records + r], "bench", 0, m[r]);
      if (!st) {
        state.SkipWithError(st.error().c_str());
        return;
      }
      benchmark::DoNotOptimize(m[r]);
    }
    k = (k + 1) % modules;
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["modules"] = double(modules);
  state.counters["raw_bytes_per_module"] = double(db.rawBytes) / double(modules);
  state.counters["version"] = double(module::encodedVersion(db.raw.front()));
}
BENCHMARK(BM_ModuleDecode)->ArgName("part")->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

void BM_ModuleReadInto(benchmark::State& state) {
  const BenchDb& db = BenchDb::get();
  if (!db.error.empty()) {
    state.SkipWithError(db.error.c_str());
    return;
  }
  const auto& h = db.reader->header();
  module::Module m;
  std::size_t k = 0;
  for (auto _ : state) {
    const auto kx = std::uint32_t(k % h.modulesX), kz = std::uint32_t(k / h.modulesX);
    const Status st = db.reader->readInto(kx, kz, m);
    if (!st) {
      state.SkipWithError(st.error().c_str());
      return;
    }
    benchmark::DoNotOptimize(m);
    k = (k + 1) % (std::size_t(h.modulesX) * h.modulesZ);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ModuleReadInto)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
