// sandtable bench render: one flight from the database centre, drawn with
// each terrain configuration in turn (rings, sse, full; mesh too where it
// helps to compare), headless at 1280x720 by default. Reports fps and
// frame-time percentiles; the first frames (uploads, shader compiles) are
// left out of the figures and reported apart.
#include "bench_render.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "sandtable/formats/database.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/renderer.h"

namespace sandtable::cli {
namespace {

constexpr const char* kName = "bench render";

struct Args {
  std::string database;
  std::uint32_t frames = 150;
  std::uint32_t warmup = 10;
  std::string size = "1280x720";
  double height = 150;
  double heading = 0;
  double pitch = -8;
  double speed = 300;
  double viewDistance = 6000;
  double pixelError = 2;
  std::string rings;
  bool mesh = false;
  bool json = false;
};

struct Case {
  std::string name;
  runtime::TerrainMode mode;
  runtime::LodMode lod;
};

struct Figures {
  std::string name;
  double fps = 0, p50 = 0, p99 = 0, mean = 0, triangles = 0, warmupMs = 0, maxErrorPx = 0;
  std::uint32_t frames = 0;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(p * double(v.size())));
  return v[std::clamp<std::size_t>(rank, 1, v.size()) - 1];
}

Figures figuresOf(const std::string& name, const runtime::FlightReport& r, std::uint32_t warmup) {
  Figures f;
  f.name = name;
  std::vector<double> ms;
  double sum = 0, tris = 0;
  for (const auto& fr : r.frames) {
    if (fr.frame < warmup) {
      f.warmupMs += fr.frameMs;
      continue;
    }
    ms.push_back(fr.frameMs);
    sum += fr.frameMs;
    tris += double(fr.triangles);
    f.maxErrorPx = std::max(f.maxErrorPx, fr.maxErrorPx);
  }
  f.frames = std::uint32_t(ms.size());
  if (ms.empty()) return f;
  f.mean = sum / double(ms.size());
  f.fps = 1000.0 / f.mean;
  f.p50 = percentile(ms, 0.5);
  f.p99 = percentile(ms, 0.99);
  f.triangles = tris / double(ms.size());
  return f;
}

std::string parseRings(const std::string& text, std::vector<double>& out) {
  std::size_t at = 0;
  while (at <= text.size() && !text.empty()) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    try {
      std::size_t used = 0;
      const std::string item = text.substr(at, comma - at);
      out.push_back(std::stod(item, &used));
      if (used != item.size()) return "--rings must be metres separated by commas";
    } catch (const std::exception&) {
      return "--rings must be metres separated by commas";
    }
    at = comma + 1;
  }
  return {};
}

int run(const Args& a) {
  auto db = openDatabase(a.database);
  if (!db) return usageError(kName, db.error());
  if (!db->modules) {
    return usageError(kName, a.database + " has no load modules (built with --no-modules); rebuild "
                                           "it without --no-modules");
  }
  runtime::FlightOptions base;
  unsigned w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(a.size.c_str(), "%u%c%u%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X')) {
    return usageError(kName, "--size must look like 1280x720");
  }
  base.view.width = w;
  base.view.height = h;
  base.output.frames = a.frames + a.warmup;
  base.motion.heightAgl = a.height;
  base.motion.headingDeg = a.heading;
  base.motion.pitchDeg = a.pitch;
  base.motion.speedKmh = a.speed;
  base.view.viewDistance = a.viewDistance;
  base.render.lod.pixelError = a.pixelError;
  if (std::string e = parseRings(a.rings, base.render.lod.rings); !e.empty()) return usageError(kName, e);
  const auto& gh = db->grid->header();
  base.motion.easting = gh.originEasting + gh.spacing * (gh.postsX - 1) / 2.0;
  base.motion.northing = gh.originNorthing - gh.spacing * (gh.postsZ - 1) / 2.0;

  std::vector<Case> cases = {{"rings", runtime::TerrainMode::modules, runtime::LodMode::rings},
                             {"sse", runtime::TerrainMode::modules, runtime::LodMode::sse},
                             {"full", runtime::TerrainMode::modules, runtime::LodMode::full}};
  if (a.mesh) cases.push_back({"mesh", runtime::TerrainMode::mesh, runtime::LodMode::full});
  std::vector<Figures> figures;
  std::string renderer;
  for (const Case& c : cases) {
    runtime::FlightOptions o = base;
    o.render.mode = c.mode;
    o.render.lod.mode = c.lod;
    auto r = runtime::fly(db.value(), o);
    if (!r) {
      const bool usage = r.problems().front().file == runtime::kFlightOptionProblem ||
                         r.problems().front().file == runtime::kGlContextProblem;
      reportProblems(kName, r.problems());
      return usage ? kUsage : kProblems;
    }
    renderer = r->summary.rendererDetail;
    figures.push_back(figuresOf(c.name, r.value(), a.warmup));
  }
  if (a.json) {
    nlohmann::json j;
    j["renderer"] = renderer;
    j["size"] = a.size;
    j["frames"] = a.frames;
    j["warmup_frames"] = a.warmup;
    j["view_distance"] = a.viewDistance;
    j["pixel_error"] = a.pixelError;
    for (const auto& f : figures) {
      j["cases"].push_back({{"name", f.name}, {"fps", f.fps}, {"frame_ms_p50", f.p50},
                            {"frame_ms_p99", f.p99}, {"frame_ms_mean", f.mean},
                            {"triangles_mean", f.triangles}, {"warmup_ms", f.warmupMs},
                            {"max_error_px", f.maxErrorPx}});
    }
    std::printf("%s\n", j.dump(2).c_str());
    return kOk;
  }
  std::printf("sandtable bench render: %s, %ux%u, %u frames after %u warm-up, view %.0f m\n",
              a.database.c_str(), w, h, a.frames, a.warmup, a.viewDistance);
  std::printf("  renderer: %s\n", renderer.c_str());
  std::printf("  %-6s %8s %10s %10s %12s %10s\n", "case", "fps", "p50 ms", "p99 ms", "triangles",
              "max err px");
  for (const auto& f : figures) {
    std::printf("  %-6s %8.1f %10.1f %10.1f %12.0f %10.2f\n", f.name.c_str(), f.fps, f.p50, f.p99,
                f.triangles, f.maxErrorPx);
  }
  return kOk;
}

}  // namespace

void registerBenchRender(CLI::App& bench, Commands& c) {
  auto args = std::make_shared<Args>();
  auto* sub = bench.add_subcommand(
      "render", "Viewer frame rate: range-ring LoD, screen-space LoD and full resolution");
  sub->footer(
      "Flies straight from the database centre at --speed, once per case, headless (EGL).\n"
      "frame ms is the time between frame completions on the render thread (main and\n"
      "render threads overlap); the first --warmup frames (uploads, shader compiles)\n"
      "are left out. Exit status: 0 done, 1 failed, 2 bad input or no GL context.");
  sub->add_option("DB", args->database, "Database with load modules")->required();
  sub->add_option("--frames", args->frames, "Frames measured per case")
      ->capture_default_str()->check(CLI::Range(1u, 100000u));
  sub->add_option("--warmup", args->warmup, "Frames drawn first and left out")->capture_default_str();
  sub->add_option("--size", args->size, "Frame size WxH")->capture_default_str();
  sub->add_option("--height", args->height, "Eye height above the ground, metres")->capture_default_str();
  sub->add_option("--heading", args->heading, "Degrees clockwise from grid north")->capture_default_str();
  sub->add_option("--pitch", args->pitch, "Degrees, negative looks down")->capture_default_str();
  sub->add_option("--speed", args->speed, "km/h")->capture_default_str();
  sub->add_option("--view-distance", args->viewDistance, "Metres")->capture_default_str();
  sub->add_option("--pixel-error", args->pixelError, "sse case: pixels")
      ->capture_default_str()->check(CLI::PositiveNumber);
  sub->add_option("--rings", args->rings, "rings case: bin edges M,M,... (default Table 8 scaled)");
  sub->add_flag("--mesh", args->mesh, "Also the first flight's full-resolution grid mesh");
  sub->add_flag("--json", args->json, "Print JSON");
  c.add(sub, [args] { return run(*args); });
}

}  // namespace sandtable::cli
