// bench render: one flight from the database centre, drawn with each
// terrain configuration in turn (rings, sse, full, sse1-20km; mesh too
// where it helps to compare), headless, between two runs of the plain
// indexed grid that gives the renderer's own rate. Reports fps,
// frame-time percentiles, triangles, draws and triangles per second
// against the grid's; the first frames (uploads, shader compiles) are left
// out of the figures and reported apart.
#include "sandtable/bench/render.h"

#include <algorithm>

#include "sandtable/base/stats.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/renderer.h"

namespace sandtable::bench {
namespace {

/// How a case draws the modules' static objects.
enum class Objects { lod, none, full, unthinned };

struct Case {
  std::string name;
  viewer::TerrainMode mode;
  scene::LodMode lod;
  double pixelError, viewDistance;
  Objects objects = Objects::lod;
};

/// The view distance and pixel error of the "sse1-20km" case (issue 11's target).
constexpr double kFarViewDistance = 20000, kFarPixelError = 1;

RenderCase figuresOf(const Case& c, const viewer::FlightReport& r, std::uint32_t warmup) {
  RenderCase f;
  f.name = c.name;
  f.pixelError = c.lod == scene::LodMode::sse ? c.pixelError : 0;
  f.viewDistance = c.viewDistance;
  std::vector<double> ms;
  double sum = 0, tris = 0, draws = 0;
  for (const auto& fr : r.frames) {
    if (fr.frame < warmup) {
      f.warmupMs += fr.frameMs;
      continue;
    }
    ms.push_back(fr.frameMs);
    sum += fr.frameMs;
    // Module frames count what the GPU was given; the mesh has no commands.
    tris += double(c.mode == viewer::TerrainMode::mesh ? fr.triangles : fr.trianglesDrawn);
    draws += double(fr.draws);
    f.uploadsDeferred += fr.uploadsDeferred;
    f.objectsDrawn += double(fr.objectsDrawn);
    f.objectDraws += double(fr.objectDraws);
    f.objectTriangles += double(fr.objectTriangles);
    f.maxErrorPx = std::max(f.maxErrorPx, fr.maxErrorPx);
  }
  f.frames = std::uint32_t(ms.size());
  if (ms.empty()) return f;
  f.mean = sum / double(ms.size());
  f.fps = 1000.0 / f.mean;
  f.p50 = stats::percentile(ms, 0.5);
  f.p99 = stats::percentile(ms, 0.99);
  f.triangles = tris / double(ms.size());
  f.draws = draws / double(ms.size());
  f.objectsDrawn /= double(ms.size());
  f.objectDraws /= double(ms.size());
  f.objectTriangles /= double(ms.size());
  f.trianglesPerSecond = f.mean > 0 ? f.triangles / (f.mean / 1000.0) : 0;
  return f;
}

/// The plain grid under an eye posed as the flights' first frame, reaching
/// as far as the farthest case: the renderer's own indexed rate.
Result<render::IndexedGridRate> gridRate(const RenderBenchOptions& a) {
  render::RenderSettings s;
  s.width = a.width;
  s.height = a.height;
  s.uploadBudgetBytes = 0;
  auto renderer = render::Renderer::create(s);
  if (!renderer) return renderer.problems();
  scene::Camera cam;
  cam.y = a.heightAgl;
  cam.headingDeg = a.headingDeg;
  cam.pitchDeg = a.pitchDeg;
  cam.aspect = double(a.width) / double(a.height);
  cam.viewDistance = std::max(a.viewDistance, kFarViewDistance);
  const std::uint32_t squares = std::max<std::uint32_t>(a.gridSquares, 16);
  const double spacing = 2.0 * cam.viewDistance / squares;
  return renderer.value()->measureIndexedGrid(cam, squares, spacing, 16, std::max<std::uint32_t>(a.gridFrames, 1));
}

viewer::FlightOptions baseFlight(const Database& db, const RenderBenchOptions& a) {
  viewer::FlightOptions base;
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
  base.render.lod.shareMorph = !a.nodeMorph;
  base.render.uploadBudgetBytes = a.uploadBudgetBytes;
  const auto& gh = db.grid->header();
  base.motion.easting = gh.originEasting + gh.spacing * (gh.postsX - 1) / 2.0;
  base.motion.northing = gh.originNorthing - gh.spacing * (gh.postsZ - 1) / 2.0;
  return base;
}

/// Whether any module of `db` has static objects (and there are icons to draw them).
bool hasObjects(const Database& db) {
  if (!db.icons || !db.modules) return false;
  const auto objects = db.manifest.build.value("objects", nlohmann::json::object());
  const auto count = objects.value("count", nlohmann::json());
  return count.is_number() && count.get<double>() > 0;
}

nlohmann::json toJson(const RenderBenchOptions& a, const RenderBenchReport& r) {
  nlohmann::json j;
  j["renderer"] = r.renderer;
  j["size"] = std::to_string(a.width) + "x" + std::to_string(a.height);
  j["frames"] = a.frames;
  j["warmup_frames"] = a.warmup;
  j["view_distance"] = a.viewDistance;
  j["pixel_error"] = a.pixelError;
  j["upload_budget_bytes"] = a.uploadBudgetBytes;
  j["node_morph"] = a.nodeMorph;
  j["grid"] = {{"triangles", r.gridBefore.triangles},
               {"draws", r.gridBefore.draws},
               {"frame_ms_p50_before", r.gridBefore.p50Ms},
               {"frame_ms_p50_after", r.gridAfter.p50Ms},
               {"triangles_per_s", r.gridRate}};
  for (const auto& f : r.cases) {
    j["cases"].push_back({{"name", f.name}, {"pixel_error", f.pixelError}, {"view_distance", f.viewDistance},
                          {"fps", f.fps}, {"frame_ms_p50", f.p50}, {"frame_ms_p99", f.p99},
                          {"frame_ms_mean", f.mean}, {"triangles_mean", f.triangles},
                          {"draws_mean", f.draws}, {"triangles_per_s", f.trianglesPerSecond},
                          {"of_grid_rate", f.ofGridRate}, {"uploads_deferred", f.uploadsDeferred},
                          {"warmup_ms", f.warmupMs}, {"max_error_px", f.maxErrorPx},
                          {"objects", {{"drawn_mean", f.objectsDrawn}, {"draws_mean", f.objectDraws},
                                       {"triangles_mean", f.objectTriangles}}}});
  }
  return j;
}

}  // namespace

Result<RenderBenchReport> runRenderBench(const Database& db, const RenderBenchOptions& a) {
  if (!db.modules) {
    return Problem{"", 0, db.directory + " has no load modules (built with ElevationOptions::modules = false); "
                                         "rebuild it with ElevationOptions::modules = true"};
  }
  const viewer::FlightOptions base = baseFlight(db, a);
  using scene::LodMode;
  using viewer::TerrainMode;
  const double vd = a.viewDistance, px = a.pixelError;
  std::vector<Case> cases = {{"rings", TerrainMode::modules, LodMode::rings, px, vd},
                             {"sse", TerrainMode::modules, LodMode::sse, px, vd},
                             {"full", TerrainMode::modules, LodMode::full, px, vd},
                             {"sse1-20km", TerrainMode::modules, LodMode::sse, kFarPixelError, kFarViewDistance}};
  if (a.mesh) cases.push_back({"mesh", TerrainMode::mesh, LodMode::full, px, vd});
  if (a.objectCases && hasObjects(db)) {
    // The sse case draws the objects with their level of detail, sprites
    // and thinning; these bracket it: no objects at all, every object at
    // full detail, and the sprites without thinning.
    cases.push_back({"no-objects", TerrainMode::modules, LodMode::sse, px, vd, Objects::none});
    cases.push_back({"objects-full", TerrainMode::modules, LodMode::sse, px, vd, Objects::full});
    cases.push_back({"unthinned", TerrainMode::modules, LodMode::sse, px, vd, Objects::unthinned});
  }
  if (!a.only.empty()) {
    std::erase_if(cases, [&](const Case& c) { return std::find(a.only.begin(), a.only.end(), c.name) == a.only.end(); });
    if (cases.empty()) return Problem{"", 0, "--cases names none of this database's cases"};
  }
  RenderBenchReport report;
  auto before = gridRate(a);
  if (!before) return before.problems();
  report.gridBefore = before.value();
  for (const Case& c : cases) {
    viewer::FlightOptions o = base;
    o.render.mode = c.mode;
    o.render.lod.mode = c.lod;
    o.render.lod.pixelError = c.pixelError;
    o.view.viewDistance = c.viewDistance;
    o.render.objects = c.objects != Objects::none;
    o.render.objectLod = c.objects == Objects::lod || c.objects == Objects::unthinned;
    if (c.objects == Objects::unthinned) o.render.objectThinPixels = 0;
    auto r = viewer::fly(db, o);
    if (!r) return r.problems();
    report.renderer = r->summary.rendererDetail;
    report.cases.push_back(figuresOf(c, r.value(), a.warmup));
  }
  auto after = gridRate(a);
  if (!after) return after.problems();
  report.gridAfter = after.value();
  report.gridRate = 0.5 * (report.gridBefore.trianglesPerSecond + report.gridAfter.trianglesPerSecond);
  for (auto& f : report.cases) f.ofGridRate = report.gridRate > 0 ? f.trianglesPerSecond / report.gridRate : 0;
  report.json = toJson(a, report);
  return report;
}

}  // namespace sandtable::bench
