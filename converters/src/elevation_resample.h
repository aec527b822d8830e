#pragma once
// Private to the resampling stage (elevation_*.cpp): what its files share.
// From target post to source position (Lattice, PostMap: elevation_lattice.cpp),
// windows of source posts (Window, readWindow), the mosaic as each worker
// opens it and the source image read once for all strips
// (elevation_mosaic.cpp), 64-row strips run in parallel, and the kernels
// that resampleRows dispatches to (elevation_weighted.cpp,
// elevation_bilinear.cpp, elevation_warp.cpp). Thread safety: plain values;
// a MosaicReader and a Window belong to one worker.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "elevation_internal.h"
#include "sandtable/converters/crs.h"
#include "sandtable/base/jobs.h"

namespace sandtable::convert::detail {

using convert::lastGdalError;

/// Target post -> fractional source post index, on a sparse lattice of
/// exact PROJ transforms with bilinear interpolation in between (like
/// GDAL's approximate transformer), plus the local Jacobian.
struct Lattice {
  static constexpr std::uint32_t kStep = 8;
  std::uint32_t i0 = 0, j0 = 0, cols = 0, rows = 0;
  std::vector<std::uint32_t> ci, rj;  // target columns / rows of lattice nodes
  std::vector<double> px, py;

  bool build(const Frame& f, std::uint32_t jBegin, std::uint32_t jEnd, OGRCoordinateTransformation& ct,
             const std::array<double, 6>& g) {
    ci.clear();
    rj.clear();
    for (std::uint32_t i = 0; i < f.postsX - 1; i += kStep) ci.push_back(i);
    ci.push_back(f.postsX - 1);
    for (std::uint32_t j = jBegin; j < jEnd - 1; j += kStep) rj.push_back(j);
    rj.push_back(jEnd - 1);
    if (rj.size() == 1) rj.push_back(jEnd - 1);  // a one-row strip still needs two rows
    cols = static_cast<std::uint32_t>(ci.size());
    rows = static_cast<std::uint32_t>(rj.size());
    px.resize(std::size_t(cols) * rows);
    py.resize(px.size());
    for (std::uint32_t r = 0; r < rows; ++r) {
      for (std::uint32_t c = 0; c < cols; ++c) {
        px[r * cols + c] = f.originEasting + ci[c] * f.spacing;
        py[r * cols + c] = f.originNorthing - rj[r] * f.spacing;
      }
    }
    if (!ct.Transform(static_cast<int>(px.size()), px.data(), py.data())) return false;
    for (std::size_t k = 0; k < px.size(); ++k) {
      const double X = px[k], Y = py[k];
      // Post index, with post k at pixel centre k + 0.5.
      px[k] = (X - g[0]) / g[1] - 0.5;
      py[k] = (Y - g[3]) / g[5] - 0.5;
    }
    return true;
  }
};

/// Cell of the lattice containing target post (i, j), with its
/// interpolated source position and target-metres-per-source-post matrix.
struct PostMap {
  double px, py;
  double m[2][2];  // metres east/south per source post step in x / y
  double hx, hy;   // search half-widths in source posts
  // |m d|^2 = qa dx^2 + 2 qb dx dy + (..) dy^2; qdet2 = det(m)^2, qinvA = 1 / qa
  double qa, qb, qdet2, qinvA, qymax;
};

/// Fills `out` for target post (i, j) in lattice cell (c, r), with a
/// search radius of `radius` metres; false where the transform is degenerate.
bool mapPost(const Lattice& L, std::uint32_t c, std::uint32_t r, std::uint32_t i, std::uint32_t j,
             double spacing, double radius, PostMap& out);

/// The metric, search box and ellipse terms of `out` (all but px, py) from
/// the source posts one target step moves along target i (aXi, aYi) and j
/// (aXj, aYj); false where they are degenerate.
bool postMetric(double aXi, double aYi, double aXj, double aYj, double spacing, double radius, PostMap& out);

/// Source position of target post (i, j) inside lattice cell (c, r).
inline void positionAt(const Lattice& L, std::uint32_t c, std::uint32_t r, std::uint32_t i, std::uint32_t j,
                       double& px, double& py) {
  // x / 8 and x * 0.125 are the same double; the multiply is far cheaper.
  const std::uint32_t di = L.ci[c + 1] - L.ci[c], dj = L.rj[r + 1] - L.rj[r];
  const double fx = di == Lattice::kStep ? double(i - L.ci[c]) * (1.0 / Lattice::kStep) : double(i - L.ci[c]) / double(di);
  const double fz = dj == 0 ? 0.0
                    : dj == Lattice::kStep ? double(j - L.rj[r]) * (1.0 / Lattice::kStep)
                                           : double(j - L.rj[r]) / double(dj);
  const std::size_t k00 = std::size_t(r) * L.cols + c, k10 = k00 + 1, k01 = k00 + L.cols, k11 = k01 + 1;
  px = (1 - fz) * (L.px[k00] + fx * (L.px[k10] - L.px[k00])) + fz * (L.px[k01] + fx * (L.px[k11] - L.px[k01]));
  py = (1 - fz) * (L.py[k00] + fx * (L.py[k10] - L.py[k00])) + fz * (L.py[k01] + fx * (L.py[k11] - L.py[k01]));
}

/// Source posts of one strip (or a view into a SourceImage): post (x, y)
/// for x0 <= x < x0 + w, y0 <= y < y0 + h, NaN for a void.
struct Window {
  int x0 = 0, y0 = 0, w = 0, h = 0;
  const float* base = nullptr;  ///< post (bx0, by0)
  std::size_t stride = 0;
  int bx0 = 0, by0 = 0;
  std::vector<float> v;
  float at(int x, int y) const { return base[std::size_t(y - by0) * stride + std::size_t(x - bx0)]; }
  const float* row(int y) const { return base + std::size_t(y - by0) * stride - bx0; }
};

/// The posts of the mosaic that the target covers, read once for all
/// strips (NaN = void). Reading through the VRT strip by strip costs
/// more than resampling: DTED is stored in one-column blocks, and GDAL
/// copies such a window pixel by pixel. Here each source is read block by
/// block, in parallel, and composited in the VRT's order with its nodata
/// rule, so the posts are those the VRT gives.
struct SourceImage {
  int x0 = 0, y0 = 0, w = 0, h = 0;
  std::unique_ptr<float[]> v;  ///< w * h posts, row-major; null: not read
  bool covers(int ax, int ay, int bx, int by) const {
    return v && ax >= x0 && ay >= y0 && bx < x0 + w && by < y0 + h;
  }
};

/// Reads the window of source posts lattice L covers, padded by `pad`
/// posts (a view into `image` when it covers it); "" or the error.
std::string readWindow(GDALRasterBand& band, const Lattice& L, double pad, Window& win,
                       const SourceImage* image = nullptr);

/// One worker's handle on the mosaic: GDAL datasets and PROJ transforms are
/// not thread-safe, so each thread opens its own.
struct MosaicReader {
  std::unique_ptr<GDALDataset> ds;
  std::array<double, 6> geo{};
  std::unique_ptr<OGRCoordinateTransformation> toSource;  // target CRS -> mosaic CRS

  std::string open(const std::string& vrtPath, const Frame& f) {
    ds.reset(GDALDataset::Open(vrtPath.c_str(), GDAL_OF_RASTER));
    if (!ds || !ds->GetSpatialRef()) return "resample: cannot open the mosaic: " + lastGdalError();
    ds->GetGeoTransform(geo.data());
    OGRSpatialReference dst, src(*ds->GetSpatialRef());
    dst.importFromWkt(f.crs.wkt.c_str());
    dst.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    toSource.reset(OGRCreateCoordinateTransformation(&dst, &src));
    return toSource ? std::string() : "resample: PROJ cannot transform into the mosaic's CRS";
  }
  GDALRasterBand& band() { return *ds->GetRasterBand(1); }
};

/// A worker's mosaic (jobs::Scratch state), opened on first use; `error`
/// says why it did not open.
struct WorkerMosaic {
  MosaicReader m;
  bool tried = false;
  std::string error;
  const std::string& open(const std::string& vrtPath, const Frame& f) {
    if (!tried) error = m.open(vrtPath, f), tried = true;
    return error;
  }
};

/// Fills `image` with the mosaic's posts over the source positions of the
/// posts of grid rows [j0, j1), padded by `pad` posts; leaves it empty (the
/// strips then read the VRT) when the VRT is not plain or the image would be
/// too big.
void buildSourceImage(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, double pad,
                      int threads, SourceImage& image);

/// Target posts per source post along the mosaic's x and y over the whole
/// frame (the bounding box of its corners' source positions), as
/// GDALWarpOperation computes a chunk's scale; and those spans in posts.
struct FrameScale {
  double sx = 1, sy = 1, spanX = 0, spanY = 0;
};

/// The frame's scale and span in source posts (FrameScale); false when PROJ fails.
bool frameScale(const Frame& f, OGRCoordinateTransformation& toSource, const std::array<double, 6>& geo,
                FrameScale& out);

/// The weighted kernel's source posts of a batch of target posts
/// (elevation_weighted.cpp): column, row and value.
struct TapScratch {
  std::vector<std::int32_t> x, y;
  std::vector<float> z;
};

/// A worker's state for resampling 64-row strips (jobs::Scratch).
struct StripState {
  WorkerMosaic mosaic;
  Lattice L;
  Window win;
  TapScratch taps;  ///< weighted only
};
inline constexpr std::uint32_t kStripRows = kMinBandRows;

/// Runs fn(state, sj0, sj1) on every 64-row strip of grid rows [j0, j1) in
/// parallel; the first error wins.
template <typename Fn>
Status forEachStrip(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                    const ProgressFn& progress, Fn fn) {
  const std::uint32_t strips = (j1 - j0 + kStripRows - 1) / kStripRows;
  std::uint32_t done = 0;
  std::mutex mutex;
  std::string firstError;
  jobs::Scratch<StripState> states;
  jobs::parallelFor(strips, threads, [&](std::size_t s) {
    if (cancelRequested()) return;
    {
      std::lock_guard lock(mutex);
      if (!firstError.empty()) return;
    }
    bool opened = true;
    const std::string err = states.use([&](StripState& st) {
      if (const std::string& e = st.mosaic.open(vrtPath, f); !e.empty()) {
        opened = false;
        return e;
      }
      const std::uint32_t a = j0 + std::uint32_t(s) * kStripRows, b = std::min(j1, a + kStripRows);
      return fn(st, a, b);
    });
    std::lock_guard lock(mutex);
    if (!err.empty() && firstError.empty()) firstError = err;
    if (!opened) return;
    const std::uint32_t d = ++done;
    if (progress) progress(double(d) / strips, "resampling");
  });
  if (cancelRequested()) return stageError("build: cancelled");
  if (!firstError.empty()) return stageError(firstError);
  return {};
}

/// The weighted kernel's radius: the target spacing, never less than a
/// source cell's diagonal (so every target post sees the source posts
/// around it); and the smaller source post size in metres.
Result<std::array<double, 2>> weightedRadius(const std::string& vrtPath, const Frame& f);

/// The kernels resampleRows dispatches to, onto grid rows [j0, j1) of `out`.
Status weightedRows(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                    float* out, const ProgressFn& progress);
Status bilinearRows(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                    float* out, const ProgressFn& progress);
/// GDALWarp with `kernel` onto grid rows [j0, j1).
Status gdalRows(const std::string& vrtPath, const Frame& f, const std::string& kernel, std::uint32_t j0,
                std::uint32_t j1, int threads, float* out, const ProgressFn& progress);

/// A MEM dataset whose single band aliases `data` (no copy).
GDALDataset* wrapBuffer(void* data, GDALDataType type, std::uint32_t w, std::uint32_t h, const Frame& f);

}  // namespace sandtable::convert::detail
