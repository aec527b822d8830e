// Void filling: GDALFillNodata near data, and a coarser grid's fill for
// voids beyond its reach.
#include <algorithm>
#include <cmath>

#include <gdal_alg.h>

#include "elevation_resample.h"

namespace sandtable::convert::detail {
namespace {

int fillProgress(double fraction, const char*, void* data) {
  const auto* p = static_cast<const ProgressFn*>(data);
  if (*p) (*p)(fraction, "filling voids");
  return cancelRequested() ? FALSE : TRUE;
}

constexpr double kFillReach = 64.0;   // posts searched by GDALFillNodata per level
constexpr std::uint32_t kCoarsen = 16; // posts per coarse cell for far voids

/// GDALFillNodata over a float buffer (NaN = void) within `reach` posts.
std::string fillNear(float* grid, std::uint32_t w, std::uint32_t h, const Frame& f, double reach,
                     const ProgressFn& progress) {
  std::vector<std::uint8_t> mask(std::size_t(w) * h);
  for (std::size_t k = 0; k < mask.size(); ++k) mask[k] = std::isnan(grid[k]) ? 0 : 255;
  GDALDataset* ds = wrapBuffer(grid, GDT_Float32, w, h, f);
  GDALDataset* mds = wrapBuffer(mask.data(), GDT_Byte, w, h, f);
  if (!ds || !mds) {
    if (ds) GDALClose(ds);
    if (mds) GDALClose(mds);
    return "fill: cannot wrap the grid: " + lastGdalError();
  }
  const char* opts[] = {"TEMP_FILE_DRIVER=MEM", nullptr};
  const CPLErr err = GDALFillNodata(ds->GetRasterBand(1), mds->GetRasterBand(1), reach, 0, 0,
                                    const_cast<char**>(opts), fillProgress, const_cast<ProgressFn*>(&progress));
  GDALClose(ds);
  GDALClose(mds);
  if (cancelRequested()) return "build: cancelled";
  return err == CE_None ? std::string() : "fill: GDALFillNodata failed: " + lastGdalError();
}

/// Fills voids everywhere: GDALFillNodata near data, and for voids further
/// than its reach (open sea in SRTM, say), the same fill on a grid 16 times
/// coarser, interpolated back. GDALFillNodata alone is far too slow with a
/// reach of thousands of posts.
std::string fillAll(std::vector<float>& grid, std::uint32_t w, std::uint32_t h, const Frame& f,
                    const ProgressFn& progress) {
  if (std::string e = fillNear(grid.data(), w, h, f, kFillReach, progress); !e.empty()) return e;
  if (std::none_of(grid.begin(), grid.end(), [](float v) { return std::isnan(v); })) return {};
  const std::uint32_t cw = (w + kCoarsen - 1) / kCoarsen + 1, ch = (h + kCoarsen - 1) / kCoarsen + 1;
  std::vector<float> coarse(std::size_t(cw) * ch, NAN);
  std::vector<double> sum(coarse.size(), 0);
  std::vector<std::uint32_t> count(coarse.size(), 0);
  for (std::uint32_t j = 0; j < h; ++j) {
    for (std::uint32_t i = 0; i < w; ++i) {
      const float v = grid[std::size_t(j) * w + i];
      if (std::isnan(v)) continue;
      // Coarse post (ci, cj) sits on fine post (ci * 16, cj * 16).
      const std::size_t c = std::size_t((j + kCoarsen / 2) / kCoarsen) * cw + (i + kCoarsen / 2) / kCoarsen;
      sum[c] += v;
      ++count[c];
    }
  }
  for (std::size_t c = 0; c < coarse.size(); ++c) {
    if (count[c]) coarse[c] = static_cast<float>(sum[c] / count[c]);
  }
  if (std::all_of(coarse.begin(), coarse.end(), [](float v) { return std::isnan(v); })) {
    return "fill: no target post has source data";
  }
  Frame cf = f;
  cf.spacing = f.spacing * kCoarsen;
  if (std::string e = fillAll(coarse, cw, ch, cf, progress); !e.empty()) return e;
  for (std::uint32_t j = 0; j < h; ++j) {
    for (std::uint32_t i = 0; i < w; ++i) {
      float& v = grid[std::size_t(j) * w + i];
      if (!std::isnan(v)) continue;
      const double u = double(i) / kCoarsen, t = double(j) / kCoarsen;
      const auto i0 = static_cast<std::uint32_t>(u), j0 = static_cast<std::uint32_t>(t);
      const double fx = u - i0, fz = t - j0;
      auto at = [&](std::uint32_t a, std::uint32_t b) { return double(coarse[std::size_t(std::min(b, ch - 1)) * cw + std::min(a, cw - 1)]); };
      const double top = at(i0, j0) + fx * (at(i0 + 1, j0) - at(i0, j0));
      const double bot = at(i0, j0 + 1) + fx * (at(i0 + 1, j0 + 1) - at(i0, j0 + 1));
      v = static_cast<float>(top + fz * (bot - top));
    }
  }
  return {};
}

}  // namespace

Result<std::uint64_t> fillVoids(const Frame& f, std::vector<float>& grid, const ProgressFn& progress) {
  const auto voids = static_cast<std::uint64_t>(std::count_if(grid.begin(), grid.end(), [](float v) { return std::isnan(v); }));
  if (voids == 0) return std::uint64_t{0};
  if (voids == grid.size()) return Problem{"build", 0, "fill: no target post has source data"};
  if (std::string e = fillAll(grid, f.postsX, f.postsZ, f, progress); !e.empty()) return Problem{"build", 0, e};
  for (float v : grid) {
    if (std::isnan(v)) return Problem{"build", 0, "fill: voids remain after interpolation"};
  }
  return voids;
}

}  // namespace sandtable::convert::detail
