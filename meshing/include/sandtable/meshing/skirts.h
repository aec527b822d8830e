#pragma once
// Skirts: vertical strips hanging below the edges of every quadtree node
// of a level, so that neither two modules nor two levels drawn side by side
// show a crack between them (docs/FORMAT.md, "module"; docs/ARCHITECTURE.md).
//
// Thread safety: pure functions over values and a read-only grid.
#include <cstdint>
#include <span>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/module.h"
#include "sandtable/meshing/lattice.h"

namespace sandtable::meshing {

/// Margin every skirt hangs below the lowest surface it must hide, metres.
inline constexpr double kSkirtMargin = 1.0;

/// How far each level's skirts must hang: the most any level's surface
/// lies below this level's along this level's node edges (every `node`
/// level-l squares, and the window's east and south edges), plus
/// kSkirtMargin. `lats` holds every level of the window, finest first.
std::vector<float> skirtDepths(const std::vector<LevelLattice>& lats, const ModuleWindow& w, std::uint32_t node);

/// A depth for a stand-in built without its other levels: the elevation
/// range of the grid blocks under the window, widened to include `seed`
/// (non-finite block bounds are skipped), at least 1 m. Deeper than
/// skirtDepths, and needs no surfaces: the block table holds the range.
float blockRangeDepth(const grid::GridFile& g, const ModuleWindow& w, float seed);

/// Adds skirts along all four sides of every quadtree node of the level (a
/// node is `node` lattice squares a side; the last may be narrower), one
/// group per node keyed by the node's north-west square, with `material`,
/// hanging `depth` below the lattice posts. Lattice vertices already in
/// the level at exactly a post's position and height are shared; the
/// groups are merged into the level's order (priority, square, half,
/// material) with the indices kept contiguous per group. The level's
/// index storage keeps its capacity when it suffices. Returns the skirt
/// triangles added.
/// `lineVertices` (dynamic terrain: the fine vertices of a refined square
/// on its edges) are level vertices lying exactly on a lattice line
/// between two posts: a node side along that line takes them as top
/// vertices too, in order, so its skirt follows the surface's edge between
/// the posts. Empty (the builder): the skirts above, unchanged.
std::uint64_t addSkirts(module::Level& level, const LevelLattice& lat, std::uint32_t node, float depth,
                        std::uint16_t material, std::span<const std::uint32_t> lineVertices = {});

}  // namespace sandtable::meshing
