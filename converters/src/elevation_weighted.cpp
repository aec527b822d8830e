// The weighted resampler: a distance-weighted least-squares plane through
// the source posts within a radius of each target post.
#include <algorithm>
#include <cmath>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "elevation_resample.h"

namespace sandtable::convert {

namespace {

/// Running sums of a distance-weighted least-squares plane z = a + b x + c y.
struct PlaneSums {
  double w = 0, wx = 0, wy = 0, wxx = 0, wxy = 0, wyy = 0, wz = 0, wxz = 0, wyz = 0;
  double zMin = INFINITY, zMax = -INFINITY;

  void add(double x, double y, double z, double weight) {
    w += weight;
    wx += weight * x;
    wy += weight * y;
    wxx += weight * x * x;
    wxy += weight * x * y;
    wyy += weight * y * y;
    wz += weight * z;
    wxz += weight * x * z;
    wyz += weight * y * z;
    zMin = std::min(zMin, z);
    zMax = std::max(zMax, z);
  }

  /// The plane's value at (0, 0). Falls back to the weighted mean when the
  /// posts are spread along a line (next to a void, say), where the plane's
  /// slope across that line is undetermined; and never leaves the range of
  /// the posts used, so a plane can not extrapolate into a spike.
  double estimate() const {
    if (w <= 0) return NAN;
    // Centre on the weighted centroid for conditioning.
    const double mx = wx / w, my = wy / w, mz = wz / w;
    const double sxx = wxx - w * mx * mx, sxy = wxy - w * mx * my, syy = wyy - w * my * my;
    const double sxz = wxz - w * mx * mz, syz = wyz - w * my * mz;
    const double det = sxx * syy - sxy * sxy;
    const double tr = sxx + syy;
    const double root = std::sqrt(std::max(0.0, tr * tr - 4 * det));
    const double lMin = 0.5 * (tr - root), lMax = 0.5 * (tr + root);
    if (!(lMax > 0) || lMin < 0.05 * lMax) return mz;
    const double b = (sxz * syy - syz * sxy) / det;
    const double c = (syz * sxx - sxz * sxy) / det;
    return std::clamp(mz - b * mx - c * my, zMin, zMax);
  }
};

}  // namespace

double weightedPlaneEstimate(const double* dx, const double* dy, const double* z, std::size_t n,
                             double radius) {
  PlaneSums s;
  for (std::size_t k = 0; k < n; ++k) {
    const double d = std::hypot(dx[k], dy[k]);
    if (d < radius) s.add(dx[k], dy[k], z[k], 1.0 - (d * d) / (radius * radius));
  }
  return s.estimate();
}

namespace detail {
namespace {

double estimatePost(const Window& win, const PostMap& p, double radius) {
  PlaneSums s;
  const int xa = std::max(win.x0, static_cast<int>(std::ceil(p.px - p.hx)));
  const int xb = std::min(win.x0 + win.w - 1, static_cast<int>(std::floor(p.px + p.hx)));
  const int ya = std::max(win.y0, static_cast<int>(std::ceil(p.py - p.hy)));
  const int yb = std::min(win.y0 + win.h - 1, static_cast<int>(std::floor(p.py + p.hy)));
  const double r2 = radius * radius, invR2 = 1.0 / r2;
  // Row y holds the posts inside the radius ellipse only between
  // cx -+ half (see mapPost); the bounds are widened a little so rounding
  // never drops a post that the exact test below would take, which keeps
  // the result identical to testing the whole box.
  const double disc0 = p.qa * r2 * (1 + 1e-9);
  for (int y = ya; y <= yb; ++y) {
    const double dy = y - p.py;
    const double disc = disc0 - p.qdet2 * dy * dy;
    if (disc < 0) continue;
    const double half = std::sqrt(disc) * p.qinvA + 1e-6;
    const double cx = p.px - p.qb * dy * p.qinvA;
    const int x0 = std::max(xa, static_cast<int>(std::ceil(cx - half)));
    const int x1 = std::min(xb, static_cast<int>(std::floor(cx + half)));
    const float* row = win.row(y);
    for (int x = x0; x <= x1; ++x) {
      const float v = row[x];
      if (std::isnan(v)) continue;
      const double dx = x - p.px;
      const double e = p.m[0][0] * dx + p.m[0][1] * dy;
      const double n = p.m[1][0] * dx + p.m[1][1] * dy;
      const double d2 = e * e + n * n;
      if (d2 < r2) s.add(e, n, v, 1.0 - d2 * invR2);
    }
  }
  return s.estimate();
}

#if defined(__SSE2__)
/// estimatePost for two posts of one lattice cell (same metric) at once,
/// one per SSE2 lane. Each lane takes exactly the posts estimatePost takes
/// (its box and d2 < r2), in the same order, with the same operations, so
/// both results are the same doubles; a lane adds +0.0 where it takes none.
void estimatePair(const Window& win, const PostMap& p, const PostMap& q, double radius, double& outP,
                  double& outQ) {
  const PostMap* pm[2] = {&p, &q};
  int xa[2], xb[2], ya[2], yb[2];
  for (int k = 0; k < 2; ++k) {
    xa[k] = std::max(win.x0, static_cast<int>(std::ceil(pm[k]->px - pm[k]->hx)));
    xb[k] = std::min(win.x0 + win.w - 1, static_cast<int>(std::floor(pm[k]->px + pm[k]->hx)));
    ya[k] = std::max(win.y0, static_cast<int>(std::ceil(pm[k]->py - pm[k]->hy)));
    yb[k] = std::min(win.y0 + win.h - 1, static_cast<int>(std::floor(pm[k]->py + pm[k]->hy)));
  }
  // Rows the ellipses reach (the others would have disc < 0 below).
  const int yFirst = std::max(std::min(ya[0], ya[1]), static_cast<int>(std::ceil(std::min(p.py, q.py) - p.qymax)));
  const int yEnd = std::min(std::max(yb[0], yb[1]), static_cast<int>(std::floor(std::max(p.py, q.py) + p.qymax)));
  const double r2 = radius * radius, invR2 = 1.0 / r2;
  const double disc0 = p.qa * r2 * (1 + 1e-9);
  const __m128d px = _mm_set_pd(q.px, p.px), py = _mm_set_pd(q.py, p.py);
  const __m128d m00 = _mm_set1_pd(p.m[0][0]), m01 = _mm_set1_pd(p.m[0][1]);
  const __m128d m10 = _mm_set1_pd(p.m[1][0]), m11 = _mm_set1_pd(p.m[1][1]);
  const __m128d vr2 = _mm_set1_pd(r2), vinv = _mm_set1_pd(invR2), one = _mm_set1_pd(1.0);
  __m128d w = _mm_setzero_pd(), wx = w, wy = w, wxx = w, wxy = w, wyy = w, wz = w, wxz = w, wyz = w;
  __m128d zMin = _mm_set1_pd(INFINITY), zMax = _mm_set1_pd(-INFINITY);
  for (int y = yFirst; y <= yEnd; ++y) {
    // Per lane: the row's posts inside the (widened) ellipse and the box.
    int lo[2], hi[2];
    for (int k = 0; k < 2; ++k) {
      lo[k] = 1, hi[k] = 0;
      if (y < ya[k] || y > yb[k]) continue;
      const double dy = y - pm[k]->py;
      const double disc = disc0 - p.qdet2 * dy * dy;
      if (disc < 0) continue;
      const double half = std::sqrt(disc) * p.qinvA + 1e-6;
      const double cx = pm[k]->px - p.qb * dy * p.qinvA;
      lo[k] = std::max(xa[k], static_cast<int>(std::ceil(cx - half)));
      hi[k] = std::min(xb[k], static_cast<int>(std::floor(cx + half)));
    }
    const int x0 = lo[0] <= hi[0] ? (lo[1] <= hi[1] ? std::min(lo[0], lo[1]) : lo[0]) : lo[1];
    const int x1 = lo[0] <= hi[0] ? (lo[1] <= hi[1] ? std::max(hi[0], hi[1]) : hi[0]) : hi[1];
    if (x0 > x1) continue;
    const __m128d vlo = _mm_set_pd(lo[1], lo[0]), vhi = _mm_set_pd(hi[1], hi[0]);
    const __m128d dy = _mm_sub_pd(_mm_set1_pd(y), py);
    const __m128d m01dy = _mm_mul_pd(m01, dy), m11dy = _mm_mul_pd(m11, dy);
    const float* row = win.row(y);
    for (int x = x0; x <= x1; ++x) {
      const float v = row[x];
      if (std::isnan(v)) continue;
      const __m128d vx = _mm_set1_pd(x);
      const __m128d dx = _mm_sub_pd(vx, px);
      const __m128d e = _mm_add_pd(_mm_mul_pd(m00, dx), m01dy);
      const __m128d n = _mm_add_pd(_mm_mul_pd(m10, dx), m11dy);
      const __m128d d2 = _mm_add_pd(_mm_mul_pd(e, e), _mm_mul_pd(n, n));
      const __m128d take =
          _mm_and_pd(_mm_cmplt_pd(d2, vr2), _mm_and_pd(_mm_cmpge_pd(vx, vlo), _mm_cmple_pd(vx, vhi)));
      if (_mm_movemask_pd(take) == 0) continue;
      const __m128d z = _mm_set1_pd(v);
      const __m128d wt = _mm_sub_pd(one, _mm_mul_pd(d2, vinv));
      const __m128d we = _mm_mul_pd(wt, e), wn = _mm_mul_pd(wt, n);
      w = _mm_add_pd(w, _mm_and_pd(take, wt));
      wx = _mm_add_pd(wx, _mm_and_pd(take, we));
      wy = _mm_add_pd(wy, _mm_and_pd(take, wn));
      wxx = _mm_add_pd(wxx, _mm_and_pd(take, _mm_mul_pd(we, e)));
      wxy = _mm_add_pd(wxy, _mm_and_pd(take, _mm_mul_pd(we, n)));
      wyy = _mm_add_pd(wyy, _mm_and_pd(take, _mm_mul_pd(wn, n)));
      wz = _mm_add_pd(wz, _mm_and_pd(take, _mm_mul_pd(wt, z)));
      wxz = _mm_add_pd(wxz, _mm_and_pd(take, _mm_mul_pd(we, z)));
      wyz = _mm_add_pd(wyz, _mm_and_pd(take, _mm_mul_pd(wn, z)));
      zMin = _mm_or_pd(_mm_and_pd(take, _mm_min_pd(z, zMin)), _mm_andnot_pd(take, zMin));
      zMax = _mm_or_pd(_mm_and_pd(take, _mm_max_pd(z, zMax)), _mm_andnot_pd(take, zMax));
    }
  }
  // PlaneSums::estimate in both lanes: the same operations, lane by lane,
  // then each lane picks the branch the scalar code takes.
  const __m128d zero = _mm_setzero_pd();
  const __m128d mx = _mm_div_pd(wx, w), my = _mm_div_pd(wy, w), mz = _mm_div_pd(wz, w);
  const __m128d wmx = _mm_mul_pd(w, mx), wmy = _mm_mul_pd(w, my);
  const __m128d sxx = _mm_sub_pd(wxx, _mm_mul_pd(wmx, mx)), sxy = _mm_sub_pd(wxy, _mm_mul_pd(wmx, my));
  const __m128d syy = _mm_sub_pd(wyy, _mm_mul_pd(wmy, my));
  const __m128d sxz = _mm_sub_pd(wxz, _mm_mul_pd(wmx, mz)), syz = _mm_sub_pd(wyz, _mm_mul_pd(wmy, mz));
  const __m128d det = _mm_sub_pd(_mm_mul_pd(sxx, syy), _mm_mul_pd(sxy, sxy));
  const __m128d tr = _mm_add_pd(sxx, syy);
  const __m128d root =
      _mm_sqrt_pd(_mm_max_pd(_mm_sub_pd(_mm_mul_pd(tr, tr), _mm_mul_pd(_mm_set1_pd(4.0), det)), zero));
  const __m128d half = _mm_set1_pd(0.5);
  const __m128d lMin = _mm_mul_pd(half, _mm_sub_pd(tr, root)), lMax = _mm_mul_pd(half, _mm_add_pd(tr, root));
  const __m128d b = _mm_div_pd(_mm_sub_pd(_mm_mul_pd(sxz, syy), _mm_mul_pd(syz, sxy)), det);
  const __m128d c = _mm_div_pd(_mm_sub_pd(_mm_mul_pd(syz, sxx), _mm_mul_pd(sxz, sxy)), det);
  __m128d v = _mm_sub_pd(_mm_sub_pd(mz, _mm_mul_pd(b, mx)), _mm_mul_pd(c, my));
  auto select = [](__m128d mask, __m128d a, __m128d other) {
    return _mm_or_pd(_mm_and_pd(mask, a), _mm_andnot_pd(mask, other));
  };
  v = select(_mm_cmplt_pd(v, zMin), zMin, v);  // std::clamp(v, zMin, zMax)
  v = select(_mm_cmplt_pd(zMax, v), zMax, v);
  // Collinear (or no positive eigenvalue): the weighted mean.
  const __m128d mean = _mm_or_pd(_mm_cmpnlt_pd(zero, lMax) /* !(lMax > 0) */,
                                 _mm_cmplt_pd(lMin, _mm_mul_pd(_mm_set1_pd(0.05), lMax)));
  v = select(mean, mz, v);
  v = select(_mm_cmple_pd(w, zero), _mm_set1_pd(NAN), v);
  alignas(16) double res[2];
  _mm_store_pd(res, v);
  outP = res[0];
  outQ = res[1];
}

#endif  // __SSE2__

std::string resampleStrip(const Frame& f, std::uint32_t jBegin, std::uint32_t jEnd, double radius,
                          GDALRasterBand& band, OGRCoordinateTransformation& ct,
                          const std::array<double, 6>& g, Lattice& L, Window& win, const SourceImage& image,
                          float* out, std::uint32_t rowBase) {
  if (!L.build(f, jBegin, jEnd, ct, g)) return "resample: PROJ failed to transform target posts to the sources";
  PostMap probe{};
  if (!mapPost(L, 0, 0, 0, jBegin, f.spacing, radius, probe)) return "resample: degenerate transform";
  const std::string err = readWindow(band, L, std::max(probe.hx, probe.hy) + 2, win, &image);
  if (!err.empty()) return err;
  for (std::uint32_t r = 0; r + 1 < L.rows; ++r) {
    const std::uint32_t jLast = (r + 2 == L.rows) ? L.rj[r + 1] : L.rj[r + 1] - 1;
    for (std::uint32_t c = 0; c + 1 < L.cols; ++c) {
      // The metric and search box are constant over a lattice cell; only
      // the source position moves, linearly.
      PostMap cell{};
      if (!mapPost(L, c, r, L.ci[c], L.rj[r], f.spacing, radius, cell)) continue;
      const std::uint32_t iLast = (c + 2 == L.cols) ? L.ci[c + 1] : L.ci[c + 1] - 1;
      for (std::uint32_t j = L.rj[r]; j <= jLast; ++j) {
        std::uint32_t i = L.ci[c];
#if defined(__SSE2__)
        for (; i + 1 <= iLast; i += 2) {
          PostMap p = cell, q = cell;
          positionAt(L, c, r, i, j, p.px, p.py);
          positionAt(L, c, r, i + 1, j, q.px, q.py);
          double a, b;
          estimatePair(win, p, q, radius, a, b);
          out[std::size_t(j - rowBase) * f.postsX + i] = static_cast<float>(a);
          out[std::size_t(j - rowBase) * f.postsX + i + 1] = static_cast<float>(b);
        }
#endif
        for (; i <= iLast; ++i) {
          PostMap p = cell;
          positionAt(L, c, r, i, j, p.px, p.py);
          out[std::size_t(j - rowBase) * f.postsX + i] = static_cast<float>(estimatePost(win, p, radius));
        }
      }
    }
  }
  return {};
}

}  // namespace

/// The weighted kernel's radius: the target spacing, never less than a
/// source cell's diagonal (so every target post sees the source posts
/// around it); and the smaller source post size in metres.
Result<std::array<double, 2>> weightedRadius(const std::string& vrtPath, const Frame& f) {
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(vrtPath.c_str(), GDAL_OF_RASTER));
  if (!ds) return stageError("resample: cannot open the mosaic: " + lastGdalError());
  std::array<double, 6> g{};
  ds->GetGeoTransform(g.data());
  const bool geographic = ds->GetSpatialRef() && ds->GetSpatialRef()->IsGeographic();
  const double lat = 0.5 * (f.cornersLonLat[0][1] + f.cornersLonLat[2][1]);
  const auto m = postMetres(g, geographic, lat);
  return std::array<double, 2>{std::max(f.spacing, std::hypot(m[0], m[1]) * 1.01), std::min(m[0], m[1])};
}

Status weightedRows(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                    float* out, const ProgressFn& progress) {
  auto r = weightedRadius(vrtPath, f);
  if (!r) return r.problems();
  const double radius = r.value()[0], minPostMetres = r.value()[1];
  SourceImage image;
  if (minPostMetres > 0) buildSourceImage(vrtPath, f, j0, j1, 2 * radius / minPostMetres + 16, threads, image);
  return forEachStrip(vrtPath, f, j0, j1, threads, progress, [&](StripState& st, std::uint32_t a, std::uint32_t b) {
    MosaicReader& m = st.mosaic.m;
    return resampleStrip(f, a, b, radius, m.band(), *m.toSource, m.geo, st.L, st.win, image, out, j0);
  });
}

}  // namespace detail
}  // namespace sandtable::convert
