#pragma once
// Grid conversion speed, ours against gdalwarp (`sandtable bench build`).
// Both sides convert the same DTED2 sources onto the same target grid (CRS,
// extent, post spacing) in one run. Measurements alternate between the
// sides and every one is repeated, reporting the median, because the
// machine is shared and noisy: a burst of load then falls on both alike.
//
// Thread safety: one benchmark at a time per process (it polls the
// converters' process-wide cancel flag, convert::requestCancel, and
// measures the process's CPU time).
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct BuildBenchOptions {
  /// An existing synth output (its dted2/ tree and synth.json square) or a
  /// directory of sources; empty: synthesize a square first (not timed).
  std::string input;
  /// Side of the synthesized square, km (1..1000); 0: just enough for
  /// 5000 x 5000 posts at `spacing`.
  double sizeKm = 0;
  /// Target post spacing, metres (> 0).
  double spacing = 30;
  /// Our kernels: weighted, bilinear (GDAL's point samples, as gdalwarp),
  /// bilinear-triangles (plus the triangle fit, as `sandtable build
  /// --resample bilinear`), cubic, average; each at most once.
  std::vector<std::string> kernels{"bilinear", "weighted"};
  /// Timed runs of each measurement; medians are reported (1..100).
  int repeat = 3;
  /// Threads for ours and for gdalwarp -multi; 0 = all cores.
  int threads = 0;
  /// Keep the work directory (synth data, outputs, logs).
  bool keep = false;
  /// The sandtable executable run as `synth` to make the square; empty:
  /// this process's own (/proc/self/exe), which is right for the CLI.
  std::string synthExecutable;
};

/// The target grid, as our build chose it; gdalwarp is given the same.
struct BuildBenchGrid {
  std::uint32_t postsX = 0, postsZ = 0;
  double spacing = 0;
  std::string crsName;
  std::uint64_t posts() const { return std::uint64_t(postsX) * postsZ; }
};

/// One of our kernels against one comparable gdalwarp kernel: medians in
/// seconds (wall, or user + system CPU over all threads).
struct BuildBenchRow {
  std::string kernel, warpKernel;
  double oursS, oursResampleS, oursCpuS, warp1tS, warp1tCpuS, warpMtS, warpMtCpuS;
  std::vector<double> oursSamples, warp1tSamples, warpMtSamples;  ///< wall seconds per repeat
  std::vector<std::pair<std::string, double>> oursStages;          ///< median seconds per stage, in order
};

struct BuildBenchReport {
  BuildBenchGrid grid;
  /// What was converted ("synthesized 162 km square, DTED2 (1 arc-second)"
  /// or "BuildBenchOptions::input DIR") and how many source files.
  std::string source;
  std::size_t sourceFiles = 0;
  std::string gdalwarpVersion;
  double loadAverageStart = 0, loadAverageEnd = 0;  ///< 1-minute load average
  unsigned cpus = 0;
  std::vector<BuildBenchRow> rows;
  /// What `sandtable bench build --json` prints: posts, posts_x, posts_z,
  /// spacing_m, repeat, crs, source, threads, cpus, warm_up,
  /// gdalwarp_version, load_average_start, load_average_end, results
  /// [{kernel, ours_s, ..., ratio_vs_mt, samples_s, ours_stages_s}].
  nlohmann::json json;
};

/// Runs the benchmark; needs gdalwarp and gdalbuildvrt on PATH. Notes: the
/// steps and one line per timed run. Fails with one problem without a file:
/// bad options (naming the BuildBenchOptions field), missing GDAL tools, a
/// failed step, or "cancelled".
Result<BuildBenchReport> runBuildBench(const BuildBenchOptions& options, const Notes& notes = {});

}  // namespace sandtable::bench
