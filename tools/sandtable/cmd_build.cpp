// sandtable build: source elevation into a database directory.
#include <csignal>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "progress.h"
#include "sandtable/converters/elevation.h"

namespace sandtable::cli {
namespace {

struct BuildArgs {
  convert::ElevationOptions o;
  std::vector<double> extent;
  bool json = false;
};

void onSignal(int) { convert::requestCancel(); }

int runBuild(BuildArgs& a) {
  if (!a.extent.empty()) {
    if (a.extent.size() != 4) return usageError("build", "--extent takes WEST SOUTH EAST NORTH");
    a.o.extent = std::array<double, 4>{a.extent[0], a.extent[1], a.extent[2], a.extent[3]};
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  Progress progress(a.json);
  auto report = convert::buildElevation(a.o, [&](double f, const std::string& s) { progress.update(f, s); });
  progress.done();
  if (!report) {
    for (const auto& p : report.problems()) std::fprintf(stderr, "sandtable build: error: %s\n", p.str().c_str());
    std::fprintf(stderr, "sandtable build: nothing was written to %s\n", a.o.output.c_str());
    return kUsage;
  }
  const auto& r = report.value();
  if (a.json) {
    nlohmann::json j = {{"output", a.o.output},       {"posts", r.posts},
                        {"posts_x", r.manifest.postsX}, {"posts_z", r.manifest.postsZ},
                        {"spacing_m", r.manifest.spacing}, {"voids_filled", r.voidsFilled},
                        {"seconds", r.seconds},        {"resample_seconds", r.resampleSeconds},
                        {"posts_per_second", r.postsPerSecond}, {"crs", r.manifest.crsName},
                        {"min_elevation", r.manifest.minElevation}, {"max_elevation", r.manifest.maxElevation}};
    std::printf("%s\n", j.dump(2).c_str());
    return kOk;
  }
  std::printf("built %s\n", a.o.output.c_str());
  std::printf("  frame      %s, %.2f m posts, %u x %u posts\n", r.manifest.crsName.c_str(), r.manifest.spacing,
              r.manifest.postsX, r.manifest.postsZ);
  std::printf("  elevation  %.1f .. %.1f m\n", r.manifest.minElevation, r.manifest.maxElevation);
  std::printf("  posts      %llu (%llu voids filled, %.3f%%)\n", static_cast<unsigned long long>(r.posts),
              static_cast<unsigned long long>(r.voidsFilled), 100.0 * double(r.voidsFilled) / double(r.posts));
  std::printf("  time       %.2f s (resampling %.2f s), %.2f M posts/s\n", r.seconds, r.resampleSeconds,
              r.postsPerSecond / 1e6);
  return kOk;
}

}  // namespace

void registerBuild(CLI::App& root, Commands& c) {
  auto a = std::make_shared<BuildArgs>();
  auto* sub = root.add_subcommand("build", "Build a terrain database from elevation sources");
  sub->footer(
      "Example:\n  sandtable build --elevation data/dted1 --crs utm --spacing 30 -o db\n"
      "Sources: DTED (.dt0/.dt1/.dt2), SRTM (.hgt, .hgt.zip), USGS DEM (.dem), GeoTIFF, any GDAL raster;\n"
      "files, directories (searched recursively) or quoted globs. All sources must share one CRS.");
  sub->add_option("--elevation", a->o.sources, "Elevation sources: files, directories or globs")->required();
  sub->add_option("-o,--output", a->o.output, "Database directory to create")->required();
  sub->add_option("--crs", a->o.crs, "Target frame: utm (zone of the centre), cassini, or EPSG:n")
      ->default_val("utm");
  sub->add_option("--spacing", a->o.spacing, "Post spacing in metres (default: finest native spacing)");
  sub->add_option("--resample", a->o.resample, "weighted (seed Fig. 13) | bilinear | cubic | average")
      ->default_val("weighted");
  sub->add_option("--fit", a->o.fit,
                  "With bilinear: triangles (least-squares fit of the drawn triangles to the source) | posts "
                  "(point samples, as gdalwarp)")
      ->default_val("triangles");
  sub->add_option("--extent", a->extent, "Crop to WEST SOUTH EAST NORTH (lon/lat degrees)")->expected(4);
  sub->add_option("--module-size", a->o.moduleSize, "Load-module edge in metres")->default_val(1000.0);
  sub->add_option("--levels", a->o.levels, "Levels of detail per module")->default_val(4);
  sub->add_option("--max-scale-error", a->o.maxScaleError,
                  "Reject a CRS whose scale error over the extent exceeds this fraction")
      ->default_val(0.01);
  sub->add_option("--threads", a->o.threads, "Worker threads (0 = all cores)")->default_val(0);
  sub->add_flag("--force", a->o.force, "Replace an existing output directory (only once the new one is complete)");
  sub->add_flag("--json", a->json, "Print the build report as JSON");
  c.add(sub, [a] { return runBuild(*a); });
}

}  // namespace sandtable::cli
