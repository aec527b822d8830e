// Resampling the source mosaic onto the target grid: the kernel dispatch,
// the stage's memory cost, and the least-squares fit of the terrain
// triangles to the source surface. The kernels and the mosaic live in
// elevation_{mosaic,lattice,weighted,bilinear,warp}.cpp (elevation_resample.h).
#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>

#include "elevation_resample.h"
#include "sandtable/base/jobs.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::convert {
namespace detail {

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

}  // namespace detail
}  // namespace sandtable::convert
