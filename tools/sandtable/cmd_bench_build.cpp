// sandtable bench build: flags and printing for bench::runBuildBench, our
// grid conversion against the gdalwarp binary on the same target grid.
#include <algorithm>
#include <cstdio>
#include <memory>

#include "cmd_bench.h"
#include "sandtable/bench/build.h"

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench build";

struct Args {
  bench::BuildBenchOptions o;
  bool json = false;
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

int run(const Args& a) {
  cancelOnSignals();
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

}  // namespace

void registerBenchBuild(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("build", "Time grid conversion against gdalwarp on the same target grid");
  sub->footer(
      "Example:\n  sandtable bench build --kernels bilinear,weighted --repeat 3\n"
      "Synthesizes a square (sandtable synth) unless --input names one, converts its DTED2 tree\n"
      "with our build and with the gdalwarp binary onto the same UTM grid, and reports the\n"
      "median seconds, posts/s and gdalwarp/ours ratios (> 1: we are faster). Needs gdal-bin.");
  sub->add_option("--input", o.input, "Existing synth output (uses DIR/dted2) or a directory of sources");
  sub->add_option("--size-km", o.sizeKm, "Side of the synthesized square (default: enough for 5000 x 5000 posts)")
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
  sub->add_option("--threads", o.threads, "Threads for ours and gdalwarp -multi (0 = all cores)")
      ->default_val(0)
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--json", a->json, "Print the results as one JSON object");
  sub->add_flag("--keep", o.keep, "Keep the work directory (synth data, outputs, logs)");
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli