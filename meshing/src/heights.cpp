// Per-square heights (heights.h).
#include "sandtable/meshing/heights.h"

#include <algorithm>
#include <limits>

namespace sandtable::meshing {

void computeMaxHeights(module::Level& level) {
  level.maxHeight.assign(std::size_t(level.squaresX) * level.squaresZ, -std::numeric_limits<float>::infinity());
  for (const module::Group& g : level.groups) {
    // docs/FORMAT.md 9.3: skin and decals only; objects (buildings) stand above.
    if (g.half == module::Half::skirt || g.priority >= module::kPriorityObject) continue;
    float& top = level.maxHeight[g.square];
    for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; ++k) {
      top = std::max(top, level.vertices[level.indices[k]].y);
    }
  }
}

}  // namespace sandtable::meshing
