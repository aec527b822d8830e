#pragma once
// The simulator benchmark (`sandtable bench sim`): entities simulated per
// second on one core, with collisions on, in the seed's Fort Hunter-Liggett
// case scaled up (VII.C.1): a 50 km square of 125 m grid squares holding
// 31,000 objects in clumps (Table 3: 3.9 per populated square) and 500,
// then 10,000, moving entities. The baseline, measured in the same run on
// the same world and entities, tests every object and every entity pair
// (SimOptions::bruteForce); the ratio is their time per step.
//
// Thread safety: one benchmark at a time per process (a work file named
// after the process id).
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct SimBenchOptions {
  std::vector<std::uint32_t> entities = {500, 10000};  ///< each 1..1,000,000
  std::uint32_t objects = 31000;                         ///< 0..10,000,000
  double sizeKm = 50;                                    ///< the square's side, 1..500
  double seconds = 10;       ///< simulated seconds per grid run (after 1 s of warm-up)
  double bruteSeconds = 1;   ///< simulated seconds per brute-force run
  int repeat = 3;            ///< runs of each; medians (1..100)
  std::uint64_t seed = 1;
};

struct SimBenchReport {
  /// What `sandtable bench sim --json` prints: size_km, objects, cases[]
  /// with entities, grid {step_ms, entities_per_s, hz, runs_ms, steps}, brute
  /// {step_ms, entities_per_s, hz, runs_ms, steps}, brute_over_grid, meets_60hz,
  /// the collisions counted, and the objects tested per entity step.
  nlohmann::json json;
};

Result<SimBenchReport> runSimBench(const SimBenchOptions& options, const Notes& notes = {});

}  // namespace sandtable::bench
