// sandtable bench modules: the full build (elevation, culture, load
// modules) against the elevation-only build of the same synthetic square,
// in one run. Builds alternate and repeat; medians are reported.
#include "bench_modules.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"

namespace sandtable::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Args {
  std::string input;
  double sizeKm = 100;
  double spacing = 31.25;
  int repeat = 3;
  int threads = 0;
  int zstdLevel = 9;
  bool json = false;
  bool keep = false;
};

struct Run {
  double seconds = 0;
  double moduleSeconds = 0;
  std::uint64_t modules = 0;
  nlohmann::json build;  ///< the manifest's build object
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void note(bool quiet, const std::string& s) {
  if (!quiet) std::fprintf(stderr, "bench: %s\n", s.c_str());
}

std::array<double, 4> boundsOf(const fs::path& synthJson) {
  std::ifstream f(synthJson);
  const auto j = nlohmann::json::parse(f);
  const auto& b = j.at("bounds");
  return {b.at("west").get<double>(), b.at("south").get<double>(), b.at("east").get<double>(),
          b.at("north").get<double>()};
}

/// One in-process build, as `sandtable build` runs it.
Result<Run> build(const Args& a, const fs::path& in, bool full, const fs::path& out) {
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

nlohmann::json summarize(const Args& a, const std::vector<Run>& full, const std::vector<Run>& elev) {
  std::vector<double> f, e, m;
  for (const auto& r : full) f.push_back(r.seconds), m.push_back(r.moduleSeconds);
  for (const auto& r : elev) e.push_back(r.seconds);
  const Run& last = full.back();
  const double mod = median(m);
  nlohmann::json j = {{"size_km", a.sizeKm},
                      {"spacing_m", a.spacing},
                      {"repeat", a.repeat},
                      {"full_build_s", median(f)},
                      {"elevation_only_s", median(e)},
                      {"full_over_elevation", median(f) / median(e)},
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
  return j;
}

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

int runBench(const Args& a) {
  const fs::path work = fs::temp_directory_path() / ("sandtable-bench-modules-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::create_directories(work, ec);
  fs::path in = a.input;
  if (in.empty()) {
    in = work / "synth";
    note(a.json, "synthesizing a " + std::to_string(int(a.sizeKm)) + " km square (not timed)");
    convert::SynthOptions so;
    so.outDir = in.string();
    so.sizeKm = a.sizeKm;
    so.threads = a.threads;
    auto s = convert::synthesize(so, nullptr);
    if (!s) {
      reportProblems("bench modules", s.problems());
      return kUsage;
    }
  }
  std::vector<Run> full, elev;
  for (int k = 0; k < a.repeat; ++k) {
    for (bool isFull : {false, true}) {
      auto r = build(a, in, isFull, work / (isFull ? "full" : "elevation"));
      if (!r) {
        reportProblems("bench modules", r.problems());
        if (!a.keep) fs::remove_all(work, ec);
        return kUsage;
      }
      note(a.json, std::string("run ") + std::to_string(k + 1) + (isFull ? " full build " : " elevation-only ") +
                       std::to_string(r->seconds) + " s");
      (isFull ? full : elev).push_back(r.value());
    }
  }
  const auto j = summarize(a, full, elev);
  if (a.json) std::printf("%s\n", j.dump(2).c_str());
  else printHuman(j);
  if (!a.keep) fs::remove_all(work, ec);
  return kOk;
}

}  // namespace

void registerBenchModules(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto* sub = bench.add_subcommand("modules", "Time the full build (culture + load modules) against elevation only");
  sub->footer(
      "Example:\n  sandtable bench modules --size-km 100 --repeat 3\n"
      "Synthesizes a square (or uses --input, a `sandtable synth` directory), then builds it alternately\n"
      "with culture and load modules and with elevation only, and reports medians, modules/s and sizes.");
  sub->add_option("--input", a->input, "An existing `sandtable synth` output directory");
  sub->add_option("--size-km", a->sizeKm, "Side of the synthesized square")->default_val(100)->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--spacing", a->spacing, "Post spacing in metres")->default_val(31.25)->check(CLI::PositiveNumber);
  sub->add_option("--repeat", a->repeat, "Runs of each build (median reported)")->default_val(3)->check(CLI::Range(1, 100));
  sub->add_option("--threads", a->threads, "Threads (0 = all cores)")->default_val(0);
  sub->add_option("--zstd-level", a->zstdLevel, "Module compression level")->default_val(9)->check(CLI::Range(1, 22));
  sub->add_flag("--json", a->json, "Print one JSON object");
  sub->add_flag("--keep", a->keep, "Keep the work directory");
  c.add(sub, [a] { return runBench(*a); });
}

}  // namespace sandtable::cli
