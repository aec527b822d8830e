// sandtable_microbench: the weighted resampling kernel and grid reads, in
// nanoseconds per call. Run: build/bench/sandtable_microbench
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "sandtable/converters/elevation.h"
#include "sandtable/formats/grid.h"

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

}  // namespace

BENCHMARK_MAIN();
