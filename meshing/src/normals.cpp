// Per-vertex normals from the post normals (normals.h).
#include "sandtable/meshing/normals.h"

#include <algorithm>
#include <cmath>

#include "sandtable/formats/terrain_rule.h"

namespace sandtable::meshing {

namespace {

/// Rounds both snorm16 halves of an octahedral normal to kNormalBits
/// significant bits (the low 16 - kNormalBits bits zero), so the module
/// encoder drops them.
std::uint32_t roundNormal(std::uint32_t n) {
  constexpr int drop = 16 - kNormalBits;
  const auto r = [](std::uint32_t c) {
    const long v = std::lround(double(std::int16_t(std::uint16_t(c))) / (1 << drop));
    return std::uint32_t(std::uint16_t(std::int16_t(std::clamp(v * (1 << drop), -32768L, 32767L - ((1L << drop) - 1)))));
  };
  return r(n & 0xffffu) | r(n >> 16) << 16;
}

}  // namespace

std::array<double, 3> gridNormal(const grid::HeightField& g, double x, double z) {
  // The renderer's sampleGrid rule (runtime/render/src/module_draw.cpp).
  const terrain::SquarePoint q = terrain::squareAt(x / g.spacing(), z / g.spacing(), g.postsX(), g.postsZ());
  const std::uint32_t i = q.i, j = q.j;
  const std::array<double, 4> w = terrain::cornerWeights(q.fx, q.fz);
  const std::uint32_t pi[4] = {i, i + 1, i, i + 1}, pj[4] = {j, j, j + 1, j + 1};
  std::array<double, 3> n{0, 0, 0};
  for (int k = 0; k < 4; ++k) {
    if (w[std::size_t(k)] == 0.0) continue;
    const auto p = g.normal(std::min<std::uint32_t>(pi[k], g.postsX() - 1), std::min<std::uint32_t>(pj[k], g.postsZ() - 1));
    for (int c = 0; c < 3; ++c) n[std::size_t(c)] += w[std::size_t(k)] * p[std::size_t(c)];
  }
  return n;
}

std::uint32_t packNormal(const std::array<double, 3>& n) {
  return roundNormal(module::octEncode(float(n[0]), float(n[1]), float(n[2])));
}

void fillNormals(const grid::HeightField& g, std::uint32_t squares, module::Module& m) {
  const double x0 = double(m.kx) * squares * g.spacing(), z0 = double(m.kz) * squares * g.spacing();
  for (module::Level& l : m.levels) {
    l.normals.resize(l.vertices.size());
    for (std::size_t k = 0; k < l.vertices.size(); ++k) {
      l.normals[k] = packNormal(gridNormal(g, x0 + l.vertices[k].x, z0 + l.vertices[k].z));
    }
  }
}

}  // namespace sandtable::meshing
