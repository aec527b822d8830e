// bench modules: the full build (elevation, culture, load modules) against
// the elevation-only build of the same synthetic square, in one run.
// Builds alternate and repeat; medians are reported.
#include "sandtable/bench/modules.h"

#include <sys/resource.h>
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
  double cpuSeconds = 0;  ///< user + system time of the process during the build
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

double processCpuSeconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
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
  const double c0 = processCpuSeconds();
  auto r = convert::buildElevation(o, nullptr);
  if (!r) return r.problems();
  Run run;
  run.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  run.cpuSeconds = processCpuSeconds() - c0;
  run.moduleSeconds = r->moduleSeconds;
  run.modules = r->modules;
  run.build = r->manifest.build;
  if (!a.keep) fs::remove_all(out, ec);
  return run;
}

ModulesBenchReport summarize(const ModulesBenchOptions& a, const std::vector<Run>& full,
                             const std::vector<Run>& elev) {
  std::vector<double> f, e, m, fc, ec, load;
  for (const auto& r : full) {
    f.push_back(r.seconds), m.push_back(r.moduleSeconds), fc.push_back(r.cpuSeconds);
    load.push_back(r.build["culture"].value("load_seconds", 0.0));
  }
  for (const auto& r : elev) e.push_back(r.seconds), ec.push_back(r.cpuSeconds);
  // The module stage's profile: per stage, the median over the full runs.
  nlohmann::json stages = nlohmann::json::object();
  if (full.back().build["modules"].contains("stage_cpu_seconds")) {
    for (const auto& [key, v] : full.back().build["modules"]["stage_cpu_seconds"].items()) {
      std::vector<double> xs;
      for (const auto& r : full) xs.push_back(r.build["modules"]["stage_cpu_seconds"].value(key, 0.0));
      stages[key] = stats::median(xs);
    }
  }
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
                      {"elevation_runs_s", e},
                      // CPU time (user + system, all threads): what a machine
                      // shared with other work does not inflate.
                      {"full_cpu_s", stats::median(fc)},
                      {"elevation_only_cpu_s", stats::median(ec)},
                      {"full_over_elevation_cpu", stats::median(fc) / stats::median(ec)},
                      {"culture_load_s", stats::median(load)},
                      {"module_stage_cpu_s", stages}};
  double roadKm = 0;
  for (const auto& [name, k] : last.build["culture"]["classes"].items()) roadKm += k["length_km"].get<double>();
  j["line_km"] = roadKm;
  rep.json = std::move(j);
  return rep;
}

Result<ModulesBenchReport> runIn(const ModulesBenchOptions& a, const Notes& notes, const fs::path& work) {
  fs::path in = a.input;
  ModulesBenchOptions named = a;
  if (!in.empty()) {
    std::ifstream f(in / "synth.json");
    named.sizeKm = nlohmann::json::parse(f).value("size_km", a.sizeKm);  // the report names the square's size
  } else {
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
  return summarize(named, full, elev);
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
