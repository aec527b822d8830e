// sandtable build: source elevation into a database directory.
#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "build_distributed.h"
#include "commands.h"
#include "culture_report.h"
#include "progress.h"
#include "sandtable/converters/elevation.h"

namespace sandtable::cli {
namespace {

void printModuleSummary(const convert::ElevationReport& r) {
  const auto& b = r.manifest.build;
  if (!b.contains("modules")) return;
  const auto& m = b["modules"];
  const auto& bytes = m["bytes"];
  std::printf("  modules    %llu (%u x %u, %.2f m, %d levels) in %.2f s, %.0f modules/s\n",
              static_cast<unsigned long long>(r.modules), m["modules_x"].get<unsigned>(),
              m["modules_z"].get<unsigned>(), m["module_size_m"].get<double>(), r.manifest.levels,
              r.moduleSeconds, m["modules_per_second"].get<double>());
  std::printf("  sizes      median %u B, p95 %u B, max %u B compressed; pack %.1f MB\n",
              bytes["median"].get<unsigned>(), bytes["p95"].get<unsigned>(), bytes["max"].get<unsigned>(),
              double(bytes["compressed_total"].get<std::uint64_t>()) / 1e6);
  const auto& c = b["culture"];
  const auto count = [&](const char* key) { return static_cast<unsigned long long>(c.value(key, std::uint64_t(0))); };
  std::printf("  culture    %llu features on the terrain (%llu read, %llu outside), %llu warnings\n",
              count("features_landed"), count("features_read"), count("features_outside"), count("warnings"));
  for (const auto& msg : c["messages"]) std::printf("    warning: %s\n", msg.get<std::string>().c_str());
  printCultureReasons(c, "    ");
  if (const std::uint64_t n = c.value("buildings", std::uint64_t(0)); n > 0) {
    const auto& levels = m["per_level"];
    std::string perLevel;
    for (const auto& l : levels) {
      perLevel += (perLevel.empty() ? "" : "/") + std::to_string(l.value("buildings", std::uint64_t(0)));
    }
    std::printf("  buildings  %llu footprints extruded; drawn per level %s\n", static_cast<unsigned long long>(n),
                perLevel.c_str());
  }
  if (!b.contains("icons")) return;
  const auto& icons = b["icons"];
  std::printf("  icons      %zu in icons.pack (%s), %zu textures\n", icons["names"].size(),
              icons["definitions"].get<std::string>().c_str(), icons["textures"].get<std::size_t>());
  for (const auto& msg : icons["warnings"]) std::printf("    warning: %s\n", msg.get<std::string>().c_str());
  if (!b.contains("objects")) return;
  const auto& objects = b["objects"];
  std::string classes;
  for (const auto& [name, n] : objects["by_class"].items()) {
    classes += (classes.empty() ? "" : ", ") + std::to_string(n.get<std::uint64_t>()) + " " + name;
  }
  std::printf("  objects    %llu placed%s%s\n", static_cast<unsigned long long>(objects["count"].get<std::uint64_t>()),
              classes.empty() ? "" : ": ", classes.c_str());
  for (const auto& msg : objects["warnings"]) std::printf("    warning: %s\n", msg.get<std::string>().c_str());
}

struct BuildArgs {
  convert::ElevationOptions o;
  std::vector<double> extent;
  bool json = false;
  DistributedArgs d;
  std::uint32_t tasks = 0;
  std::string parts;
};

volatile std::sig_atomic_t gSignal = 0;

/// Asks the build to stop; a second signal ends the process at once.
void onSignal(int sig) {
  gSignal = sig;
  convert::requestCancel();
  std::signal(sig, SIG_DFL);
}

std::string megabytes(std::uint64_t bytes) {
  char s[32];
  std::snprintf(s, sizeof s, bytes >= 10'000'000'000ull ? "%.0f GB" : bytes >= 1'000'000 ? "%.0f MB" : "%.1f MB",
                double(bytes) / (bytes >= 10'000'000'000ull ? 1e9 : 1e6));
  return s;
}

/// The one line printed before the build starts (README, "Build estimate").
void printEstimate(const convert::BuildEstimate& e) {
  std::fprintf(stderr,
               "estimate: %llu posts (%u x %u), grid %s, %llu modules, about %.0f s on %d threads%s, peak memory "
               "about %s\n",
               static_cast<unsigned long long>(e.posts), e.postsX, e.postsZ, megabytes(e.gridBytes).c_str(),
               static_cast<unsigned long long>(e.modules), std::max(1.0, e.seconds), e.threads,
               std::lround(e.secondsMax) > std::lround(std::max(1.0, e.seconds))
                   ? (" (up to " + std::to_string(long(e.secondsMax)) + " s if the culture is town-dense everywhere)").c_str()
                   : "",
               megabytes(e.peakBytes).c_str());
  if (e.tooBig) {
    std::fprintf(stderr, "warning: that is more memory than this machine has (%s); a coarser --spacing or a "
                 "smaller --extent needs less\n", megabytes(e.memoryBytes).c_str());
  } else if (e.slow) {
    std::fprintf(stderr, "note: a long build; Ctrl-C stops it and leaves nothing behind\n");
  }
}

nlohmann::json estimateJson(const convert::BuildEstimate& e) {
  return {{"posts", e.posts},         {"posts_x", e.postsX},     {"posts_z", e.postsZ},
          {"grid_bytes", e.gridBytes}, {"modules", e.modules},    {"threads", e.threads},
          {"seconds", e.seconds},     {"seconds_max", e.secondsMax}, {"peak_bytes", e.peakBytes}, {"memory_bytes", e.memoryBytes},
          {"slow", e.slow},           {"too_big", e.tooBig}};
}

int printReport(const convert::ElevationReport& r, const std::string& output, bool asJson,
                const convert::BuildEstimate& estimate) {
  if (asJson) {
    nlohmann::json j = {{"output", output},       {"posts", r.posts},
                        {"posts_x", r.manifest.postsX}, {"posts_z", r.manifest.postsZ},
                        {"spacing_m", r.manifest.spacing}, {"voids_filled", r.voidsFilled},
                        {"seconds", r.seconds},        {"resample_seconds", r.resampleSeconds},
                        {"posts_per_second", r.postsPerSecond}, {"crs", r.manifest.crsName},
                        {"min_elevation", r.manifest.minElevation}, {"max_elevation", r.manifest.maxElevation},
                        {"estimate", estimateJson(estimate)}};
    j["sea_posts"] = r.seaPosts;
    j["resample"] = {{"request", r.manifest.build.value("resample_request", std::string())}, {"kernel", r.kernel.resample}, {"fit", r.kernel.fit},
                     {"spacing_ratio", r.kernel.spacingRatio}, {"reason", r.kernel.reason}};
    j["accuracy"] = r.manifest.build["accuracy"];
    if (r.manifest.build.contains("modules")) {
      j["modules"] = r.manifest.build["modules"];
      j["culture"] = r.manifest.build["culture"];
      j["icons"] = r.manifest.build["icons"];
      j["objects"] = r.manifest.build["objects"];
    }
    std::printf("%s\n", j.dump(2).c_str());
    return kOk;
  }
  std::printf("built %s\n", output.c_str());
  std::printf("  frame      %s, %.2f m posts, %u x %u posts\n", r.manifest.crsName.c_str(), r.manifest.spacing,
              r.manifest.postsX, r.manifest.postsZ);
  std::printf("  elevation  %.1f .. %.1f m\n", r.manifest.minElevation, r.manifest.maxElevation);
  std::printf("  posts      %llu (%llu voids filled, %.3f%%; %llu sea posts from voids, %.3f%%)\n",
              static_cast<unsigned long long>(r.posts), static_cast<unsigned long long>(r.voidsFilled),
              100.0 * double(r.voidsFilled) / double(r.posts), static_cast<unsigned long long>(r.seaPosts),
              100.0 * double(r.seaPosts) / double(r.posts));
  std::printf("  resample   %s%s: %s\n", r.kernel.resample.c_str(), r.kernel.fit == "triangles" ? " + triangle fit" : "",
              r.kernel.reason.c_str());
  const auto& acc = r.accuracy;
  std::printf("  accuracy   RMSE %.2f m, max |error| %.2f m (%.1f m source post at lon %.5f lat %.5f), "
              "mean %+.2f m, against %llu source posts\n",
              acc.rmse, acc.maxAbs, acc.worstSource, acc.worstLonLat[0], acc.worstLonLat[1], acc.mean,
              static_cast<unsigned long long>(acc.samples));
  std::printf("  time       %.2f s (resampling %.2f s), %.2f M posts/s\n", r.seconds, r.resampleSeconds,
              r.postsPerSecond / 1e6);
  printModuleSummary(r);
  return kOk;
}

int runBuild(BuildArgs& a) {
  if (!a.extent.empty()) {
    if (a.extent.size() != 4) return usageError("build", "--extent takes WEST SOUTH EAST NORTH");
    a.o.extent = std::array<double, 4>{a.extent[0], a.extent[1], a.extent[2], a.extent[3]};
  }
  if (!a.d.task.empty()) return runTask(a.d, a.o.threads, a.json);
  convert::BuildEstimate estimate;
  const PrintReport print = [&](const convert::ElevationReport& r, const std::string& output) {
    return printReport(r, output, a.json, estimate);
  };
  if (!a.d.merge.empty()) {
    std::error_code ec;
    const std::string out = a.o.output.empty() ? "" : std::filesystem::absolute(a.o.output, ec).string();
    return runMerge(a.d, {out, a.o.force, a.o.threads}, print, a.json);
  }
  if (a.o.sources.empty() || a.o.output.empty()) {
    return usageError("build", "--elevation and -o are required (except with --task or --merge)");
  }
  if (!a.d.executor.empty() || !a.d.planOnly.empty() || a.d.emitSbatch || a.tasks > 0 || !a.parts.empty()) {
    if (a.d.executor.empty()) a.d.executor = "local";
    return runPlanned({a.o, a.tasks, a.parts}, a.d, print, a.json);
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  Progress progress(a.json);
  a.o.onEstimate = [&](const convert::BuildEstimate& e) {
    estimate = e;
    if (!a.json) printEstimate(e);
  };
  auto report = convert::buildElevation(a.o, [&](double f, const std::string& s) { progress.update(f, s); });
  progress.done();
  if (!report && gSignal != 0) {
    std::fprintf(stderr, "sandtable build: cancelled by signal %d; nothing was written to %s\n", int(gSignal),
                 a.o.output.c_str());
    return 128 + gSignal;  // the shell's convention for a process ended by a signal
  }
  if (!report) {
    reportProblems("build", report.problems());
    std::fprintf(stderr, "sandtable build: nothing was written to %s\n", a.o.output.c_str());
    return kUsage;
  }
  return printReport(report.value(), a.o.output, a.json, estimate);
}

}  // namespace

void registerBuild(CLI::App& root, Commands& c) {
  auto a = std::make_shared<BuildArgs>();
  auto* sub = root.add_subcommand("build", "Build a terrain database from elevation sources");
  sub->footer(
      "Examples:\n  sandtable build --elevation data/dted1 --crs utm --spacing 30 -o db\n"
      "  sandtable build --elevation synth/dted2 --culture synth/culture.gpkg --spacing 31.25 -o db\n"
      "Sources: DTED (.dt0/.dt1/.dt2), SRTM (.hgt, .hgt.zip), USGS DEM (.dem), GeoTIFF, any GDAL raster;\n"
      "files, directories (searched recursively) or quoted globs. All sources must share one CRS.");
  sub->add_option("--elevation", a->o.sources, "Elevation sources: files, directories or globs (required)");
  sub->add_option("-o,--output", a->o.output, "Database directory to create (required)");
  sub->add_option("--crs", a->o.crs, "Target frame: utm (zone of the centre), cassini, or EPSG:n")
      ->default_val("utm");
  sub->add_option("--spacing", a->o.spacing, "Post spacing in metres (default: finest native spacing)");
  sub->add_option("--resample", a->o.resample,
                  "auto (weighted when the spacing is >= 4x the source's, else bilinear) | weighted (seed Fig. 13) "
                  "| bilinear | cubic | average")
      ->default_val("auto");
  sub->add_option("--fit", a->o.fit,
                  "With bilinear: triangles (least-squares fit of the drawn triangles to the source) | posts "
                  "(point samples, as gdalwarp)")
      ->default_val("triangles");
  sub->add_option("--extent", a->extent, "Crop to WEST SOUTH EAST NORTH (lon/lat degrees)")->expected(4);
  sub->add_option("--culture", a->o.culture,
                  "Culture sources decaled onto the terrain: any OGR vector (Shapefile, GeoPackage, GeoJSON, "
                  "OSM .osm/.osm.gz/.pbf)");
  sub->add_option("--materials", a->o.materials,
                  "Material table (default: the built-in samples/materials.txt; format in docs/FORMAT.md)");
  sub->add_option("--icons", a->o.icons,
                  "Icon definition file (docs/ICONS.md); icons.pack always holds the built-in tree too");
  sub->add_option("--objects", a->o.objects,
                  "Points files of explicit objects: fields icon, heading (degrees), scale; any OGR vector "
                  "(GeoJSON, GeoPackage, CSV with x/lon and y/lat columns)");
  sub->add_option("--module-size", a->o.moduleSize,
                  "Load-module edge in metres, rounded to a whole number of coarsest-level posts")
      ->default_val(1000.0);
  sub->add_option("--levels", a->o.levels, "Levels of detail per module (1..8)")->default_val(4);
  sub->add_flag("--no-sea-from-voids", [a](std::int64_t) { a->o.seaFromVoids = false; },
                "Fill every void by interpolation; by default voids reaching the grid's edge with a shore at sea "
                "level (median within 5 m of 0) become sea (0 m, water)");
  sub->add_flag("--no-modules", [a](std::int64_t) { a->o.modules = false; },
                "Build only the elevation grid (no load modules)");
  sub->add_option("--zstd-level", a->o.zstdLevel, "Module compression level (1..22)")->default_val(9);
  sub->add_option("--module-version", a->o.moduleVersion,
                  "Load-module format: 6 (version 4 with static objects as rules: scatter rules, exceptions and "
                  "compact explicit objects), 5 (version 4 with every static object stored), 4 (compact: lattice heights, implicit "
                  "skirts, culture heights on the lattice "
                  "plane, integer decal texture, meshopt streams, optional normals), 3 (culture heights re-quantised, "
                  "float decal texture), 2 (the same without implicit skirts and plane heights) or 1 (the original "
                  "float planes); docs/FORMAT.md section 9")
      ->default_val(6)
      ->check(CLI::Range(1, 6));
  sub->add_option("--height-step", a->o.heightStep,
                  "Module version 2 to 4 height quantisation step in metres; every module height is within half a "
                  "step of the grid's (0 keeps exact float heights)")
      ->default_val(convert::kBuildHeightStep)
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--module-normals", a->o.moduleNormals,
                "Module versions 2 and 3: also store per-vertex octahedral normals (about 30% more bytes; the "
                "viewer samples the grid's normals, so it does not need them)");
  sub->add_option("--max-scale-error", a->o.maxScaleError,
                  "Reject a CRS whose scale error over the extent exceeds this fraction")
      ->default_val(0.01);
  sub->add_option("--threads", a->o.threads, "Worker threads (0 = all cores)")->default_val(0);
  sub->add_option("--memory-budget", a->o.memoryBudgetBytes,
                  "Peak memory of the elevation stage, e.g. 512M or 2G (K, M, G = 1024-based): the grid is "
                  "resampled and written in row bands that fit it (at least 64 rows); a grid with voids left "
                  "after resampling is still held whole")
      ->transform(CLI::AsSizeValue(false))
      ->default_str("1G");
  sub->add_flag("--force", a->o.force, "Replace an existing output directory (only once the new one is complete)");
  sub->add_flag("--json", a->json, "Print the build report as JSON");
  auto* dist = "Distributed build (docs/DISTRIBUTED.md)";
  sub->add_option("--executor", a->d.executor,
                  "Split the build into tasks and run them: local (here, one after another) or slurm (one "
                  "sbatch job array, then the merge); a rerun builds only the tasks whose part is missing or bad")
      ->group(dist);
  sub->add_option("--tasks", a->tasks, "Tasks to split the build into (default: one per 8 module rows)")->group(dist);
  sub->add_option("--parts", a->parts, "Shared directory for the plan and the tasks' parts (default: OUTPUT.parts)")
      ->group(dist);
  sub->add_option("--partition", a->d.partition, "Slurm partition for the job array")->group(dist);
  sub->add_option("--cpus-per-task", a->d.cpusPerTask, "Slurm CPUs per array task (its --threads)")
      ->default_val(1)
      ->group(dist);
  sub->add_option("--plan", a->d.planOnly, "Write the plan (JSON) to this file and stop")->group(dist);
  sub->add_flag("--emit-sbatch", a->d.emitSbatch,
                "Write the plan and print the sbatch script instead of submitting it")
      ->group(dist);
  sub->add_option("--task", a->d.task, "Build task I of plan PLAN.json into its part (PLAN I)")
      ->expected(2)
      ->group(dist);
  sub->add_option("--merge", a->d.merge, "Merge the parts of PLAN.json into the database (-o overrides its output)")
      ->group(dist);
  c.add(sub, [a] { return runBuild(*a); });
}

}  // namespace sandtable::cli
