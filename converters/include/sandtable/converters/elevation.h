#pragma once
// Elevation conversion: GDAL rasters (DTED, SRTM .hgt/.hgt.zip, USGS DEM,
// GeoTIFF, ...) into a database directory holding a manifest and a
// memory-mapped grid file at constant post spacing in a projected frame.
#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/formats/manifest.h"
#include "sandtable/formats/module.h"
#include "sandtable/base/result.h"

namespace sandtable::convert {

/// The height step the build and `upgrade` write by default: 1 cm
/// (module::kDefaultHeightStep), about 10% off a module. Version 4 stores
/// culture heights as whole steps from the decoded lattice plane, so a
/// vertex on a grid edge stays on it (version 3 re-quantised it and opened
/// cracks); `--height-step 0` keeps exact float heights.
inline constexpr double kBuildHeightStep = module::kDefaultHeightStep;

/// fraction in [0, 1] and the stage that is running.
using ProgressFn = std::function<void(double, const std::string&)>;

/// What a build will cost, estimated once its frame is known and before
/// any heavy work, from the documented rates in build_estimate.cpp (README,
/// "Build estimate"). Rough: within a factor of about two on the VM the
/// rates were measured on; slower with dense culture.
struct BuildEstimate {
  std::uint32_t postsX = 0, postsZ = 0;
  std::uint64_t posts = 0;
  std::uint64_t gridBytes = 0;  ///< the grid file
  std::uint64_t modules = 0;    ///< load modules (0 without)
  int threads = 1;              ///< worker threads the estimate assumes
  double seconds = 0;           ///< wall time, culture as sparse as rural OSM (or none)
  double secondsMax = 0;        ///< wall time if the culture were town-dense everywhere
  std::uint64_t peakBytes = 0;  ///< peak resident memory
  std::uint64_t memoryBytes = 0;  ///< physical memory of this machine (0 if unknown)
  bool slow = false;    ///< seconds above kSlowBuildSeconds
  bool tooBig = false;  ///< peakBytes above memoryBytes
};
inline constexpr double kSlowBuildSeconds = 60.0;

/// ElevationOptions::memoryBudgetBytes by default: 1 GiB.
inline constexpr std::uint64_t kDefaultMemoryBudget = std::uint64_t(1) << 30;
/// Bands are whole 64-row strips (the resampling lattice's strips), so a
/// band's posts are the same bytes whatever the band height.
inline constexpr std::uint32_t kMinBandRows = 64;

struct ElevationOptions {
  std::vector<std::string> sources;  ///< files, directories or globs
  std::string output;                ///< database directory to create
  std::string crs = "utm";           ///< utm | cassini | EPSG:n
  double spacing = 0;                ///< metres; 0 = the sources' finest native spacing
  /// auto | weighted | bilinear | cubic | average. auto picks by the ratio
  /// of the target spacing to the sources' finest native spacing:
  /// weighted (the seed's average) at ratio >= kAutoWeightedRatio, else
  /// bilinear (with the triangle fit unless fit = "posts"); see chooseKernel.
  std::string resample = "auto";
  /// With bilinear: "triangles" fits the posts so the drawn triangles best
  /// match the source surface (least squares); "posts" keeps GDAL's point
  /// samples at the posts, as gdalwarp would.
  std::string fit = "triangles";
  /// Optional crop, lon/lat degrees: west, south, east, north.
  std::optional<std::array<double, 4>> extent;
  double moduleSize = 1000.0;  ///< seed: 1 km load modules
  int levels = 4;              ///< seed: 4 levels of detail
  std::vector<std::string> culture;  ///< OGR vector sources decaled onto the modules
  std::string materials;       ///< material table; "" = the built-in default (samples/materials.txt)
  /// Icon definition file (docs/ICONS.md); "" = the built-in tree only.
  /// Every build with modules writes icons.pack.
  std::string icons;
  /// Points files of explicit objects (icon, heading, scale; docs/ICONS.md §8).
  std::vector<std::string> objects;
  bool modules = true;         ///< false: grid only (no load modules)
  int zstdLevel = 9;           ///< module compression level
  std::uint32_t moduleVersion = module::kNewestVersion;  ///< load-module format version (1 to 6; objects need 5 or 6; ModuleOptions)
  double heightStep = kBuildHeightStep;  ///< version 2 height step, metres (0: exact; ModuleOptions)
  bool moduleNormals = false;  ///< version 2: store octahedral normals (ModuleOptions::normals)
  double maxScaleError = 0.01; ///< reject CRSs distorting more than this over the extent
  bool force = false;          ///< replace an existing output directory
  /// Voids connected to the grid's edge (through voids and posts at or
  /// below 0 m) whose shore (the valid posts next to them) has a median
  /// elevation within kSeaShoreMedianM of 0 become sea: elevation 0,
  /// material water. Other voids are filled by interpolation.
  bool seaFromVoids = true;
  int threads = 0;             ///< 0 = all cores
  /// Peak memory of the elevation stage (resampling, triangle fit, grid
  /// writing): the grid is resampled and written in row bands sized to fit
  /// it, so the stage's memory does not grow with the grid (the band never
  /// goes below kMinBandRows rows). A grid with voids left after resampling
  /// still needs the whole grid at once (sea and void fill are global):
  /// then the budget is exceeded, and the report says so (banded = false).
  std::uint64_t memoryBudgetBytes = kDefaultMemoryBudget;
  /// Called once with the estimate, before resampling starts. May be empty.
  std::function<void(const BuildEstimate&)> onEstimate;
};

/// auto picks the seed's weighted average when the target spacing is at
/// least this many times the sources' finest native spacing. Below it the
/// triangle fit has the lower RMSE and the lower worst error against the
/// source posts on rugged cells (measured: docs/ARCHITECTURE.md, stage 6);
/// from about 4x its 3 x 3 samples per square alias (fewer than one per
/// source post) and its worst errors pass the average's.
inline constexpr double kAutoWeightedRatio = 4.0;

/// An edge-connected void becomes sea when the median elevation of its
/// shore is within this many metres of 0.
inline constexpr double kSeaShoreMedianM = 5.0;

/// The kernel a build uses, and why.
struct KernelChoice {
  std::string resample;  ///< weighted | bilinear | cubic | average
  std::string fit;       ///< triangles | posts (always posts unless bilinear)
  double spacingRatio = 0;  ///< target spacing / finest native source spacing
  std::string reason;
};

/// The kernel for `request` (an ElevationOptions::resample value) at this
/// target and native spacing; explicit kernels are kept as given.
KernelChoice chooseKernel(const std::string& request, const std::string& fit, double targetSpacing,
                          double nativeSpacing);

/// The built grid's drawn triangles against the source posts, at a
/// deterministic sample of valid source posts inside the grid.
struct SourceAccuracy {
  std::uint64_t samples = 0;
  double rmse = 0;     ///< metres
  double maxAbs = 0;   ///< metres
  double mean = 0;     ///< grid minus source, metres
  std::array<double, 2> worstLonLat{};  ///< where |error| = maxAbs
  double worstSource = 0;  ///< the source post there, metres
  double worstError = 0;   ///< grid minus source there (signed), metres
};

struct ElevationReport {
  std::uint64_t posts = 0;
  std::uint64_t modules = 0;
  double moduleSeconds = 0;
  std::uint64_t voidsFilled = 0;  ///< inland voids filled by interpolation (material 2)
  std::uint64_t seaPosts = 0;     ///< voids that became sea (elevation 0, material 1)
  KernelChoice kernel;
  SourceAccuracy accuracy;
  double seconds = 0;
  double resampleSeconds = 0;
  double postsPerSecond = 0;
  std::uint32_t bandRows = 0;     ///< rows per band (the grid's height when one band)
  std::uint32_t bands = 0;        ///< bands resampled
  bool banded = false;            ///< false: the whole grid was held at once (one band, or voids)
  std::uint64_t bandBytes = 0;    ///< the stage's estimated peak for one band
  manifest::Manifest manifest;
};

/// Expands files, directories (recursively, by raster extension) and globs.
Result<std::vector<std::string>> expandSources(const std::vector<std::string>& args);

/// Runs the whole build and publishes `options.output` atomically: on any
/// failure or cancellation no output directory is left behind.
Result<ElevationReport> buildElevation(const ElevationOptions& options, const ProgressFn& progress);

/// The estimate for a frame of postsX x postsZ posts at `spacing`.
BuildEstimate estimateBuild(const ElevationOptions& options, std::uint32_t postsX, std::uint32_t postsZ,
                            double spacing);

/// Asks a running build to stop (safe from a signal handler).
void requestCancel();
bool cancelRequested();

/// Weighted resampling kernel (seed Figure 13, refined): a distance-weighted
/// least-squares plane through every source post within `radius` of the
/// target, evaluated at the target. Offsets are in metres. Exact for planes.
/// Returns NaN when no post has weight.
double weightedPlaneEstimate(const double* dx, const double* dy, const double* z, std::size_t n,
                             double radius);

/// The grid stage's weighted kernel comes in instruction-set variants, all
/// giving the same bytes: "avx512" (8 target posts at once), "avx2" (4) and
/// "scalar" (one post at a time, the reference; as fast as two-lane SSE2
/// code was). Those this CPU runs, best first; a build uses the first.
/// Exposed for tests and benchmarks.
std::vector<std::string> weightedKernelVariants();

/// Makes later builds in this process use `variant` ("" = the best this CPU
/// runs); false, changing nothing, if the CPU cannot run it. Process-wide:
/// not while a build runs.
bool setWeightedKernelVariant(const std::string& variant);

/// Source posts and target steps for weightedKernelProbe: an image of w x h
/// source posts (row-major, NaN = void) and the source posts one target
/// step moves along target i (aXi, aYi) and j (aXj, aYj).
struct WeightedProbe {
  const float* image = nullptr;
  int w = 0, h = 0;
  double spacing = 30, radius = 30;  ///< target spacing and kernel radius, metres
  double aXi = 1, aYi = 0, aXj = 0, aYj = 1;
};

/// The weighted kernel's estimates as the grid stage computes them with
/// `variant`, before they are stored as float: for target posts at source
/// positions (px[k], py[k]) (in source posts, post x at x), one lattice
/// cell's metric. Empty when the CPU cannot run `variant` or the metric is
/// degenerate. Exposed for tests.
std::vector<double> weightedKernelProbe(const std::string& variant, const WeightedProbe& probe,
                                        const std::vector<double>& px, const std::vector<double>& py);

}  // namespace sandtable::convert
