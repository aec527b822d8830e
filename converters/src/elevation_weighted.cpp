// The weighted resampler: a distance-weighted least-squares plane through
// the source posts within a radius of each target post.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <string>
#include <vector>

#include <immintrin.h>

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

/// The source posts target post (px, py) of `cell` takes, in the order they
/// are summed (row by row, west to east): those inside its search box and,
/// on each row, inside the radius ellipse (see mapPost; the bounds are
/// widened a little so rounding never drops a post that the exact d2 < r2
/// test of the sum would take, which keeps the result identical to testing
/// the whole box), voids included (the sums skip them). Writes each post's
/// column, row and value every `stride` elements of x, y and z (one lane of
/// a batch); returns how many, at most tapBound(cell).
[[gnu::always_inline]] inline int gatherTaps(const Window& win, const PostMap& cell, double px, double py,
                                             double radius, std::int32_t* xs, std::int32_t* ys, float* z,
                                             std::size_t stride) {
  const int xa = std::max(win.x0, static_cast<int>(std::ceil(px - cell.hx)));
  const int xb = std::min(win.x0 + win.w - 1, static_cast<int>(std::floor(px + cell.hx)));
  // Rows beyond qymax have disc < 0 below (mapPost): not even visited.
  const int ya = std::max({win.y0, static_cast<int>(std::ceil(py - cell.hy)),
                           static_cast<int>(std::ceil(py - cell.qymax))});
  const int yb = std::min({win.y0 + win.h - 1, static_cast<int>(std::floor(py + cell.hy)),
                           static_cast<int>(std::floor(py + cell.qymax))});
  const double disc0 = cell.qa * (radius * radius) * (1 + 1e-9);
  std::size_t k = 0;
  for (std::int32_t y = ya; y <= yb; ++y) {
    const double ry = y - py;
    const double disc = disc0 - cell.qdet2 * ry * ry;
    if (disc < 0) continue;
    const double half = std::sqrt(disc) * cell.qinvA + 1e-6;
    const double cx = px - cell.qb * ry * cell.qinvA;
    const int x0 = std::max(xa, static_cast<int>(std::ceil(cx - half)));
    const int x1 = std::min(xb, static_cast<int>(std::floor(cx + half)));
    const float* row = win.row(y);
    for (std::int32_t x = x0; x <= x1; ++x, k += stride) {
      xs[k] = x;
      ys[k] = y;
      z[k] = row[x];
    }
  }
  return static_cast<int>(k / stride);
}

/// The most posts gatherTaps can take for a post of `cell`: its search box.
int tapBound(const PostMap& cell) {
  return (static_cast<int>(2 * cell.hx) + 2) * (static_cast<int>(2 * cell.hy) + 2);
}

/// A batch of target posts' taps, lane by lane: source column x, row y and
/// value z, each `cap` rows of W (tap k of lane l at [k * W + l]). Offsets
/// from the target post (x - px, y - py) are taken in the sums.
struct Taps {
  std::int32_t* x;
  std::int32_t* y;
  float* z;
  int count[8];            ///< taps per lane
  double px[8], py[8];     ///< each lane's target post, in source posts
};

/// The estimate of each lane of a batch from its taps: the plane through
/// every tap with d2 < r2 that is not a void, summed in order. One function
/// per instruction set (WeightedVariant).
using SumFn = void (*)(const Taps& t, const PostMap& cell, double radius, double* estimate);

/// The one-post definition, PlaneSums::add tap by tap: the reference the
/// vector variants must match bit for bit.
void sumScalar(const Taps& t, const PostMap& cell, double radius, double* estimate) {
  const double r2 = radius * radius, invR2 = 1.0 / r2;
  PlaneSums s;
  for (int k = 0; k < t.count[0]; ++k) {
    const double dx = t.x[k] - t.px[0], dy = t.y[k] - t.py[0];
    const double e = cell.m[0][0] * dx + cell.m[0][1] * dy;
    const double n = cell.m[1][0] * dx + cell.m[1][1] * dy;
    const double d2 = e * e + n * n;
    if (d2 < r2 && !std::isnan(t.z[k])) s.add(e, n, t.z[k], 1.0 - d2 * invR2);
  }
  estimate[0] = s.estimate();
}

/// sumScalar in W lanes at once, one target post per lane. Each lane does
/// exactly the scalar operations in the same order (no FMA: this file is
/// compiled with -ffp-contract=off), and adds +0.0 where it takes no tap,
/// which leaves a sum unchanged (a sum from +0.0 is never -0.0), so every
/// lane's sums are the scalar doubles. Inlined into each instruction set's
/// wrapper below (cellAvx2), which decides the vector instructions.
template <int W>
struct Lanes {
  typedef double type __attribute__((vector_size(W * sizeof(double))));
  typedef std::int64_t mask __attribute__((vector_size(W * sizeof(double))));
  typedef std::int32_t ints __attribute__((vector_size(W * sizeof(std::int32_t))));
  typedef float floats __attribute__((vector_size(W * sizeof(float))));
};

template <int W>
[[gnu::always_inline]] inline void sumLanes(const Taps& t, const PostMap& cell, double radius, double* estimate) {
  using V = typename Lanes<W>::type;
  using M = typename Lanes<W>::mask;
  using I = typename Lanes<W>::ints;
  using F = typename Lanes<W>::floats;
  const double r2 = radius * radius, invR2 = 1.0 / r2;
  const V zero = {};
  V count = zero, px, py;
  int kEnd = 0;
  for (int l = 0; l < W; ++l) {
    count[l] = t.count[l];
    px[l] = t.px[l], py[l] = t.py[l];
    kEnd = std::max(kEnd, t.count[l]);
  }
  const V vr2 = zero + r2, vinv = zero + invR2, one = zero + 1.0;
  const V m00 = zero + cell.m[0][0], m01 = zero + cell.m[0][1], m10 = zero + cell.m[1][0], m11 = zero + cell.m[1][1];
  V w = zero, wx = zero, wy = zero, wxx = zero, wxy = zero, wyy = zero, wz = zero, wxz = zero, wyz = zero;
  V zMin = zero + INFINITY, zMax = zero - INFINITY;
  for (int k = 0; k < kEnd; ++k) {
    I x, y;
    F zf;
    std::memcpy(&x, t.x + std::size_t(k) * W, sizeof(I));
    std::memcpy(&y, t.y + std::size_t(k) * W, sizeof(I));
    std::memcpy(&zf, t.z + std::size_t(k) * W, sizeof(F));
    const V dx = __builtin_convertvector(x, V) - px, dy = __builtin_convertvector(y, V) - py;
    const V z = __builtin_convertvector(zf, V);
    const V e = m00 * dx + m01 * dy;
    const V n = m10 * dx + m11 * dy;
    const V d2 = e * e + n * n;
    const M take = (d2 < vr2) & (zero + k < count) & (z == z);  // z == z: not a void
    const V wt = one - d2 * vinv;
    const V we = wt * e, wn = wt * n;
    w += V(M(wt) & take);
    wx += V(M(we) & take);
    wy += V(M(wn) & take);
    wxx += V(M(we * e) & take);
    wxy += V(M(we * n) & take);
    wyy += V(M(wn * n) & take);
    wz += V(M(wt * z) & take);
    wxz += V(M(we * z) & take);
    wyz += V(M(wn * z) & take);
    const M lower = take & (z < zMin), higher = take & (zMax < z);  // std::min(zMin, z), std::max(zMax, z)
    zMin = V((M(z) & lower) | (M(zMin) & ~lower));
    zMax = V((M(z) & higher) | (M(zMax) & ~higher));
  }
  for (int l = 0; l < W; ++l) {
    estimate[l] = PlaneSums{w[l], wx[l], wy[l], wxx[l], wxy[l], wyy[l], wz[l], wxz[l], wyz[l], zMin[l], zMax[l]}.estimate();
  }
}

// ---- AVX-512: GCC 12 turns generic 8-lane vectors' compares into scalar
// code, so this width is written with intrinsics. Every lane does the
// scalar code's operations in its order (as sumLanes).

// static_cast<int>(std::ceil(v)) and (std::floor(v)) per lane. Here and
// below the maskz forms with a full mask: GCC 12 warns that the plain
// forms' undefined operand is uninitialised (-Wmaybe-uninitialized).
[[gnu::target("avx512f")]] inline __m256i ceilToInt(__m512d v) {
  return _mm512_maskz_cvttpd_epi32(0xff, _mm512_maskz_roundscale_pd(0xff, v, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC));
}
[[gnu::target("avx512f")]] inline __m256i floorToInt(__m512d v) {
  return _mm512_maskz_cvttpd_epi32(0xff, _mm512_maskz_roundscale_pd(0xff, v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
}

/// Row y's posts lo[l]..hi[l] appended to lane l's taps, for each lane
/// whose bit is set in `ok`.
template <std::size_t W>
[[gnu::always_inline]] inline void appendRow(const Window& win, std::int32_t y, unsigned ok, const int* lo,
                                             const int* hi, Taps& t) {
  const float* row = win.row(y);
  for (std::size_t l = 0; l < W; ++l) {
    if (!(ok >> l & 1u)) continue;
    std::size_t k = std::size_t(t.count[l]) * W + l;
    for (std::int32_t x = lo[l]; x <= hi[l]; ++x, k += W) {
      t.x[k] = x;
      t.y[k] = y;
      t.z[k] = row[x];
    }
    t.count[l] = static_cast<int>(k / W);
  }
}

/// gatherTaps for 8 posts at once: the box and each row's ellipse bounds
/// in vectors (one sqrt for 8 posts), the taps copied lane by lane.
[[gnu::target("avx512f")]] void gatherAvx512(const Window& win, const PostMap& cell, double radius, Taps& t) {
  const __m512d vpx = _mm512_loadu_pd(t.px), vpy = _mm512_loadu_pd(t.py);
  const __m512d hx = _mm512_set1_pd(cell.hx), hy = _mm512_set1_pd(cell.hy), qymax = _mm512_set1_pd(cell.qymax);
  const __m256i xa = _mm256_max_epi32(_mm256_set1_epi32(win.x0), ceilToInt(_mm512_sub_pd(vpx, hx)));
  const __m256i xb = _mm256_min_epi32(_mm256_set1_epi32(win.x0 + win.w - 1), floorToInt(_mm512_add_pd(vpx, hx)));
  const __m256i ya = _mm256_max_epi32(_mm256_set1_epi32(win.y0), _mm256_max_epi32(ceilToInt(_mm512_sub_pd(vpy, hy)),
                                                                                   ceilToInt(_mm512_sub_pd(vpy, qymax))));
  const __m256i yb = _mm256_min_epi32(_mm256_set1_epi32(win.y0 + win.h - 1),
                                      _mm256_min_epi32(floorToInt(_mm512_add_pd(vpy, hy)),
                                                       floorToInt(_mm512_add_pd(vpy, qymax))));
  alignas(32) int yaL[8], ybL[8], lo[8], hi[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(yaL), ya);
  _mm256_store_si256(reinterpret_cast<__m256i*>(ybL), yb);
  const int yFirst = *std::min_element(yaL, yaL + 8), yLast = *std::max_element(ybL, ybL + 8);
  const __m512d yaD = _mm512_maskz_cvtepi32_pd(0xff, ya), ybD = _mm512_maskz_cvtepi32_pd(0xff, yb);
  const __m512d disc0 = _mm512_set1_pd(cell.qa * (radius * radius) * (1 + 1e-9)), qdet2 = _mm512_set1_pd(cell.qdet2);
  const __m512d qinvA = _mm512_set1_pd(cell.qinvA), qb = _mm512_set1_pd(cell.qb), slack = _mm512_set1_pd(1e-6);
  for (int l = 0; l < 8; ++l) t.count[l] = 0;
  for (int y = yFirst; y <= yLast; ++y) {
    const __m512d vy = _mm512_set1_pd(y), ry = _mm512_sub_pd(vy, vpy);
    const __m512d disc = _mm512_sub_pd(disc0, _mm512_mul_pd(_mm512_mul_pd(qdet2, ry), ry));
    const unsigned ok = _mm512_cmp_pd_mask(vy, yaD, _CMP_GE_OQ) & _mm512_cmp_pd_mask(vy, ybD, _CMP_LE_OQ) &
                        _mm512_cmp_pd_mask(disc, _mm512_setzero_pd(), _CMP_NLT_UQ);  // !(disc < 0)
    if (!ok) continue;
    const __m512d half = _mm512_add_pd(_mm512_mul_pd(_mm512_maskz_sqrt_pd(0xff, disc), qinvA), slack);
    const __m512d cx = _mm512_sub_pd(vpx, _mm512_mul_pd(_mm512_mul_pd(qb, ry), qinvA));
    _mm256_store_si256(reinterpret_cast<__m256i*>(lo), _mm256_max_epi32(xa, ceilToInt(_mm512_sub_pd(cx, half))));
    _mm256_store_si256(reinterpret_cast<__m256i*>(hi), _mm256_min_epi32(xb, floorToInt(_mm512_add_pd(cx, half))));
    appendRow<8>(win, y, ok, lo, hi, t);
  }
}

/// sumLanes<8> with the plane's estimate (PlaneSums::estimate) in vectors
/// too. Masked adds leave a lane's sums as they are where it takes no tap,
/// as the scalar code does.
[[gnu::target("avx512f")]] void sumAvx512(const Taps& t, const PostMap& cell, double radius, double* estimate) {
  const double r2 = radius * radius, invR2 = 1.0 / r2;
  int kEnd = 0;
  for (int l = 0; l < 8; ++l) kEnd = std::max(kEnd, t.count[l]);
  const __m512d count = _mm512_maskz_cvtepi32_pd(0xff, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t.count)));
  const __m512d vr2 = _mm512_set1_pd(r2), vinv = _mm512_set1_pd(invR2), one = _mm512_set1_pd(1.0);
  const __m512d m00 = _mm512_set1_pd(cell.m[0][0]), m01 = _mm512_set1_pd(cell.m[0][1]);
  const __m512d m10 = _mm512_set1_pd(cell.m[1][0]), m11 = _mm512_set1_pd(cell.m[1][1]);
  const __m512d zero = _mm512_setzero_pd(), px = _mm512_loadu_pd(t.px), py = _mm512_loadu_pd(t.py);
  __m512d w = zero, wx = zero, wy = zero, wxx = zero, wxy = zero, wyy = zero, wz = zero, wxz = zero, wyz = zero;
  __m512d zMin = _mm512_set1_pd(INFINITY), zMax = _mm512_set1_pd(-INFINITY);
  for (int k = 0; k < kEnd; ++k) {
    const std::size_t o = std::size_t(k) * 8;
    const __m256i xi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t.x + o));
    const __m256i yi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t.y + o));
    const __m512d dx = _mm512_sub_pd(_mm512_maskz_cvtepi32_pd(0xff, xi), px);  // x - px
    const __m512d dy = _mm512_sub_pd(_mm512_maskz_cvtepi32_pd(0xff, yi), py);
    const __m512d z = _mm512_maskz_cvtps_pd(0xff, _mm256_loadu_ps(t.z + o));
    const __m512d e = _mm512_add_pd(_mm512_mul_pd(m00, dx), _mm512_mul_pd(m01, dy));
    const __m512d n = _mm512_add_pd(_mm512_mul_pd(m10, dx), _mm512_mul_pd(m11, dy));
    const __m512d d2 = _mm512_add_pd(_mm512_mul_pd(e, e), _mm512_mul_pd(n, n));
    const __mmask8 take = _mm512_cmp_pd_mask(d2, vr2, _CMP_LT_OQ) &
                          _mm512_cmp_pd_mask(_mm512_set1_pd(k), count, _CMP_LT_OQ) &
                          _mm512_cmp_pd_mask(z, z, _CMP_ORD_Q);  // not a void
    const __m512d wt = _mm512_sub_pd(one, _mm512_mul_pd(d2, vinv));
    const __m512d we = _mm512_mul_pd(wt, e), wn = _mm512_mul_pd(wt, n);
    w = _mm512_mask_add_pd(w, take, w, wt);
    wx = _mm512_mask_add_pd(wx, take, wx, we);
    wy = _mm512_mask_add_pd(wy, take, wy, wn);
    wxx = _mm512_mask_add_pd(wxx, take, wxx, _mm512_mul_pd(we, e));
    wxy = _mm512_mask_add_pd(wxy, take, wxy, _mm512_mul_pd(we, n));
    wyy = _mm512_mask_add_pd(wyy, take, wyy, _mm512_mul_pd(wn, n));
    wz = _mm512_mask_add_pd(wz, take, wz, _mm512_mul_pd(wt, z));
    wxz = _mm512_mask_add_pd(wxz, take, wxz, _mm512_mul_pd(we, z));
    wyz = _mm512_mask_add_pd(wyz, take, wyz, _mm512_mul_pd(wn, z));
    zMin = _mm512_mask_min_pd(zMin, take, z, zMin);  // z < zMin ? z : zMin, as std::min(zMin, z)
    zMax = _mm512_mask_max_pd(zMax, take, z, zMax);  // z > zMax ? z : zMax, as std::max(zMax, z)
  }
  // PlaneSums::estimate, lane by lane; each lane then takes the branch the
  // scalar code takes.
  const __m512d mx = _mm512_div_pd(wx, w), my = _mm512_div_pd(wy, w), mz = _mm512_div_pd(wz, w);
  const __m512d wmx = _mm512_mul_pd(w, mx), wmy = _mm512_mul_pd(w, my);
  const __m512d sxx = _mm512_sub_pd(wxx, _mm512_mul_pd(wmx, mx)), sxy = _mm512_sub_pd(wxy, _mm512_mul_pd(wmx, my));
  const __m512d syy = _mm512_sub_pd(wyy, _mm512_mul_pd(wmy, my));
  const __m512d sxz = _mm512_sub_pd(wxz, _mm512_mul_pd(wmx, mz)), syz = _mm512_sub_pd(wyz, _mm512_mul_pd(wmy, mz));
  const __m512d det = _mm512_sub_pd(_mm512_mul_pd(sxx, syy), _mm512_mul_pd(sxy, sxy));
  const __m512d tr = _mm512_add_pd(sxx, syy);
  // std::max(0.0, x): max_pd gives its second operand unless x > 0.
  const __m512d disc = _mm512_sub_pd(_mm512_mul_pd(tr, tr), _mm512_mul_pd(_mm512_set1_pd(4.0), det));
  const __m512d root = _mm512_maskz_sqrt_pd(0xff, _mm512_maskz_max_pd(0xff, disc, zero));
  const __m512d half = _mm512_set1_pd(0.5);
  const __m512d lMin = _mm512_mul_pd(half, _mm512_sub_pd(tr, root)), lMax = _mm512_mul_pd(half, _mm512_add_pd(tr, root));
  const __m512d b = _mm512_div_pd(_mm512_sub_pd(_mm512_mul_pd(sxz, syy), _mm512_mul_pd(syz, sxy)), det);
  const __m512d c = _mm512_div_pd(_mm512_sub_pd(_mm512_mul_pd(syz, sxx), _mm512_mul_pd(sxz, sxy)), det);
  __m512d v = _mm512_sub_pd(_mm512_sub_pd(mz, _mm512_mul_pd(b, mx)), _mm512_mul_pd(c, my));
  v = _mm512_mask_mov_pd(v, _mm512_cmp_pd_mask(v, zMin, _CMP_LT_OQ), zMin);  // std::clamp(v, zMin, zMax)
  v = _mm512_mask_mov_pd(v, _mm512_cmp_pd_mask(zMax, v, _CMP_LT_OQ), zMax);
  const __mmask8 mean = _mm512_cmp_pd_mask(lMax, zero, _CMP_NGT_UQ) |  // !(lMax > 0)
                        _mm512_cmp_pd_mask(lMin, _mm512_mul_pd(_mm512_set1_pd(0.05), lMax), _CMP_LT_OQ);
  v = _mm512_mask_mov_pd(v, mean, mz);
  v = _mm512_mask_mov_pd(v, _mm512_cmp_pd_mask(w, zero, _CMP_LE_OQ), _mm512_set1_pd(NAN));
  _mm512_storeu_pd(estimate, v);
}

/// Every target post of lattice cell (c, r) up to column iLast and row
/// jLast, in batches of W posts, one per lane of Sum; `taps` is the
/// worker's scratch. Inlined into each instruction set's wrapper below, so
/// the gathering is compiled for it too (SSE4.1's roundsd for ceil and floor).
struct CellArgs {
  const Window& win;
  const Lattice& L;
  std::uint32_t c, r;
  const PostMap& cell;
  std::uint32_t iLast, jLast;
  double radius;
  TapScratch& taps;
  float* out;
  std::size_t outStride;
  std::uint32_t rowBase;
};

/// gatherTaps for each of W posts, into its lane.
template <std::size_t W>
[[gnu::always_inline]] inline void gatherLanes(const Window& win, const PostMap& cell, double radius, Taps& t) {
  for (std::size_t l = 0; l < W; ++l) {
    t.count[l] = gatherTaps(win, cell, t.px[l], t.py[l], radius, t.x + l, t.y + l, t.z + l, W);
  }
}

using GatherFn = void (*)(const Window&, const PostMap&, double, Taps&);

/// The estimates of a batch's first `lanes` posts (t.px, t.py); a short
/// batch repeats its last post in the spare lanes.
template <std::size_t W, GatherFn Gather, SumFn Sum>
[[gnu::always_inline]] inline void runBatch(const Window& win, const PostMap& cell, double radius, Taps& t,
                                            std::size_t lanes, double* estimate) {
  for (std::size_t l = lanes; l < W; ++l) t.px[l] = t.px[lanes - 1], t.py[l] = t.py[lanes - 1];
  Gather(win, cell, radius, t);
  Sum(t, cell, radius, estimate);
}

/// Taps on the worker's scratch, room for W posts of `cell`.
template <std::size_t W>
Taps tapsFor(const PostMap& cell, TapScratch& s) {
  const std::size_t cap = std::size_t(tapBound(cell));
  if (s.z.size() < cap * W) s.x.resize(cap * W), s.y.resize(cap * W), s.z.resize(cap * W);
  return Taps{s.x.data(), s.y.data(), s.z.data(), {}, {}, {}};
}

template <std::size_t W, GatherFn Gather, SumFn Sum>
[[gnu::always_inline]] inline void resampleCell(const CellArgs& a) {
  Taps t = tapsFor<W>(a.cell, a.taps);
  double estimate[W];
  float* dst[W] = {};
  std::uint32_t i = a.L.ci[a.c], j = a.L.rj[a.r];
  while (j <= a.jLast) {
    std::size_t lanes = 0;
    for (; lanes < W && j <= a.jLast; ++lanes) {
      positionAt(a.L, a.c, a.r, i, j, t.px[lanes], t.py[lanes]);
      dst[lanes] = a.out + std::size_t(j - a.rowBase) * a.outStride + i;
      if (++i > a.iLast) i = a.L.ci[a.c], ++j;
    }
    runBatch<W, Gather, Sum>(a.win, a.cell, a.radius, t, lanes, estimate);
    for (std::size_t l = 0; l < lanes; ++l) *dst[l] = static_cast<float>(estimate[l]);
  }
}

/// weightedKernelProbe's posts, in batches as resampleCell runs them.
struct ProbeArgs {
  const Window& win;
  const PostMap& cell;
  double radius;
  const double* px;
  const double* py;
  std::size_t n;
  double* out;
};

template <std::size_t W, GatherFn Gather, SumFn Sum>
[[gnu::always_inline]] inline void probePosts(const ProbeArgs& a) {
  TapScratch scratch;
  Taps t = tapsFor<W>(a.cell, scratch);
  for (std::size_t k = 0; k < a.n; k += W) {
    const std::size_t lanes = std::min(W, a.n - k);
    for (std::size_t l = 0; l < lanes; ++l) t.px[l] = a.px[k + l], t.py[l] = a.py[k + l];
    double estimate[W];
    runBatch<W, Gather, Sum>(a.win, a.cell, a.radius, t, lanes, estimate);
    std::copy(estimate, estimate + lanes, a.out + k);
  }
}

void cellScalar(const CellArgs& a) { resampleCell<1, gatherLanes<1>, sumScalar>(a); }
[[gnu::target("avx2")]] void cellAvx2(const CellArgs& a) { resampleCell<4, gatherLanes<4>, sumLanes<4>>(a); }
[[gnu::target("avx512f"), gnu::flatten]] void cellAvx512(const CellArgs& a) { resampleCell<8, gatherAvx512, sumAvx512>(a); }
void probeScalar(const ProbeArgs& a) { probePosts<1, gatherLanes<1>, sumScalar>(a); }
[[gnu::target("avx2")]] void probeAvx2(const ProbeArgs& a) { probePosts<4, gatherLanes<4>, sumLanes<4>>(a); }
[[gnu::target("avx512f"), gnu::flatten]] void probeAvx512(const ProbeArgs& a) { probePosts<8, gatherAvx512, sumAvx512>(a); }

/// The weighted kernel's instruction-set variants, best first; the build
/// takes the first the CPU runs (or the one setWeightedKernelVariant chose).
struct WeightedVariant {
  const char* name;
  void (*cell)(const CellArgs&);
  void (*probe)(const ProbeArgs&);
  bool (*runs)();
};
const WeightedVariant kVariants[] = {
    {"avx512", cellAvx512, probeAvx512, [] { return __builtin_cpu_supports("avx512f") != 0; }},
    {"avx2", cellAvx2, probeAvx2, [] { return __builtin_cpu_supports("avx2") != 0; }},
    {"scalar", cellScalar, probeScalar, [] { return true; }},
};

const WeightedVariant* findVariant(const std::string& name) {
  for (const auto& v : kVariants) {
    if (name == v.name && v.runs()) return &v;
  }
  return nullptr;
}
std::atomic<const WeightedVariant*> gChosen{nullptr};

const WeightedVariant& chosenVariant() {
  if (const WeightedVariant* v = gChosen.load()) return *v;
  for (const auto& v : kVariants) {
    if (v.runs()) return v;
  }
  return kVariants[std::size(kVariants) - 1];
}

std::string resampleStrip(const Frame& f, std::uint32_t jBegin, std::uint32_t jEnd, double radius,
                          GDALRasterBand& band, OGRCoordinateTransformation& ct,
                          const std::array<double, 6>& g, Lattice& L, Window& win, TapScratch& taps,
                          const SourceImage& image, float* out, std::uint32_t rowBase) {
  if (!L.build(f, jBegin, jEnd, ct, g)) return "resample: PROJ failed to transform target posts to the sources";
  PostMap probe{};
  if (!mapPost(L, 0, 0, 0, jBegin, f.spacing, radius, probe)) return "resample: degenerate transform";
  const std::string err = readWindow(band, L, std::max(probe.hx, probe.hy) + 2, win, &image);
  if (!err.empty()) return err;
  const WeightedVariant& v = chosenVariant();
  for (std::uint32_t r = 0; r + 1 < L.rows; ++r) {
    const std::uint32_t jLast = (r + 2 == L.rows) ? L.rj[r + 1] : L.rj[r + 1] - 1;
    for (std::uint32_t c = 0; c + 1 < L.cols; ++c) {
      // The metric and search box are constant over a lattice cell; only
      // the source position moves, linearly.
      PostMap cell{};
      if (!mapPost(L, c, r, L.ci[c], L.rj[r], f.spacing, radius, cell)) continue;
      const std::uint32_t iLast = (c + 2 == L.cols) ? L.ci[c + 1] : L.ci[c + 1] - 1;
      v.cell({win, L, c, r, cell, iLast, jLast, radius, taps, out, f.postsX, rowBase});
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
    return resampleStrip(f, a, b, radius, m.band(), *m.toSource, m.geo, st.L, st.win, st.taps, image, out, j0);
  });
}

}  // namespace detail

std::vector<std::string> weightedKernelVariants() {
  std::vector<std::string> out;
  for (const auto& v : detail::kVariants) {
    if (v.runs()) out.emplace_back(v.name);
  }
  return out;
}

bool setWeightedKernelVariant(const std::string& variant) {
  if (variant.empty()) {
    detail::gChosen.store(nullptr);
    return true;
  }
  const detail::WeightedVariant* v = detail::findVariant(variant);
  if (v) detail::gChosen.store(v);
  return v != nullptr;
}

std::vector<double> weightedKernelProbe(const std::string& variant, const WeightedProbe& probe,
                                        const std::vector<double>& px, const std::vector<double>& py) {
  const detail::WeightedVariant* v = detail::findVariant(variant);
  detail::PostMap cell{};
  if (!v || px.size() != py.size() || !probe.image || probe.w <= 0 || probe.h <= 0 ||
      !detail::postMetric(probe.aXi, probe.aYi, probe.aXj, probe.aYj, probe.spacing, probe.radius, cell)) {
    return {};
  }
  detail::Window win;
  win.w = probe.w, win.h = probe.h;
  win.base = probe.image;
  win.stride = std::size_t(probe.w);
  std::vector<double> out(px.size());
  v->probe({win, cell, probe.radius, px.data(), py.data(), px.size(), out.data()});
  return out;
}

}  // namespace sandtable::convert
