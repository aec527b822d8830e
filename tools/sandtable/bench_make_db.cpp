// sandtable bench make-db: the standard paging benchmark database. Synth
// writes DTED2 and culture for a square, then the ordinary build turns them
// into a grid and 1 km load modules with roads decaled on, exactly as
// `sandtable synth` followed by `sandtable build` would.
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <system_error>

#include <nlohmann/json.hpp>

#include "bench_paging.h"
#include "progress.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"

namespace sandtable::cli {
namespace {

namespace fs = std::filesystem;

struct MakeDbArgs {
  std::string output = "out/bench-db";
  double sizeKm = 500;
  double spacing = 31.25;
  double moduleSize = 1000;
  int levels = 4;
  std::uint64_t seed = 1;
  int threads = 0;
  int zstdLevel = 9;
  bool force = false;
  bool keepInputs = false;
  bool json = false;
};

void onSignal(int) { convert::requestCancel(); }

void note(bool quiet, const std::string& s) {
  if (!quiet) std::fprintf(stderr, "bench make-db: %s\n", s.c_str());
}

int fail(const std::vector<Problem>& problems, const char* what) {
  for (const Problem& p : problems) {
    usageError("bench make-db", std::string(what) + ": " + p.str());
  }
  return kUsage;
}

/// Synth inputs in a sibling directory, so a failed build leaves the
/// output untouched and the inputs can be reused (--keep-inputs).
Result<convert::SynthSummary> synthesizeInputs(const MakeDbArgs& a, const fs::path& dir) {
  convert::SynthOptions so;
  so.outDir = dir.string();
  so.sizeKm = a.sizeKm;
  so.seed = a.seed;
  so.threads = a.threads;
  so.force = true;
  // The build reads DTED2 and culture only; the rest would cost time and disk.
  so.dted1 = false;
  so.dem = false;
  if (Status valid = convert::validateSynthOptions(so); !valid) return valid.problems();
  Progress progress(a.json);
  auto s = convert::synthesize(so, [&](double f, const std::string& stage) { progress.update(f, "synth " + stage); });
  progress.done();
  return s;
}

Result<convert::ElevationReport> buildDb(const MakeDbArgs& a, const convert::SynthSummary& s,
                                         const fs::path& in) {
  convert::ElevationOptions o;
  o.sources = {(in / "dted2").string()};
  o.culture = {(in / "culture.gpkg").string()};
  o.output = a.output;
  o.spacing = a.spacing;
  o.extent = std::array<double, 4>{s.west, s.south, s.east, s.north};
  o.moduleSize = a.moduleSize;
  o.levels = a.levels;
  o.threads = a.threads;
  o.zstdLevel = a.zstdLevel;
  o.force = a.force;
  Progress progress(a.json);
  auto r = convert::buildElevation(o, [&](double f, const std::string& stage) { progress.update(f, stage); });
  progress.done();
  return r;
}

int runMakeDb(const MakeDbArgs& a) {
  if (fs::exists(a.output) && !a.force) {
    return usageError("bench make-db", a.output + " exists; pass --force to replace it or choose another -o");
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  const fs::path in = fs::path(a.output).string() + ".synth";
  note(a.json, "synthesizing a " + std::to_string(int(a.sizeKm)) + " km square (DTED2 + culture) in " + in.string());
  auto s = synthesizeInputs(a, in);
  if (!s) return fail(s.problems(), "synth");
  note(a.json, "synth done in " + std::to_string(s->seconds) + " s; building " + a.output);
  auto r = buildDb(a, s.value(), in);
  std::error_code ec;
  if (!a.keepInputs) fs::remove_all(in, ec);
  if (!r) return fail(r.problems(), "build");
  nlohmann::json j = {{"output", a.output},
                      {"size_km", a.sizeKm},
                      {"spacing_m", a.spacing},
                      {"module_size_m", a.moduleSize},
                      {"levels", a.levels},
                      {"posts", r->posts},
                      {"modules", r->modules},
                      {"synth_s", s->seconds},
                      {"build_s", r->seconds},
                      {"module_stage_s", r->moduleSeconds},
                      {"module_bytes", r->manifest.build["modules"]["bytes"]},
                      {"roads", s->roads}};
  if (a.json) {
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("bench make-db: %s: %.0f km square, %.2f m posts, %llu posts, %llu modules of %.0f m, %d levels\n",
                a.output.c_str(), a.sizeKm, a.spacing, static_cast<unsigned long long>(r->posts),
                static_cast<unsigned long long>(r->modules), a.moduleSize, a.levels);
    std::printf("  synth %.1f s, build %.1f s (modules %.1f s), %d roads\n", s->seconds, r->seconds, r->moduleSeconds,
                s->roads);
  }
  return kOk;
}

}  // namespace

void registerBenchMakeDb(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<MakeDbArgs>();
  auto* sub = bench.add_subcommand("make-db", "Build the standard paging benchmark database from synth");
  sub->footer(
      "Example:\n  sandtable bench make-db -o out/bench-db            # 500 x 500 km, 31.25 m posts, 1 km modules, 4 levels\n"
      "  sandtable bench make-db -o out/bench-db-100 --size-km 100\n"
      "Synthesizes DTED2 and culture (roads, rivers, lakes, forest) into OUTPUT.synth, builds OUTPUT\n"
      "with load modules and decaled culture, then removes OUTPUT.synth unless --keep-inputs.\n"
      "The full square takes a long time and several GB of disk; see docs/PAGER.md.");
  sub->add_option("-o,--output", a->output, "Database directory to create")->default_val("out/bench-db");
  sub->add_option("--size-km", a->sizeKm, "Side of the square in km (standard: 500)")
      ->default_val(500)
      ->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--spacing", a->spacing, "Post spacing in metres")->default_val(31.25)->check(CLI::PositiveNumber);
  sub->add_option("--module-size", a->moduleSize, "Load module edge in metres")
      ->default_val(1000)
      ->check(CLI::PositiveNumber);
  sub->add_option("--levels", a->levels, "Levels of detail")->default_val(4)->check(CLI::Range(1, 8));
  sub->add_option("--seed", a->seed, "Synth random seed")->default_val(1);
  sub->add_option("--threads", a->threads, "Threads (0 = all cores)")->default_val(0);
  sub->add_option("--zstd-level", a->zstdLevel, "Module compression level")->default_val(9)->check(CLI::Range(1, 22));
  sub->add_flag("--force", a->force, "Replace OUTPUT if it exists");
  sub->add_flag("--keep-inputs", a->keepInputs, "Keep the synth inputs in OUTPUT.synth");
  sub->add_flag("--json", a->json, "Print one JSON object (no progress)");
  c.add(sub, [a] { return runMakeDb(*a); });
}

}  // namespace sandtable::cli
