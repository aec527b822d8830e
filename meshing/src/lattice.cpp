// Level lattices from the grid (lattice.h).
#include "sandtable/meshing/lattice.h"

#include <algorithm>
#include <cmath>

namespace sandtable::meshing {

std::uint32_t moduleSquares(double moduleSize, double spacing, int levels) {
  const double unit = double(1u << (levels - 1));
  const double n = std::round(moduleSize / spacing / unit) * unit;
  return std::uint32_t(std::max(unit, n));
}

std::vector<std::uint32_t> latticePosts(std::uint32_t first, std::uint32_t last, std::uint32_t step) {
  std::vector<std::uint32_t> posts;
  for (std::uint32_t p = first; p < last; p += step) posts.push_back(p);
  posts.push_back(last);
  return posts;
}

ModuleWindow moduleWindow(const grid::HeightField& g, std::uint32_t squares, int levels, std::uint32_t kx,
                          std::uint32_t kz) {
  ModuleWindow m;
  m.i0 = kx * squares;
  m.j0 = kz * squares;
  m.i1 = std::min(m.i0 + squares, g.postsX() - 1);
  m.j1 = std::min(m.j0 + squares, g.postsZ() - 1);
  for (int l = 0; l < levels; ++l) {
    m.cols.push_back(latticePosts(m.i0, m.i1, 1u << l));
    m.rows.push_back(latticePosts(m.j0, m.j1, 1u << l));
  }
  return m;
}

LevelLattice levelLattice(const grid::HeightField& g, const ModuleWindow& m, int l, NonFinite nonFinite) {
  const double s = g.spacing();
  LevelLattice lat;
  lat.moduleX = double(m.i0) * s;
  lat.moduleZ = double(m.j0) * s;
  lat.spacing = s * double(1u << l);
  lat.level = l;
  const auto& cols = m.cols[std::size_t(l)];
  const auto& rows = m.rows[std::size_t(l)];
  for (std::uint32_t i : cols) lat.xs.push_back(double(i - m.i0) * s);
  for (std::uint32_t j : rows) lat.zs.push_back(double(j - m.j0) * s);
  lat.heights.reserve(lat.xs.size() * lat.zs.size());
  for (std::uint32_t j : rows) {
    for (std::uint32_t i : cols) {
      const float e = g.elevation(i, j);
      lat.heights.push_back(nonFinite == NonFinite::zero && !std::isfinite(e) ? 0.0f : e);
    }
  }
  return lat;
}

namespace {

/// Index of the lattice interval holding post p (posts sorted ascending).
std::size_t intervalOf(const std::vector<std::uint32_t>& posts, std::uint32_t p) {
  const auto it = std::upper_bound(posts.begin(), posts.end(), p);
  const std::size_t k = std::size_t(it - posts.begin());
  return std::min(k == 0 ? 0 : k - 1, posts.size() - 2);
}

}  // namespace

double surfaceAt(const LevelLattice& lat, const ModuleWindow& m, int l, std::uint32_t i, std::uint32_t j) {
  const auto& cols = m.cols[std::size_t(l)];
  const auto& rows = m.rows[std::size_t(l)];
  const std::size_t a = intervalOf(cols, i), b = intervalOf(rows, j);
  const double fx = double(i - cols[a]) / double(cols[a + 1] - cols[a]);
  const double fz = double(j - rows[b]) / double(rows[b + 1] - rows[b]);
  const std::size_t w = cols.size();
  const double nw = lat.heights[b * w + a], ne = lat.heights[b * w + a + 1];
  const double sw = lat.heights[(b + 1) * w + a], se = lat.heights[(b + 1) * w + a + 1];
  if (fx + fz <= 1.0) return nw + fx * (ne - nw) + fz * (sw - nw);
  return se + (1.0 - fx) * (sw - se) + (1.0 - fz) * (ne - se);
}

}  // namespace sandtable::meshing
