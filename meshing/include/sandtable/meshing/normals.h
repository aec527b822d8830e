#pragma once
// Per-vertex normals of a load module (module::Level::normals, docs/FORMAT.md
// §2 "Normals"): the HeightField's post normals interpolated on the grid
// triangle under each vertex, as the renderer samples them, so a lattice
// vertex gets its post's normal exactly; rounded to kNormalBits significant
// bits per octahedral component so they compress. The module builder and
// dynamic terrain's re-mesher (runtime/edits) both call these, so a
// re-meshed module's normals are the builder's where the ground is as built.
//
// Thread safety: pure functions over a HeightField (its thread contract).
#include <array>
#include <cstdint>

#include "sandtable/formats/height_field.h"
#include "sandtable/formats/module.h"

namespace sandtable::meshing {

/// Significant bits kept of each snorm16 octahedral component: 2^-9 on the
/// octahedron is under 0.2 degrees.
inline constexpr int kNormalBits = 10;

/// The field's normal at world (x, z) metres from its north-west post,
/// interpolated on the SW-NE grid triangle there (not normalised).
std::array<double, 3> gridNormal(const grid::HeightField& g, double x, double z);

/// A normal (any length) octahedral-encoded and rounded to kNormalBits.
std::uint32_t packNormal(const std::array<double, 3>& n);

/// Fills every level's normals of module m (module-local vertices; the
/// module's north-west corner at post (kx, kz) * squares) from gridNormal.
void fillNormals(const grid::HeightField& g, std::uint32_t squares, module::Module& m);

}  // namespace sandtable::meshing
