// Level lattices from the grid (lattice.h).
#include "sandtable/meshing/lattice.h"

#include <algorithm>
#include <cmath>

#include "sandtable/formats/terrain_rule.h"

namespace sandtable::meshing {

std::uint32_t moduleSquares(double moduleSize, double spacing, int levels) {
  const double unit = double(1u << (levels - 1));
  const double n = std::round(moduleSize / spacing / unit) * unit;
  return std::uint32_t(std::max(unit, n));
}

std::vector<std::uint32_t> latticePosts(std::uint32_t first, std::uint32_t last, std::uint32_t step) {
  return terrain::latticePosts(first, last, step);
}

ModuleWindow moduleWindow(const grid::HeightField& g, std::uint32_t squares, int levels, std::uint32_t kx,
                          std::uint32_t kz) {
  ModuleWindow m;
  m.i0 = kx * squares;
  m.j0 = kz * squares;
  m.i1 = terrain::moduleLastPost(m.i0, squares, g.postsX() - 1);
  m.j1 = terrain::moduleLastPost(m.j0, squares, g.postsZ() - 1);
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

double surfaceAt(const LevelLattice& lat, const ModuleWindow& m, int l, std::uint32_t i, std::uint32_t j) {
  const std::uint32_t step = 1u << l;
  const terrain::LatticeSpan x = terrain::latticeSpan(i, m.i0, m.i1, step);
  const terrain::LatticeSpan z = terrain::latticeSpan(j, m.j0, m.j1, step);
  const double fx = x.fraction(i), fz = z.fraction(j);
  // Lattice column and row of the span's first post.
  const std::size_t a = (x.a - m.i0) / step, b = (z.a - m.j0) / step;
  const std::size_t w = m.cols[std::size_t(l)].size();
  const double nw = lat.heights[b * w + a], ne = lat.heights[b * w + a + 1];
  const double sw = lat.heights[(b + 1) * w + a], se = lat.heights[(b + 1) * w + a + 1];
  return terrain::planeHeight(fx, fz, nw, ne, sw, se);
}

}  // namespace sandtable::meshing
