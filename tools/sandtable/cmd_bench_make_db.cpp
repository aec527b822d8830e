// sandtable bench make-db: flags, progress and printing for
// bench::makeBenchDatabase, the standard paging benchmark database.
#include <cstdio>
#include <memory>

#include "cmd_bench.h"
#include "progress.h"
#include "sandtable/bench/make_db.h"

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench make-db";

struct Args {
  bench::MakeDbOptions o;
  bool json = false;
  std::string repackFrom;  ///< rewrite this database's pack instead of building
  std::string packLayout = "v2-morton";
};

const FlagMap kFlags = {{"MakeDbOptions::output", "-o"},          {"MakeDbOptions::sizeKm", "--size-km"},
                        {"MakeDbOptions::spacing", "--spacing"},   {"MakeDbOptions::moduleSize", "--module-size"},
                        {"MakeDbOptions::levels", "--levels"},     {"MakeDbOptions::seed", "--seed"},
                        {"MakeDbOptions::threads", "--threads"},   {"MakeDbOptions::zstdLevel", "--zstd-level"},
                        {"MakeDbOptions::force", "--force"},       {"MakeDbOptions::keepInputs", "--keep-inputs"}};

void printHuman(const bench::MakeDbOptions& o, const bench::MakeDbReport& r) {
  std::printf("bench make-db: %s: %.0f km square, %.2f m posts, %llu posts, %llu modules of %.0f m, %d levels\n",
              o.output.c_str(), o.sizeKm, o.spacing, static_cast<unsigned long long>(r.posts),
              static_cast<unsigned long long>(r.modules), o.moduleSize, o.levels);
  std::printf("  synth %.1f s, build %.1f s (modules %.1f s), %d roads\n", r.synthSeconds, r.buildSeconds,
              r.moduleStageSeconds, r.roads);
}

int run(const Args& a) {
  cancelOnSignals();
  // Each note starts a stage (synth, then the build): the bar of the one
  // before ends, and the next one's clock starts from zero.
  std::unique_ptr<Progress> progress;
  bench::Notes notes = stderrNotes("bench make-db", a.json, kFlags);
  notes.note = [&, say = notes.note](const std::string& line) {
    progress.reset();
    if (say) say(line);
    progress = std::make_unique<Progress>(a.json);
  };
  notes.progress = [&](double f, const std::string& stage) {
    if (progress) progress->update(f, stage);
  };
  if (!a.repackFrom.empty()) {
    const pack::PackLayout layout = a.packLayout == "v1"         ? pack::PackLayout{}
                                    : a.packLayout == "v2-rows" ? pack::PackLayout::split(std::uint32_t(a.o.levels), pack::PackOrder::rowMajor)
                                                                : pack::PackLayout::split(std::uint32_t(a.o.levels));
    auto rp = bench::repackBenchDatabase(a.repackFrom, a.o.output, layout, a.o.threads, a.o.zstdLevel, a.o.force, notes);
    progress.reset();
    if (!rp) return reportBenchProblems(kCmd, rp.problems(), kFlags);
    std::printf("%s\n", rp->dump(2).c_str());
    return kOk;
  }
  auto r = bench::makeBenchDatabase(a.o, notes);
  progress.reset();
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  if (a.json) std::printf("%s\n", r->json.dump(2).c_str());
  else printHuman(a.o, r.value());
  return kOk;
}

}  // namespace

void registerBenchMakeDb(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("make-db", "Build the standard paging benchmark database from synth");
  sub->footer(
      "Example:\n  sandtable bench make-db -o out/bench-db            # 500 x 500 km, 31.25 m posts, 1 km modules, 4 levels\n"
      "  sandtable bench make-db -o out/bench-db-100 --size-km 100\n"
      "Synthesizes DTED2 and culture (roads, rivers, lakes, forest) into OUTPUT.synth, builds OUTPUT\n"
      "with load modules and decaled culture, then removes OUTPUT.synth unless --keep-inputs.\n"
      "The full square takes a long time and several GB of disk; see docs/PAGER.md.");
  sub->add_option("-o,--output", o.output, "Database directory to create")->default_val("out/bench-db");
  sub->add_option("--size-km", o.sizeKm, "Side of the square in km (standard: 500)")
      ->default_val(500)
      ->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--spacing", o.spacing, "Post spacing in metres")->default_val(31.25)->check(CLI::PositiveNumber);
  sub->add_option("--module-size", o.moduleSize, "Load module edge in metres")
      ->default_val(1000)
      ->check(CLI::PositiveNumber);
  sub->add_option("--levels", o.levels, "Levels of detail")->default_val(4)->check(CLI::Range(1, 8));
  sub->add_option("--seed", o.seed, "Synth random seed")->default_val(1);
  sub->add_option("--threads", o.threads, "Threads (0 = all cores)")->default_val(0);
  sub->add_option("--zstd-level", o.zstdLevel, "Module compression level")->default_val(9)->check(CLI::Range(1, 22));
  sub->add_flag("--force", o.force, "Replace OUTPUT if it exists");
  sub->add_flag("--keep-inputs", o.keepInputs, "Keep the synth inputs in OUTPUT.synth");
  sub->add_flag("--json", a->json, "Print one JSON object (no progress)");
  sub->add_option("--repack-from", a->repackFrom,
                  "Instead of building: link DIR's files into OUTPUT and rewrite its pack in --pack-layout "
                  "(compares pack layouts on the same modules; --levels must match DIR's)");
  sub->add_option("--pack-layout", a->packLayout, "Pack layout of --repack-from")
      ->default_val("v2-morton")
      ->check(CLI::IsMember({"v1", "v2-morton", "v2-rows"}));
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli
