// bench render: one flight from the database centre, drawn with each
// terrain configuration in turn (rings, sse, full; mesh too where it helps
// to compare), headless. Reports fps and frame-time percentiles; the first
// frames (uploads, shader compiles) are left out of the figures and
// reported apart.
#include "sandtable/bench/render.h"

#include <algorithm>

#include "sandtable/base/stats.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/renderer.h"

namespace sandtable::bench {
namespace {

struct Case {
  std::string name;
  runtime::TerrainMode mode;
  runtime::LodMode lod;
};

RenderCase figuresOf(const std::string& name, const runtime::FlightReport& r, std::uint32_t warmup) {
  RenderCase f;
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
  f.p50 = stats::percentile(ms, 0.5);
  f.p99 = stats::percentile(ms, 0.99);
  f.triangles = tris / double(ms.size());
  return f;
}

runtime::FlightOptions baseFlight(const Database& db, const RenderBenchOptions& a) {
  runtime::FlightOptions base;
  base.view.width = a.width;
  base.view.height = a.height;
  base.output.frames = a.frames + a.warmup;
  base.motion.heightAgl = a.heightAgl;
  base.motion.headingDeg = a.headingDeg;
  base.motion.pitchDeg = a.pitchDeg;
  base.motion.speedKmh = a.speedKmh;
  base.view.viewDistance = a.viewDistance;
  base.render.lod.pixelError = a.pixelError;
  base.render.lod.rings = a.rings;
  const auto& gh = db.grid->header();
  base.motion.easting = gh.originEasting + gh.spacing * (gh.postsX - 1) / 2.0;
  base.motion.northing = gh.originNorthing - gh.spacing * (gh.postsZ - 1) / 2.0;
  return base;
}

nlohmann::json toJson(const RenderBenchOptions& a, const RenderBenchReport& r) {
  nlohmann::json j;
  j["renderer"] = r.renderer;
  j["size"] = std::to_string(a.width) + "x" + std::to_string(a.height);
  j["frames"] = a.frames;
  j["warmup_frames"] = a.warmup;
  j["view_distance"] = a.viewDistance;
  j["pixel_error"] = a.pixelError;
  for (const auto& f : r.cases) {
    j["cases"].push_back({{"name", f.name}, {"fps", f.fps}, {"frame_ms_p50", f.p50},
                          {"frame_ms_p99", f.p99}, {"frame_ms_mean", f.mean},
                          {"triangles_mean", f.triangles}, {"warmup_ms", f.warmupMs},
                          {"max_error_px", f.maxErrorPx}});
  }
  return j;
}

}  // namespace

Result<RenderBenchReport> runRenderBench(const Database& db, const RenderBenchOptions& a) {
  if (!db.modules) {
    return Problem{"", 0, db.directory + " has no load modules (built with ElevationOptions::modules = false); "
                                         "rebuild it with ElevationOptions::modules = true"};
  }
  const runtime::FlightOptions base = baseFlight(db, a);
  std::vector<Case> cases = {{"rings", runtime::TerrainMode::modules, runtime::LodMode::rings},
                             {"sse", runtime::TerrainMode::modules, runtime::LodMode::sse},
                             {"full", runtime::TerrainMode::modules, runtime::LodMode::full}};
  if (a.mesh) cases.push_back({"mesh", runtime::TerrainMode::mesh, runtime::LodMode::full});
  RenderBenchReport report;
  for (const Case& c : cases) {
    runtime::FlightOptions o = base;
    o.render.mode = c.mode;
    o.render.lod.mode = c.lod;
    auto r = runtime::fly(db, o);
    if (!r) return r.problems();
    report.renderer = r->summary.rendererDetail;
    report.cases.push_back(figuresOf(c.name, r.value(), a.warmup));
  }
  report.json = toJson(a, report);
  return report;
}

}  // namespace sandtable::bench
