// sandtable bench edits: flags and printing for bench::runEditsBench, what a
// crater costs from apply() to the ground drawn (issue 37).
#include <cstdio>
#include <memory>

#include "cmd_bench.h"
#include "sandtable/bench/edits.h"

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench edits";

struct Args {
  bench::EditsBenchOptions o;
  bool json = false;
  bool quick = false;
};

const FlagMap kFlags = {{"EditsBenchOptions::database", "--db"},
                        {"EditsBenchOptions::sizeKm", "--size-km"},
                        {"EditsBenchOptions::repeat", "--repeat"},
                        {"EditsBenchOptions::journalEdits", "--journal-edits"},
                        {"EditsBenchOptions::journalMeshedEdits", "--journal-meshed-edits"},
                        {"EditsBenchOptions::memoryCraters", "--memory-craters"},
                        {"EditsBenchOptions::latencySamples", "--latency-samples"},
                        {"EditsBenchOptions::rates", "--rates"},
                        {"EditsBenchOptions::sustainSeconds", "--sustain-seconds"},
                        {"EditsBenchOptions::battleCraters", "--battle-craters"},
                        {"EditsBenchOptions::battlePerFrame", "--battle-per-frame"},
                        {"EditsBenchOptions::viewDistance", "--view-distance"}};

/// --quick: every part, small (a smoke run of a few seconds).
void makeQuick(bench::EditsBenchOptions& o) {
  o.sizeKm = 3;
  o.repeat = 3;
  o.journalEdits = 2000;
  o.journalMeshedEdits = 20;
  o.memoryCraters = 20;
  o.latencySamples = 3;
  o.rates = {30};
  o.sustainSeconds = 0.5;
  o.battleCraters = 100;
}

double num(const nlohmann::json& j, const char* key) { return j[key].get<double>(); }
unsigned long long count(const nlohmann::json& j, const char* key) { return j[key].get<unsigned long long>(); }

void printRemesh(const nlohmann::json& j) {
  std::printf("  re-mesh and publish, medium crater (thread CPU, median; baseline: the build's path for the same modules)\n");
  for (const auto& c : j["remesh"]) {
    std::printf("    %-10s %3llu modules  %7.2f ms (wall %7.2f, cold %7.2f)  baseline %8.2f ms  %6.1fx\n",
                c["case"].get<std::string>().c_str(), count(c, "modules"), num(c, "cpu_ms"), num(c, "wall_ms"),
                num(c, "cold_ms"), num(c, "baseline_cpu_ms"), num(c, "baseline_over_remesh"));
  }
}

void printJournalMemory(const nlohmann::json& j) {
  const auto& jr = j["journal"];
  std::printf("  journal replay    %llu small craters in %.3f s (read %.3f s): %.3f s per 100,000 (heights only)\n",
              count(jr, "edits"), num(jr, "replay_s"), num(jr, "read_s"), num(jr, "replay_per_100k_s"));
  if (jr.contains("meshed")) {
    std::printf("                    %llu with modules re-meshed in %.3f s: %.1f s per 100,000\n",
                count(jr["meshed"], "edits"), num(jr["meshed"], "replay_s"), num(jr["meshed"], "per_100k_s"));
  }
  const auto& m = j["memory"]["per_1000"];
  std::printf("  memory / 1,000    heights %.1f MB, re-meshed modules %.1f MB, RSS %+.1f MB (medium craters)\n",
              num(m, "heights_bytes") / 1e6, num(m, "remeshed_module_bytes") / 1e6, num(m, "rss_delta_bytes") / 1e6);
}

void printLive(const nlohmann::json& j) {
  const auto& l = j["latency"];
  std::printf("  detonation->drawn published %.1f ms, resident at level 0 %.1f ms (p50; max %.1f ms = %.0f frames at 60 Hz)\n",
              num(l["published_ms"], "p50"), num(l["drawn_ms"], "p50"), num(l["drawn_ms"], "max"),
              num(l["drawn_frames_60hz"], "max"));
  for (const auto& s : j["sustained"]) {
    std::printf("  sustained %5.0f/s  holes %llu, frames over budget %llu/%llu, latency p95 %.0f frames, worker %.0f%% busy, %s\n",
                num(s, "rate_per_s"), count(s, "holes"), count(s, "frames_over_budget"), count(s, "frames"),
                num(s["latency_frames"], "p95"), 100 * num(s, "worker_busy"),
                s["keeps_up"].get<bool>() ? "keeps up" : "falls behind");
  }
  if (j.contains("battle")) {
    const auto& b = j["battle"];
    std::printf("  battle            %llu craters: applied in %.2f s, all drawn after %.2f s; holes %llu, frames over "
                "budget %llu/%llu, worker %.2f s CPU\n",
                count(b, "craters"), num(b, "apply_seconds"), num(b, "seconds"), count(b, "holes"),
                count(b, "frames_over_budget"), count(b, "frames"), num(b, "worker_cpu_s"));
  }
}

void printHuman(const nlohmann::json& j) {
  std::printf("bench edits: %s, %.2f m posts, %llu modules of %.0f m, %u cpus\n", j["database"].get<std::string>().c_str(),
              num(j, "spacing_m"), count(j, "modules"), num(j, "module_size_m"), j["cpus"].get<unsigned>());
  printRemesh(j);
  printJournalMemory(j);
  printLive(j);
  std::printf("  goals\n");
  for (const auto& [name, g] : j["goals"].items()) {
    std::printf("    %-34s %10.3f  (goal %g)  %s\n", name.c_str(), g["value"].get<double>(), g["goal"].get<double>(),
                g["met"].get<bool>() ? "met" : "MISSED");
  }
}

int run(Args& a) {
  if (a.quick) makeQuick(a.o);
  auto r = bench::runEditsBench(a.o, stderrNotes("bench", a.json, kFlags));
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  if (a.json) std::printf("%s\n", r->json.dump(2).c_str());
  else printHuman(r->json);
  return kOk;
}

}  // namespace

void registerBenchEdits(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("edits", "Dynamic terrain: re-mesh, journal replay, memory, latency and craters per second");
  sub->footer(
      "Example:\n  sandtable bench edits                 # a synthesized 6 km square\n"
      "  sandtable bench edits --db out/bayreuth --battle-craters 2000\n"
      "Re-mesh time per crater touching 1, 2 and 4 modules against building them with the build's path,\n"
      "journal replay per 100,000 edits, memory per 1,000 craters, apply()-to-drawn latency with a headless\n"
      "pager, sustained craters per second and a battle, all in one run (docs/DYNAMIC.md, \"Benchmark\").");
  sub->add_option("--db", o.database, "A database with load modules (default: synthesize one)");
  sub->add_option("--size-km", o.sizeKm, "Side of the synthesized square, km")->default_val(6);
  sub->add_option("--repeat", o.repeat, "Repeats of each re-mesh case and replay (median reported)")->default_val(7);
  sub->add_option("--journal-edits", o.journalEdits, "Edits in the replayed journal")->default_val(100000);
  sub->add_option("--journal-meshed-edits", o.journalMeshedEdits, "Edits replayed with modules re-meshed (0: skip)")->default_val(1000);
  sub->add_option("--memory-craters", o.memoryCraters, "Craters applied for the memory figure")->default_val(1000);
  sub->add_option("--latency-samples", o.latencySamples, "Craters timed one at a time")->default_val(20);
  sub->add_option("--rates", o.rates, "Sustained rates, craters/s, comma separated")->delimiter(',')->default_str("10,30,100,300");
  sub->add_option("--sustain-seconds", o.sustainSeconds, "Seconds per sustained rate")->default_val(5);
  sub->add_option("--battle-craters", o.battleCraters, "Craters in the battle (0: skip)")->default_val(10000);
  sub->add_option("--battle-per-frame", o.battlePerFrame, "Most battle craters per frame")->default_val(50);
  sub->add_option("--view-distance", o.viewDistance, "The pager's view distance, m")->default_val(2500);
  sub->add_option("--seed", o.seed, "Seed of the synthesized square and the crater sites")->default_val(1);
  sub->add_flag("--quick", a->quick, "Every part, small (a smoke run; overrides the sizes)");
  sub->add_flag("--json", a->json, "Print one JSON object");
  sub->add_flag("--keep", o.keep, "Keep the work directory");
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli
