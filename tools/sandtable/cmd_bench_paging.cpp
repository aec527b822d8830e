// sandtable bench paging DB: flags and printing for bench::runPagingBench,
// real-time flights at a list of speeds with the predictive pager against
// the seed's scheme, demand paging and the NPSStealth mmap mode.
#include <cstdio>
#include <memory>

#include "cmd_bench.h"
#include "db_util.h"
#include "sandtable/bench/paging.h"

namespace sandtable::cli {
namespace {

using nlohmann::json;

constexpr const char* kCmd = "bench paging";

struct Args {
  bench::PagingBenchOptions o;
  bool json = false;
};

const FlagMap kFlags = {{"PagingBenchOptions::database", "DB"},
                        {"PagingBenchOptions::viewDistance", "--view-distance"},
                        {"PagingBenchOptions::speedsKmh", "--speeds"},
                        {"PagingBenchOptions::ramp", "--ramp"},
                        {"PagingBenchOptions::path", "--path"},
                        {"PagingBenchOptions::plots", "--plot"},
                        {"PagingBenchOptions::seconds", "--seconds"},
                        {"PagingBenchOptions::repeat", "--repeat"},
                        {"PagingBenchOptions::modes", "--modes"},
                        {"PagingBenchOptions::loaders", "--loaders"},
                        {"PagingBenchOptions::maxLeadStrips", "--max-lead-strips"},
                        {"PagingBenchOptions::lookAhead", "--look-ahead"},
                        {"PagingBenchOptions::halfAngle", "--half-angle"},
                        {"PagingBenchOptions::budgetMb", "--budget-mb"},
                        {"PagingBenchOptions::warm", "--warm"},
                        {"PagingBenchOptions::coarseFirst", "--no-coarse-first"},
                        {"PagingBenchOptions::readahead", "--no-readahead"}};

void printHuman(const json& j) {
  std::printf("bench paging: %s, %s path, view distance %.0f m, %s, median of %d\n",
              j["database"].get<std::string>().c_str(), j["path"].get<std::string>().c_str(),
              j["view_distance_m"].get<double>(), j["cold_cache"].get<bool>() ? "cold cache" : "warm cache",
              j["repeat"].get<int>());
  std::printf("%-10s %9s %6s %6s %7s %7s %8s %8s %8s %8s %7s %7s %6s\n", "mode", "km/h", "sec", "frames", "holes",
              "degr.", "p50 ms", "p99 ms", "max ms", "mod/s", "MB/s", "RSS MB", "lead");
  for (const std::string mode : {"predictive", "seed", "demand", "mmap"}) {
    if (!j["modes"].contains(mode)) continue;
    const json& m = j["modes"][mode];
    for (const json& s : m["speeds"]) {
      const double rate = s.contains("modules_per_s") ? s["modules_per_s"].get<double>() : s["blocks_per_s"].get<double>();
      std::printf("%-10s %9.0f %6.2f %6.0f %7.0f %7.0f %8.1f %8.1f %8.1f %8.0f %7.1f %7.0f %6.0f\n", mode.c_str(),
                  s["speed_kmh"].get<double>(), s["seconds_flown"].get<double>(), s["frames"].get<double>(),
                  s["hole_frames"].get<double>(), s["degraded_frames"].get<double>(), s["latency_ms"]["p50"].get<double>(),
                  s["latency_ms"]["p99"].get<double>(), s["latency_ms"]["max"].get<double>(), rate,
                  s[mode == "mmap" ? "disk_mb_per_s" : "mb_per_s"].get<double>(), s["peak_rss_mb"].get<double>(),
                  s["lead_strips_max"].get<double>());
    }
    std::printf("%-10s highest speed with zero hole frames (every repeat): %.0f km/h; under 1%% of frames: %.0f km/h\n",
                mode.c_str(), m["max_speed_zero_holes_kmh"].get<double>(),
                m["max_speed_under_1pct_hole_frames_kmh"].get<double>());
  }
  for (const auto& [k, v] : j["ratios"].items()) {
    if (v.is_number()) std::printf("ratio %s: %.1f\n", k.c_str(), v.get<double>());
    else std::printf("ratio %s: %s\n", k.c_str(), v.get<std::string>().c_str());
  }
  if (const json& st = j["stages"]; !st.empty()) {
    std::printf("one load, one core, %s (%llu modules along the path, %.1f kB compressed, %.1f kB raw): pread %.0f us,"
                " unpack (CRC + zstd) %.0f us, decode %.0f us, copy %.0f us = %.0f us, %.0f modules/s\n",
                st["cold_cache"].get<bool>() ? "cold cache" : "warm", static_cast<unsigned long long>(st["modules"].get<std::uint64_t>()),
                st["compressed_kb_mean"].get<double>(), st["raw_kb_mean"].get<double>(), st["pread_us"].get<double>(),
                st["unpack_us"].get<double>(), st["decode_us"].get<double>(), st["copy_us"].get<double>(),
                st["total_us"].get<double>(), st["modules_per_s_one_core"].get<double>());
  }
  std::printf("(mmap: mod/s is grid blocks prefetched per second, MB/s is disk reads; holes are needed modules whose\n"
              " grid pages are not in the page cache; mmap has one level, so never a degraded frame)\n");
}


int run(const Args& a) {
  // Opened here first for the hint on a bad database; the benchmark opens
  // it again for each flight.
  if (!openOrReport(kCmd, a.o.database)) return kUsage;
  auto r = bench::runPagingBench(a.o, stderrNotes(kCmd, false, kFlags));
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  if (a.json) std::printf("%s\n", r->json.dump(2).c_str());
  else printHuman(r->json);
  return kOk;
}

}  // namespace

void registerBenchPaging(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("paging", "Fly in real time at a list of speeds: predictive pager vs demand vs mmap");
  sub->footer(
      "Example:\n  sandtable bench paging out/bench-db --view-distance 10000 --speeds 2000,20000,200000 --plot paging.svg\n"
      "Each speed and mode is one real-time flight at 60 Hz from a cold cache (posix_fadvise DONTNEED on every\n"
      "database file) along a path that never revisits a module. Every tick counts the modules under the view\n"
      "triangle that are not resident (holes) or only coarser than needed (degraded). See docs/PAGER.md.");
  sub->add_option("DB", o.database, "Database directory (with load modules)")->required();
  sub->add_option("--view-distance", o.viewDistance, "View distance, metres")
      ->default_val(10000)
      ->check(CLI::Range(100.0, 100000.0));
  sub->add_option("--speeds", o.speedsKmh, "Speeds in km/h, comma separated")
      ->delimiter(',')
      ->default_str("2000,5000,10000,20000,50000,100000,200000,300000");
  sub->add_flag("--ramp", o.ramp, "One flight per mode with the speed rising geometrically through the list");
  sub->add_option("--path", o.path, "Flight path")->default_val("straight")->check(CLI::IsMember({"straight", "zigzag", "circle", "rows"}));
  sub->add_option("--seconds", o.seconds, "Seconds per speed (capped by what the path allows)")
      ->default_val(8)
      ->check(CLI::Range(0.5, 600.0));
  sub->add_option("--repeat", o.repeat, "Flights per speed and mode (median reported)")->default_val(3)->check(CLI::Range(1, 50));
  sub->add_option("--modes", o.modes,
                  "Modes, comma separated: predictive, seed (the seed's strips, no lead), demand, mmap")
      ->delimiter(',')
      ->default_str("predictive,seed,demand,mmap");
  sub->add_option("--loaders", o.loaders, "Loader threads (1..4)")->default_val(4)->check(CLI::Range(1, 4));
  sub->add_option("--max-lead-strips", o.maxLeadStrips, "Most strips loaded ahead on one axis (0..16)")
      ->default_val(16)
      ->check(CLI::Range(0, 16));
  sub->add_option("--look-ahead", o.lookAhead, "Lead time as a multiple of the loaders' latency estimate")
      ->default_val(2)
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--half-angle", o.halfAngle, "Half the view triangle's ground angle, degrees")
      ->default_val(35)
      ->check(CLI::Range(1.0, 89.0));
  sub->add_option("--budget-mb", o.budgetMb, "Pager memory budget, MiB")->default_val(2048)->check(CLI::PositiveNumber);
  sub->add_flag("--warm", o.warm, "Keep the page cache (skip the cold-cache drop)");
  sub->add_flag("!--no-coarse-first", o.coarseFirst,
                "Read a v2 pack's modules whole, as for v1 (default: coarse records first, fine ones after)");
  sub->add_flag("!--no-readahead", o.readahead, "No readahead for the strips the loaders take: no posix_fadvise WILLNEED on disk; over HTTP, no prefetch of their records and grid blocks");
  sub->add_flag("--json", a->json, "Print one JSON object");
  sub->add_option("--plot", o.plots, "Write holes and degraded frames against speed, FILE.png or FILE.svg (repeatable)")
      ->take_all()
      ->allow_extra_args(false);
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli
