#pragma once
// Internal pieces of the elevation build, shared between its source files.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/formats/grid.h"

namespace sandtable::convert::detail {

/// Values outside this range are voids even without a nodata tag
/// (e.g. -32767 fill in files that declare no nodata).
inline constexpr double kMinValid = -12000.0;
inline constexpr double kMaxValid = 9000.0;

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
Result<std::vector<Source>> openSources(const std::vector<std::string>& paths, int threads,
                                        const ProgressFn& progress);

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

/// Writes a VRT mosaic of the sources (GDALBuildVRT, highest resolution)
/// to `vrtPath`. Voids are told apart by nodata or the valid range.
std::string buildMosaic(const std::vector<Source>& sources, const std::string& vrtPath);

/// Resamples the mosaic into `out` (postsX * postsZ, row-major from the
/// north-west; NaN = void).
std::string resampleWeighted(const std::string& vrtPath, const Frame& f, int threads,
                             std::vector<float>& out, const ProgressFn& progress);
std::string resampleGdal(const std::string& vrtPath, const Frame& f, const std::string& kernel,
                         int threads, std::vector<float>& out, const ProgressFn& progress);

/// Refines the posts so the terrain triangles are the least-squares fit of
/// the source's bilinear surface (not point samples of it).
std::string fitTriangles(const std::string& vrtPath, const Frame& f, int threads, std::vector<float>& grid,
                         const ProgressFn& progress);

/// Fills NaN posts by interpolation (GDALFillNodata); returns how many.
Result<std::uint64_t> fillVoids(const Frame& f, std::vector<float>& grid, const ProgressFn& progress);

int threadCount(int requested);

}  // namespace sandtable::convert::detail
