// Load modules: for every module and level, the lattice from the grid, the
// culture decaled onto it, skirts along every quadtree node edge, the
// highest vertex per square (all but the decaling in sandtable_meshing);
// then compressed into the pack in parallel.
#include "sandtable/converters/modules.h"

#include "sandtable/meshing/assemble.h"
#include "sandtable/meshing/normals.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include "sandtable/base/jobs.h"

namespace sandtable::convert {

StageSeconds& StageSeconds::operator+=(const StageSeconds& o) {
  terrain += o.terrain, partition += o.partition, gather += o.gather, arrangement += o.arrangement;
  pieces += o.pieces, cut += o.cut, compress += o.compress, write += o.write;
  return *this;
}

module::Module buildModule(const grid::GridFile& g, const Culture& culture, std::uint16_t skirtMaterial,
                           std::uint32_t squares, int levels, std::uint32_t kx, std::uint32_t kz,
                           LevelTotals* totals, StageSeconds* stages) {
  const double t0 = threadCpuSeconds();
  double cultureSeconds = 0;
  module::Module out = meshing::assembleModule(
      grid::GridHeightField(g), squares, levels, kx, kz, skirtMaterial, [&](int l, const LevelLattice& lat, module::Level& level) {
        if (cancelRequested()) return false;  // the caller discards a cancelled module
        const DecalStats ds = culture.decalLevel(lat, level);
        if (stages) {
          stages->partition += ds.partitionSeconds, stages->gather += ds.gatherSeconds;
          stages->arrangement += ds.arrangementSeconds, stages->pieces += ds.piecesSeconds;
          stages->cut += ds.cutSeconds;
          cultureSeconds += ds.partitionSeconds + ds.cutSeconds;
        }
        if (totals) {
          LevelTotals& t = totals[l];
          t.triangles += ds.triangles;
          t.skinPolygons += ds.skinPolygons;
          t.decalPolygons += ds.decalPolygons;
          t.buildings += ds.buildings;
          t.buildingTriangles += ds.buildingTriangles;
        }
        return true;
      });
  if (stages) stages->terrain += threadCpuSeconds() - t0 - cultureSeconds;
  if (totals) {
    for (std::size_t l = 0; l < out.levels.size(); ++l) {
      for (const module::Group& grp : out.levels[l].groups) {
        if (grp.half == module::Half::skirt) totals[l].skirtTriangles += grp.indexCount / 3;
      }
    }
  }
  return out;
}

ModuleReport moduleLayout(const grid::GridFile& g, const ModuleOptions& o) {
  ModuleReport r;
  r.moduleSquares = moduleSquares(o.moduleSize, g.spacing(), o.levels);
  r.moduleSize = r.moduleSquares * g.spacing();
  r.modulesX = (g.postsX() - 2) / r.moduleSquares + 1;
  r.modulesZ = (g.postsZ() - 2) / r.moduleSquares + 1;
  r.modules = std::uint64_t(r.modulesX) * r.modulesZ;
  r.moduleVersion = o.moduleVersion;
  r.heightStep = o.moduleVersion >= module::kVersion2 ? o.heightStep : 0.0;
  r.normals = o.moduleVersion >= module::kVersion2 && o.normals;
  return r;
}

Result<std::unique_ptr<pack::PackWriter>> createPackWriter(const std::string& directory, const ModuleReport& r,
                                                           const ModuleOptions& o) {
  pack::IndexHeader h;
  h.modulesX = r.modulesX;
  h.modulesZ = r.modulesZ;
  h.levels = std::uint32_t(o.levels);
  h.moduleSquares = r.moduleSquares;
  h.moduleSize = r.moduleSize;
  // Pack v2: a coarse and a fine record per module, coarse records first,
  // in Morton order, so the pager reads coarse versions in small runs.
  pack::PackLayout layout = pack::PackLayout::split(h.levels);
  layout.encode = {.version = o.moduleVersion, .heightStep = o.heightStep};
  return pack::PackWriter::create(directory, h, o.zstdLevel, layout);
}

void addTotals(ModuleReport& r, const std::vector<LevelTotals>& totals) {
  for (std::size_t l = 0; l < totals.size() && l < r.levels.size(); ++l) {
    r.levels[l].triangles += totals[l].triangles;
    r.levels[l].skinPolygons += totals[l].skinPolygons;
    r.levels[l].decalPolygons += totals[l].decalPolygons;
    r.levels[l].skirtTriangles += totals[l].skirtTriangles;
    r.levels[l].buildings += totals[l].buildings;
    r.levels[l].buildingTriangles += totals[l].buildingTriangles;
  }
}

void addObjects(ObjectTotals& to, const ObjectTotals& from) {
  to.placed += from.placed;
  to.scatterRefused += from.scatterRefused;
  for (const auto& [cls, n] : from.byClass) to.byClass[cls] += n;
}

Result<ModuleReport> buildModuleRows(const grid::GridFile& g, const Culture& culture, std::uint16_t skirtMaterial,
                                     const ModuleOptions& o, ModuleRows rows, const pack::PackWriter& compressor,
                                     const ModuleAppend& append, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  ModuleReport r = moduleLayout(g, o);
  const std::uint32_t row1 = rows.count == 0 ? r.modulesZ : std::min(r.modulesZ, rows.first + rows.count);
  const std::uint64_t first = std::uint64_t(rows.first) * r.modulesX;
  const std::uint64_t n = rows.first < row1 ? std::uint64_t(row1 - rows.first) * r.modulesX : 0;

  // Modules are built and compressed on every worker and appended in
  // row-major order: the records do not depend on thread timing.
  struct Built {
    std::optional<pack::PackWriter::Record> record;  ///< none: skipped or failed
    std::string error;
    std::vector<LevelTotals> totals;
    StageSeconds stages;
    ObjectTotals objects;
  };
  // Each plan point belongs to the module that holds it (the east and
  // south edges to the last module).
  std::vector<std::vector<std::uint32_t>> pointsOf;
  const bool objects = o.objects && !o.objects->empty() && o.moduleVersion >= module::kVersion5;  // 5 and 6
  if (objects) {
    pointsOf.resize(n);
    for (std::size_t k = 0; k < o.objects->points.size(); ++k) {
      const auto& p = o.objects->points[k];
      const auto kx = std::min(std::uint32_t(std::max(0.0, p.x / r.moduleSize)), r.modulesX - 1);
      const auto kz = std::min(std::uint32_t(std::max(0.0, p.z / r.moduleSize)), r.modulesZ - 1);
      const std::uint64_t at = std::uint64_t(kz) * r.modulesX + kx;
      if (at >= first && at - first < n) pointsOf[at - first].push_back(std::uint32_t(k));
    }
  }
  std::atomic<bool> stop{false};
  std::string error;
  std::uint64_t done = 0;
  auto lastReport = std::chrono::steady_clock::now();
  r.levels.assign(std::size_t(o.levels), {});
  if (progress) progress(0.0, "modules");
  // Records wait in module order to be appended; a town module costs 40x
  // the median, so the window must hold many modules per worker or the
  // other workers idle behind it (a few MB of compressed records).
  constexpr std::size_t kInFlightPerWorker = 32;
  jobs::orderedPipeline<Built>(
      n, o.threads, kInFlightPerWorker * std::size_t(jobs::threadCount(o.threads)),
      [&](std::size_t i) {
        Built b;
        if (stop || cancelRequested()) return b;
        b.totals.assign(std::size_t(o.levels), {});
        const std::uint64_t k = first + i;
        const auto kx = std::uint32_t(k % r.modulesX), kz = std::uint32_t(k / r.modulesX);
        module::Module m =
            buildModule(g, culture, skirtMaterial, r.moduleSquares, o.levels, kx, kz, b.totals.data(), &b.stages);
        if (objects) {
          placeObjects(*o.objects, pointsOf[i], double(kx) * r.moduleSize, double(kz) * r.moduleSize, m, b.objects);
        }
        if (o.moduleVersion >= module::kVersion2 && o.normals) meshing::fillNormals(grid::GridHeightField(g), r.moduleSquares, m);  // v1 has no place for them
        if (cancelRequested()) return b;  // not compressed nor written: the build is being abandoned
        const double tc = threadCpuSeconds();
        auto packed = compressor.compress(m);
        b.stages.compress = threadCpuSeconds() - tc;
        if (packed) b.record = std::move(packed.value());
        else b.error = packed.problems().front().message;
        return b;
      },
      [&](std::size_t, Built&& b) {
        if (stop) return;
        const double tw = threadCpuSeconds();
        if (b.record) b.error = append(std::move(*b.record)).message();
        b.stages.write = threadCpuSeconds() - tw;
        r.stages += b.stages;
        addObjects(r.objects, b.objects);
        if (!b.error.empty()) {
          error = b.error;  // the first in module order
          stop = true;
          return;
        }
        if (!b.record) {
          stop = true;  // cancelled
          return;
        }
        addTotals(r, b.totals);
        ++done;
        const auto now = std::chrono::steady_clock::now();
        if (progress && now - lastReport >= std::chrono::milliseconds(100)) {
          progress(double(done) / double(n), "modules");
          lastReport = now;
        }
      },
      &stop);
  if (!error.empty()) return Problem{"", 0, "build: modules: " + error};
  if (cancelRequested()) return Problem{"", 0, "build: cancelled"};
  if (progress) progress(1.0, "modules");
  r.modules = n;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

Result<ModuleReport> buildModules(const std::string& directory, const grid::GridFile& g, const Culture& culture,
                                  std::uint16_t skirtMaterial, const ModuleOptions& o, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  auto writer = createPackWriter(directory, moduleLayout(g, o), o);
  if (!writer) return writer.problems();
  pack::PackWriter& w = *writer.value();
  auto built = buildModuleRows(g, culture, skirtMaterial, o, {}, w,
                               [&w](pack::PackWriter::Record&& rec) { return w.append(std::move(rec)); }, progress);
  if (!built) return Problem{directory, 0, built.problems().front().message};
  ModuleReport r = std::move(built.value());
  if (Status st = w.finish(); !st) return Problem{directory, 0, "build: modules: " + st.message()};
  r.sizes = w.stats();
  r.packBytes = w.packBytes();
  r.indexBytes = w.indexBytes();
  r.packCrc = w.packCrc();
  r.indexCrc = w.indexCrc();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

nlohmann::json sizeStatsJson(const pack::SizeStats& s) {
  return {{"compressed_total", s.totalCompressed}, {"raw_total", s.totalRaw},
          {"min", s.minCompressed},                {"median", s.medianCompressed},
          {"p95", s.p95Compressed},                {"max", s.maxCompressed},
          {"mean", s.count ? double(s.totalCompressed) / double(s.count) : 0.0}};
}

}  // namespace sandtable::convert
