#pragma once
// Internal pieces of the elevation build, shared between its source files.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/grid.h"

namespace sandtable::convert::detail {

/// Values outside this range are voids even without a nodata tag
/// (e.g. -32767 fill in files that declare no nodata).
inline constexpr double kMinValid = -12000.0;
inline constexpr double kMaxValid = 9000.0;

/// A source post that is not elevation becomes NaN (a void).
inline float validOrNan(float x, bool hasNoData, float nd) {
  return (!std::isfinite(x) || (hasNoData && x == nd) || x < kMinValid || x > kMaxValid) ? NAN : x;
}

/// Whether `path` is one of GDAL's virtual file paths (/vsicurl/,
/// /vsis3/, /vsizip/, ...): read through GDAL's VSI, never the local file
/// system, and kept as given (no absolute path, no normalising: it would
/// fold the "//" of "/vsizip//vsicurl/http://...").
inline bool isGdalVirtual(const std::string& path) { return path.rfind("/vsi", 0) == 0; }

/// Size and CRC-32 of an input, read whole through GDAL's VSI (a local
/// file or a virtual path alike). Problems name the path and `kind`.
Result<FileCrc> crcThroughGdal(const std::string& path, const std::string& kind);

/// One opened and checked source raster.
struct Source {
  std::string path;
  std::string driver;
  std::string srsWkt;
  std::array<double, 6> geo{};  ///< GDAL geotransform
  int width = 0, height = 0;
  bool geographic = true;
  std::array<double, 4> lonLatBox{};  ///< west, south, east, north
  std::uint64_t bytes = 0;
  std::uint32_t crc = 0;
};

/// Opens each source, checks its georeferencing and reads its first and
/// last blocks (truncation), in parallel.
/// Without `checksums` the sources are not read whole: bytes is the file's
/// size and crc 0 (a distributed task checks only the sources under its
/// rows: checksumSources).
Result<std::vector<Source>> openSources(const std::vector<std::string>& paths, int threads,
                                        const ProgressFn& progress, bool checksums = true);

/// The target grid: CRS, north-west corner post, spacing, post counts.
struct Frame {
  TargetCrs crs;
  double originEasting = 0, originNorthing = 0, spacing = 0;
  std::uint32_t postsX = 0, postsZ = 0;
  std::array<std::array<double, 2>, 4> cornersLonLat{};  ///< NW, NE, SE, SW
};

Result<Frame> planFrame(const ElevationOptions& o, const std::vector<Source>& sources);

/// Ground metres between source posts along x and y at latitude `latDeg`.
std::array<double, 2> postMetres(const std::array<double, 6>& geo, bool geographic, double latDeg);

/// Finest source post spacing in metres near the sources' centre.
double nativeSpacingMetres(const std::vector<Source>& sources);

/// The failure of a stage below buildElevation: no file or offset (the
/// build names its output), the message alone ("resample: ...").
inline Problem stageError(std::string message) { return {"", 0, std::move(message)}; }

/// Writes a VRT mosaic of the sources (GDALBuildVRT, highest resolution)
/// to `vrtPath`. Voids are told apart by nodata or the valid range.
Status buildMosaic(const std::vector<Source>& sources, const std::string& vrtPath);

/// Resamples grid rows [j0, j1) of the frame (global row numbers; j0 a
/// multiple of kMinBandRows) into `out`, (j1 - j0) * postsX floats,
/// row-major, NaN = void, with `kernel` (weighted | bilinear | cubic |
/// average). weighted and bilinear give every post the same bytes whatever
/// the range: their lattice strips are fixed 64-row strips of the grid.
/// cubic and average run GDALWarp on the range, whose chunking (and so the
/// last bits of a post) can depend on the range.
Status resampleRows(const std::string& vrtPath, const Frame& f, const std::string& kernel, std::uint32_t j0,
                    std::uint32_t j1, int threads, float* out, const ProgressFn& progress);

/// Refines posts [j0, j1) (`grid`, (j1 - j0) * postsX floats, the point
/// samples of those rows) so the terrain triangles are the least-squares
/// fit of the source's bilinear surface (not point samples of it). A post
/// depends only on the rows within kFitReach of it: on a range cut out of
/// a bigger grid, the rows that far from a cut (and not at the grid's
/// edge) are those of the whole grid's fit, byte for byte.
Status fitTriangles(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                    float* grid, const ProgressFn& progress);
/// Rows on each side of a band that its fit needs (a whole 64-row strip:
/// the fit's reach is 12 rows, 10 Jacobi sweeps plus the right-hand side).
inline constexpr std::uint32_t kFitHalo = 64;

/// Memory a band costs, from the frame's source footprint: bytes per grid
/// row (output, source image rows, fit arrays) and bytes per band whatever
/// its height (the source image's pad rows, the fit's halo).
struct BandCost {
  double perRow = 0, fixed = 0;
};
BandCost bandCost(const std::string& vrtPath, const Frame& f, const KernelChoice& kernel);

/// What a post was after resampling: the void map behind materials 1 and 2.
enum PostClass : std::uint8_t { kValidPost = 0, kVoidPost = 1, kSeaPost = 2 };

/// The sea rule (ElevationOptions::seaFromVoids). A 4-connected void
/// component of `grid` (NaN posts; kVoidPost in `cls`) is sea when (1) the
/// grid's edge reaches it through voids and valid posts at or below 0 m
/// (a sea stored as 0 can enclose void patches), and (2) the median
/// elevation of its shore (the valid posts 4-adjacent to it) is within
/// kSeaShoreMedianM of 0. Its posts become 0 m and kSeaPost. Returns the
/// number of sea posts.
std::uint64_t markSea(const Frame& f, std::vector<float>& grid, std::vector<std::uint8_t>& cls);

/// The grid's drawn triangles (FORMAT.md §2) against the mosaic's valid
/// posts: every k-th source post along rows and columns, k chosen for about
/// kAccuracyPosts posts over the grid, those inside the grid kept.
inline constexpr double kAccuracyPosts = 8192;
Result<SourceAccuracy> measureAccuracy(const std::string& vrtPath, const Frame& f, const std::vector<float>& grid);

/// measureAccuracy band by band: prepare() reads the source posts, add()
/// evaluates those over grid squares in rows [j0, j1) (row(j) is grid row
/// j, for j0 <= j <= j1), finish() sums them in source order, so the
/// result does not depend on the bands.
class AccuracySampler {
 public:
  Status prepare(const std::string& vrtPath, const Frame& f);
  template <typename RowFn>
  void add(std::uint32_t j0, std::uint32_t j1, RowFn row);
  SourceAccuracy finish() const;

 private:
  struct Post {
    double u = 0, v = 0;  ///< grid coordinates in posts
    double z = 0;         ///< source elevation
    double e = 0, n = 0;  ///< target easting, northing
  };
  double error(std::uint32_t i, double fx, double fz, const float* r0, const float* r1, const Post& p) const;
  std::vector<Post> posts_;
  std::vector<std::size_t> byRow_;  ///< posts_ indices sorted by square row
  std::vector<double> err_;         ///< grid minus source; NaN until added
  std::uint32_t w_ = 0, h_ = 0;
  std::string wkt_;
};

template <typename RowFn>
void AccuracySampler::add(std::uint32_t j0, std::uint32_t j1, RowFn row) {
  // Binary search for the first post whose square row is >= j0.
  auto squareRow = [&](std::size_t k) {
    return static_cast<std::uint32_t>(std::min(std::floor(posts_[k].v), double(h_ - 2)));
  };
  std::size_t a = 0, b = byRow_.size();
  while (a < b) {
    const std::size_t m = (a + b) / 2;
    if (squareRow(byRow_[m]) < j0) a = m + 1; else b = m;
  }
  for (std::size_t q = a; q < byRow_.size(); ++q) {
    const Post& p = posts_[byRow_[q]];
    const std::uint32_t j = squareRow(byRow_[q]);
    if (j >= j1) break;
    const auto i = static_cast<std::uint32_t>(std::min(std::floor(p.u), double(w_ - 2)));
    err_[byRow_[q]] = error(i, p.u - i, p.v - j, row(j), row(j + 1), p);
  }
}

/// Fills NaN posts by interpolation (GDALFillNodata); returns how many.
Result<std::uint64_t> fillVoids(const Frame& f, std::vector<float>& grid, const ProgressFn& progress);

/// samples/materials.txt, compiled in (generated by CMake).
const char* defaultMaterialsText();

}  // namespace sandtable::convert::detail
