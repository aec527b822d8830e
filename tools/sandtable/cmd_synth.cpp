// sandtable synth: realistic synthetic inputs (DTED1/2, GeoTIFF, GeoPackage).
#include <csignal>
#include <cstdio>

#include "commands.h"
#include "progress.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"

namespace sandtable::cli {
namespace {

struct SynthArgs {
  convert::SynthOptions o;
  std::vector<double> center;
  bool json = false;
};

std::string humanBytes(std::uint64_t b) {
  char buf[32];
  if (b >= (1ull << 30)) std::snprintf(buf, sizeof buf, "%.2f GB", static_cast<double>(b) / (1ull << 30));
  else if (b >= (1ull << 20)) std::snprintf(buf, sizeof buf, "%.1f MB", static_cast<double>(b) / (1ull << 20));
  else std::snprintf(buf, sizeof buf, "%.1f kB", static_cast<double>(b) / 1024.0);
  return buf;
}

void printSummary(const convert::SynthSummary& s) {
  std::printf("synthesized %s\n", s.outDir.c_str());
  std::printf("  square     %.0f km centred %.4f, %.4f (lon, lat), seed %llu\n", s.sizeKm, s.centerLon, s.centerLat,
              static_cast<unsigned long long>(s.seed));
  std::printf("  bounds     W %.5f  S %.5f  E %.5f  N %.5f\n", s.west, s.south, s.east, s.north);
  std::printf("  dted       %d level-1 cells, %d level-2 cells\n", s.dted1Cells, s.dted2Cells);
  if (s.demWidth > 0) {
    std::printf("  dem.tif    %d x %d, %g arc-second pixels, Float32\n", s.demWidth, s.demHeight, s.demArcSeconds);
  }
  std::printf("  culture    %d roads, %d rivers, %d lakes, %d forest polygons\n", s.roads, s.rivers, s.lakes,
              s.forests);
  std::printf("  elevation  %.1f .. %.1f m\n", s.minElevation, s.maxElevation);
  std::printf("  files      %zu (+ synth.json), %s\n", s.files.size(), humanBytes(s.bytes).c_str());
  std::printf("  time       %.1f s\n", s.seconds);
}

// Ctrl-C stops the workers at the next row; the temp directory goes away.
void onSignal(int) { convert::requestCancel(); }

int runSynth(SynthArgs& a) {
  if (!a.center.empty()) {
    if (a.center.size() != 2) return usageError("synth", "--center takes LON LAT");
    a.o.centerLon = a.center[0];
    a.o.centerLat = a.center[1];
  }
  if (Status valid = convert::validateSynthOptions(a.o); !valid) return usageError("synth", valid.message());
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  Progress progress(a.json);
  auto result = convert::synthesize(a.o, [&](double f, const std::string& stage) { progress.update(f, stage); });
  progress.done();
  if (!result) {
    // The byte offset means nothing for files being written: path and message.
    for (const auto& p : result.problems()) {
      const bool named = p.file.empty() || p.message.find(p.file) != std::string::npos;
      const std::string line = named ? p.message : p.file + ": " + p.message;
      usageError("synth", line);
    }
    std::fprintf(stderr, "sandtable synth: nothing was written\n");
    return kUsage;
  }
  if (a.json) {
    std::fputs(result->json.c_str(), stdout);
  } else {
    printSummary(result.value());
  }
  return kOk;
}

}  // namespace

void registerSynth(CLI::App& root, Commands& c) {
  auto a = std::make_shared<SynthArgs>();
  auto* sub = root.add_subcommand("synth", "Write synthetic DTED, GeoTIFF and GeoPackage inputs");
  sub->footer(
      "Example:\n  sandtable synth -o data --size-km 20 --seed 1\n"
      "Writes DIR/dted1/eXXX/nYY.dt1, DIR/dted2/eXXX/nYY.dt2, DIR/dem.tif, DIR/culture.gpkg\n"
      "(roads, rivers, lakes, forest; EPSG:4326) and DIR/synth.json, atomically.");
  sub->add_option("-o,--output", a->o.outDir, "Directory to create")->required();
  sub->add_option("--size-km", a->o.sizeKm, "Side of the square in km (1..1000)")->default_val(20.0);
  sub->add_option("--seed", a->o.seed, "Random seed")->default_val(1);
  sub->add_option("--center", a->center, "Centre of the square: LON LAT (default 13.30 42.30)")->expected(2);
  sub->add_option("--threads", a->o.threads, "Worker threads (0: all cores)")->default_val(0);
  sub->add_flag("--force", a->o.force, "Replace DIR if it exists");
  sub->add_flag("--json", a->json, "Print synth.json to stdout instead of the summary");
  c.add(sub, [a] { return runSynth(*a); });
}

}  // namespace sandtable::cli
