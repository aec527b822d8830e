#pragma once
// `sandtable synth`: realistic synthetic source data in the formats the
// converters read, so the whole toolchain can run without licensed data.
//
// One deterministic elevation function of (lon, lat) -- coast, ridges,
// river valleys, lakes -- is sampled into DTED level 1 and 2 cells and a
// GeoTIFF DEM; a GeoPackage holds culture (roads, rivers, lakes, forest)
// derived from the same terrain. Output layout under the chosen directory:
//
//   dted1/eXXX/nYY.dt1   dted2/eXXX/nYY.dt2   (w/s for west/south)
//   dem.tif              culture.gpkg         synth.json
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::convert {

struct SynthOptions {
  std::string outDir;          ///< written atomically (temp dir + rename)
  double sizeKm = 20.0;        ///< side of the square, 1..1000
  std::uint64_t seed = 1;
  double centerLon = 13.30;    ///< below 50N, so DTED posts are square in degrees
  double centerLat = 42.30;
  bool force = false;          ///< replace outDir when it exists
  int threads = 0;             ///< 0: one per hardware thread
  // Parts to write; all on for the CLI. Tests switch parts off to stay fast.
  bool dted1 = true;
  bool dted2 = true;
  bool dem = true;
  bool culture = true;
};

/// What synthesize() wrote; synth.json is json.
struct SynthSummary {
  std::string outDir;
  double west = 0, south = 0, east = 0, north = 0;  ///< the square, degrees
  double centerLon = 0, centerLat = 0, sizeKm = 0;
  std::uint64_t seed = 0;
  int dted1Cells = 0, dted2Cells = 0;
  int demWidth = 0, demHeight = 0;
  double demArcSeconds = 0;  ///< DEM pixel size
  int roads = 0, rivers = 0, lakes = 0, forests = 0, buildings = 0;  ///< features per layer
  double minElevation = 0, maxElevation = 0;          ///< over everything written, m
  std::vector<std::string> files;  ///< relative to outDir, synth.json excluded
  std::uint64_t bytes = 0;         ///< total size of files
  double seconds = 0;              ///< wall time (not in json: it would break determinism)
  std::string json;                ///< the content of synth.json
};

/// fraction in [0, 1] over the whole run, and the stage now running.
/// Called from worker threads, but never concurrently.
using SynthProgress = std::function<void(double fraction, const std::string& stage)>;

/// Checks options without touching the disk: the problems are usage errors,
/// each naming its SynthOptions field.
Status validateSynthOptions(const SynthOptions& options);

/// Writes the synthetic data set. Fails (nothing left behind) when outDir
/// exists and force is off, or on any write error.
Result<SynthSummary> synthesize(const SynthOptions& options, const SynthProgress& progress = {});

/// The elevation function itself, for tests and ground-truth comparisons.
/// Building it traces rivers and places lakes (a fraction of a second for
/// the default square). elevation() is thread-safe.
class SynthTerrain {
 public:
  static Result<std::unique_ptr<SynthTerrain>> create(const SynthOptions& options);
  ~SynthTerrain();
  SynthTerrain(const SynthTerrain&) = delete;
  SynthTerrain& operator=(const SynthTerrain&) = delete;

  /// Metres above sea level at (lon, lat) in WGS 84 degrees; <= 0 is sea.
  /// DTED posts are max(0, round(elevation)).
  double elevation(double lon, double lat) const;

  struct Impl;

 private:
  explicit SynthTerrain(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sandtable::convert
