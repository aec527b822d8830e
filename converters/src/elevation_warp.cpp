// The GDALWarp path: GDAL's own kernels (cubic, lanczos, ...) warping the
// shared source image, or the VRT, into an in-memory band of the grid.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <cpl_string.h>
#include <gdal_utils.h>

#include "elevation_resample.h"

namespace sandtable::convert::detail {

/// A MEM dataset whose single band aliases `data` (no copy).
GDALDataset* wrapBuffer(void* data, GDALDataType type, std::uint32_t w, std::uint32_t h, const Frame& f) {
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDataset* ds = mem->Create("", static_cast<int>(w), static_cast<int>(h), 0, type, nullptr);
  if (!ds) return nullptr;
  char ptr[64];
  std::snprintf(ptr, sizeof ptr, "DATAPOINTER=%p", data);
  char* opts[] = {ptr, nullptr};
  if (ds->AddBand(type, opts) != CE_None) {
    GDALClose(ds);
    return nullptr;
  }
  const double s = f.spacing;
  double g[6] = {f.originEasting - s / 2, s, 0, f.originNorthing + s / 2, 0, -s};
  ds->SetGeoTransform(g);
  ds->SetProjection(f.crs.wkt.c_str());
  return ds;
}

namespace {

int gdalProgress(double fraction, const char*, void* data) {
  const auto* p = static_cast<const ProgressFn*>(data);
  if (*p) (*p)(fraction, "resampling");
  return cancelRequested() ? FALSE : TRUE;
}

/// True when GDAL's kernels stay within the source image's 16-post pad:
/// the target is at most 8 times coarser than the source along each axis
/// (GDAL widens its kernels by the scale), as GDALWarpOperation computes it.
bool imageCoversKernel(const std::string& vrtPath, const Frame& f) {
  MosaicReader m;
  FrameScale s;
  if (!m.open(vrtPath, f).empty() || !frameScale(f, *m.toSource, m.geo, s)) return false;
  return s.sx >= 0.125 && s.sy >= 0.125;
}

/// GDALWarp's source: the shared source image (read block by block, in
/// parallel) as a MEM dataset in the mosaic's frame, so GDAL's own kernels
/// warp from memory instead of copying DTED's one-column blocks through the
/// VRT pixel by pixel (a quarter of the build's CPU). Null: use the VRT.
GDALDataset* imageDataset(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                          SourceImage& image) {
  if (!imageCoversKernel(vrtPath, f)) return nullptr;
  buildSourceImage(vrtPath, f, j0, j1, 16, threads, image);
  MosaicReader m;
  if (!image.v || !m.open(vrtPath, f).empty()) return nullptr;
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDataset* ds = mem->Create("", image.w, image.h, 0, GDT_Float32, nullptr);
  if (!ds) return nullptr;
  char ptr[64];
  std::snprintf(ptr, sizeof ptr, "DATAPOINTER=%p", static_cast<void*>(image.v.get()));
  char* opts[] = {ptr, nullptr};
  if (ds->AddBand(GDT_Float32, opts) != CE_None) {
    GDALClose(ds);
    return nullptr;
  }
  const auto& g = m.geo;
  double sub[6] = {g[0] + image.x0 * g[1] + image.y0 * g[2], g[1], g[2],
                   g[3] + image.x0 * g[4] + image.y0 * g[5], g[4], g[5]};
  ds->SetGeoTransform(sub);
  ds->SetSpatialRef(m.ds->GetSpatialRef());
  ds->GetRasterBand(1)->SetNoDataValue(NAN);  // the image holds voids as NaN
  return ds;
}

}  // namespace

/// GDALWarp with `kernel` onto grid rows [j0, j1).
Status gdalRows(const std::string& vrtPath, const Frame& f, const std::string& kernel, std::uint32_t j0,
                std::uint32_t j1, int threads, float* out, const ProgressFn& progress) {
  std::fill(out, out + std::size_t(f.postsX) * (j1 - j0), NAN);
  Frame band = f;  // only GDAL sees this origin; our lattices keep the grid's
  band.originNorthing = f.originNorthing - j0 * f.spacing;
  GDALDataset* dst = wrapBuffer(out, GDT_Float32, f.postsX, j1 - j0, band);
  if (!dst) return stageError("resample: cannot create the in-memory target: " + lastGdalError());
  dst->GetRasterBand(1)->SetNoDataValue(NAN);
  SourceImage image;  // must outlive the MEM dataset that aliases it
  GDALDatasetH src = imageDataset(vrtPath, f, j0, j1, threads, image);
  if (!src) src = GDALOpen(vrtPath.c_str(), GA_ReadOnly);
  if (!src) {
    GDALClose(dst);
    return stageError("resample: cannot open the mosaic: " + lastGdalError());
  }
  const std::string nthreads = "NUM_THREADS=" + std::to_string(jobs::threadCount(threads));
  const char* args[] = {"-r", kernel.c_str(), "-multi", "-wo", nthreads.c_str(), "-wo", "INIT_DEST=NO_DATA",
                        "-wm", "512", "-et", "0.01", "-q", nullptr};
  GDALWarpAppOptions* opts = GDALWarpAppOptionsNew(const_cast<char**>(args), nullptr);
  GDALWarpAppOptionsSetProgress(opts, gdalProgress, const_cast<ProgressFn*>(&progress));
  int usageError = 0;
  CPLErrorReset();
  GDALDatasetH res = GDALWarp(nullptr, dst, 1, &src, opts, &usageError);
  GDALWarpAppOptionsFree(opts);
  GDALClose(src);
  GDALClose(dst);  // does not free `out`: the band only aliases it
  if (cancelRequested()) return stageError("build: cancelled");
  if (!res) return stageError("resample: GDAL warp failed: " + lastGdalError());
  return {};
}

}  // namespace sandtable::convert::detail
