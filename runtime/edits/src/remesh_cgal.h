#pragma once
// The re-mesher's CGAL calls (remesh_cgal.cpp, an object library of its own
// built with -frounding-math: runtime/CMakeLists.txt): a refined square's
// rest-of-square triangulation and the clipping of a decal triangle
// against the new triangles (docs/DYNAMIC.md, "Re-meshing").
//
// Thread safety: pure functions.
#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace sandtable::edits::detail {

/// A point of a grid square in its patch's fine units: u east, v south of
/// its north-west post, 0 .. n (n = the patch's cells). Fine posts are
/// whole numbers and a neighbour's finer posts dyadic fractions, so every
/// point the re-mesher triangulates is exact in double.
struct UV {
  double u = 0, v = 0;
  bool operator==(const UV&) const = default;
};

/// The constrained Delaunay triangulation of `points` (exact predicates)
/// with the segments `constraints` (pairs of indices; they may meet only at
/// their ends): every finite face, as indices into `points`,
/// counter-clockwise in (u, v).
void constrainedTriangulation(std::span<const UV> points, std::span<const std::pair<std::uint32_t, std::uint32_t>> constraints,
                              std::vector<std::array<std::uint32_t, 3>>& faces);

/// The part of triangle `a` inside triangle `b` (CGAL's Triangle_2
/// intersection): a convex polygon of three or more points, in either
/// orientation, or nothing when they share no area.
void intersectTriangles(const std::array<UV, 3>& a, const std::array<UV, 3>& b, std::vector<UV>& out);

}  // namespace sandtable::edits::detail
