#pragma once
// The re-mesher's parts (modules.h; docs/DYNAMIC.md, "Re-meshing"): the
// CGAL calls (remesh_cgal.h), the mesh of one refined square
// (remesh_square.cpp) and the rebuild of a module from its base and the
// edited heights (remesh_module.cpp).
//
// Thread safety: pure functions over values and HeightFields (their thread
// contract); call from one thread per module.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "remesh_cgal.h"
#include "sandtable/edits/modules.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/scatter.h"

namespace sandtable::edits::detail {

// ------------------------------------------------------ one refined square

/// Height at fraction t (0..1) along the level-0 grid edge from post (i, j)
/// to (i, j + 1) (vertical) or (i + 1, j): the west (north) square's patch
/// where it reaches the edge at t, else the east (south) square's, else the
/// straight line between the posts. The one rule for a point on a grid
/// edge, so the squares on both sides (in one module or two) give the same
/// bits.
double edgeHeight(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, bool vertical, double t);

/// Sides of a square as bits.
enum SideBit : std::uint8_t { kNorth = 1, kSouth = 2, kWest = 4, kEast = 8 };

/// A refined grid square's new level-0 triangles: the fine lattice inside
/// the fine region and a constrained triangulation of the rest of the
/// square (docs/DYNAMIC.md, "Re-meshing").
struct SquareMesh {
  std::uint32_t i = 0, j = 0;  ///< the grid square
  std::shared_ptr<const grid::RefinedSquare> patch;
  double n = 1;  ///< fine units per side (the patch's cells)
  /// The fine region: fine squares fa0 .. fa1-1 x fb0 .. fb1-1 (the patch
  /// less the rows and columns along an edge beside an unrefined square);
  /// empty when fa0 >= fa1.
  std::uint32_t fa0 = 0, fb0 = 0, fa1 = 0, fb1 = 0;
  /// Vertices: 0..3 are the square's corners NW, NE, SW, SE (the level's
  /// lattice vertices), then the others.
  std::vector<UV> uv;
  std::vector<double> y;
  std::vector<std::uint8_t> sides;  ///< SideBit mask of the square's sides each vertex lies on
  struct Tri {
    std::array<std::uint32_t, 3> v{};  ///< facing up in the module frame (x east, z south)
    module::Half half = module::Half::upper;
    bool fine = false;  ///< inside the fine region
  };
  std::vector<Tri> tris;
  /// Triangles of fine square (a, b): tris[fineStart[k]] .. tris[fineStart[k + 1]],
  /// k = (b - fb0) * (fa1 - fa0) + (a - fa0); the rest region's follow.
  std::vector<std::uint32_t> fineStart;
  bool fineEmpty() const { return fa0 >= fa1 || fb0 >= fb1; }
  std::uint32_t restBegin() const { return fineStart.empty() ? 0 : fineStart.back(); }
};

/// The mesh of grid square (i, j) of `h` at level 0, its corners at
/// heights `cornerY` (NW, NE, SW, SE: the level's lattice vertices), or
/// false when the square has no patch that changes its triangles (no patch,
/// or one that lies wholly along edges beside unrefined squares, and no
/// refined neighbour's edge points).
bool meshRefinedSquare(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, const std::array<double, 4>& cornerY,
                       SquareMesh& out);

// ------------------------------------------------------------ the module

/// What a module rebuild needs besides the heights.
struct RebuildInput {
  const module::Module* base = nullptr;  ///< decoded base module (geometry as built)
  const std::vector<module::Object>* objects = nullptr;  ///< the objects now (object edits applied)
  const grid::HeightField* before = nullptr;  ///< the ground the base was built on
  const grid::HeightField* heights = nullptr;  ///< the edited ground
  std::uint32_t squares = 0;  ///< level-0 squares along a module edge
  std::uint32_t kx = 0, kz = 0;
  const RemeshOptions* options = nullptr;
  /// Posts whose elevation or normal changed since the base (a bound):
  /// outside it a vertex keeps the base's normal.
  grid::PostRect dirty;
};

struct RebuildStats {
  std::uint64_t refinedSquares = 0;
};

/// Module (kx, kz) rebuilt at every level from its base and the heights now.
module::Module rebuildModule(const RebuildInput& in, RebuildStats& stats);

/// Sets every level's objectY: module::placeBases, then, on level 0, the
/// fine surface's height for an object standing in a refined patch.
void placeObjects(module::Module& m, const grid::HeightField& h, std::uint32_t squares);

}  // namespace sandtable::edits::detail
