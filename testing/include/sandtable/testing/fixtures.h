#pragma once
// Module and grid fixtures shared by the unit tests of meshing, paging and
// the viewer (they were written out in each). Test-only; not thread-safe.
#include <cstdint>
#include <functional>
#include <string>

#include "sandtable/base/result.h"
#include "sandtable/formats/module.h"

namespace sandtable::fixtures {

/// Elevation of grid post (i, j).
using PostElevation = std::function<float(std::uint32_t i, std::uint32_t j)>;

/// Writes a px x pz grid at `path` (posts `spacing` apart, origin
/// (originE, originN), flat normals) with the elevation `f`.
Status writeGrid(const std::string& path, std::uint32_t px, std::uint32_t pz, double spacing,
                 const PostElevation& f, double originE = 500000.0, double originN = 4000000.0);

/// The skin of an n x n lattice of posts already in `lv.vertices` (row by
/// row, (n + 1)^2 of them): two triangles a square split along its SW-NE
/// diagonal, one group each, in square order; and maxHeight per square
/// from its corners.
void addLatticeSkin(module::Level& lv, std::uint32_t n);

}  // namespace sandtable::fixtures
