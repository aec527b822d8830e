#pragma once
// The standard paging benchmark database (`sandtable bench make-db`).
// Synth writes DTED2 and culture for a square, then the ordinary build
// turns them into a grid and load modules with roads decaled on, exactly
// as `sandtable synth` followed by `sandtable build` would.
//
// Thread safety: one call at a time per process (it polls the converters'
// process-wide cancel flag, convert::requestCancel).
#include <cstdint>
#include <string>

#include "sandtable/formats/pack.h"

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct MakeDbOptions {
  /// Database directory to create. The synth inputs go to OUTPUT.synth.
  std::string output = "out/bench-db";
  /// Side of the square, km (standard: 500; 1..1000).
  double sizeKm = 500;
  /// Post spacing, metres (> 0).
  double spacing = 31.25;
  /// Load module edge, metres (> 0).
  double moduleSize = 1000;
  /// Levels of detail (1..8).
  int levels = 4;
  /// Synth random seed.
  std::uint64_t seed = 1;
  /// Threads for synth and the build; 0 = all cores.
  int threads = 0;
  /// Module compression level (1..22).
  int zstdLevel = 9;
  /// Replace `output` if it exists.
  bool force = false;
  /// Keep the synth inputs in OUTPUT.synth.
  bool keepInputs = false;
};

struct MakeDbReport {
  std::uint64_t posts = 0, modules = 0;
  double synthSeconds = 0, buildSeconds = 0, moduleStageSeconds = 0;
  int roads = 0;
  /// What `sandtable bench make-db --json` prints: output, size_km,
  /// spacing_m, module_size_m, levels, posts, modules, synth_s, build_s,
  /// module_stage_s, module_bytes, roads.
  nlohmann::json json;
};

/// Synthesizes the inputs and builds the database. Notes: one line before
/// synth and one before the build; progress: synth's stages prefixed
/// "synth ", then the build's. Fails, without touching an existing
/// `output` unless `force`, with one problem per error, each message
/// starting "synth: " or "build: " and holding the converter's
/// "file @offset: message" (Problem::file empty).
Result<MakeDbReport> makeBenchDatabase(const MakeDbOptions& options, const Notes& notes = {});

/// The same database with its pack rewritten in another layout (pack v1,
/// or v2 in Morton or row-major order), so that layouts are compared on the
/// same modules without building twice: every other file is hard-linked
/// from `from` (copied where links fail), every module is read and added to
/// a PackWriter of `layout` on `threads` threads, and the manifest's entries
/// for the two pack files get their new sizes and CRCs. Refuses an existing
/// `to` without `force`. Returns the new pack's size statistics as JSON.
Result<nlohmann::json> repackBenchDatabase(const std::string& from, const std::string& to,
                                           const pack::PackLayout& layout, int threads, int zstdLevel, bool force,
                                           const Notes& notes = {});

}  // namespace sandtable::bench
