// Skirts along the quadtree node edges (skirts.h).
#include "sandtable/meshing/skirts.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <utility>

#include "sandtable/formats/terrain_rule.h"

namespace sandtable::meshing {

using module::Group;
using module::Half;
using module::Level;
using module::Vertex;

std::vector<float> skirtDepths(const std::vector<LevelLattice>& lats, const ModuleWindow& m, std::uint32_t node) {
  const int levels = int(lats.size());
  const std::uint32_t w = m.i1 - m.i0 + 1, h = m.j1 - m.j0 + 1;
  std::vector<double> lowest(std::size_t(w) * h, std::numeric_limits<double>::infinity());
  std::vector<std::vector<double>> surf(std::size_t(levels), std::vector<double>(lowest.size()));
  // surfaceAt(lat, m, l, i, j), with each column's and row's span and
  // fraction worked out once instead of at every post.
  struct Axis {
    std::size_t cell;  ///< lattice column (row) of the span's first post
    double f;          ///< fraction along the span
  };
  auto axis = [](std::uint32_t first, std::uint32_t last, std::uint32_t step, std::uint32_t n) {
    std::vector<Axis> out(n);
    for (std::uint32_t k = 0; k < n; ++k) {
      const terrain::LatticeSpan s = terrain::latticeSpan(first + k, first, last, step);
      out[k] = {(s.a - first) / step, s.fraction(first + k)};
    }
    return out;
  };
  for (int l = 0; l < levels; ++l) {
    const LevelLattice& lat = lats[std::size_t(l)];
    const std::uint32_t step = 1u << l;
    const std::vector<Axis> xs = axis(m.i0, m.i1, step, w), zs = axis(m.j0, m.j1, step, h);
    const std::size_t lw = m.cols[std::size_t(l)].size();
    for (std::uint32_t j = 0; j < h; ++j) {
      const std::size_t b = zs[j].cell;
      for (std::uint32_t i = 0; i < w; ++i) {
        const std::size_t a = xs[i].cell;
        const double nw = lat.heights[b * lw + a], ne = lat.heights[b * lw + a + 1];
        const double sw = lat.heights[(b + 1) * lw + a], se = lat.heights[(b + 1) * lw + a + 1];
        const double v = terrain::planeHeight(xs[i].f, zs[j].f, nw, ne, sw, se);
        surf[std::size_t(l)][j * w + i] = v;
        lowest[j * w + i] = std::min(lowest[j * w + i], v);
      }
    }
  }
  std::vector<float> depth(std::size_t(levels), static_cast<float>(kSkirtMargin));
  for (int l = 0; l < levels; ++l) {
    const std::uint32_t edge = node << l;  // node edge in level-0 posts
    double worst = 0;
    for (std::uint32_t j = 0; j < h; ++j) {
      for (std::uint32_t i = 0; i < w; ++i) {
        const bool onLine = i % edge == 0 || j % edge == 0 || i == w - 1 || j == h - 1;
        if (onLine) worst = std::max(worst, surf[std::size_t(l)][j * w + i] - lowest[j * w + i]);
      }
    }
    depth[std::size_t(l)] = float(worst + kSkirtMargin);
  }
  return depth;
}

float blockRangeDepth(const grid::GridFile& g, const ModuleWindow& w, float seed) {
  const std::uint32_t lastI = g.postsX() - 1, lastJ = g.postsZ() - 1;
  const grid::Header& gh = g.header();
  float lo = seed, hi = seed;
  for (std::uint32_t bz = std::min(w.j0, lastJ) / grid::kBlockPosts;
       bz <= std::min(w.j1, lastJ) / grid::kBlockPosts && bz < gh.blocksZ; ++bz) {
    for (std::uint32_t bx = std::min(w.i0, lastI) / grid::kBlockPosts;
         bx <= std::min(w.i1, lastI) / grid::kBlockPosts && bx < gh.blocksX; ++bx) {
      const grid::BlockEntry e = g.blockEntry(bx, bz);
      if (std::isfinite(e.minElevation)) lo = std::min(lo, e.minElevation);
      if (std::isfinite(e.maxElevation)) hi = std::max(hi, e.maxElevation);
    }
  }
  return std::max(1.0f, hi - lo);
}

namespace {

/// Appends one node side's skirt: a strip of quads hanging below the
/// lattice vertices top[0..n] (module-local positions from the level).
void appendSkirtSide(Level& level, const std::vector<std::uint32_t>& top, float depth,
                     std::vector<std::uint32_t>& indices) {
  const std::uint32_t base = std::uint32_t(level.vertices.size());
  for (std::uint32_t v : top) {
    const Vertex b = terrain::skirtBottom(level.vertices[v], depth);
    level.vertices.push_back(b);
  }
  for (std::size_t k = 0; k + 1 < top.size(); ++k) {
    const auto quad = terrain::skirtQuad(top[k], top[k + 1], base + std::uint32_t(k), base + std::uint32_t(k + 1));
    indices.insert(indices.end(), quad.begin(), quad.end());
  }
}

/// Finds (or adds) the level vertex at lattice post (a, b).
std::uint32_t latticeVertex(Level& level, const LevelLattice& lat, std::size_t a, std::size_t b,
                            std::vector<std::uint32_t>& cache) {
  const std::size_t k = b * lat.xs.size() + a;
  if (cache[k] == UINT32_MAX) {
    cache[k] = std::uint32_t(level.vertices.size());
    level.vertices.push_back({float(lat.xs[a]), lat.heights[k], float(lat.zs[b]), 0, 0});
  }
  return cache[k];
}

/// std::lower_bound(xs, v) as an index, for lattice coordinates about
/// `spacing` apart: starts at the guess v / spacing and steps to the
/// answer (a binary search per vertex was most of addSkirts' time).
std::size_t firstAtOrAbove(const std::vector<double>& xs, double spacing, double v) {
  const std::size_t n = xs.size();
  if (!(v > xs.front()) || !(spacing > 0)) {
    return std::size_t(std::lower_bound(xs.begin(), xs.end(), v) - xs.begin());
  }
  std::size_t i = std::size_t(std::min(double(n), std::ceil((v - xs.front()) / spacing)));
  while (i > 0 && xs[i - 1] >= v) --i;
  while (i < n && xs[i] < v) ++i;
  return i;
}

/// Extra vertices on the lattice lines, bucketed by line and sorted along
/// it: rows[b] holds (x, vertex) of those on row b, cols[a] (z, vertex).
struct LineVertices {
  std::vector<std::vector<std::pair<float, std::uint32_t>>> rows, cols;
  bool empty = true;
};

LineVertices bucketLineVertices(const Level& level, const LevelLattice& lat, std::span<const std::uint32_t> extra) {
  LineVertices out;
  if (extra.empty()) return out;
  out.rows.resize(lat.zs.size());
  out.cols.resize(lat.xs.size());
  for (const std::uint32_t v : extra) {
    const Vertex& p = level.vertices[v];
    const std::size_t a = firstAtOrAbove(lat.xs, lat.spacing, double(p.x) - 1e-4);
    const std::size_t b = firstAtOrAbove(lat.zs, lat.spacing, double(p.z) - 1e-4);
    const bool onCol = a < lat.xs.size() && float(lat.xs[a]) == p.x;
    const bool onRow = b < lat.zs.size() && float(lat.zs[b]) == p.z;
    if (onCol == onRow) continue;  // a post (already a top) or on no line
    if (onRow) out.rows[b].push_back({p.x, v});
    else out.cols[a].push_back({p.z, v});
    out.empty = false;
  }
  for (auto* lines : {&out.rows, &out.cols}) {
    for (auto& line : *lines) std::sort(line.begin(), line.end());
  }
  return out;
}

/// The skirt groups and their indices, apart from the level's.
void skirtGroups(Level& level, const LevelLattice& lat, std::uint32_t node, float depth, std::uint16_t material,
                 std::span<const std::uint32_t> lineVertices, std::vector<Group>& groups,
                 std::vector<std::uint32_t>& indices) {
  const LineVertices extra = bucketLineVertices(level, lat, lineVertices);
  // Lattice vertices already emitted by the skin are reused when found at
  // exactly the lattice position, so skirts share the skin's edge vertices.
  std::vector<std::uint32_t> cache(lat.xs.size() * lat.zs.size(), UINT32_MAX);
  // The builder writes the posts first, row by row: when vertices 0..P-1
  // are exactly them, the search below would find just these (the first
  // match wins), so it is skipped (most of addSkirts' time on a big level).
  bool postsFirst = level.vertices.size() >= cache.size();
  for (std::size_t k = 0; postsFirst && k < cache.size(); ++k) {
    const Vertex& p = level.vertices[k];
    postsFirst = p.x == float(lat.xs[k % lat.xs.size()]) && p.z == float(lat.zs[k / lat.xs.size()]) && p.y == lat.heights[k];
  }
  if (postsFirst) {
    for (std::size_t k = 0; k < cache.size(); ++k) cache[k] = std::uint32_t(k);
  }
  for (std::uint32_t v = postsFirst ? std::uint32_t(level.vertices.size()) : 0; v < level.vertices.size(); ++v) {
    const Vertex& p = level.vertices[v];
    const std::size_t a = firstAtOrAbove(lat.xs, lat.spacing, double(p.x) - 1e-4);
    const std::size_t b = firstAtOrAbove(lat.zs, lat.spacing, double(p.z) - 1e-4);
    if (a == lat.xs.size() || b == lat.zs.size()) continue;
    if (float(lat.xs[a]) != p.x || float(lat.zs[b]) != p.z) continue;
    const std::size_t k = b * lat.xs.size() + a;
    if (cache[k] == UINT32_MAX && p.y == lat.heights[k]) cache[k] = v;
  }
  const std::size_t sx = lat.xs.size() - 1, sz = lat.zs.size() - 1;
  std::vector<std::uint32_t> top;
  terrain::forEachSkirtNode(sx, sz, node, [&](std::uint32_t square, const std::array<terrain::SkirtSide, 4>& sides) {
    Group g;
    g.square = square;
    g.half = Half::skirt;
    g.priority = module::kPrioritySkin;
    g.material = material;
    g.firstIndex = std::uint32_t(indices.size());
    for (const terrain::SkirtSide& side : sides) {
      top.clear();
      for (std::size_t k = 0; k < side.posts(); ++k) {
        top.push_back(latticeVertex(level, lat, side.column(k), side.row(k), cache));
        if (extra.empty || k + 1 == side.posts()) continue;
        // The surface's own vertices between this post and the next (a
        // refined square's fine edge): the skirt follows them down.
        const bool alongRow = side.b0 == side.b1;
        const auto& line = alongRow ? extra.rows[side.b0] : extra.cols[side.a0];
        const double lo = alongRow ? lat.xs[side.column(k)] : lat.zs[side.row(k)];
        const double hi = alongRow ? lat.xs[side.column(k + 1)] : lat.zs[side.row(k + 1)];
        auto it = std::upper_bound(line.begin(), line.end(), std::pair{float(lo), UINT32_MAX});
        for (; it != line.end() && double(it->first) < hi; ++it) {
          if (double(it->first) > lo && (top.empty() || level.vertices[top.back()].x != level.vertices[it->second].x ||
                                          level.vertices[top.back()].z != level.vertices[it->second].z)) {
            top.push_back(it->second);
          }
        }
      }
      appendSkirtSide(level, top, depth, indices);
    }
    g.indexCount = std::uint32_t(indices.size()) - g.firstIndex;
    groups.push_back(g);
  });
}

bool groupBefore(const Group& a, const Group& b) {
  if (a.priority != b.priority) return a.priority < b.priority;
  if (a.square != b.square) return a.square < b.square;
  if (a.half != b.half) return a.half < b.half;
  return a.material < b.material;
}

/// Merges the skirt groups into the level, keeping groups sorted and each
/// group's indices contiguous in group order.
void mergeGroups(Level& level, const std::vector<Group>& extra, const std::vector<std::uint32_t>& extraIndices) {
  std::vector<std::pair<Group, bool>> all;  // bool: indices live in extraIndices
  all.reserve(level.groups.size() + extra.size());
  for (const Group& g : level.groups) all.push_back({g, false});
  for (const Group& g : extra) all.push_back({g, true});
  const auto before = [](const auto& a, const auto& b) { return groupBefore(a.first, b.first); };
  // Both runs are usually sorted already (the skin in square order, the
  // skirts too): a merge then gives what the stable sort would.
  const auto mid = all.begin() + std::ptrdiff_t(level.groups.size());
  if (std::is_sorted(all.begin(), mid, before) && std::is_sorted(mid, all.end(), before)) {
    std::inplace_merge(all.begin(), mid, all.end(), before);
  } else {
    std::stable_sort(all.begin(), all.end(), before);
  }
  std::vector<std::uint32_t> indices;
  indices.reserve(level.indices.size() + extraIndices.size());
  level.groups.clear();
  for (auto& [g, isExtra] : all) {
    const auto& src = isExtra ? extraIndices : level.indices;
    const std::uint32_t first = std::uint32_t(indices.size());
    indices.insert(indices.end(), src.begin() + g.firstIndex, src.begin() + g.firstIndex + g.indexCount);
    g.firstIndex = first;
    level.groups.push_back(g);
  }
  // A pager slot's level keeps its reserved capacity; a fresh level takes
  // the merged vector as it is.
  if (level.indices.capacity() >= indices.size()) {
    level.indices.assign(indices.begin(), indices.end());
  } else {
    level.indices = std::move(indices);
  }
}

}  // namespace

std::uint64_t addSkirts(Level& level, const LevelLattice& lat, std::uint32_t node, float depth,
                        std::uint16_t material, std::span<const std::uint32_t> lineVertices) {
  std::vector<Group> groups;
  std::vector<std::uint32_t> indices;
  skirtGroups(level, lat, node, depth, material, lineVertices, groups, indices);
  mergeGroups(level, groups, indices);
  return indices.size() / 3;
}

}  // namespace sandtable::meshing
