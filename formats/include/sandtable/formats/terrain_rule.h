#pragma once
// The terrain contract, in one place (docs/FORMAT.md §2 and §9): how a grid
// square splits into two triangles and the plane over each, which grid
// posts a module level's lattice uses, and the skirts hung below the edges
// of a level's quadtree nodes. The module builder, the module decoder and
// validator, the ground clamp, the sampler, the simulator, the renderer and
// the converters all call these, so they agree by construction. Versions 3
// and later of the load module decode lattice triangles, plane heights and
// skirts from these rules: a change here changes what old files decode to,
// and the module golden-bytes tests catch it.
//
// Floating point: planeHeight and halfPlane are always inlined, so the
// module codec's copy is compiled with its translation unit's
// -ffp-contract=off (encoder and decoder must round alike on every
// machine; docs/FORMAT.md §9.8) whatever other callers are built with.
//
// Thread safety: pure functions over values; call from any thread.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sandtable/formats/module.h"

#if defined(__GNUC__) || defined(__clang__)
#define SANDTABLE_TERRAIN_INLINE [[gnu::always_inline]] inline
#else
#define SANDTABLE_TERRAIN_INLINE inline
#endif

namespace sandtable::terrain {

// ------------------------------------------------------------ the split

/// A grid square's corners; every four-corner array here is in this order.
/// Bit 0 is east, bit 1 south: corner c is post (i + east(c), j + south(c)).
enum Corner : std::uint8_t { kNW = 0, kNE = 1, kSW = 2, kSE = 3 };
constexpr std::uint32_t east(Corner c) { return c & 1u; }
constexpr std::uint32_t south(Corner c) { return c >> 1u; }

/// The half of a square holding the point (fx, fz), the fractions of the
/// square east and south of its north-west corner (0..1). The square splits
/// along its SW-NE diagonal, fx + fz = 1: the upper half holds the NW corner
/// and the diagonal itself, the lower half the SE corner (seed Figures 14,
/// 15).
constexpr module::Half halfAt(double fx, double fz) {
  return fx + fz <= 1.0 ? module::Half::upper : module::Half::lower;
}

/// Each half's corners in the builder's vertex order (a lattice triangle is
/// written exactly so): upper NW, SW, NE; lower NE, SW, SE.
inline constexpr std::array<std::array<Corner, 3>, 2> kHalfCorners = {{{kNW, kSW, kNE}, {kNE, kSW, kSE}}};

/// The three of `corners` (NW, NE, SW, SE) that make up half `half` (upper
/// or lower), in kHalfCorners' order.
template <typename T>
constexpr std::array<T, 3> halfCorners(module::Half half, const std::array<T, 4>& corners) {
  const auto& c = kHalfCorners[half == module::Half::lower ? 1 : 0];
  return {corners[c[0]], corners[c[1]], corners[c[2]]};
}

/// Height at (fx, fz) on the plane of half `half` through the corner
/// heights: each half's plane is written from its own right-angle corner
/// (NW or SE), so a post's height comes back exactly at the post. Corner
/// differences are taken in the heights' own type H (float for a module's
/// vertices, double for a grid's elevations), the products in double.
template <typename H>
SANDTABLE_TERRAIN_INLINE constexpr double halfPlane(module::Half half, double fx, double fz, H nw, H ne, H sw, H se) {
  if (half != module::Half::lower) return nw + fx * (ne - nw) + fz * (sw - nw);
  return se + (1.0 - fx) * (sw - se) + (1.0 - fz) * (ne - se);
}

/// Height of the square's surface at (fx, fz): the plane of the half that
/// holds the point. Both planes, then a select: which half a point lies in
/// is close to random for the decoder's culture vertices, and a
/// mispredicted branch costs more than the other half's arithmetic.
template <typename H>
SANDTABLE_TERRAIN_INLINE constexpr double planeHeight(double fx, double fz, H nw, H ne, H sw, H se) {
  const double upper = halfPlane(module::Half::upper, fx, fz, nw, ne, sw, se);
  const double lower = halfPlane(module::Half::lower, fx, fz, nw, ne, sw, se);
  return halfAt(fx, fz) == module::Half::upper ? upper : lower;
}

/// The weights of the corners (NW, NE, SW, SE) at (fx, fz) on the half
/// that holds it (barycentric; the far corner's is 0): for interpolating
/// anything stored per post (normals, water, a least-squares fit).
constexpr std::array<double, 4> cornerWeights(double fx, double fz) {
  if (halfAt(fx, fz) == module::Half::upper) return {1.0 - fx - fz, fx, fz, 0.0};
  return {0.0, 1.0 - fz, 1.0 - fx, fx + fz - 1.0};
}

/// A point's grid square and its place in it.
struct SquarePoint {
  std::uint32_t i = 0, j = 0;  ///< the square's north-west post
  double fx = 0, fz = 0;       ///< fractions east and south of it (0..1)
};

/// The square of a grid of postsX x postsZ posts holding post coordinates
/// (u, v) (metres over the spacing), clamped onto the grid; a point on the
/// east or south edge lies in the last square (fraction 1). A grid one
/// post wide has its only post as square 0.
constexpr SquarePoint squareAt(double u, double v, std::uint32_t postsX, std::uint32_t postsZ) {
  const double maxI = double(postsX - 1), maxJ = double(postsZ - 1);
  const double uc = std::clamp(u, 0.0, maxI), vc = std::clamp(v, 0.0, maxJ);
  SquarePoint p;
  p.i = std::uint32_t(std::min(std::floor(uc), std::max(0.0, maxI - 1)));
  p.j = std::uint32_t(std::min(std::floor(vc), std::max(0.0, maxJ - 1)));
  p.fx = uc - p.i;
  p.fz = vc - p.j;
  return p;
}

// ---------------------------------------------------------- the lattice

/// The grid posts of one lattice axis of a module level: from the module's
/// first post every `step` (2^level) posts, with the module's last post
/// always kept, so a module at the database's east or south edge has a
/// narrower last square at coarse levels (docs/FORMAT.md §9).
inline std::vector<std::uint32_t> latticePosts(std::uint32_t first, std::uint32_t last, std::uint32_t step) {
  std::vector<std::uint32_t> posts;
  for (std::uint32_t p = first; p < last; p += step) posts.push_back(p);
  posts.push_back(last);
  return posts;
}

/// One interval of a lattice axis: neighbouring lattice posts a < b.
struct LatticeSpan {
  std::uint32_t a = 0, b = 0;
  /// Where post coordinate u lies between a and b, 0..1.
  constexpr double fraction(double u) const { return std::clamp((u - a) / double(b - a), 0.0, 1.0); }
};

/// The interval of latticePosts(first, last, step) that holds post
/// coordinate u (first <= u <= last; a point on an inner lattice post
/// belongs to the interval it starts, the last post to the last interval).
constexpr LatticeSpan latticeSpan(double u, std::uint32_t first, std::uint32_t last, std::uint32_t step) {
  const double k = std::floor((u - first) / step);
  std::uint32_t a = first + std::uint32_t(std::max(0.0, k)) * step;
  if (a >= last) a = first + ((last - first - 1) / step) * step;
  return {a, std::min(a + step, last)};
}

/// The square (column or row) of a module level's lattice, n squares of
/// nominal spacing `spacing` along the axis, that holds module-local
/// coordinate c: the nominal spacing decides, clamped to 0 .. n-1 (the last
/// square may be narrower; a coordinate that is not a number is in square 0).
constexpr std::uint32_t latticeCell(double c, double spacing, std::uint32_t n) {
  const double f = c / spacing;
  if (!(f > 0)) return 0;
  if (f >= double(n)) return n - 1;
  return std::uint32_t(f);
}

/// The first grid post of the module holding post coordinate u along an
/// axis of posts 0..lastPost, for modules of `squares` level-0 squares
/// (module k spans posts k * squares .. k * squares + squares, clamped).
constexpr std::uint32_t moduleFirstPost(double u, std::uint32_t squares, std::uint32_t lastPost) {
  const auto k = std::min(std::uint32_t(u / squares), (lastPost - 1) / squares);
  return k * squares;
}

/// The last grid post of the module starting at post `first`.
constexpr std::uint32_t moduleLastPost(std::uint32_t first, std::uint32_t squares, std::uint32_t lastPost) {
  return std::min(first + squares, lastPost);
}

// ----------------------------------------------------------- the skirts

/// Vertices, indices and groups that skirts add to a level of sx x sz
/// lattice squares with quadtree nodes of `node` squares.
struct SkirtCounts {
  std::uint64_t vertices = 0, indices = 0, groups = 0;
};

constexpr SkirtCounts skirtCounts(std::uint64_t sx, std::uint64_t sz, std::uint64_t node) {
  const std::uint64_t nx = (sx + node - 1) / node, nz = (sz + node - 1) / node;
  return {2 * nz * (sx + nx) + 2 * nx * (sz + nz), 12 * (nz * sx + nx * sz), nx * nz};
}

/// One side of a node: lattice posts (a0, b0) to (a1, b1) (column, row),
/// along a row (b0 == b1) or a column (a0 == a1).
struct SkirtSide {
  std::size_t a0 = 0, b0 = 0, a1 = 0, b1 = 0;
  /// Lattice posts along the side, ends included.
  constexpr std::size_t posts() const { return std::max(a1 - a0, b1 - b0) + 1; }
  /// Column and row of its k-th post.
  constexpr std::size_t column(std::size_t k) const { return a0 == a1 ? a0 : a0 + k; }
  constexpr std::size_t row(std::size_t k) const { return b0 == b1 ? b0 : b0 + k; }
};

/// Visits the quadtree nodes of a level of sx x sz lattice squares (nodes
/// of `node` squares; the last in a row or column may be narrower) in
/// row-major order: f(square, sides), where `square` is the node's
/// north-west square (its skirt group's square) and `sides` its north,
/// south, west and east sides, in the order their skirts are written.
template <typename F>
constexpr void forEachSkirtNode(std::size_t sx, std::size_t sz, std::size_t node, F&& f) {
  for (std::size_t nz = 0; nz < sz; nz += node) {
    for (std::size_t nx = 0; nx < sx; nx += node) {
      const std::size_t ax = nx, bx = std::min(nx + node, sx), az = nz, bz = std::min(nz + node, sz);
      const std::array<SkirtSide, 4> sides = {{{ax, az, bx, az}, {ax, bz, bx, bz}, {ax, az, ax, bz}, {bx, az, bx, bz}}};
      f(std::uint32_t(nz * sx + nx), sides);
    }
  }
}

/// The bottom vertex of a skirt below top vertex `top`: `depth` lower, with
/// texture coordinates 0.
constexpr module::Vertex skirtBottom(const module::Vertex& top, float depth) {
  return {top.x, top.y - depth, top.z, 0.0f, 0.0f};
}

/// The two triangles of the skirt quad below the lattice edge from top
/// vertex a to top vertex c, whose bottoms are ab and cb.
constexpr std::array<std::uint32_t, 6> skirtQuad(std::uint32_t a, std::uint32_t c, std::uint32_t ab,
                                                 std::uint32_t cb) {
  return {a, ab, c, c, ab, cb};
}

}  // namespace sandtable::terrain

#undef SANDTABLE_TERRAIN_INLINE
