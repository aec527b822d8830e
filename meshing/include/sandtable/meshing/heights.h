#pragma once
// Per-square heights: the highest vertex of each grid square of a level
// (module::Level::maxHeight), which the runtime's ground clamp and the
// simulator's line of sight use without touching the triangles.
//
// Thread safety: pure functions; distinct levels from any threads.
#include "sandtable/formats/module.h"

namespace sandtable::meshing {

/// Sets level.maxHeight (squaresX * squaresZ, row-major) to the highest
/// vertex y of every skin and decal group of each square; skirts are left
/// out (they hang below the surface). A square with no group reads -inf.
void computeMaxHeights(module::Level& level);

}  // namespace sandtable::meshing
