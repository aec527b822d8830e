#pragma once
// The module-stage benchmark (`sandtable bench modules`): the full build
// (elevation, culture, load modules) against the elevation-only build of
// the same synthetic square, in one run. Builds alternate and repeat;
// medians are reported.
//
// Thread safety: one benchmark at a time per process (builds use every
// core and a work directory named after the process id).
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct ModulesBenchOptions {
  /// An existing `sandtable synth` output directory; empty: synthesize a
  /// square of `sizeKm` first (not timed).
  std::string input;
  /// Side of the synthesized square, km (1..1000).
  double sizeKm = 100;
  /// Post spacing of both builds, metres (> 0).
  double spacing = 31.25;
  /// Runs of each build; the medians are reported (1..100).
  int repeat = 3;
  /// Threads for synth and both builds; 0 = all cores.
  int threads = 0;
  /// Module compression level (1..22).
  int zstdLevel = 9;
  /// Keep the work directory (synth inputs, both databases).
  bool keep = false;
};

struct ModulesBenchReport {
  double fullBuildSeconds = 0;      ///< median
  double elevationOnlySeconds = 0;  ///< median
  double moduleStageSeconds = 0;    ///< median of the full build's module stage
  std::uint64_t modules = 0;
  /// What `sandtable bench modules --json` prints: size_km, spacing_m,
  /// repeat, full_build_s, elevation_only_s, full_over_elevation,
  /// module_stage_s, modules, modules_per_second, module_bytes, per_level,
  /// culture_features, full_runs_s, elevation_runs_s, line_km; and, for a
  /// machine shared with other work, full_cpu_s, elevation_only_cpu_s,
  /// full_over_elevation_cpu (process user + system time, medians),
  /// culture_load_s, and module_stage_cpu_s (the module stage's CPU seconds
  /// per stage, medians: convert::StageSeconds).
  nlohmann::json json;
};

/// Runs the benchmark. Notes: the synth step and one line per build.
/// Fails with the problems of synth or of a build.
Result<ModulesBenchReport> runModulesBench(const ModulesBenchOptions& options, const Notes& notes = {});

}  // namespace sandtable::bench
