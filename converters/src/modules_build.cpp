// Load modules: for every module and level, the lattice from the grid, the
// culture decaled onto it, skirts along every quadtree node edge, the
// highest vertex per square (all but the decaling in sandtable_meshing);
// then compressed into the pack in parallel.
#include "sandtable/converters/modules.h"

#include "sandtable/meshing/assemble.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <thread>

namespace sandtable::convert {

module::Module buildModule(const grid::GridFile& g, const Culture& culture, std::uint16_t skirtMaterial,
                           std::uint32_t squares, int levels, std::uint32_t kx, std::uint32_t kz,
                           LevelTotals* totals) {
  module::Module out = meshing::assembleModule(
      g, squares, levels, kx, kz, skirtMaterial, [&](int l, const LevelLattice& lat, module::Level& level) {
        if (cancelRequested()) return false;  // the caller discards a cancelled module
        const DecalStats ds = culture.decalLevel(lat, level);
        if (totals) {
          LevelTotals& t = totals[l];
          t.triangles += ds.triangles;
          t.skinPolygons += ds.skinPolygons;
          t.decalPolygons += ds.decalPolygons;
        }
        return true;
      });
  if (totals) {
    for (std::size_t l = 0; l < out.levels.size(); ++l) {
      for (const module::Group& grp : out.levels[l].groups) {
        if (grp.half == module::Half::skirt) totals[l].skirtTriangles += grp.indexCount / 3;
      }
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
      if (std::string e = writer.value()->add(m); !e.empty()) {
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
  if (std::string e = writer.value()->finish(); !e.empty()) return Problem{directory, 0, "build: modules: " + e};
  r.sizes = writer.value()->stats();
  r.packBytes = writer.value()->packBytes();
  r.indexBytes = writer.value()->indexBytes();
  r.packCrc = writer.value()->packCrc();
  r.indexCrc = writer.value()->indexCrc();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace sandtable::convert
