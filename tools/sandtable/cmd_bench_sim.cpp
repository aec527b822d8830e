// sandtable bench sim: flags and printing for bench::runSimBench, the
// simulator's step with collisions against brute force.
#include <cstdio>
#include <memory>

#include "cmd_bench.h"
#include "sandtable/bench/sim.h"

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench sim";

struct Args {
  bench::SimBenchOptions o;
  bool json = false;
};

const FlagMap kFlags = {{"SimBenchOptions::entities", "--entities"}, {"SimBenchOptions::objects", "--objects"},
                        {"SimBenchOptions::sizeKm", "--size-km"},    {"SimBenchOptions::seconds", "--seconds"},
                        {"SimBenchOptions::bruteSeconds", "--brute-seconds"},
                        {"SimBenchOptions::repeat", "--repeat"}};

void printHuman(const nlohmann::json& j) {
  std::printf("bench sim: %.0f km square of %.0f m squares, %llu objects, one core, collisions on (medians of %d)\n",
              j["size_km"].get<double>(), j["square_m"].get<double>(),
              static_cast<unsigned long long>(j["objects"].get<std::uint64_t>()), j["repeat"].get<int>());
  for (const auto& c : j["cases"]) {
    const auto& g = c["grid"];
    const auto& b = c["brute"];
    std::printf("  %6llu entities  grid %8.3f ms/step  %7.1f Hz  %12.0f entities/s  %s\n",
                static_cast<unsigned long long>(c["entities"].get<std::uint64_t>()), g["step_ms"].get<double>(),
                g["hz"].get<double>(), g["entities_per_s"].get<double>(),
                c["meets_60hz"].get<bool>() ? "meets 60 Hz" : "below 60 Hz");
    std::printf("                  brute force %8.3f ms/step  %7.1f Hz  (%.0fx the grid's time)\n",
                b["step_ms"].get<double>(), b["hz"].get<double>(), c["brute_over_grid"].get<double>());
  }
}

int run(const Args& a) {
  auto r = bench::runSimBench(a.o, stderrNotes("bench", a.json, kFlags));
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  if (a.json) std::printf("%s\n", r->json.dump(2).c_str());
  else printHuman(r->json);
  return kOk;
}

}  // namespace

void registerBenchSim(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("sim", "Entities simulated per second on one core, against brute-force collisions");
  sub->footer(
      "Example:\n  sandtable bench sim --entities 500,10000 --repeat 3\n"
      "The seed's Fort Hunter-Liggett case scaled up (VII.C.1): a 50 km square, 31,000 objects in clumps of\n"
      "about 3.9 per populated 125 m square, and zig-zagging land entities. The grid search (3x3 squares,\n"
      "100 m box) and brute force (every object, every pair) run alternately on the same world.");
  sub->add_option("--entities", o.entities, "Entity counts, comma separated")->delimiter(',')->default_str("500,10000");
  sub->add_option("--objects", o.objects, "Static objects")->default_val(31000);
  sub->add_option("--size-km", o.sizeKm, "Side of the square, km")->default_val(50);
  sub->add_option("--seconds", o.seconds, "Simulated seconds per grid run")->default_val(10);
  sub->add_option("--brute-seconds", o.bruteSeconds, "Simulated seconds per brute-force run")->default_val(1);
  sub->add_option("--repeat", o.repeat, "Runs of each (median reported)")->default_val(3);
  sub->add_option("--seed", o.seed, "Seed of the world and the entities")->default_val(1);
  sub->add_flag("--json", a->json, "Print one JSON object");
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli
