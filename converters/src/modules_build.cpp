// Load modules: for every module and level, the lattice from the grid, the
// culture decaled onto it, skirts along every quadtree node edge, the
// highest vertex per square; then compressed into the pack in parallel.
#include "sandtable/converters/modules.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <thread>

namespace sandtable::convert {
namespace {

using module::Group;
using module::Half;
using module::Level;
using module::Vertex;

/// Grid post columns (or rows) of one level's lattice inside a module.
std::vector<std::uint32_t> latticePosts(std::uint32_t first, std::uint32_t last, std::uint32_t step) {
  std::vector<std::uint32_t> posts;
  for (std::uint32_t p = first; p < last; p += step) posts.push_back(p);
  posts.push_back(last);
  return posts;
}

struct ModuleLattices {
  std::uint32_t i0 = 0, j0 = 0, i1 = 0, j1 = 0;  ///< level-0 post range (inclusive)
  std::vector<std::vector<std::uint32_t>> cols, rows;  ///< per level
};

ModuleLattices lattices(const grid::GridFile& g, std::uint32_t squares, int levels, std::uint32_t kx,
                        std::uint32_t kz) {
  ModuleLattices m;
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

LevelLattice levelLattice(const grid::GridFile& g, const ModuleLattices& m, int l) {
  const double s = g.spacing();
  LevelLattice lat;
  lat.moduleX = double(m.i0) * s;
  lat.moduleZ = double(m.j0) * s;
  lat.spacing = s * double(1u << l);
  for (std::uint32_t i : m.cols[l]) lat.xs.push_back(double(i - m.i0) * s);
  for (std::uint32_t j : m.rows[l]) lat.zs.push_back(double(j - m.j0) * s);
  lat.heights.reserve(lat.xs.size() * lat.zs.size());
  for (std::uint32_t j : m.rows[l]) {
    for (std::uint32_t i : m.cols[l]) lat.heights.push_back(g.elevation(i, j));
  }
  return lat;
}

/// Index of the lattice interval holding post p (posts sorted ascending).
std::size_t intervalOf(const std::vector<std::uint32_t>& posts, std::uint32_t p) {
  const auto it = std::upper_bound(posts.begin(), posts.end(), p);
  const std::size_t k = std::size_t(it - posts.begin());
  return std::min(k == 0 ? 0 : k - 1, posts.size() - 2);
}

/// Height of a level's drawn surface (SW-NE triangles) at level-0 post (i, j).
double surfaceAt(const LevelLattice& lat, const ModuleLattices& m, int l, std::uint32_t i, std::uint32_t j) {
  const auto& cols = m.cols[l];
  const auto& rows = m.rows[l];
  const std::size_t a = intervalOf(cols, i), b = intervalOf(rows, j);
  const double fx = double(i - cols[a]) / double(cols[a + 1] - cols[a]);
  const double fz = double(j - rows[b]) / double(rows[b + 1] - rows[b]);
  const std::size_t w = cols.size();
  const double nw = lat.heights[b * w + a], ne = lat.heights[b * w + a + 1];
  const double sw = lat.heights[(b + 1) * w + a], se = lat.heights[(b + 1) * w + a + 1];
  if (fx + fz <= 1.0) return nw + fx * (ne - nw) + fz * (sw - nw);
  return se + (1.0 - fx) * (sw - se) + (1.0 - fz) * (ne - se);
}

/// How far each level's skirts must hang: the most any level's surface lies
/// below this level's along this level's node edges, plus a margin so the
/// skirt overlaps what it hides.
std::vector<float> skirtDepths(const std::vector<LevelLattice>& lats, const ModuleLattices& m,
                               std::uint32_t node) {
  const int levels = int(lats.size());
  const std::uint32_t w = m.i1 - m.i0 + 1, h = m.j1 - m.j0 + 1;
  std::vector<double> lowest(std::size_t(w) * h, std::numeric_limits<double>::infinity());
  std::vector<std::vector<double>> surf(std::size_t(levels), std::vector<double>(lowest.size()));
  for (int l = 0; l < levels; ++l) {
    for (std::uint32_t j = 0; j < h; ++j) {
      for (std::uint32_t i = 0; i < w; ++i) {
        const double v = surfaceAt(lats[std::size_t(l)], m, l, m.i0 + i, m.j0 + j);
        surf[std::size_t(l)][j * w + i] = v;
        lowest[j * w + i] = std::min(lowest[j * w + i], v);
      }
    }
  }
  constexpr double kMargin = 1.0;  // metres below the lowest neighbour surface
  std::vector<float> depth(std::size_t(levels), static_cast<float>(kMargin));
  for (int l = 0; l < levels; ++l) {
    const std::uint32_t edge = node << l;  // node edge in level-0 posts
    double worst = 0;
    for (std::uint32_t j = 0; j < h; ++j) {
      for (std::uint32_t i = 0; i < w; ++i) {
        const bool onLine = i % edge == 0 || j % edge == 0 || i == w - 1 || j == h - 1;
        if (onLine) worst = std::max(worst, surf[std::size_t(l)][j * w + i] - lowest[j * w + i]);
      }
    }
    depth[std::size_t(l)] = float(worst + kMargin);
  }
  return depth;
}

/// Appends one node side's skirt: a strip of quads hanging below the
/// lattice vertices top[0..n] (module-local positions from the level).
void appendSkirtSide(Level& level, const std::vector<std::uint32_t>& top, float depth,
                     std::vector<std::uint32_t>& indices) {
  const std::uint32_t base = std::uint32_t(level.vertices.size());
  for (std::uint32_t v : top) {
    Vertex b = level.vertices[v];
    b.y -= depth;
    b.s = b.t = 0;
    level.vertices.push_back(b);
  }
  for (std::size_t k = 0; k + 1 < top.size(); ++k) {
    const std::uint32_t a = top[k], c = top[k + 1];
    const std::uint32_t ab = base + std::uint32_t(k), cb = base + std::uint32_t(k + 1);
    indices.insert(indices.end(), {a, ab, c, c, ab, cb});
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

/// Skirts along all four sides of every quadtree node of the level: one
/// group per node, keyed by the node's north-west square.
void addSkirts(Level& level, const LevelLattice& lat, std::uint32_t node, float depth,
               std::uint16_t material, std::vector<Group>& groups, std::vector<std::uint32_t>& indices) {
  // Lattice vertices already emitted by the decaler are reused when found at
  // exactly the lattice position, so skirts share the skin's edge vertices.
  std::vector<std::uint32_t> cache(lat.xs.size() * lat.zs.size(), UINT32_MAX);
  for (std::uint32_t v = 0; v < level.vertices.size(); ++v) {
    const Vertex& p = level.vertices[v];
    const auto a = std::lower_bound(lat.xs.begin(), lat.xs.end(), double(p.x) - 1e-4);
    const auto b = std::lower_bound(lat.zs.begin(), lat.zs.end(), double(p.z) - 1e-4);
    if (a == lat.xs.end() || b == lat.zs.end()) continue;
    if (float(*a) != p.x || float(*b) != p.z) continue;
    const std::size_t k = std::size_t(b - lat.zs.begin()) * lat.xs.size() + std::size_t(a - lat.xs.begin());
    if (cache[k] == UINT32_MAX && p.y == lat.heights[k]) cache[k] = v;
  }
  const std::size_t sx = lat.xs.size() - 1, sz = lat.zs.size() - 1;
  for (std::size_t nz = 0; nz < sz; nz += node) {
    for (std::size_t nx = 0; nx < sx; nx += node) {
      const std::size_t ax = nx, bx = std::min(nx + node, sx), az = nz, bz = std::min(nz + node, sz);
      Group g;
      g.square = std::uint32_t(nz * sx + nx);
      g.half = Half::skirt;
      g.priority = module::kPrioritySkin;
      g.material = material;
      g.firstIndex = std::uint32_t(indices.size());
      std::vector<std::uint32_t> top;
      auto side = [&](std::size_t a0, std::size_t b0, std::size_t a1, std::size_t b1) {
        top.clear();
        const std::size_t n = std::max(a1 - a0, b1 - b0);
        for (std::size_t k = 0; k <= n; ++k) {
          const std::size_t a = a0 == a1 ? a0 : a0 + k, b = b0 == b1 ? b0 : b0 + k;
          top.push_back(latticeVertex(level, lat, a, b, cache));
        }
        appendSkirtSide(level, top, depth, indices);
      };
      side(ax, az, bx, az);  // north
      side(ax, bz, bx, bz);  // south
      side(ax, az, ax, bz);  // west
      side(bx, az, bx, bz);  // east
      g.indexCount = std::uint32_t(indices.size()) - g.firstIndex;
      groups.push_back(g);
    }
  }
}

bool groupBefore(const Group& a, const Group& b) {
  if (a.priority != b.priority) return a.priority < b.priority;
  if (a.square != b.square) return a.square < b.square;
  if (a.half != b.half) return a.half < b.half;
  return a.material < b.material;
}

/// Merges the skirt groups into the decaled level, keeping groups sorted and
/// each group's indices contiguous in group order.
void mergeGroups(Level& level, std::vector<Group> extra, const std::vector<std::uint32_t>& extraIndices) {
  std::vector<std::pair<Group, bool>> all;  // bool: indices live in extraIndices
  all.reserve(level.groups.size() + extra.size());
  for (const Group& g : level.groups) all.push_back({g, false});
  for (const Group& g : extra) all.push_back({g, true});
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return groupBefore(a.first, b.first); });
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
  level.indices = std::move(indices);
}

void computeMaxHeights(Level& level) {
  level.maxHeight.assign(std::size_t(level.squaresX) * level.squaresZ, -std::numeric_limits<float>::infinity());
  for (const Group& g : level.groups) {
    if (g.half == Half::skirt) continue;
    float& top = level.maxHeight[g.square];
    for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; ++k) {
      top = std::max(top, level.vertices[level.indices[k]].y);
    }
  }
}

}  // namespace

std::uint32_t moduleSquares(double moduleSize, double spacing, int levels) {
  const double unit = double(1u << (levels - 1));
  const double n = std::round(moduleSize / spacing / unit) * unit;
  return std::uint32_t(std::max(unit, n));
}

module::Module buildModule(const grid::GridFile& g, const Culture& culture, std::uint16_t skirtMaterial,
                           std::uint32_t squares, int levels, std::uint32_t kx, std::uint32_t kz,
                           LevelTotals* totals) {
  const ModuleLattices m = lattices(g, squares, levels, kx, kz);
  std::vector<LevelLattice> lats;
  for (int l = 0; l < levels; ++l) lats.push_back(levelLattice(g, m, l));
  const std::vector<float> depths = skirtDepths(lats, m, nodeSquares(squares, levels));
  module::Module out;
  out.kx = kx;
  out.kz = kz;
  out.levels.resize(std::size_t(levels));
  for (int l = 0; l < levels; ++l) {
    if (cancelRequested()) break;  // the caller discards a cancelled module
    const LevelLattice& lat = lats[std::size_t(l)];
    Level& level = out.levels[std::size_t(l)];
    const DecalStats ds = culture.decalLevel(lat, level);
    level.spacing = lat.spacing;
    level.squaresX = std::uint32_t(lat.xs.size() - 1);
    level.squaresZ = std::uint32_t(lat.zs.size() - 1);
    level.skirtDepth = depths[std::size_t(l)];
    std::vector<Group> skirts;
    std::vector<std::uint32_t> skirtIndices;
    addSkirts(level, lat, nodeSquares(squares, levels), level.skirtDepth, skirtMaterial, skirts, skirtIndices);
    mergeGroups(level, std::move(skirts), skirtIndices);
    computeMaxHeights(level);
    if (totals) {
      LevelTotals& t = totals[l];
      t.triangles += ds.triangles;
      t.skinPolygons += ds.skinPolygons;
      t.decalPolygons += ds.decalPolygons;
      t.skirtTriangles += skirtIndices.size() / 3;
    }
  }
  return out;
}

Result<ModuleReport> buildModules(const std::string& directory, const grid::GridFile& g, const Culture& culture,
                                  std::uint16_t skirtMaterial, const ModuleOptions& o, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  ModuleReport r;
  r.moduleSquares = moduleSquares(o.moduleSize, g.spacing(), o.levels);
  r.moduleSize = r.moduleSquares * g.spacing();
  r.modulesX = (g.postsX() - 2) / r.moduleSquares + 1;
  r.modulesZ = (g.postsZ() - 2) / r.moduleSquares + 1;
  r.modules = std::uint64_t(r.modulesX) * r.modulesZ;
  pack::IndexHeader h;
  h.modulesX = r.modulesX;
  h.modulesZ = r.modulesZ;
  h.levels = std::uint32_t(o.levels);
  h.moduleSquares = r.moduleSquares;
  h.moduleSize = r.moduleSize;
  auto writer = pack::PackWriter::create(directory, h, o.zstdLevel);
  if (!writer) return writer.problems();

  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const unsigned threads = o.threads > 0 ? unsigned(o.threads) : hw;
  std::atomic<std::uint64_t> next{0}, done{0};
  std::mutex mu;
  std::string error;
  r.levels.assign(std::size_t(o.levels), {});
  auto work = [&] {
    std::vector<LevelTotals> local(std::size_t(o.levels));
    for (std::uint64_t k = next++; k < r.modules; k = next++) {
      if (cancelRequested()) break;
      {
        std::lock_guard lock(mu);
        if (!error.empty()) break;
      }
      const auto kx = std::uint32_t(k % r.modulesX), kz = std::uint32_t(k / r.modulesX);
      const module::Module m = buildModule(g, culture, skirtMaterial, r.moduleSquares, o.levels, kx, kz, local.data());
      if (cancelRequested()) break;  // not compressed nor written: the build is being abandoned
      if (std::string e = writer.value()->add(m).message(); !e.empty()) {
        std::lock_guard lock(mu);
        if (error.empty()) error = e;
        break;
      }
      ++done;
    }
    std::lock_guard lock(mu);
    for (std::size_t l = 0; l < local.size(); ++l) {
      r.levels[l].triangles += local[l].triangles;
      r.levels[l].skinPolygons += local[l].skinPolygons;
      r.levels[l].decalPolygons += local[l].decalPolygons;
      r.levels[l].skirtTriangles += local[l].skirtTriangles;
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t) pool.emplace_back(work);
  while (done.load() < r.modules) {
    {
      std::lock_guard lock(mu);
      if (!error.empty()) break;
    }
    if (cancelRequested()) break;
    if (progress) progress(double(done.load()) / double(r.modules), "modules");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  for (auto& t : pool) t.join();
  if (!error.empty()) return Problem{directory, 0, "build: modules: " + error};
  if (cancelRequested()) return Problem{directory, 0, "build: cancelled"};
  if (progress) progress(1.0, "modules");
  if (Status st = writer.value()->finish(); !st) return Problem{directory, 0, "build: modules: " + st.message()};
  r.sizes = writer.value()->stats();
  r.packBytes = writer.value()->packBytes();
  r.indexBytes = writer.value()->indexBytes();
  r.packCrc = writer.value()->packCrc();
  r.indexCrc = writer.value()->indexCrc();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace sandtable::convert
