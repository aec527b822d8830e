// bench modules: the full build (elevation, culture, load modules) against
// the elevation-only build of the same synthetic square, in one run.
// Builds alternate and repeat; medians are reported.
#include "sandtable/bench/modules.h"

#include <unistd.h>

#include <array>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <vector>

#include "sandtable/base/stats.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"

namespace sandtable::bench {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Run {
  double seconds = 0;
  double moduleSeconds = 0;
  std::uint64_t modules = 0;
  nlohmann::json build;  ///< the manifest's build object
};

std::array<double, 4> boundsOf(const fs::path& synthJson) {
  std::ifstream f(synthJson);
  const auto j = nlohmann::json::parse(f);
  const auto& b = j.at("bounds");
  return {b.at("west").get<double>(), b.at("south").get<double>(), b.at("east").get<double>(),
          b.at("north").get<double>()};
}

/// One in-process build, as `sandtable build` runs it.
Result<Run> build(const ModulesBenchOptions& a, const fs::path& in, bool full, const fs::path& out) {
  std::error_code ec;
  fs::remove_all(out, ec);
  convert::ElevationOptions o;
  o.sources = {(in / "dted2").string()};
  o.output = out.string();
  o.spacing = a.spacing;
  o.extent = boundsOf(in / "synth.json");
  o.threads = a.threads;
  o.zstdLevel = a.zstdLevel;
  o.modules = full;
  if (full) o.culture = {(in / "culture.gpkg").string()};
  const auto t0 = Clock::now();
  auto r = convert::buildElevation(o, nullptr);
  if (!r) return r.problems();
  Run run;
  run.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  run.moduleSeconds = r->moduleSeconds;
  run.modules = r->modules;
  run.build = r->manifest.build;
  if (!a.keep) fs::remove_all(out, ec);
  return run;
}

ModulesBenchReport summarize(const ModulesBenchOptions& a, const std::vector<Run>& full,
                             const std::vector<Run>& elev) {
  std::vector<double> f, e, m;
  for (const auto& r : full) f.push_back(r.seconds), m.push_back(r.moduleSeconds);
  for (const auto& r : elev) e.push_back(r.seconds);
  const Run& last = full.back();
  ModulesBenchReport rep;
  rep.fullBuildSeconds = stats::median(f);
  rep.elevationOnlySeconds = stats::median(e);
  rep.moduleStageSeconds = stats::median(m);
  rep.modules = last.modules;
  const double mod = rep.moduleStageSeconds;
  nlohmann::json j = {{"size_km", a.sizeKm},
                      {"spacing_m", a.spacing},
                      {"repeat", a.repeat},
                      {"full_build_s", rep.fullBuildSeconds},
                      {"elevation_only_s", rep.elevationOnlySeconds},
                      {"full_over_elevation", rep.fullBuildSeconds / rep.elevationOnlySeconds},
                      {"module_stage_s", mod},
                      {"modules", last.modules},
                      {"modules_per_second", double(last.modules) / mod},
                      {"module_bytes", last.build["modules"]["bytes"]},
                      {"per_level", last.build["modules"]["per_level"]},
                      {"culture_features", last.build["culture"]["features_read"]},
                      {"full_runs_s", f},
                      {"elevation_runs_s", e}};
  double roadKm = 0;
  for (const auto& [name, k] : last.build["culture"]["classes"].items()) roadKm += k["length_km"].get<double>();
  j["line_km"] = roadKm;
  rep.json = std::move(j);
  return rep;
}

Result<ModulesBenchReport> runIn(const ModulesBenchOptions& a, const Notes& notes, const fs::path& work) {
  fs::path in = a.input;
  if (in.empty()) {
    in = work / "synth";
    notes.say("synthesizing a " + std::to_string(int(a.sizeKm)) + " km square (not timed)");
    convert::SynthOptions so;
    so.outDir = in.string();
    so.sizeKm = a.sizeKm;
    so.threads = a.threads;
    auto s = convert::synthesize(so, nullptr);
    if (!s) return s.problems();
  }
  std::vector<Run> full, elev;
  for (int k = 0; k < a.repeat; ++k) {
    for (bool isFull : {false, true}) {
      auto r = build(a, in, isFull, work / (isFull ? "full" : "elevation"));
      if (!r) return r.problems();
      notes.say(std::string("run ") + std::to_string(k + 1) + (isFull ? " full build " : " elevation-only ") +
                std::to_string(r->seconds) + " s");
      (isFull ? full : elev).push_back(r.value());
    }
  }
  return summarize(a, full, elev);
}

}  // namespace

Result<ModulesBenchReport> runModulesBench(const ModulesBenchOptions& options, const Notes& notes) {
  const fs::path work = fs::temp_directory_path() / ("sandtable-bench-modules-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::create_directories(work, ec);
  auto r = [&]() -> Result<ModulesBenchReport> {
    try {
      return runIn(options, notes, work);
    } catch (const std::exception& e) {  // an unreadable synth.json
      return Problem{"", 0, e.what()};
    }
  }();
  if (!options.keep) fs::remove_all(work, ec);
  return r;
}

}  // namespace sandtable::bench
