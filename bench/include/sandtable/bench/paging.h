#pragma once
// The paging benchmark (`sandtable bench paging`): real-time flights over
// a database, one per speed and mode, each from a cold cache. The
// predictive pager is measured against the seed's scheme, demand paging
// (no prediction) and the NPSStealth mmap mode in the same run, modes
// interleaved so that drift on a shared machine hits them alike.
// Definitions (hole, degraded frame, mmap holes) and measured figures:
// docs/PAGER.md §11.
//
// Thread safety: one benchmark at a time per process (it drops the page
// cache, resets the process's peak RSS and reads /proc/self). Notes come
// from the caller's thread and, for the pager's log lines ("pager: ..."),
// from its loader threads.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct PagingBenchOptions {
  /// Database directory, with load modules.
  std::string database;
  /// View distance, metres (100..100000).
  double viewDistance = 10000;
  /// Speeds flown, km/h, each > 0; sorted and deduplicated before flying.
  std::vector<double> speedsKmh = {2000, 5000, 10000, 20000, 50000, 100000, 200000, 300000};
  /// One flight per mode with the speed rising geometrically through
  /// `speedsKmh`, instead of one flight per speed.
  bool ramp = false;
  /// Flight path: "straight", "zigzag", "circle" or "rows" (back and forth
  /// along X, rows a window's width apart: the longest path that never
  /// comes back to a module it left).
  std::string path = "straight";
  /// Files to plot holes and degraded frames against speed into, each
  /// ending in .png or .svg.
  std::vector<std::string> plots;
  /// Seconds per speed, capped by what the path allows (0.5..600).
  double seconds = 8;
  /// Flights per speed and mode; medians are reported (1..50).
  int repeat = 3;
  /// Modes flown: predictive, seed (the seed's strips, no lead, no work
  /// stealing), demand, mmap.
  std::vector<std::string> modes = {"predictive", "seed", "demand", "mmap"};
  /// Loader threads (1..4).
  std::uint32_t loaders = 4;
  /// Most strips loaded ahead on one axis (0..16).
  std::uint32_t maxLeadStrips = 16;
  /// Lead time as a multiple of the loaders' latency estimate (>= 0).
  double lookAhead = 2;
  /// Half the view triangle's ground angle, degrees (1..89).
  double halfAngle = 35;
  /// Pager memory budget, MiB (> 0).
  double budgetMb = 2048;
  /// Keep the page cache instead of dropping it before each flight.
  bool warm = false;
  /// PagerOptions::coarseFirst (a v2 pack's coarse records first).
  bool coarseFirst = true;
  /// PagerOptions::readaheadHints.
  bool readahead = true;
};

struct PagingBenchReport {
  /// Per mode flown: the highest speed whose every repeat had no hole
  /// frame (0: none), km/h.
  std::map<std::string, double> maxSpeedZeroHolesKmh;
  /// What `sandtable bench paging --json` prints: database, modules,
  /// view_distance_m, half_angle_deg, path, path_length_km, ramp, repeat,
  /// seconds_per_speed, tick_hz, cold_cache, loaders, max_lead_strips,
  /// look_ahead_scale, cpus, modes {MODE: {speeds, max_speed_zero_holes_kmh,
  /// max_speed_under_1pct_hole_frames_kmh}}, ratios, stages.
  nlohmann::json json;
};

/// Flies every mode at every speed `repeat` times and writes the plots.
/// Notes: one line per speed bin flown ("[k/n] MODE ...") and the pager's
/// log ("pager: ..."). Fails with a problem without a file for bad options
/// (naming the PagingBenchOptions field) or an unwritable plot, with
/// Problem::file "bench paging" for a database too small for the view
/// distance, and otherwise with the problems of opening the database or
/// the pager.
Result<PagingBenchReport> runPagingBench(const PagingBenchOptions& options, const Notes& notes = {});

}  // namespace sandtable::bench
