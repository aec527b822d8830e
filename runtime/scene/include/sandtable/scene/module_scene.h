#pragma once
// Scene selection over paged load modules (seed chapter IX: the view
// triangle of Figure 76, its grid-square selection of Figure 78 done at
// module granularity, the vertical extent of the view volume, and the LoD
// of lod.h). Fills a DisplayBuffer's module list on the main thread with
// no GL calls; the render thread uploads and draws what it lists.
//
// Thread safety: one ModuleScene per main thread. It reads the pager with
// resident() (lock-free) and keeps a small cache of per-module level
// errors and heights, keyed by the pager's generation.
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include "sandtable/scene/display_buffer.h"
#include "sandtable/scene/lod.h"
#include "sandtable/paging/pager.h"
#include "sandtable/world/ground.h"

namespace sandtable::scene {

struct ModuleSceneSettings {
  LodOptions lod;
  std::uint32_t imageHeight = 720;  ///< for projected errors
  double gridSpacing = 30;          ///< the view triangle's pull-back (one post)
  float minElevation = 0;           ///< lowest ground in the database (vertical extent)
  /// Level-0 squares along a module edge (pack::IndexHeader::moduleSquares);
  /// quadtree nodes hold moduleSquares >> (levels - 1) squares at every level.
  std::uint32_t moduleSquares = 0;
};

class ModuleScene {
 public:
  ModuleScene(const paging::Pager& pager, const ModuleSceneSettings& s);

  /// Selects the modules for `cam` (world frame, metres) into `out`,
  /// nearest first, each with its level, morph factor and read guard;
  /// fills out.scene and out.triangles. Reuses out's memory.
  void fill(const Camera& cam, std::uint64_t frame, DisplayBuffer& out);

  const ModuleSceneSettings& settings() const { return settings_; }

 private:
  struct Info {
    std::uint64_t generation = 0;
    std::uint32_t finest = 0;
    std::vector<double> errors;  ///< per level, against `finest` (whole module)
    std::uint32_t cellsPerSide = 1;  ///< the finest node grid
    std::vector<std::vector<double>> cellErrors;  ///< [level][cell], Morton order
    std::vector<float> cellTop;                   ///< highest vertex over each cell
    std::vector<float> minY, maxY;  ///< per level, skirts included
    std::vector<std::vector<std::uint64_t>> nodeTriangles;  ///< per level, prefix sums in Morton order
  };
  struct Walk;  ///< one module being walked (module_scene.cpp)
  const Info& infoFor(const paging::ResidentRef& ref);
  void visit(const Walk& w, std::uint32_t depth, std::uint32_t a, std::uint32_t b);
  void emit(const Walk& w, std::uint32_t level, std::uint32_t depth, std::uint32_t a,
            std::uint32_t b, float morph);

  const paging::Pager& pager_;
  ModuleSceneSettings settings_;
  double moduleSize_ = 0;
  std::uint32_t modulesX_ = 0, modulesZ_ = 0, levels_ = 1, nodeSquares_ = 1;
  std::unordered_map<std::uint64_t, Info> info_;
  std::uint64_t frame_ = 0;
};

}  // namespace sandtable::scene

namespace sandtable::scene {

/// What `buf` draws at world (x east, z south of the grid origin): the
/// level and morph of the quadtree node there, for the ground clamp
/// (world/ground.h). Nullopt in grid-mesh mode or where no module is drawn.
std::optional<world::DrawnLevel> drawnLevelAt(const DisplayBuffer& buf, double x, double z);

/// What a frame drew where, kept after its display buffer is reused: the
/// simulator's entities stand on it (seed: they follow the terrain that is
/// drawn). A plain value; safe to read from any thread once built.
class DrawnLevels {
 public:
  DrawnLevels() = default;
  explicit DrawnLevels(const DisplayBuffer& buf);
  /// As drawnLevelAt on the buffer it was made from.
  std::optional<world::DrawnLevel> at(double x, double z) const;

 private:
  struct Node {
    std::uint32_t level = 0, side = 1, first = 0, last = 0;
    float morph = 0;
  };
  double moduleSize_ = 0;
  /// Per module (kz * modulesX + kx, sorted): its drawn nodes.
  std::vector<std::pair<std::uint64_t, Node>> nodes_;
};

}  // namespace sandtable::scene
