// sandtable bench build: flags and printing for bench::runBuildBench, our
// grid conversion against the gdalwarp binary on the same target grid; and,
// with --distributed, the one-machine build against the distributed one
// (plan, tasks, merge; docs/DISTRIBUTED.md), every step a child process.

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "cmd_bench.h"
#include "sandtable/bench/build.h"
#include "sandtable/bench/distributed_build.h"

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench build";

struct Args {
  bench::BuildBenchOptions o;
  bool json = false;
  bool distributed = false;
  std::uint32_t tasks = 8;              ///< --tasks (distributed)
  int concurrent = 2;                   ///< --concurrent (distributed)
  std::vector<std::string> buildArgs;   ///< after --: the build's own arguments (distributed)
};

const FlagMap kFlags = {{"BuildBenchOptions::input", "--input"},     {"BuildBenchOptions::sizeKm", "--size-km"},
                        {"BuildBenchOptions::spacing", "--spacing"}, {"BuildBenchOptions::kernels", "--kernels"},
                        {"BuildBenchOptions::repeat", "--repeat"},   {"BuildBenchOptions::threads", "--threads"},
                        {"BuildBenchOptions::keep", "--keep"}};

struct Context {
  const bench::BuildBenchOptions& args;
  const bench::BuildBenchReport& report;
  const bench::BuildBenchGrid& grid;
};

std::string threadsText(int threads, unsigned cpus) {
  return threads > 0 ? std::to_string(threads) : "all (" + std::to_string(cpus) + ")";
}

void printHeader(const Context& c) {
  std::printf("sandtable bench build: %u x %u posts (%.1f M) at %g m, %s\n", c.grid.postsX, c.grid.postsZ,
              static_cast<double>(c.grid.posts()) / 1e6, c.grid.spacing, c.grid.crsName.c_str());
  std::printf("  sources   %s, %zu files\n", c.report.source.c_str(), c.report.sourceFiles);
  std::printf("  gdalwarp  %s: same sources (VRT), CRS, -te, -tr; -of ENVI -ot Float32\n",
              c.report.gdalwarpVersion.c_str());
  std::printf("  method    one untimed warm-up of each side first, so both read the sources from the page cache;\n"
              "            then the median of %d repeats, wall clock, sides alternating\n", c.args.repeat);
  std::printf("  threads   ours %s; gdalwarp 1t = default (no -multi), mt = -multi -wo NUM_THREADS=%s\n",
              threadsText(c.args.threads, c.report.cpus).c_str(),
              c.args.threads > 0 ? std::to_string(c.args.threads).c_str() : "ALL_CPUS");
  std::printf("  load      %.2f at start, %.2f at end (1-minute load average, %u CPUs)\n\n",
              c.report.loadAverageStart, c.report.loadAverageEnd, c.report.cpus);
}

int kernelWidth(const std::vector<bench::BuildBenchRow>& rs) {
  std::size_t w = 6;
  for (const auto& r : rs) w = std::max(w, r.kernel.size());
  return static_cast<int>(w);
}

void printResults(const Context& c, const std::vector<bench::BuildBenchRow>& rs) {
  const double posts = static_cast<double>(c.grid.posts());
  const int w = kernelWidth(rs);
  std::printf("%-*s %8s %9s %9s | %-8s %8s %9s %8s %9s | %7s %7s\n", w, "kernel", "ours s", "Mposts/s", "resamp s",
              "gdalwarp", "1t s", "Mposts/s", "mt s", "Mposts/s", "1t/ours", "mt/ours");
  for (const auto& r : rs) {
    std::printf("%-*s %8.2f %9.2f %9.2f | %-8s %8.2f %9.2f %8.2f %9.2f | %7.2f %7.2f\n", w, r.kernel.c_str(),
                r.oursS, posts / r.oursS / 1e6, r.oursResampleS, r.warpKernel.c_str(), r.warp1tS,
                posts / r.warp1tS / 1e6, r.warpMtS, posts / r.warpMtS / 1e6, r.warp1tS / r.oursS, r.warpMtS / r.oursS);
  }
  std::printf("\nratio = gdalwarp seconds / our seconds: above 1 we are faster. Ours is the whole build\n"
              "(read + CRC of the sources, resample, void fill, normals, grid file with CRCs, fsync);\n"
              "\"resamp s\" is its resampling stage alone. gdalwarp only resamples and writes raw floats.\n");
}

/// Where our time goes, and CPU seconds, which other users' load inflates
/// less than wall time. Once per kernel of ours.
void printBreakdown(const std::vector<bench::BuildBenchRow>& rs) {
  std::printf("\nours by stage (median s) and CPU seconds (user + system, median):\n");
  std::string last;
  for (const auto& r : rs) {
    if (r.kernel == last) continue;
    last = r.kernel;
    std::printf("  %-18s", r.kernel.c_str());
    for (const auto& [name, sec] : r.oursStages) std::printf(" %s %.2f,", name.c_str(), sec);
    std::printf(" cpu %.1f\n", r.oursCpuS);
  }
  std::vector<std::string> seen;
  for (const auto& r : rs) {
    if (std::find(seen.begin(), seen.end(), r.warpKernel) != seen.end()) continue;
    seen.push_back(r.warpKernel);
    std::printf("  gdalwarp %-9s cpu %.1f (1t), %.1f (mt)\n", r.warpKernel.c_str(), r.warp1tCpuS, r.warpMtCpuS);
  }
}

/// The goal: no slower than gdalwarp, i.e. ratio >= 1 against
/// gdalwarp's faster mode.
void printVerdict(const std::vector<bench::BuildBenchRow>& rs) {
  std::printf("\ngoal (no slower than gdalwarp, against its faster mode):\n");
  for (const auto& r : rs) {
    const double ratio = std::min(r.warp1tS, r.warpMtS) / r.oursS;
    std::printf("  %-18s vs %-8s %5.2f  %s\n", r.kernel.c_str(), r.warpKernel.c_str(), ratio,
                ratio >= 1 ? "met" : "NOT met");
  }
}

void printTable(const Context& c, const std::vector<bench::BuildBenchRow>& rs) {
  printHeader(c);
  printResults(c, rs);
  printBreakdown(rs);
  printVerdict(rs);
}

int runDistributed(const Args& a);

int run(const Args& a) {
  cancelOnSignals();
  if (a.distributed) return runDistributed(a);
  if (!a.buildArgs.empty()) {
    return usageError(kCmd, "build arguments after -- need --distributed (the gdalwarp comparison builds its own)");
  }
  auto r = bench::runBuildBench(a.o, stderrNotes("bench", false, kFlags));
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  bench::BuildBenchReport& rep = r.value();
  rep.source = withFlags(rep.source, kFlags);
  rep.json["source"] = rep.source;
  if (a.json) {
    std::printf("%s\n", rep.json.dump(2).c_str());
  } else {
    const Context c{a.o, rep, rep.grid};
    printTable(c, rep.rows);
  }
  return kOk;
}

// ------------------------------------------------------------ --distributed

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : " ") + x;
  return s;
}

std::string mb(std::uint64_t bytes) {
  char s[32];
  std::snprintf(s, sizeof s, "%.1f MB", double(bytes) / 1e6);
  return s;
}

void printStepRow(const char* name, const bench::DistributedStep& s) {
  std::string samples;
  for (double v : s.samples) {
    char t[32];
    std::snprintf(t, sizeof t, "%s%.2f", samples.empty() ? "" : " ", v);
    samples += t;
  }
  std::printf("  %-34s %8.2f %8.1f %8.0f %7.0f  %s\n", name, s.median(), s.cpuS, double(s.peakRssBytes) / 1e6,
              double(s.peakAnonBytes) / 1e6, samples.c_str());
}

void printDistributed(const bench::DistributedBuildReport& r) {
  const double oneAll = r.oneAll.median(), one1 = r.one1.median(), serial = r.serial.median(),
               conc = r.concurrentStep.median(), merge = r.merge.median();
  std::printf("sandtable bench build --distributed: %u x %u posts (%.2f M), %llu modules, %u tasks\n", r.postsX,
              r.postsZ, r.posts() / 1e6, static_cast<unsigned long long>(r.modules), r.tasks);
  std::printf("  build     %s\n            (%s)\n", joined(r.input.args).c_str(), r.input.description.c_str());
  std::printf("  method    every step a child process (this executable); one untimed plan first, which reads\n"
              "            every input (page cache); then the median of %d repeats, wall clock; parts and\n"
              "            databases on one disk (%s)\n", r.repeat, r.work.c_str());
  std::printf("  load      %.2f at start, %.2f at end (1-minute load average, %u CPUs)\n\n", r.loadStart, r.loadEnd,
              r.cpus);
  std::printf("  %-34s %8s %8s %8s %7s  %s\n", "step", "median s", "cpu s", "peak RSS", "anon", "samples s");
  printStepRow(("one machine, threads " + threadsText(r.threads, r.cpus)).c_str(), r.oneAll);
  printStepRow("one machine, threads 1", r.one1);
  printStepRow("plan", r.plan);
  printStepRow("tasks 1 at a time, threads 1", r.serial);
  printStepRow(("tasks " + std::to_string(r.concurrent) + " at a time, threads 1").c_str(), r.concurrentStep);
  printStepRow("merge", r.merge);
  std::printf("  (MB, the largest of the step's processes: peak RSS from wait4, mapped files included; anon: its\n"
              "  largest RssAnon, sampled every 5 ms. cpu s: user + system of all its processes)\n\n");
  std::vector<double> perTask;
  for (const auto& t : r.perTask) perTask.push_back(stats::median(t));
  const auto [lo, hi] = std::minmax_element(perTask.begin(), perTask.end());
  std::printf("tasks     1 at a time %.2f tasks/s, %d at a time %.2f tasks/s: speed-up %.2fx\n", r.tasks / serial,
              r.concurrent, r.tasks / conc, serial / conc);
  std::printf("          %d at a time, speed-up over the one-machine build: %.2fx (threads 1), %.2fx (threads %s)\n",
              r.concurrent, one1 / conc, oneAll / conc, threadsText(r.threads, r.cpus).c_str());
  std::printf("          per task (median s, 1 at a time): min %.2f, median %.2f, max %.2f", *lo, stats::median(perTask), *hi);
  if (perTask.size() <= 16) {
    std::printf(":");
    for (std::size_t t = 0; t < perTask.size(); ++t) std::printf(" %zu:%.2f", t, perTask[t]);
  }
  std::printf("\n          work: the tasks' seconds add up to %.2fx the one-machine threads-1 build (each task\n"
              "          loads the whole culture, re-reads every source for its CRC and resamples a halo)\n",
              serial / one1);
  std::printf("          rate: %.2f M posts/s per task process (1 thread), %.0f modules/s\n", r.posts() / serial / 1e6,
              double(r.modules) / serial);
  const double pct = 100 * merge / oneAll;
  std::printf("merge     %.2f s: %s of parts read + %s written = %.0f MB/s\n", merge, mb(r.partsBytes).c_str(),
              mb(r.dbBytes).c_str(), double(r.partsBytes + r.dbBytes) / merge / 1e6);
  std::printf("          peak RSS %.0f MB, anonymous %.0f MB (pack index %llu x 64 B = %.2f MB; grid.stg %s)\n",
              double(r.merge.peakRssBytes) / 1e6, double(r.merge.peakAnonBytes) / 1e6,
              static_cast<unsigned long long>(r.modules), double(r.modules) * 64 / 1e6, mb(r.gridBytes).c_str());
  std::printf("          %.1f%% of the one-machine build (threads %s), %.1f%% of its threads-1 time\n", pct,
              threadsText(r.threads, r.cpus).c_str(), 100 * merge / one1);
  std::printf("          distributed end to end (plan + %d at a time + merge): %.2f s\n", r.concurrent,
              r.plan.median() + conc + merge);
  std::printf("goal      merge < %.0f%% of the single-machine build: %s (%.1f%%)\n", bench::kMergeGoalPercent,
              pct < bench::kMergeGoalPercent ? "met" : "MISSED", pct);
  std::printf("identical");
  for (const auto& [file, same] : r.identical) std::printf(" %s %s,", file.c_str(), same ? "yes" : "NO");
  std::printf(" manifest.json apart from kVolatileManifestKeys %s\n", r.manifestDiffs.empty() ? "yes" : "NO");
  for (std::size_t k = 0; k < r.manifestDiffs.size() && k < 8; ++k) {
    std::printf("          manifest differs at %s\n", r.manifestDiffs[k].c_str());
  }
}

int runDistributed(const Args& a) {
  if (a.tasks < 1) return usageError(kCmd, "--tasks must be at least 1");
  if (a.concurrent < 1) return usageError(kCmd, "--concurrent must be at least 1");
  if (!a.buildArgs.empty() && (!a.o.input.empty() || a.o.sizeKm > 0)) {
    return usageError(kCmd, "--input and --size-km choose the default inputs; leave them out with build arguments "
                            "after --");
  }
  for (const auto& arg : a.buildArgs) {
    for (const auto& own : bench::kDistributedOwnFlags) {
      if (arg == own || arg.rfind(own + "=", 0) == 0) {
        return usageError(kCmd, "the build arguments after -- must leave out " + own + ": the bench sets it");
      }
    }
  }
  // Every step runs this executable as /proc/self/exe, so a rebuild that
  // replaces the file mid-run does not change (or break) the bench.
  const bench::DistributedBuildOptions o{"/proc/self/exe", a.o, a.tasks, a.concurrent, a.buildArgs};
  bench::Notes notes;
  notes.note = [](const std::string& line) { std::fprintf(stderr, "bench: %s\n", line.c_str()); };
  auto r = bench::runDistributedBuildBench(o, notes);
  if (!r) return reportProblems(kCmd, r.problems());
  if (a.json) std::printf("%s\n", bench::distributedBuildJson(r.value()).dump(2).c_str());
  else printDistributed(r.value());
  bool same = r->manifestDiffs.empty();
  for (const auto& [file, ok] : r->identical) same = same && ok;
  return same ? kOk : kProblems;
}
}  // namespace

void registerBenchBuild(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("build", "Time grid conversion against gdalwarp on the same target grid");
  sub->footer(
      "Example:\n  sandtable bench build --kernels bilinear,weighted --repeat 3\n"
      "Synthesizes a square (sandtable synth) unless --input names one, converts its DTED2 tree\n"
      "with our build and with the gdalwarp binary onto the same UTM grid, and reports the\n"
      "median seconds, posts/s and gdalwarp/ours ratios (> 1: we are faster). Needs gdal-bin.\n"
      "  sandtable bench build --distributed --tasks 8 -- --elevation N49E011.hgt.zip --spacing 30\n"
      "times the one-machine build, the plan, the tasks (1 and --concurrent at a time, threads 1) and\n"
      "the merge (MB/s, peak RSS, share of the one-machine build) and compares the databases byte for\n"
      "byte (docs/DISTRIBUTED.md).");
  sub->add_option("--input", o.input, "Existing synth output (uses DIR/dted2) or a directory of sources");
  sub->add_option("--size-km", o.sizeKm,
                  "Side of the synthesized square (default: enough for 5000 x 5000 posts; with --distributed, 40)")
      ->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--spacing", o.spacing, "Target post spacing in metres")
      ->default_val(30.0)
      ->check(CLI::PositiveNumber);
  sub->add_option("--kernels", o.kernels,
                  "Our kernels: weighted, bilinear (point samples, as gdalwarp), bilinear-triangles (plus the "
                  "triangle fit, as `sandtable build --resample bilinear`), cubic, average")
      ->delimiter(',')
      ->default_str("bilinear,weighted");
  sub->add_option("--repeat", o.repeat, "Timed runs of each measurement (median reported)")
      ->default_val(3)
      ->check(CLI::Range(1, 100));
  sub->add_option("--threads", o.threads,
                  "Threads for ours and gdalwarp -multi (0 = all cores); with --distributed, the one-machine "
                  "build's")
      ->default_val(0)
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--json", a->json, "Print the results as one JSON object");
  sub->add_flag("--keep", o.keep, "Keep the work directory (synth data, outputs, logs)");
  auto* dist = "Distributed build (--distributed; docs/DISTRIBUTED.md)";
  sub->add_flag("--distributed", a->distributed,
                "Time the one-machine build against plan, tasks (1 and --concurrent at a time) and merge, and "
                "check that the databases are byte-identical")
      ->group(dist);
  sub->add_option("--tasks", a->tasks, "Tasks to split the build into")->default_val(8)->group(dist);
  sub->add_option("--concurrent", a->concurrent, "Tasks run at once in the second pass (threads 1 each)")
      ->default_val(2)
      ->check(CLI::Range(1, 1024))
      ->group(dist);
  sub->add_option("BUILD_ARGS", a->buildArgs,
                  "After --: the build's arguments (sources, extent, spacing, ...; not -o, --threads or the "
                  "distributed flags); default: a synthesized square (--size-km, default 40) at --spacing")
      ->group(dist);
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli