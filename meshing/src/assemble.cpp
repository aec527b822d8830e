// Module assembly from a grid window (assemble.h).
#include "sandtable/meshing/assemble.h"

#include <array>

#include "sandtable/formats/terrain_rule.h"
#include "sandtable/meshing/heights.h"
#include "sandtable/meshing/skirts.h"

namespace sandtable::meshing {

void plainSkin(const LevelLattice& lat, std::uint16_t material, module::Level& out) {
  const auto nx = std::uint32_t(lat.xs.size() - 1), nz = std::uint32_t(lat.zs.size() - 1);
  out.spacing = lat.spacing;
  out.squaresX = nx;
  out.squaresZ = nz;
  out.vertices.clear();
  out.indices.clear();
  out.groups.clear();
  for (std::uint32_t b = 0; b <= nz; ++b) {
    for (std::uint32_t a = 0; a <= nx; ++a) {
      out.vertices.push_back({float(lat.xs[a]), lat.heights[std::size_t(b) * (nx + 1) + a], float(lat.zs[b]), 0, 0});
    }
  }
  auto post = [&](std::uint32_t a, std::uint32_t b) { return b * (nx + 1) + a; };
  for (std::uint32_t sz = 0; sz < nz; ++sz) {
    for (std::uint32_t sx = 0; sx < nx; ++sx) {
      const std::array<std::uint32_t, 4> corners = {post(sx, sz), post(sx + 1, sz), post(sx, sz + 1),
                                                    post(sx + 1, sz + 1)};
      for (const module::Half half : {module::Half::upper, module::Half::lower}) {
        const auto [a, b, c] = terrain::halfCorners(half, corners);
        module::Group g;
        g.square = sz * nx + sx;
        g.half = half;
        g.priority = module::kPrioritySkin;
        g.material = material;
        g.firstIndex = std::uint32_t(out.indices.size());
        g.indexCount = 3;
        out.indices.insert(out.indices.end(), {a, b, c});
        out.groups.push_back(g);
      }
    }
  }
}

std::uint64_t finishLevel(const LevelLattice& lat, std::uint32_t node, float depth, std::uint16_t skirtMaterial,
                          module::Level& level, std::span<const std::uint32_t> lineVertices) {
  level.spacing = lat.spacing;
  level.squaresX = std::uint32_t(lat.xs.size() - 1);
  level.squaresZ = std::uint32_t(lat.zs.size() - 1);
  level.skirtDepth = depth;
  const std::uint64_t skirts = addSkirts(level, lat, node, depth, skirtMaterial, lineVertices);
  computeMaxHeights(level);
  return skirts;
}

module::Module assembleModule(const grid::HeightField& g, std::uint32_t squares, int levels, std::uint32_t kx,
                              std::uint32_t kz, std::uint16_t skirtMaterial, const SkinFn& skin) {
  const ModuleWindow w = moduleWindow(g, squares, levels, kx, kz);
  std::vector<LevelLattice> lats;
  for (int l = 0; l < levels; ++l) lats.push_back(levelLattice(g, w, l));
  const std::uint32_t node = nodeSquares(squares, levels);
  const std::vector<float> depths = skirtDepths(lats, w, node);
  module::Module out;
  out.kx = kx;
  out.kz = kz;
  out.levels.resize(std::size_t(levels));
  for (int l = 0; l < levels; ++l) {
    const LevelLattice& lat = lats[std::size_t(l)];
    module::Level& level = out.levels[std::size_t(l)];
    if (!skin(l, lat, level)) break;
    finishLevel(lat, node, depths[std::size_t(l)], skirtMaterial, level);
  }
  return out;
}

}  // namespace sandtable::meshing
