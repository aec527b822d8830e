// The estimate a build prints before it starts (README, "Build estimate"):
// sizes are exact (the grid file's layout, the module count), time and
// memory come from the rates below, measured on the 2-core VM of
// docs/CULTURE.md and README (Release builds, N49E011 SRTM at 30 m).
#include <unistd.h>

#include <algorithm>

#include "sandtable/base/jobs.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/modules.h"
#include "sandtable/formats/grid.h"

namespace sandtable::convert {
namespace {

// Per worker thread, measured on the idle 2-core VM (Release): N49E011 at
// 30 m (8.3 M posts, 8,208 modules of 32 x 32 squares: 3.2 s before the
// modules, 4.96 s of modules); N49E011 + N50E011 at 62.5 m (14,300 modules
// of 16 x 16 squares: 3.30 s, 5.25 s with the north-Bayreuth OSM extract);
// Monaco's town culture for the dense rate. A module's cost follows its
// squares, so the rates are per level-0 grid square.
constexpr double kPostsPerSecond = 1.0e6;           ///< sources, resampling, void fill and grid writing together
constexpr double kSquaresPerSecond = 0.7e6;         ///< load modules without culture
constexpr double kSparseCultureFactor = 1.6;        ///< rural OSM (north Bayreuth) against none
constexpr double kDenseCultureSquaresPerSecond = 30e3; ///< town culture everywhere (Monaco): the upper bound
// Memory: the resampled grid (float), its void mask and the void filler's
// working copies per post, plus the process and GDAL's cache, plus one
// module's partition and levels per worker.
constexpr double kBytesPerPost = 15.0;
constexpr double kBaseBytes = 70e6;
constexpr double kBytesPerModuleThread = 20e6;

std::uint64_t physicalMemory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && size > 0 ? std::uint64_t(pages) * std::uint64_t(size) : 0;
}

}  // namespace

BuildEstimate estimateBuild(const ElevationOptions& o, std::uint32_t postsX, std::uint32_t postsZ, double spacing) {
  BuildEstimate e;
  e.postsX = postsX, e.postsZ = postsZ;
  e.posts = std::uint64_t(postsX) * postsZ;
  e.gridBytes = grid::makeHeader(postsX, postsZ, spacing, 0, 0).fileBytes;
  const int hw = jobs::threadCount(0);
  e.threads = o.threads > 0 ? std::min(o.threads, hw) : hw;
  double squares = 0;  // level-0 squares over all modules
  if (o.modules && postsX >= 2 && postsZ >= 2) {
    const std::uint32_t side = moduleSquares(o.moduleSize, spacing, std::clamp(o.levels, 1, 8));
    e.modules = std::uint64_t((postsX - 2) / side + 1) * ((postsZ - 2) / side + 1);
    squares = double(e.modules) * side * side;
  }
  const double grid = double(e.posts) / kPostsPerSecond;
  const double plain = squares / kSquaresPerSecond;
  const bool culture = !o.culture.empty();
  e.seconds = (grid + plain * (culture ? kSparseCultureFactor : 1.0)) / e.threads;
  e.secondsMax = culture ? (grid + squares / kDenseCultureSquaresPerSecond) / e.threads : e.seconds;
  e.peakBytes = std::uint64_t(kBaseBytes + kBytesPerPost * double(e.posts) +
                              (e.modules ? kBytesPerModuleThread * e.threads : 0.0));
  e.memoryBytes = physicalMemory();
  e.slow = e.seconds > kSlowBuildSeconds;
  e.tooBig = e.memoryBytes > 0 && e.peakBytes > e.memoryBytes;
  return e;
}

}  // namespace sandtable::convert
