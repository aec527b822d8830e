// sandtable bench render DB: flags and printing for bench::runRenderBench,
// the viewer's frame rate with range-ring LoD, screen-space-error LoD and
// the full resolution over the same flight.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <memory>

#include "cmd_bench.h"
#include "sandtable/bench/render.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/renderer.h"

namespace sandtable::cli {
namespace {

constexpr const char* kName = "bench render";

struct Args {
  std::string database;
  bench::RenderBenchOptions o;
  std::string size = "1280x720";
  std::string rings;
  std::string cases;
  bool noObjectCases = false;
  bool json = false;
};

const FlagMap kFlags = {{"ElevationOptions::modules = false", "--no-modules"},
                        {"with ElevationOptions::modules = true", "without --no-modules"}};

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

void printHuman(const Args& a, const bench::RenderBenchReport& r) {
  std::printf("sandtable bench render: %s, %ux%u, %u frames after %u warm-up, view %.0f m, upload budget %llu B\n",
              a.database.c_str(), a.o.width, a.o.height, a.o.frames, a.o.warmup, a.o.viewDistance,
              static_cast<unsigned long long>(a.o.uploadBudgetBytes));
  std::printf("  renderer: %s\n", r.renderer.c_str());
  std::printf("  plain indexed grid: %llu triangles in %u draws, p50 %.1f ms before and %.1f ms after the "
              "flights: %.2f M triangles/s\n",
              static_cast<unsigned long long>(r.gridBefore.triangles), r.gridBefore.draws, r.gridBefore.p50Ms,
              r.gridAfter.p50Ms, r.gridRate / 1e6);
  std::printf("  %-12s %6s %7s %7s %7s %7s %10s %7s %8s %6s %8s %7s %9s %10s\n", "case", "px", "view m", "fps",
              "p50 ms", "p99 ms", "triangles", "draws", "M tri/s", "grid", "deferred", "err px", "objects",
              "obj tris");
  for (const auto& f : r.cases) {
    std::printf("  %-12s %6.1f %7.0f %7.1f %7.1f %7.1f %10.0f %7.0f %8.2f %5.0f%% %8llu %7.2f %9.0f %10.0f\n",
                f.name.c_str(), f.pixelError, f.viewDistance, f.fps, f.p50, f.p99, f.triangles, f.draws,
                f.trianglesPerSecond / 1e6, 100 * f.ofGridRate, static_cast<unsigned long long>(f.uploadsDeferred),
                f.maxErrorPx, f.objectsDrawn, f.objectTriangles);
  }
}

int run(Args& a) {
  unsigned w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(a.size.c_str(), "%u%c%u%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X')) {
    return usageError(kName, "--size must look like 1280x720");
  }
  a.o.objectCases = !a.noObjectCases;
  a.o.only.clear();
  for (std::size_t at = 0; at < a.cases.size();) {
    const std::size_t comma = std::min(a.cases.find(',', at), a.cases.size());
    if (comma > at) a.o.only.push_back(a.cases.substr(at, comma - at));
    at = comma + 1;
  }
  a.o.width = w;
  a.o.height = h;
  a.o.rings.clear();
  if (std::string e = parseRings(a.rings, a.o.rings); !e.empty()) return usageError(kName, e);
  auto db = openDatabase(a.database);
  if (!db) return usageError(kName, db.error());
  auto r = bench::runRenderBench(db.value(), a.o);
  if (!r) {
    const Problem& first = r.problems().front();
    if (first.file.empty()) return reportBenchProblems(kName, r.problems(), kFlags);
    const bool usage = first.file == viewer::kFlightOptionProblem || first.file == render::kGlContextProblem;
    reportProblems(kName, r.problems());
    return usage ? kUsage : kProblems;
  }
  if (a.json) std::printf("%s\n", r->json.dump(2).c_str());
  else printHuman(a, r.value());
  return kOk;
}

}  // namespace

void registerBenchRender(CLI::App& bench, Commands& c) {
  auto args = std::make_shared<Args>();
  auto& o = args->o;
  auto* sub = bench.add_subcommand(
      "render", "Viewer frame rate: range-ring LoD, screen-space LoD and full resolution");
  sub->footer(
      "Flies straight from the database centre at --speed, once per case, headless (EGL):\n"
      "rings, sse (--pixel-error), full, and sse1-20km (1 px at a 20 km view distance); with\n"
      "static objects also no-objects (sse without them), objects-full (sse, every object\n"
      "in the view distance at its icon's full detail) and unthinned (sse, every sprite drawn);\n"
      "the other cases draw objects as the viewer does.\n"
      "Before and after the flights, a plain indexed grid drawn through the same program\n"
      "gives the renderer's own triangle rate; each case's triangles/s is set against it.\n"
      "frame ms is the time between frame completions on the render thread (main and\n"
      "render threads overlap); the first --warmup frames (uploads, shader compiles)\n"
      "are left out. Exit status: 0 done, 1 failed, 2 bad input or no GL context.");
  sub->add_option("DB", args->database, "Database with load modules")->required();
  sub->add_option("--frames", o.frames, "Frames measured per case")
      ->capture_default_str()->check(CLI::Range(1u, 100000u));
  sub->add_option("--warmup", o.warmup, "Frames drawn first and left out")->capture_default_str();
  sub->add_option("--size", args->size, "Frame size WxH")->capture_default_str();
  sub->add_option("--height", o.heightAgl, "Eye height above the ground, metres")->capture_default_str();
  sub->add_option("--heading", o.headingDeg, "Degrees clockwise from grid north")->capture_default_str();
  sub->add_option("--pitch", o.pitchDeg, "Degrees, negative looks down")->capture_default_str();
  sub->add_option("--speed", o.speedKmh, "km/h")->capture_default_str();
  sub->add_option("--view-distance", o.viewDistance, "Metres")->capture_default_str();
  sub->add_option("--pixel-error", o.pixelError, "sse case: pixels")
      ->capture_default_str()->check(CLI::PositiveNumber);
  sub->add_option("--rings", args->rings, "rings case: bin edges M,M,... (default Table 8 scaled)");
  sub->add_flag("--mesh", o.mesh, "Also the first flight's full-resolution grid mesh");
  sub->add_flag("--node-morph", o.nodeMorph, "sse cases: one morph factor per node, as fly --node-morph");
  sub->add_option("--upload-budget", o.uploadBudgetBytes, "GPU upload bytes per frame (0: no limit)")
      ->capture_default_str();
  sub->add_option("--grid-squares", o.gridSquares, "Plain indexed grid: squares a side")
      ->capture_default_str()->check(CLI::Range(16u, 4096u));
  sub->add_flag("--no-object-cases", args->noObjectCases,
                "Leave out the no-objects, objects-full and unthinned cases");
  sub->add_option("--cases", args->cases,
                  "Only these cases, NAME,NAME,... (e.g. sse,no-objects; default all)");
  sub->add_flag("--json", args->json, "Print JSON");
  c.add(sub, [args] { return run(*args); });
}

}  // namespace sandtable::cli
