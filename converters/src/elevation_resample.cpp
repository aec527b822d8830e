// Resampling the source mosaic onto the target grid, and void filling.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <memory>
#include <mutex>
#include <new>

#include <cpl_string.h>
#include <gdal_alg.h>
#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include "elevation_internal.h"
#include "sandtable/base/jobs.h"
#include "sandtable/formats/terrain_rule.h"

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

std::string lastGdalError() {
  const char* m = CPLGetLastErrorMsg();
  return (m && *m) ? std::string(m) : std::string("unknown GDAL error");
}

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

Status buildMosaic(const std::vector<Source>& sources, const std::string& vrtPath) {
  std::vector<const char*> names;
  for (const auto& s : sources) names.push_back(s.path.c_str());
  const char* args[] = {"-resolution", "highest", "-q", nullptr};
  GDALBuildVRTOptions* opts = GDALBuildVRTOptionsNew(const_cast<char**>(args), nullptr);
  int usageError = 0;
  CPLErrorReset();
  GDALDatasetH vrt = GDALBuildVRT(vrtPath.c_str(), static_cast<int>(names.size()), nullptr,
                                  names.data(), opts, &usageError);
  GDALBuildVRTOptionsFree(opts);
  if (!vrt) {
    return stageError("mosaic: cannot build a mosaic of the sources: " + lastGdalError() +
                      " (all sources must share one coordinate system)");
  }
  GDALClose(vrt);
  return {};
}

namespace {

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

bool mapPost(const Lattice& L, std::uint32_t c, std::uint32_t r, std::uint32_t i, std::uint32_t j,
             double spacing, double radius, PostMap& out) {
  const double di = L.ci[c + 1] - L.ci[c];
  const double dj = std::max(1u, L.rj[r + 1] - L.rj[r]);
  const double fx = (i - L.ci[c]) / di, fz = L.rj[r + 1] == L.rj[r] ? 0.0 : (j - L.rj[r]) / dj;
  auto at = [&](const std::vector<double>& v, std::uint32_t cc, std::uint32_t rr) { return v[rr * L.cols + cc]; };
  auto lerp = [&](const std::vector<double>& v) {
    const double top = at(v, c, r) + fx * (at(v, c + 1, r) - at(v, c, r));
    const double bot = at(v, c, r + 1) + fx * (at(v, c + 1, r + 1) - at(v, c, r + 1));
    return top + fz * (bot - top);
  };
  out.px = lerp(L.px);
  out.py = lerp(L.py);
  // Source posts per target post, along target i and j.
  const double aXi = (at(L.px, c + 1, r) - at(L.px, c, r)) / di;
  const double aYi = (at(L.py, c + 1, r) - at(L.py, c, r)) / di;
  double aXj = (at(L.px, c, r + 1) - at(L.px, c, r)) / dj;
  double aYj = (at(L.py, c, r + 1) - at(L.py, c, r)) / dj;
  if (L.rj[r + 1] == L.rj[r]) {  // single-row strip: assume a conformal frame
    aXj = -aYi;
    aYj = aXi;
  }
  const double det = aXi * aYj - aXj * aYi;
  if (!(std::fabs(det) > 1e-15)) return false;
  out.m[0][0] = spacing * aYj / det;
  out.m[0][1] = -spacing * aXj / det;
  out.m[1][0] = -spacing * aYi / det;
  out.m[1][1] = spacing * aXi / det;
  const double rPosts = radius / spacing;
  out.hx = rPosts * (std::fabs(aXi) + std::fabs(aXj)) + 1;
  out.hy = rPosts * (std::fabs(aYi) + std::fabs(aYj)) + 1;
  out.qa = out.m[0][0] * out.m[0][0] + out.m[1][0] * out.m[1][0];
  out.qb = out.m[0][0] * out.m[0][1] + out.m[1][0] * out.m[1][1];
  const double dm = out.m[0][0] * out.m[1][1] - out.m[0][1] * out.m[1][0];
  out.qdet2 = dm * dm;
  out.qinvA = 1.0 / out.qa;
  // Rows beyond |dy| = qymax have no post inside the ellipse (disc < 0 in
  // estimatePost); a little wider, so rounding keeps every row with one.
  out.qymax = std::sqrt(out.qa * radius * radius * (1 + 1e-9) / out.qdet2) * (1 + 1e-9) + 1e-6;
  return true;
}

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

/// The window of lattice L padded by `pad` posts, clamped to the band.
void windowBounds(GDALRasterBand& band, const Lattice& L, double pad, Window& win) {
  const auto [pxMin, pxMax] = std::minmax_element(L.px.begin(), L.px.end());
  const auto [pyMin, pyMax] = std::minmax_element(L.py.begin(), L.py.end());
  const int W = band.GetXSize(), H = band.GetYSize();
  win.x0 = std::clamp(static_cast<int>(std::floor(*pxMin - pad)), 0, W - 1);
  win.y0 = std::clamp(static_cast<int>(std::floor(*pyMin - pad)), 0, H - 1);
  const int x1 = std::clamp(static_cast<int>(std::ceil(*pxMax + pad)), 0, W - 1);
  const int y1 = std::clamp(static_cast<int>(std::ceil(*pyMax + pad)), 0, H - 1);
  win.w = x1 - win.x0 + 1;
  win.h = y1 - win.y0 + 1;
}

std::string readWindow(GDALRasterBand& band, const Lattice& L, double pad, Window& win,
                       const SourceImage* image = nullptr) {
  windowBounds(band, L, pad, win);
  if (image && image->covers(win.x0, win.y0, win.x0 + win.w - 1, win.y0 + win.h - 1)) {
    win.base = image->v.get();
    win.stride = std::size_t(image->w);
    win.bx0 = image->x0;
    win.by0 = image->y0;
    return {};
  }
  win.v.resize(std::size_t(win.w) * win.h);
  win.base = win.v.data();
  win.stride = std::size_t(win.w);
  win.bx0 = win.x0;
  win.by0 = win.y0;
  if (band.RasterIO(GF_Read, win.x0, win.y0, win.w, win.h, win.v.data(), win.w, win.h, GDT_Float32, 0, 0) !=
      CE_None) {
    return "resample: cannot read the sources: " + lastGdalError();
  }
  int hasNoData = 0;
  const float nd = static_cast<float>(band.GetNoDataValue(&hasNoData));
  for (float& x : win.v) x = validOrNan(x, hasNoData != 0, nd);
  return {};
}

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

/// One source of the VRT mosaic, as GDALBuildVRT writes it.
struct VrtSource {
  std::string path;
  int band = 1;
  int sx = 0, sy = 0, dx = 0, dy = 0, w = 0, h = 0;  // SrcRect origin, DstRect origin, size
  bool hasNoData = false;
  double noData = 0;
};

bool integerAttr(const CPLXMLNode* n, const char* name, int& out) {
  const char* v = CPLGetXMLValue(n, name, nullptr);
  if (!v) return false;
  const double d = CPLAtof(v);
  out = static_cast<int>(std::lround(d));
  return std::fabs(d - out) < 1e-9;
}

/// The sources of band 1 of the VRT in its order, or false when the VRT
/// holds anything but plain unscaled sources (then the VRT itself is read).
bool vrtSources(const std::string& vrtPath, std::vector<VrtSource>& out) {
  CPLXMLNode* root = CPLParseXMLFile(vrtPath.c_str());
  if (!root) return false;
  bool ok = true;
  const CPLXMLNode* ds = CPLGetXMLNode(root, "=VRTDataset");
  const CPLXMLNode* band = nullptr;
  for (const CPLXMLNode* c = ds ? ds->psChild : nullptr; c; c = c->psNext) {
    if (c->eType == CXT_Element && std::string(c->pszValue) == "VRTRasterBand" &&
        std::string(CPLGetXMLValue(c, "band", "1")) == "1") {
      band = c;
    }
  }
  if (!band || CPLGetXMLValue(band, "subClass", nullptr)) ok = false;
  for (const CPLXMLNode* c = band ? band->psChild : nullptr; ok && c; c = c->psNext) {
    if (c->eType != CXT_Element) continue;
    const std::string kind = c->pszValue;
    if (kind != "SimpleSource" && kind != "ComplexSource") {
      if (kind != "NoDataValue" && kind != "ColorInterp" && kind != "Metadata" && kind != "Description") ok = false;
      continue;
    }
    VrtSource v;
    for (const CPLXMLNode* e = c->psChild; e; e = e->psNext) {
      if (e->eType != CXT_Element) continue;
      const std::string n = e->pszValue;
      if (n == "NODATA") {
        v.hasNoData = true;
        v.noData = CPLAtof(CPLGetXMLValue(e, nullptr, "0"));
      } else if (n != "SourceFilename" && n != "SourceBand" && n != "SourceProperties" && n != "SrcRect" &&
                 n != "DstRect") {
        ok = false;  // scaling, LUT, masks, resampling...: leave it to GDAL
      }
    }
    const char* name = CPLGetXMLValue(c, "SourceFilename", nullptr);
    int sw = 0, sh = 0;
    if (!name || !integerAttr(c, "SrcRect.xOff", v.sx) || !integerAttr(c, "SrcRect.yOff", v.sy) ||
        !integerAttr(c, "SrcRect.xSize", sw) || !integerAttr(c, "SrcRect.ySize", sh) ||
        !integerAttr(c, "DstRect.xOff", v.dx) || !integerAttr(c, "DstRect.yOff", v.dy) ||
        !integerAttr(c, "DstRect.xSize", v.w) || !integerAttr(c, "DstRect.ySize", v.h) || sw != v.w || sh != v.h) {
      ok = false;
      break;
    }
    v.band = std::atoi(CPLGetXMLValue(c, "SourceBand", "1"));
    const bool relative = std::atoi(CPLGetXMLValue(c, "SourceFilename.relativeToVRT", "0")) != 0;
    v.path = relative ? CPLProjectRelativeFilename(CPLGetPath(vrtPath.c_str()), name) : name;
    out.push_back(std::move(v));
  }
  CPLDestroyXMLNode(root);
  return ok && !out.empty();
}

/// Reads rect (x, y, w, h) of a source band as floats, row-major. Bands in
/// one-column blocks (DTED) are read block by block: RasterIO would copy
/// them pixel by pixel.
bool readSourceRect(GDALRasterBand& b, int x, int y, int w, int h, std::vector<float>& out) {
  out.resize(std::size_t(w) * h);
  int bw = 0, bh = 0;
  b.GetBlockSize(&bw, &bh);
  if (bw != 1 || bh < 2) {
    return b.RasterIO(GF_Read, x, y, w, h, out.data(), w, h, GDT_Float32, 0, 0) == CE_None;
  }
  const GDALDataType type = b.GetRasterDataType();
  const int bytes = GDALGetDataTypeSizeBytes(type);
  std::vector<std::byte> block(std::size_t(bh) * bytes);
  for (int by = y / bh; by * bh < y + h; ++by) {
    const int r0 = std::max(y, by * bh), r1 = std::min(y + h, (by + 1) * bh);
    for (int c = x; c < x + w; ++c) {
      if (b.ReadBlock(c, by, block.data()) != CE_None) return false;
      GDALCopyWords64(block.data() + std::size_t(r0 - by * bh) * bytes, type, bytes,
                      out.data() + std::size_t(r0 - y) * w + (c - x), GDT_Float32, w * int(sizeof(float)), r1 - r0);
    }
  }
  return true;
}

/// Fills `image` with the mosaic's posts over the source positions of the
/// posts of grid rows [j0, j1), padded by `pad` posts; leaves it empty (the
/// strips then read the VRT) when the VRT is not plain or the image would be
/// too big.
void buildSourceImage(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, double pad,
                      int threads, SourceImage& image) {
  image = {};
  MosaicReader m;
  if (!m.open(vrtPath, f).empty()) return;
  std::vector<VrtSource> sources;
  if (!vrtSources(vrtPath, sources)) return;
  // Source positions along the frame's edge, every 8 posts.
  std::vector<double> x, y;
  auto add = [&](std::uint32_t i, std::uint32_t j) {
    x.push_back(f.originEasting + i * f.spacing);
    y.push_back(f.originNorthing - j * f.spacing);
  };
  for (std::uint32_t i = 0; i < f.postsX; i += 8) add(i, j0), add(i, j1 - 1);
  for (std::uint32_t j = j0; j < j1; j += 8) add(0, j), add(f.postsX - 1, j);
  add(f.postsX - 1, j0);
  add(f.postsX - 1, j1 - 1);
  add(0, j1 - 1);
  if (!m.toSource->Transform(static_cast<int>(x.size()), x.data(), y.data())) return;
  double xMin = INFINITY, xMax = -INFINITY, yMin = INFINITY, yMax = -INFINITY;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double px = (x[k] - m.geo[0]) / m.geo[1] - 0.5, py = (y[k] - m.geo[3]) / m.geo[5] - 0.5;
    xMin = std::min(xMin, px), xMax = std::max(xMax, px), yMin = std::min(yMin, py), yMax = std::max(yMax, py);
  }
  if (!std::isfinite(xMin + xMax + yMin + yMax)) return;
  GDALRasterBand& band = m.band();
  const int W = band.GetXSize(), H = band.GetYSize();
  const int x0 = std::clamp(static_cast<int>(std::floor(xMin - pad)), 0, W - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(yMin - pad)), 0, H - 1);
  const int x1 = std::clamp(static_cast<int>(std::ceil(xMax + pad)), 0, W - 1);
  const int y1 = std::clamp(static_cast<int>(std::ceil(yMax + pad)), 0, H - 1);
  const std::size_t n = std::size_t(x1 - x0 + 1) * std::size_t(y1 - y0 + 1);
  // No more than 4 bytes per post of 1 G posts; bigger mosaics go strip by strip.
  if (n > (std::size_t(1) << 30)) return;
  int hasNoData = 0;
  const double nd = band.GetNoDataValue(&hasNoData);
  SourceImage img;
  img.x0 = x0, img.y0 = y0, img.w = x1 - x0 + 1, img.h = y1 - y0 + 1;
  // As VRTSourcedRasterBand: posts no source covers hold the nodata value,
  // or 0. Values are stored as validOrNan of what the VRT would give.
  const float fnd = static_cast<float>(nd);
  const float init = validOrNan(hasNoData ? fnd : 0.0f, hasNoData != 0, fnd);
  img.v.reset(new (std::nothrow) float[n]);
  if (!img.v) return;  // no memory for it: strip by strip
  jobs::parallelRanges(n, threads, std::size_t(1) << 20,
                       [&](std::size_t b, std::size_t e) { std::fill(img.v.get() + b, img.v.get() + e, init); });
  // Sources are read in parallel and composited in the VRT's order (a
  // later source's valid posts replace an earlier one's, as in the VRT);
  // as many are read ahead as there are workers.
  struct Read {
    bool ok = true, empty = false;
    int ax = 0, ay = 0, bx = 0, by = 0;
    std::vector<float> buf;
  };
  bool failed = false;
  jobs::orderedPipeline<Read>(
      sources.size(), threads, std::size_t(jobs::threadCount(threads)),
      [&](std::size_t k) {
        const VrtSource& s = sources[k];
        Read r;
        r.ax = std::max(x0, s.dx), r.ay = std::max(y0, s.dy);
        r.bx = std::min(x1 + 1, s.dx + s.w), r.by = std::min(y1 + 1, s.dy + s.h);
        r.empty = r.ax >= r.bx || r.ay >= r.by;
        if (!r.empty) {
          std::unique_ptr<GDALDataset> ds(GDALDataset::Open(s.path.c_str(), GDAL_OF_RASTER | GDAL_OF_VERBOSE_ERROR));
          GDALRasterBand* b = ds && s.band >= 1 && s.band <= ds->GetRasterCount() ? ds->GetRasterBand(s.band) : nullptr;
          r.ok = b && readSourceRect(*b, s.sx + r.ax - s.dx, s.sy + r.ay - s.dy, r.bx - r.ax, r.by - r.ay, r.buf);
        }
        return r;
      },
      [&](std::size_t k, Read&& r) {
        const VrtSource& s = sources[k];
        if (!r.ok) failed = true;
        if (!r.ok || r.empty || failed) return;
        const int w = r.bx - r.ax;
        const float snd = static_cast<float>(s.noData);
        const bool vnd = hasNoData != 0;
        for (int row = r.ay; row < r.by; ++row) {
          float* dst = img.v.get() + std::size_t(row - y0) * img.w + (r.ax - x0);
          const float* src = r.buf.data() + std::size_t(row - r.ay) * w;
          if (!s.hasNoData) {
            for (int c = 0; c < w; ++c) dst[c] = validOrNan(src[c], vnd, fnd);
          } else {
            for (int c = 0; c < w; ++c) {
              if (!(src[c] == snd || (std::isnan(snd) && std::isnan(src[c])))) dst[c] = validOrNan(src[c], vnd, fnd);
            }
          }
        }
      });
  if (failed) return;  // the strips read the VRT and report its error
  image = std::move(img);
}

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

namespace {

/// A worker's state for resampling 64-row strips (jobs::Scratch).
struct StripState {
  WorkerMosaic mosaic;
  Lattice L;
  Window win;
};
constexpr std::uint32_t kStripRows = kMinBandRows;

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

/// Target posts per source post along the mosaic's x and y over the whole
/// frame (the bounding box of its corners' source positions), as
/// GDALWarpOperation computes a chunk's scale; and those spans in posts.
struct FrameScale {
  double sx = 1, sy = 1, spanX = 0, spanY = 0;
};

bool frameScale(const Frame& f, OGRCoordinateTransformation& toSource, const std::array<double, 6>& geo,
                FrameScale& out) {
  double x[4] = {f.originEasting, f.originEasting + (f.postsX - 1) * f.spacing, f.originEasting,
                 f.originEasting + (f.postsX - 1) * f.spacing};
  double y[4] = {f.originNorthing, f.originNorthing, f.originNorthing - (f.postsZ - 1) * f.spacing,
                 f.originNorthing - (f.postsZ - 1) * f.spacing};
  if (!toSource.Transform(4, x, y)) return false;
  out.spanX = (std::max({x[0], x[1], x[2], x[3]}) - std::min({x[0], x[1], x[2], x[3]})) / std::fabs(geo[1]);
  out.spanY = (std::max({y[0], y[1], y[2], y[3]}) - std::min({y[0], y[1], y[2], y[3]})) / std::fabs(geo[5]);
  out.sx = f.postsX / (out.spanX + 1);
  out.sy = f.postsZ / (out.spanY + 1);
  return std::isfinite(out.sx + out.sy) && out.sx > 0 && out.sy > 0;
}

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

}  // namespace

namespace {

// ---- least-squares fit of the terrain triangles to the source surface

constexpr int kFitSamples = 3;     // samples per square side
constexpr int kFitIterations = 10; // damped Jacobi sweeps; the start is close
constexpr double kFitDamping = 0.8;

using terrain::cornerWeights;

/// The quadrature shared by the right-hand side and the mass matrix, so a
/// source surface that is already linear on a triangle is reproduced exactly.
struct SquareRule {
  std::array<std::array<double, 4>, kFitSamples * kFitSamples> phi{};
  std::array<std::array<double, 4>, 4> mass{};
  SquareRule() {
    int s = 0;
    for (int c = 0; c < kFitSamples; ++c) {
      for (int a = 0; a < kFitSamples; ++a, ++s) {
        phi[s] = cornerWeights((a + 0.5) / kFitSamples, (c + 0.5) / kFitSamples);
        for (int p = 0; p < 4; ++p) {
          for (int q = 0; q < 4; ++q) mass[p][q] += phi[s][p] * phi[s][q];
        }
      }
    }
  }
};

double sourceBilinear(const Window& win, double px, double py) {
  const int x0 = static_cast<int>(std::floor(px)), y0 = static_cast<int>(std::floor(py));
  if (x0 < win.x0 || y0 < win.y0 || x0 + 1 >= win.x0 + win.w || y0 + 1 >= win.y0 + win.h) return NAN;
  const double fx = px - x0, fy = py - y0;
  const double a = win.at(x0, y0), b = win.at(x0 + 1, y0), c = win.at(x0, y0 + 1), d = win.at(x0 + 1, y0 + 1);
  const double top = a + fx * (b - a), bot = c + fx * (d - c);
  return top + fy * (bot - top);  // NaN if any corner is a void
}

struct FitSystem {
  std::uint32_t w = 0, h = 0;
  std::vector<double> b;              // right-hand side per post
  std::vector<std::uint8_t> included; // per square: all samples valid
  std::mutex mutex;
};

/// Source post positions of every target post on row j.
void rowPositions(const Lattice& L, const Frame& f, std::uint32_t j, std::uint32_t jBegin, std::vector<double>& px,
                  std::vector<double>& py) {
  const std::uint32_t r = std::min((j - jBegin) / Lattice::kStep, L.rows - 2);
  for (std::uint32_t i = 0; i < f.postsX; ++i) {
    const std::uint32_t c = std::min(i / Lattice::kStep, L.cols - 2);
    PostMap m{};
    mapPost(L, c, r, i, j, f.spacing, f.spacing, m);
    px[i] = m.px;
    py[i] = m.py;
  }
}

std::string fitStrip(const Frame& f, std::uint32_t j0, std::uint32_t j1, GDALRasterBand& band,
                     OGRCoordinateTransformation& ct, const std::array<double, 6>& g, const SquareRule& rule,
                     FitSystem& sys, std::uint32_t rowBase) {
  Lattice L;
  Window win;
  if (!L.build(f, j0, j1 + 1, ct, g)) return "fit: PROJ failed to transform target posts to the sources";
  if (std::string e = readWindow(band, L, 2, win); !e.empty()) return e;
  std::vector<double> local(std::size_t(j1 - j0 + 1) * f.postsX, 0.0);
  std::vector<std::uint8_t> inc(std::size_t(j1 - j0) * (f.postsX - 1), 0);
  std::vector<double> pxA(f.postsX), pyA(f.postsX), pxB(f.postsX), pyB(f.postsX);
  rowPositions(L, f, j0, j0, pxA, pyA);
  for (std::uint32_t j = j0; j < j1; ++j) {
    rowPositions(L, f, j + 1, j0, pxB, pyB);
    for (std::uint32_t i = 0; i + 1 < f.postsX; ++i) {
      std::array<double, 4> acc{};
      bool ok = true;
      for (int s = 0; s < kFitSamples * kFitSamples && ok; ++s) {
        const auto& w = rule.phi[s];
        const double px = w[0] * pxA[i] + w[1] * pxA[i + 1] + w[2] * pxB[i] + w[3] * pxB[i + 1];
        const double py = w[0] * pyA[i] + w[1] * pyA[i + 1] + w[2] * pyB[i] + w[3] * pyB[i + 1];
        const double v = sourceBilinear(win, px, py);
        ok = !std::isnan(v);
        for (int k = 0; k < 4; ++k) acc[k] += v * w[k];
      }
      if (!ok) continue;
      inc[std::size_t(j - j0) * (f.postsX - 1) + i] = 1;
      double* top = &local[std::size_t(j - j0) * f.postsX + i];
      double* bot = top + f.postsX;
      top[0] += acc[0], top[1] += acc[1], bot[0] += acc[2], bot[1] += acc[3];
    }
    std::swap(pxA, pxB);
    std::swap(pyA, pyB);
  }
  std::lock_guard lock(sys.mutex);
  for (std::size_t k = 0; k < local.size(); ++k) sys.b[std::size_t(j0 - rowBase) * f.postsX + k] += local[k];
  std::copy(inc.begin(), inc.end(),
            sys.included.begin() + std::ptrdiff_t(std::size_t(j0 - rowBase) * (f.postsX - 1)));
  return {};
}

/// (M z)(i, j) and M's diagonal, gathered from the included squares around
/// the post; corners are NW, NE, SW, SE.
void applyMass(const FitSystem& sys, const SquareRule& rule, const std::vector<double>& z, std::uint32_t i,
               std::uint32_t j, double& mz, double& diag) {
  mz = 0;
  diag = 0;
  const std::uint32_t sw = sys.w - 1;
  const int corner[4][2] = {{-1, -1}, {0, -1}, {-1, 0}, {0, 0}};  // square offset for the post as SE, SW, NE, NW
  const int local[4] = {3, 2, 1, 0};
  for (int q = 0; q < 4; ++q) {
    const long si = long(i) + corner[q][0], sj = long(j) + corner[q][1];
    if (si < 0 || sj < 0 || si >= long(sys.w) - 1 || sj >= long(sys.h) - 1) continue;
    if (!sys.included[std::size_t(sj) * sw + std::size_t(si)]) continue;
    const double* zr0 = &z[std::size_t(sj) * sys.w + std::size_t(si)];
    const double* zr1 = zr0 + sys.w;
    const auto& m = rule.mass[local[q]];
    mz += m[0] * zr0[0] + m[1] * zr0[1] + m[2] * zr1[0] + m[3] * zr1[1];
    diag += m[local[q]];
  }
}

template <typename Fn>
void parallelRows(std::uint32_t rows, int threads, Fn fn) {
  jobs::parallelRanges(rows, threads, 16, [&](std::size_t b, std::size_t e) {
    for (std::size_t j = b; j < e; ++j) fn(std::uint32_t(j));
  });
}

}  // namespace

Status fitTriangles(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, int threads,
                    float* grid, const ProgressFn& progress) {
  const SquareRule rule;
  FitSystem sys;
  sys.w = f.postsX;
  sys.h = j1 - j0;
  const std::size_t posts = std::size_t(sys.w) * sys.h;
  if (sys.h < 2) return {};
  sys.b.assign(posts, 0.0);
  sys.included.assign(std::size_t(f.postsX - 1) * (sys.h - 1), 0);
  // Strips of 64 square rows from j0 (a multiple of 64), so a strip's
  // lattice is the whole grid's whatever the range.
  const std::uint32_t squareEnd = j1 - 1;
  const std::uint32_t strips = (squareEnd - j0 + kStripRows - 1) / kStripRows;
  std::uint32_t done = 0;
  std::string firstError;
  std::mutex errMutex;
  jobs::Scratch<WorkerMosaic> mosaics;
  jobs::parallelFor(strips, threads, [&](std::size_t s) {
    if (cancelRequested()) return;
    bool opened = true;
    const std::string e = mosaics.use([&](WorkerMosaic& w) {
      if (const std::string& err = w.open(vrtPath, f); !err.empty()) {
        opened = false;
        return err;
      }
      const std::uint32_t a = j0 + std::uint32_t(s) * kStripRows, b = std::min(squareEnd, a + kStripRows);
      return fitStrip(f, a, b, w.m.band(), *w.m.toSource, w.m.geo, rule, sys, j0);
    });
    std::lock_guard lock(errMutex);
    if (!e.empty() && firstError.empty()) firstError = e;
    if (opened && progress) progress(0.5 * double(++done) / strips, "fitting triangles");
  });
  if (cancelRequested()) return stageError("build: cancelled");
  if (!firstError.empty()) return stageError(firstError);

  // Start from the point samples; a post no included square touches keeps its sample.
  std::vector<double> z(posts), next2(posts);
  parallelRows(sys.h, threads, [&](std::uint32_t j) {
    for (std::uint32_t i = 0; i < f.postsX; ++i) {
      const std::size_t k = std::size_t(j) * f.postsX + i;
      double mz, diag;
      z[k] = grid[k];
      if (std::isnan(z[k])) {
        z[k] = 0;  // provisional; replaced below when the post is fitted
        applyMass(sys, rule, z, i, j, mz, diag);
        if (diag > 0) z[k] = sys.b[k] / diag;
      }
    }
  });
  for (int it = 0; it < kFitIterations; ++it) {
    parallelRows(sys.h, threads, [&](std::uint32_t j) {
      for (std::uint32_t i = 0; i < f.postsX; ++i) {
        const std::size_t k = std::size_t(j) * f.postsX + i;
        double mz, diag;
        applyMass(sys, rule, z, i, j, mz, diag);
        next2[k] = diag > 0 ? z[k] + kFitDamping * (sys.b[k] - mz) / diag : z[k];
      }
    });
    std::swap(z, next2);
    if (progress) progress(0.5 + 0.5 * (it + 1) / kFitIterations, "fitting triangles");
  }
  parallelRows(sys.h, threads, [&](std::uint32_t j) {
    for (std::uint32_t i = 0; i < f.postsX; ++i) {
      const std::size_t k = std::size_t(j) * f.postsX + i;
      double mz, diag;
      applyMass(sys, rule, z, i, j, mz, diag);
      if (diag > 0) grid[k] = static_cast<float>(z[k]);
    }
  });
  return {};
}

namespace {

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

int gdalProgress(double fraction, const char*, void* data) {
  const auto* p = static_cast<const ProgressFn*>(data);
  if (*p) (*p)(fraction, "resampling");
  return cancelRequested() ? FALSE : TRUE;
}

int fillProgress(double fraction, const char*, void* data) {
  const auto* p = static_cast<const ProgressFn*>(data);
  if (*p) (*p)(fraction, "filling voids");
  return cancelRequested() ? FALSE : TRUE;
}

}  // namespace

namespace {

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

}  // namespace

Status resampleRows(const std::string& vrtPath, const Frame& f, const std::string& kernel, std::uint32_t j0,
                    std::uint32_t j1, int threads, float* out, const ProgressFn& progress) {
  const std::size_t n = std::size_t(f.postsX) * (j1 - j0);
  Status st = kernel == "weighted"   ? weightedRows(vrtPath, f, j0, j1, threads, out, progress)
              : kernel == "bilinear" ? bilinearRows(vrtPath, f, j0, j1, threads, out, progress)
                                     : gdalRows(vrtPath, f, kernel, j0, j1, threads, out, progress);
  if (!st) return st;
  for (std::size_t k = 0; k < n; ++k) {
    if (!(out[k] >= kMinValid && out[k] <= kMaxValid)) out[k] = NAN;
  }
  return {};
}

BandCost bandCost(const std::string& vrtPath, const Frame& f, const KernelChoice& kernel) {
  BandCost c;
  const double w = f.postsX;
  c.perRow = 4 * w;  // the band's posts
  MosaicReader m;
  FrameScale scale;
  if (m.open(vrtPath, f).empty() && frameScale(f, *m.toSource, m.geo, scale)) {
    // The source image: its rows per grid row, each the footprint's width,
    // plus its pad rows (at most kernel reach + 16, or the weighted radius).
    const double srcW = scale.spanX + 64;
    c.perRow += 4 * srcW * (scale.spanY + 1) / f.postsZ;
    double pad = 64;
    if (kernel.resample == "weighted") {
      if (auto r = weightedRadius(vrtPath, f); r && r.value()[1] > 0) pad = 2 * r.value()[0] / r.value()[1] + 18;
    }
    c.fixed += 4 * srcW * 2 * pad;
  }
  if (kernel.resample != "weighted" && kernel.resample != "bilinear") c.perRow += 4 * w;  // GDALWarp's chunk buffers
  if (kernel.fit == "triangles") {
    // b, z, next (doubles) and the included squares, over the band and its halo.
    c.perRow += 25 * w;
    c.fixed += (4 + 25) * w * 2 * kFitHalo;
  }
  // Writing: one row more each side, the class bytes, a block per worker.
  c.perRow += 1 * w;
  c.fixed += 8 * w + double(jobs::threadCount(0)) * sizeof(grid::BlockData) * 2;
  return c;
}

namespace {

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

}  // namespace detail
}  // namespace sandtable::convert
