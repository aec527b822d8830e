#include "sandtable/testing/fixtures.h"

#include <algorithm>
#include <array>
#include <memory>
#include <utility>

#include "sandtable/formats/grid.h"

namespace sandtable::fixtures {

Status writeGrid(const std::string& path, std::uint32_t px, std::uint32_t pz, double spacing,
                 const PostElevation& f, double originE, double originN) {
  auto gw = grid::GridWriter::create(path, grid::makeHeader(px, pz, spacing, originE, originN));
  if (!gw) return Status(gw.problems());
  const grid::Header& gh = gw.value()->header();
  auto b = std::make_unique<grid::BlockData>();
  for (std::uint32_t bz = 0; bz < gh.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < gh.blocksX; ++bx) {
      for (std::uint32_t k = 0; k < grid::kPostsPerBlock; ++k) {
        // Posts past the grid's edge (block padding) repeat the edge.
        const std::uint32_t i = std::min(px - 1, bx * grid::kBlockPosts + k % grid::kBlockPosts);
        const std::uint32_t j = std::min(pz - 1, bz * grid::kBlockPosts + k / grid::kBlockPosts);
        b->elevation[k] = f(i, j);
        b->normalY[k] = grid::toSnorm(1.0f);
      }
      if (Status st = gw.value()->writeBlock(bx, bz, *b); !st) return st;
    }
  }
  return gw.value()->finish();
}

void addLatticeSkin(module::Level& lv, std::uint32_t n) {
  const auto post = [&](std::uint32_t a, std::uint32_t b) { return b * (n + 1) + a; };
  for (std::uint32_t sz = 0; sz < n; ++sz) {
    for (std::uint32_t sx = 0; sx < n; ++sx) {
      const std::uint32_t nw = post(sx, sz), ne = post(sx + 1, sz), sw = post(sx, sz + 1),
                          se = post(sx + 1, sz + 1);
      for (const auto& [half, tri] : {std::pair{module::Half::upper, std::array{nw, sw, ne}},
                                      std::pair{module::Half::lower, std::array{ne, sw, se}}}) {
        module::Group g;
        g.square = sz * n + sx;
        g.half = half;
        g.firstIndex = std::uint32_t(lv.indices.size());
        g.indexCount = 3;
        lv.indices.insert(lv.indices.end(), tri.begin(), tri.end());
        lv.groups.push_back(g);
      }
    }
  }
  lv.maxHeight.assign(std::size_t(n) * n, 0);
  for (std::uint32_t q = 0; q < n * n; ++q) {
    const std::uint32_t a = q % n, b = q / n;
    lv.maxHeight[q] = std::max({lv.vertices[post(a, b)].y, lv.vertices[post(a + 1, b)].y,
                                lv.vertices[post(a, b + 1)].y, lv.vertices[post(a + 1, b + 1)].y});
  }
}

}  // namespace sandtable::fixtures
