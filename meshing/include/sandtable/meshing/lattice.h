#pragma once
// The lattice of one module level (seed chapter V.H): which grid posts a
// module's levels use, and their elevations. Level 0 uses every post of
// the module's window; level l every 2^l-th, with the last post of the
// window always kept, so a module at the database's east or south edge has
// narrower last squares at coarse levels (docs/FORMAT.md, "module").
//
// The posts come from a HeightField (the grid file, or a field that
// changes: dynamic terrain re-meshes a changed module from it).
//
// Thread safety: plain values and pure functions over a HeightField; call
// from any thread (a lattice read while the field changes may mix the
// change's old and new posts: compare the field's regionGeneration).
#include <cstdint>
#include <vector>

#include "sandtable/formats/height_field.h"

namespace sandtable::meshing {

/// Grid squares along a module edge at level 0: moduleSize / spacing,
/// rounded to a multiple of 2^(levels-1) (at least that) so every level's
/// lattice lands on grid posts. 1000 m at 31.25 m posts gives 32.
std::uint32_t moduleSquares(double moduleSize, double spacing, int levels);

/// Squares along a quadtree node edge, the same at every level: the
/// coarsest level is one node per module, and each finer level splits
/// every node into four (squares >> (levels - 1); 4 at 32 squares, 4 levels).
inline std::uint32_t nodeSquares(std::uint32_t squares, int levels) { return squares >> (levels - 1); }

/// Grid post columns (or rows) from `first` to `last` every `step`, `last`
/// always included.
std::vector<std::uint32_t> latticePosts(std::uint32_t first, std::uint32_t last, std::uint32_t step);

/// The grid window under one module and each level's posts in it.
struct ModuleWindow {
  std::uint32_t i0 = 0, j0 = 0, i1 = 0, j1 = 0;  ///< level-0 post range (inclusive)
  std::vector<std::vector<std::uint32_t>> cols, rows;  ///< per level, grid post indices
  int levels() const { return int(cols.size()); }
};

/// Module (kx, kz) of `squares` level-0 squares a side: posts
/// [kx * squares, kx * squares + squares], clamped to the grid's last post.
ModuleWindow moduleWindow(const grid::HeightField& g, std::uint32_t squares, int levels, std::uint32_t kx,
                          std::uint32_t kz);

/// One module level's lattice: where its posts are and their elevations.
/// Every level of one module has the same extent (xs.front()..xs.back(),
/// zs.front()..zs.back()); that extent and moduleX/moduleZ key the
/// culture decaler's cache.
struct LevelLattice {
  double moduleX = 0;  ///< world X of the module's NW corner (metres east of the grid origin)
  double moduleZ = 0;  ///< world Z of the module's NW corner (metres south of the grid origin)
  std::vector<double> xs;   ///< module-local x of each lattice column (size squaresX + 1)
  std::vector<double> zs;   ///< module-local z of each lattice row (size squaresZ + 1)
  std::vector<float> heights;  ///< (squaresZ + 1) * (squaresX + 1), row-major, from the grid
  double spacing = 0;  ///< nominal spacing of the level
  int level = 0;       ///< 0 is the finest
};

/// What a lattice reads at a post whose stored elevation is NaN or
/// infinite (only a damaged grid has one; validate reports it).
enum class NonFinite : std::uint8_t {
  keep,  ///< the stored value (the module builder: its own grid is finite)
  zero,  ///< 0 (the pager's placeholders: a damaged grid still draws)
};

/// Level `level` of window `w`: the posts' module-local positions
/// ((post - i0) * spacing) and the grid's elevations at them.
LevelLattice levelLattice(const grid::HeightField& g, const ModuleWindow& w, int level,
                          NonFinite nonFinite = NonFinite::keep);

/// Height of a level's drawn surface (SW-NE triangles, docs/FORMAT.md) at
/// level-0 post (i, j) of the window: linear on the lattice triangle that
/// holds the post.
double surfaceAt(const LevelLattice& lat, const ModuleWindow& w, int level, std::uint32_t i, std::uint32_t j);

}  // namespace sandtable::meshing
