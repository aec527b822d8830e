// From target posts to source positions (a sparse lattice of exact PROJ
// transforms) and the windows of source posts they read.
#include <algorithm>
#include <cmath>

#include "elevation_resample.h"

namespace sandtable::convert::detail {

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
  return postMetric(aXi, aYi, aXj, aYj, spacing, radius, out);
}

bool postMetric(double aXi, double aYi, double aXj, double aYj, double spacing, double radius, PostMap& out) {
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
  // the weighted kernel's gathering); a little wider, so rounding keeps
  // every row with one.
  out.qymax = std::sqrt(out.qa * radius * radius * (1 + 1e-9) / out.qdet2) * (1 + 1e-9) + 1e-6;
  return true;
}

namespace {

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

}  // namespace

std::string readWindow(GDALRasterBand& band, const Lattice& L, double pad, Window& win,
                       const SourceImage* image) {
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

}  // namespace sandtable::convert::detail
