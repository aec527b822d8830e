#pragma once
// Quadtree load modules (seed chapter V.H): the grid cut into square
// modules (1 km by default), each with L levels of detail (4 by default),
// the culture decaled onto every level's own triangles, skirts along every
// quadtree node edge, stored in one pack file with a memory-mappable index.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "sandtable/converters/culture.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/objects.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/pack.h"
#include "sandtable/meshing/lattice.h"

#include <nlohmann/json.hpp>

namespace sandtable::convert {

struct ModuleOptions {
  double moduleSize = 1000.0;  ///< metres (seed: 1 km); rounded to whole node multiples of posts
  int levels = 4;              ///< seed: 4
  int threads = 0;             ///< 0 = all cores
  int zstdLevel = 9;
  /// Load-module format version written (1 or 2; docs/FORMAT.md §9, §9.7).
  std::uint32_t moduleVersion = module::kNewestVersion;
  /// Version 2 height quantisation step, metres (0: exact float heights).
  /// Every decoded height is within heightStep / 2 of the built one.
  double heightStep = kBuildHeightStep;
  /// Version 2: store per-vertex octahedral normals. Off by default because
  /// they cost about 30% of the pack and the renderer samples the grid's
  /// normals itself (docs/FORMAT.md §9.7).
  bool normals = false;
  /// Static objects to place (version 5 modules; null or empty: none). Not
  /// owned; must outlive buildModules.
  const ObjectPlan* objects = nullptr;
};

// moduleSquares and nodeSquares (sandtable/meshing/lattice.h), as the
// module builder's callers have always named them.
using meshing::moduleSquares;
using meshing::nodeSquares;

struct LevelTotals {
  std::uint64_t triangles = 0;
  std::uint64_t skinPolygons = 0;
  std::uint64_t decalPolygons = 0;
  std::uint64_t skirtTriangles = 0;
  std::uint64_t buildings = 0, buildingTriangles = 0;  ///< extruded footprints (docs/CULTURE.md, "Buildings")
};

/// CPU seconds of the module stage by stage, summed over its workers
/// (threadCpuSeconds, so a busy machine does not inflate them): the
/// build's profile (docs/CULTURE.md, "Profile").
struct StageSeconds {
  double terrain = 0;      ///< lattices, skirts, highest vertices: all but the culture
  double partition = 0;    ///< culture: each module's partition (once per module), of which
  double gather = 0;       ///<   candidate features clipped to the module,
  double arrangement = 0;  ///<   the CGAL arrangement and face windings,
  double pieces = 0;       ///<   label boundaries, triangulation and convex pieces
  double cut = 0;          ///< culture: cutting to every level's triangles, merging, writing
  double compress = 0;     ///< encoding, checking the encoding, zstd, CRCs
  double write = 0;        ///< appending to the pack (one thread)
  StageSeconds& operator+=(const StageSeconds& o);
};

struct ModuleReport {
  std::uint32_t modulesX = 0, modulesZ = 0, moduleSquares = 0;
  double moduleSize = 0;  ///< actual edge in metres
  std::uint64_t modules = 0;
  double seconds = 0;
  pack::SizeStats sizes;
  std::vector<LevelTotals> levels;
  std::uint64_t packBytes = 0, indexBytes = 0;
  std::uint32_t packCrc = 0, indexCrc = 0;
  std::uint32_t moduleVersion = 0;  ///< as written (ModuleOptions)
  double heightStep = 0;
  bool normals = false;  ///< version 2 levels carry octahedral normals
  StageSeconds stages;
  ObjectTotals objects;  ///< objects placed, over every module
};

/// Builds every module of `grid` into `directory` (modules.pack, modules.idx).
/// Workers take modules in row order, so memory stays bounded by one module
/// per worker plus the index (32 bytes per module) whatever the database size.
/// A pack's record sizes as the manifest's `build.modules.bytes` object
/// (docs/FORMAT.md §5.5): totals, min, median, p95, max and mean.
nlohmann::json sizeStatsJson(const pack::SizeStats& s);

Result<ModuleReport> buildModules(const std::string& directory, const grid::GridFile& grid,
                                  const Culture& culture, std::uint16_t skirtMaterial,
                                  const ModuleOptions& options, const ProgressFn& progress);

/// The module tiling of `grid` under `options` (modulesX/Z, squares, size,
/// version fields); counts and stages zero.
ModuleReport moduleLayout(const grid::GridFile& grid, const ModuleOptions& options);

/// A pack writer for that tiling (pack v2, the layout the build writes).
Result<std::unique_ptr<pack::PackWriter>> createPackWriter(const std::string& directory, const ModuleReport& layout,
                                                           const ModuleOptions& options);

/// Rows of modules [first, first + count); count 0: to the last row.
struct ModuleRows {
  std::uint32_t first = 0, count = 0;
};
/// Takes each compressed module, in row-major order, from the one thread
/// that appends (buildModules: the pack writer; a distributed task: its part).
using ModuleAppend = std::function<Status(pack::PackWriter::Record&&)>;

/// The module stage over some rows: built and compressed (by `compressor`,
/// whose compress() alone is used) on every worker, handed to `append` in
/// row-major order. The one loop buildModules and a distributed build's
/// tasks share. The report's modules counts the modules built; sizes and
/// file fields are left zero.
Result<ModuleReport> buildModuleRows(const grid::GridFile& grid, const Culture& culture, std::uint16_t skirtMaterial,
                                     const ModuleOptions& options, ModuleRows rows,
                                     const pack::PackWriter& compressor, const ModuleAppend& append,
                                     const ProgressFn& progress);

/// Sums another report's level totals and objects into r (a merge).
void addTotals(ModuleReport& r, const std::vector<LevelTotals>& totals);
void addObjects(ObjectTotals& to, const ObjectTotals& from);

/// Builds one module (exposed for tests and benchmarks).
module::Module buildModule(const grid::GridFile& grid, const Culture& culture,
                           std::uint16_t skirtMaterial, std::uint32_t squares, int levels,
                           std::uint32_t kx, std::uint32_t kz, LevelTotals* totals = nullptr,
                           StageSeconds* stages = nullptr);


struct UpgradeOptions {
  double heightStep = kBuildHeightStep;  ///< as ModuleOptions::heightStep
  int zstdLevel = 9;
};

struct UpgradeReport {
  bool upgraded = false;     ///< false: the modules already were the newest version, 6 (nothing written)
  std::uint32_t fromVersion = 0;
  std::uint64_t modules = 0;
  std::uint64_t packBytesBefore = 0, packBytesAfter = 0;
  double seconds = 0;
};

/// Rewrites the load modules of database `directory` (versions 1 to 5) in
/// the newest version (6; a version 5 module's objects become explicit
/// objects, docs/FORMAT.md §9.11): a new
/// database is assembled beside it in `DIR.upgrade.<pid>/` (grid and
/// material table hard-linked or copied, modules re-encoded, manifest
/// files[] and build.modules updated), fsynced, and swapped with the old
/// directory in one renameat2(RENAME_EXCHANGE); the old one is then
/// removed. Interrupted at any point, `directory` is the old database or
/// the new one, each complete. A database whose modules are already
/// version 6 is left untouched (upgraded = false). Problems name the file.
Result<UpgradeReport> upgradeDatabase(const std::string& directory, const UpgradeOptions& options,
                                      const ProgressFn& progress);

}  // namespace sandtable::convert
