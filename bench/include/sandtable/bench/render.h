#pragma once
// The viewer's frame rate (`sandtable bench render`): one flight from the
// database centre, drawn with each terrain configuration in turn (rings,
// sse, full, sse1-20km: 1 px at a 20 km view distance; the full-resolution
// mesh too when asked), headless. Reports fps, frame-time percentiles,
// the triangles and draws the GPU was given, and the triangles per second
// reached against the renderer's own rate on a plain indexed grid,
// measured in the same run (before and after the flights) through the
// same program and draw path. The first frames (uploads, shader compiles)
// are left out of the figures and reported apart.
//
// Thread safety: one benchmark at a time per process (it owns the GL
// context while it flies).
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/formats/database.h"
#include "sandtable/render/renderer.h"

namespace sandtable::bench {

struct RenderBenchOptions {
  /// Frames measured per case (>= 1).
  std::uint32_t frames = 150;
  /// Frames drawn first and left out of the figures.
  std::uint32_t warmup = 10;
  /// Frame size, pixels.
  std::uint32_t width = 1280, height = 720;
  /// Eye height above the ground, metres.
  double heightAgl = 150;
  /// Degrees clockwise from grid north.
  double headingDeg = 0;
  /// Degrees, negative looks down.
  double pitchDeg = -8;
  double speedKmh = 300;
  /// Metres.
  double viewDistance = 6000;
  /// The sse case's largest projected error, pixels (> 0).
  double pixelError = 2;
  /// The rings case's bin edges, metres; empty: the seed's Table 8 scaled.
  std::vector<double> rings;
  /// Also a case with the full-resolution grid mesh.
  bool mesh = false;
  /// The sse cases keep one morph factor per node (LodOptions::shareMorph off).
  bool nodeMorph = false;
  /// GPU upload bytes per frame (RenderOptions::uploadBudgetBytes); 0: none.
  std::uint64_t uploadBudgetBytes = render::kDefaultUploadBudgetBytes;
  /// With a database that has static objects: also the cases "no-objects"
  /// (sse without them), "objects-full" (sse with every object in the view
  /// distance at full detail) and "unthinned" (sse with every sprite drawn),
  /// to bracket the sse case's objects.
  bool objectCases = true;
  /// Only the cases of these names (e.g. {"sse", "no-objects"}, to set the
  /// objects against the terrain alone in one short run); empty: all.
  std::vector<std::string> only;
  /// The plain grid: squares a side (nodes of 16 squares), frames timed.
  std::uint32_t gridSquares = 512;
  std::uint32_t gridFrames = 20;
};

/// The figures of one case, over the frames after the warm-up.
struct RenderCase {
  std::string name;  ///< "rings", "sse", "full", "sse1-20km" or "mesh"
  double pixelError = 0, viewDistance = 0;     ///< what the case drew with
  double fps = 0, p50 = 0, p99 = 0, mean = 0;  ///< frame ms, except fps
  double triangles = 0;  ///< mean per frame: what the GPU was given (mesh: the strips')
  double draws = 0;      ///< mean draw commands per frame (modules)
  double trianglesPerSecond = 0;  ///< triangles / mean frame time
  double ofGridRate = 0;          ///< trianglesPerSecond / the plain grid's rate
  double warmupMs = 0;            ///< the warm-up frames' total
  double maxErrorPx = 0;
  std::uint64_t uploadsDeferred = 0;  ///< in the measured frames, by the upload budget
  /// Static objects, means per frame: drawn, instanced draws, triangles.
  double objectsDrawn = 0, objectDraws = 0, objectTriangles = 0;
  std::uint32_t frames = 0;
};

struct RenderBenchReport {
  std::string renderer;  ///< the GL renderer's description
  /// The plain indexed grid, before and after the flights.
  render::IndexedGridRate gridBefore, gridAfter;
  double gridRate = 0;  ///< mean of the two, triangles per second
  std::vector<RenderCase> cases;
  /// What `sandtable bench render --json` prints: renderer, size ("WxH"),
  /// frames, warmup_frames, view_distance, pixel_error,
  /// upload_budget_bytes, grid {triangles, draws, frame_ms_p50_before,
  /// frame_ms_p50_after, triangles_per_s}, cases [{name, pixel_error,
  /// view_distance, fps, frame_ms_p50, frame_ms_p99, frame_ms_mean,
  /// triangles_mean, draws_mean, triangles_per_s, of_grid_rate,
  /// uploads_deferred, warmup_ms, max_error_px}].
  nlohmann::json json;
};

/// Flies every case over `db`. Fails with a problem without a file when
/// `db` has no load modules, and otherwise with viewer::fly's problems
/// (Problem::file kFlightOptionProblem or kGlContextProblem for bad
/// options or no GL context).
Result<RenderBenchReport> runRenderBench(const Database& db, const RenderBenchOptions& options);

}  // namespace sandtable::bench
