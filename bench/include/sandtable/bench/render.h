#pragma once
// The viewer's frame rate (`sandtable bench render`): one flight from the
// database centre, drawn with each terrain configuration in turn (rings,
// sse, full; the full-resolution mesh too when asked), headless. Reports
// fps and frame-time percentiles; the first frames (uploads, shader
// compiles) are left out of the figures and reported apart.
//
// Thread safety: one benchmark at a time per process (it owns the GL
// context while it flies).
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/formats/database.h"

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
};

/// The figures of one case, over the frames after the warm-up.
struct RenderCase {
  std::string name;  ///< "rings", "sse", "full" or "mesh"
  double fps = 0, p50 = 0, p99 = 0, mean = 0;  ///< frame ms, except fps
  double triangles = 0;                        ///< mean per frame
  double warmupMs = 0;                         ///< the warm-up frames' total
  double maxErrorPx = 0;
  std::uint32_t frames = 0;
};

struct RenderBenchReport {
  std::string renderer;  ///< the GL renderer's description
  std::vector<RenderCase> cases;
  /// What `sandtable bench render --json` prints: renderer, size ("WxH"),
  /// frames, warmup_frames, view_distance, pixel_error, cases [{name, fps,
  /// frame_ms_p50, frame_ms_p99, frame_ms_mean, triangles_mean,
  /// warmup_ms, max_error_px}].
  nlohmann::json json;
};

/// Flies every case over `db`. Fails with a problem without a file when
/// `db` has no load modules, and otherwise with runtime::fly's problems
/// (Problem::file kFlightOptionProblem or kGlContextProblem for bad
/// options or no GL context).
Result<RenderBenchReport> runRenderBench(const Database& db, const RenderBenchOptions& options);

}  // namespace sandtable::bench
