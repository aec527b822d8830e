// The bilinear resampler: GDAL's bilinear kernel over the shared source
// image, at source positions from the lattice of exact transforms.
#include <algorithm>
#include <cmath>

#include "elevation_resample.h"

namespace sandtable::convert::detail {
namespace {

/// GDAL's bilinear kernel (gdalwarpkernel.cpp), over source posts in a
/// Window. At a scale of 0.95 or more on both axes it is the four-post
/// interpolation (GWKBilinearResample4Sample); below, GDAL widens the tent
/// by 1 / scale on the axes below 1 (GWKResample), so a coarser target
/// averages the posts it covers. Either way voids and posts off the mosaic
/// drop out and the weights of the rest are renormalised, as GDAL does with
/// a nodata mask.
struct BilinearKernel {
  double sx = 1, sy = 1;  ///< the tent's scale per axis (1 = not widened)
  int rx = 1, ry = 1;     ///< taps each side
  bool four = true;
  int W = 0, H = 0;       ///< the mosaic's size in posts

  BilinearKernel(const FrameScale& s, int width, int height) : W(width), H(height) {
    four = s.sx >= 0.95 && s.sy >= 0.95;
    sx = std::min(1.0, s.sx), sy = std::min(1.0, s.sy);
    rx = static_cast<int>(std::ceil(1.0 / sx)), ry = static_cast<int>(std::ceil(1.0 / sy));
  }
  /// Posts the kernel reaches beyond its centre post, for window padding.
  int reach() const { return std::max(rx, ry) + 1; }

  static double tent(double t) {
    t = std::fabs(t);
    return t <= 1.0 ? 1.0 - t : 0.0;
  }

  /// At post coordinates (px, py) (post k's centre at k): NaN when no post
  /// with weight is valid, or when the position is off the mosaic.
  double at(const Window& win, double px, double py) const {
    // GDAL's pixel coordinates put post k's centre at k + 0.5; a target
    // pixel whose source position is off the raster is not computed.
    if (!(px >= -0.5 && py >= -0.5 && px < W - 0.5 && py < H - 0.5)) return NAN;
    const int ix = static_cast<int>(std::floor(px)), iy = static_cast<int>(std::floor(py));
    const double dx = px - ix, dy = py - iy;
    const int xa = win.x0, xb = win.x0 + win.w, ya = win.y0, yb = win.y0 + win.h;  // [a, b)
    if (four) {
      double acc = 0, div = 0;
      const double wx[2] = {1.0 - dx, dx}, wy[2] = {1.0 - dy, dy};
      for (int j = 0; j < 2; ++j) {
        const int y = iy + j;
        if (y < ya || y >= yb) continue;
        const float* row = win.row(y);
        for (int i = 0; i < 2; ++i) {
          const int x = ix + i;
          if (x < xa || x >= xb) continue;
          const float v = row[x];
          if (std::isnan(v)) continue;
          const double m = wx[i] * wy[j];
          div += m;
          acc += v * m;
        }
      }
      if (div < 0.00001) return NAN;
      return div == 1.0 ? acc : acc / div;
    }
    double acc = 0, weight = 0;
    for (int j = -ry; j <= ry; ++j) {
      const int y = iy + j;
      if (y < ya || y >= yb) continue;
      const double w1 = tent((j - dy) * sy);
      if (w1 == 0.0) continue;
      const float* row = win.row(y);
      double accRow = 0, weightRow = 0;
      for (int i = -rx; i <= rx; ++i) {
        const int x = ix + i;
        if (x < xa || x >= xb) continue;
        const float v = row[x];
        if (std::isnan(v)) continue;
        const double w2 = tent((i - dx) * sx);
        accRow += v * w2;
        weightRow += w2;
      }
      acc += accRow * w1;
      weight += weightRow * w1;
    }
    if (weight < 0.000001) return NAN;
    return (weight < 0.99999 || weight > 1.00001) ? acc / weight : acc;
  }
};

}  // namespace

/// Bilinear over GDAL-read source posts (the shared source image, or the
/// VRT window by window), at source positions from the same lattice of
/// exact PROJ transforms the weighted kernel uses (docs/ARCHITECTURE.md,
/// stage 6, gives its error against exact transforms).
Status bilinearRows(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                    float* out, const ProgressFn& progress) {
  MosaicReader m;
  if (std::string e = m.open(vrtPath, f); !e.empty()) return stageError(e);
  FrameScale scale;
  if (!frameScale(f, *m.toSource, m.geo, scale)) return stageError("resample: PROJ failed to transform the frame");
  const BilinearKernel kernel(scale, m.band().GetXSize(), m.band().GetYSize());
  SourceImage image;
  buildSourceImage(vrtPath, f, j0, j1, kernel.reach() + 16, threads, image);
  return forEachStrip(vrtPath, f, j0, j1, threads, progress, [&](StripState& st, std::uint32_t a, std::uint32_t b) {
    MosaicReader& mr = st.mosaic.m;
    Lattice& L = st.L;
    if (!L.build(f, a, b, *mr.toSource, mr.geo)) return std::string("resample: PROJ failed to transform target posts to the sources");
    if (std::string e = readWindow(mr.band(), L, kernel.reach() + 2, st.win, &image); !e.empty()) return e;
    for (std::uint32_t r = 0; r + 1 < L.rows; ++r) {
      const std::uint32_t jLast = (r + 2 == L.rows) ? L.rj[r + 1] : L.rj[r + 1] - 1;
      for (std::uint32_t j = L.rj[r]; j <= jLast; ++j) {
        float* row = out + std::size_t(j - j0) * f.postsX;
        for (std::uint32_t c = 0; c + 1 < L.cols; ++c) {
          const std::uint32_t iLast = (c + 2 == L.cols) ? L.ci[c + 1] : L.ci[c + 1] - 1;
          for (std::uint32_t i = L.ci[c]; i <= iLast; ++i) {
            double px, py;
            positionAt(L, c, r, i, j, px, py);
            row[i] = static_cast<float>(kernel.at(st.win, px, py));
          }
        }
      }
    }
    return std::string();
  });
}

}  // namespace sandtable::convert::detail
