// sandtable bench modules: flags and printing for bench::runModulesBench,
// the full build against the elevation-only build of one synthetic square.
#include <cstdio>
#include <memory>

#include "cmd_bench.h"
#include "sandtable/bench/modules.h"

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench modules";

struct Args {
  bench::ModulesBenchOptions o;
  bool json = false;
};

const FlagMap kFlags = {{"ModulesBenchOptions::input", "--input"},         {"ModulesBenchOptions::sizeKm", "--size-km"},
                        {"ModulesBenchOptions::spacing", "--spacing"},     {"ModulesBenchOptions::repeat", "--repeat"},
                        {"ModulesBenchOptions::threads", "--threads"},     {"ModulesBenchOptions::zstdLevel", "--zstd-level"},
                        {"ModulesBenchOptions::keep", "--keep"}};

void printHuman(const nlohmann::json& j) {
  std::printf("bench modules: %.0f km synthetic square at %.2f m posts, %d runs each (median)\n",
              j["size_km"].get<double>(), j["spacing_m"].get<double>(), j["repeat"].get<int>());
  std::printf("  elevation-only build  %8.2f s\n", j["elevation_only_s"].get<double>());
  std::printf("  full build            %8.2f s  (%.2fx the elevation-only build)\n", j["full_build_s"].get<double>(),
              j["full_over_elevation"].get<double>());
  std::printf("  module stage          %8.2f s  %llu modules, %.0f modules/s\n", j["module_stage_s"].get<double>(),
              static_cast<unsigned long long>(j["modules"].get<std::uint64_t>()),
              j["modules_per_second"].get<double>());
  const auto& b = j["module_bytes"];
  std::printf("  module bytes          min %u, median %u, p95 %u, max %u (compressed); seed modules were < 2 KB\n",
              b["min"].get<unsigned>(), b["median"].get<unsigned>(), b["p95"].get<unsigned>(),
              b["max"].get<unsigned>());
  std::printf("  culture               %llu features, %.1f km of lines\n",
              static_cast<unsigned long long>(j["culture_features"].get<std::uint64_t>()), j["line_km"].get<double>());
}

int run(const Args& a) {
  auto r = bench::runModulesBench(a.o, stderrNotes("bench", a.json, kFlags));
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  if (a.json) std::printf("%s\n", r->json.dump(2).c_str());
  else printHuman(r->json);
  return kOk;
}

}  // namespace

void registerBenchModules(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("modules", "Time the full build (culture + load modules) against elevation only");
  sub->footer(
      "Example:\n  sandtable bench modules --size-km 100 --repeat 3\n"
      "Synthesizes a square (or uses --input, a `sandtable synth` directory), then builds it alternately\n"
      "with culture and load modules and with elevation only, and reports medians, modules/s and sizes.");
  sub->add_option("--input", o.input, "An existing `sandtable synth` output directory");
  sub->add_option("--size-km", o.sizeKm, "Side of the synthesized square")->default_val(100)->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--spacing", o.spacing, "Post spacing in metres")->default_val(31.25)->check(CLI::PositiveNumber);
  sub->add_option("--repeat", o.repeat, "Runs of each build (median reported)")->default_val(3)->check(CLI::Range(1, 100));
  sub->add_option("--threads", o.threads, "Threads (0 = all cores)")->default_val(0);
  sub->add_option("--zstd-level", o.zstdLevel, "Module compression level")->default_val(9)->check(CLI::Range(1, 22));
  sub->add_flag("--json", a->json, "Print one JSON object");
  sub->add_flag("--keep", o.keep, "Keep the work directory");
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli
