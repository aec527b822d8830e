#pragma once
// The dynamic-terrain benchmark (`sandtable bench edits`, issue 37): what
// a crater costs from apply() to the ground a viewer draws, on a synthetic
// database the benchmark builds (bench make-db's square, its synth inputs
// kept for the baseline's culture) or on a database given. Measured in one
// run (definitions and figures: docs/DYNAMIC.md, "Benchmark"):
//  - re-mesh and publish time per crater touching 1, 2 and 4 modules
//    (edits::EditedModules::remesh, thread CPU and wall, medians), against
//    the baseline of building the same modules as `sandtable build` does
//    (meshing::assembleModule with the culture's decals over the edited
//    posts, then the pack's compression), in the same run;
//  - journal replay: Editor::open of a journal of small craters spread over
//    the grid, heights only, scaled to 100,000 edits; and with the modules
//    re-meshed (inline) on a shorter journal;
//  - memory per 1,000 craters: the overlay's own accounting (heights tiles
//    and patches, re-meshed modules as published) and the process's RSS;
//  - detonation to drawn: one crater at a time, from apply() until the new
//    generation of every module it touches is published by the
//    ModuleSource, and until a headless pager over the editor's world has
//    it resident at level 0 (what a frame would draw; no GL);
//  - sustained craters per second: craters applied at a rate in 60 Hz
//    frames while the pager follows; holes (window modules not resident),
//    frames over budget (the main thread's apply + update + reads over
//    1/60 s), latency in frames, the worker's CPU time;
//  - a battle: many craters in a burst, until every module is drawn again.
//
// Thread safety: one benchmark at a time per process (a work directory
// named after the process id, /proc/self reads). Notes come from the
// caller's thread.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct EditsBenchOptions {
  /// A database with load modules; "" synthesizes a square of `sizeKm`
  /// (not timed). The baseline's culture is the sources the database's
  /// manifest names (build.culture.sources) where they still exist, else
  /// the grid's plain triangles (said in the report).
  std::string database;
  /// Side of the synthesized square, km (3..100: the 4-module crater needs
  /// a module corner with modules all round it).
  double sizeKm = 6;
  /// Re-mesh repeats per case and journal replays; medians (1..101).
  int repeat = 7;
  /// Edits in the replayed journal (heights only; 1..10,000,000).
  std::uint64_t journalEdits = 100000;
  /// Edits in the journal replayed with the modules re-meshed (0: skip).
  std::uint64_t journalMeshedEdits = 1000;
  /// Medium craters applied for the memory figure (1..1,000,000).
  std::uint32_t memoryCraters = 1000;
  /// Craters timed one at a time from apply() to drawn (1..10,000).
  std::uint32_t latencySamples = 20;
  /// Sustained runs, craters per second each (> 0).
  std::vector<double> rates = {10, 30, 100, 300};
  /// Seconds of frames per sustained run (0.1..600).
  double sustainSeconds = 5;
  /// Craters in the battle (0: skip) and the most applied per frame (>= 1).
  std::uint32_t battleCraters = 10000;
  std::uint32_t battlePerFrame = 50;
  /// The pager's view distance, metres (500..100000).
  double viewDistance = 2500;
  std::uint64_t seed = 1;
  /// Keep the work directory (synthesized database and journals).
  bool keep = false;
};

struct EditsBenchReport {
  /// What `sandtable bench edits --json` prints: database, synthesized,
  /// spacing_m, module_size_m, modules, levels, repeat, cpus, baseline
  /// (what it builds with), remesh[] {case, modules, crater {radius_m,
  /// depth_m}, cold_ms, cpu_ms, wall_ms, cpu_runs_ms, baseline_cpu_ms,
  /// baseline_wall_ms, baseline_over_remesh, triangles_level0,
  /// refined_squares}, journal {edits, file_bytes, read_s, replay_s,
  /// replay_per_100k_s, meshed {edits, replay_s, per_100k_s, modules_remeshed}},
  /// memory {craters, heights_bytes, remeshed_module_bytes, modules_remeshed,
  /// rss_delta_bytes, per_1000 {heights_bytes, remeshed_module_bytes,
  /// rss_delta_bytes}}, pager {view_distance_m, loaders, window_modules,
  /// log}, latency {samples, drawn, worker_cpu_ms {p50, p95, max},
  /// published_ms {p50, p95, max},
  /// drawn_ms {...}, drawn_frames_60hz {...}, modules_touched_mean},
  /// sustained[] {rate_per_s, seconds, craters, frames, hole_frames,
  /// holes, frames_over_budget, frame_ms {p50, p95, max}, latency_frames
  /// {p50, p95, max}, undrawn, worker_cpu_s, worker_cpu_per_crater_ms,
  /// worker_busy, modules_remeshed, batches, keeps_up}, max_sustained_rate_per_s,
  /// battle {craters, per_frame, frames, seconds, apply_seconds, holes,
  /// hole_frames, frames_over_budget, frame_ms, latency_frames, undrawn,
  /// worker_cpu_s, modules_remeshed, batches}, goals {name: {value, goal,
  /// met}}.
  nlohmann::json json;
};

/// Runs every part. Notes: the synthesis, then one line per part or case.
/// Fails with a problem without a file for bad options (naming the
/// EditsBenchOptions field) or a database too small, and otherwise with
/// the problems of the synthesis, the database, the journal or the editor.
Result<EditsBenchReport> runEditsBench(const EditsBenchOptions& options, const Notes& notes = {});

}  // namespace sandtable::bench
