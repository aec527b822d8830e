#pragma once
// Terrain level-of-detail choice for load modules (seed chapter IX.B.2,
// Figures 84-85, Table 8) and, beyond the seed, a screen-space-error mode
// with geomorphing. Design: docs/VIEWER.md, "Level of detail".
//
// Nodes (seed Figure 85). Every level l of a module with L levels carries
// skirts on the lines of a grid of 2^(L-1-l) x 2^(L-1-l) nodes of
// `nodeSquares` level-l squares each: the module's quadtree, with the
// whole module as the root at the coarsest level. A node at depth d (size
// edge / 2^d) has skirts on its edges at every level l <= L-1-d, so it may
// be drawn at any of them next to neighbours at other levels without a
// crack. Selection walks the tree from the root: a node whose wanted level
// is at least the coarsest it allows is drawn whole; otherwise its four
// children are visited.
//
// Rings: the level of a node is the first range bin that reaches the
// node's nearest point on the ground (seed: circle / rectangle test).
// Screen-space error: each level's geometric error is the largest vertical
// distance between that level's surface and the finest level's posts; the
// level drawn is the coarsest whose error, projected at the node's nearest
// 3-D point, stays within the requested pixels.
// Geomorphing: every vertex of level l moves towards the surface of level
// l + 1 by a factor m that is constant over the node, so each morphed
// triangle stays planar and decals stay exactly on the skin; m reaches 1
// exactly where the node switches to l + 1, so nothing pops. With
// LodOptions::shareMorph (sse), one module's nodes of one level share the
// smallest of their factors: the error bound still holds, and a switch
// pops by at most the pixel budget.
//
// Thread safety: pure functions and plain values.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/morton.h"
#include "sandtable/formats/module.h"

namespace sandtable::scene {

enum class LodMode : std::uint8_t {
  rings,  ///< seed range rings (Table 8 bins), per module
  sse,    ///< screen-space error in pixels
  full,   ///< always the finest level (the reference case)
};
const char* lodModeName(LodMode m);

struct LodOptions {
  LodMode mode = LodMode::rings;
  /// Outer edge of each level's range bin, finest first, metres. Empty:
  /// Table 8's four equal bins scaled to the view distance.
  std::vector<double> rings;
  double pixelError = 2.0;  ///< sse: largest projected error, pixels
  bool morph = true;        ///< geomorph towards the next coarser level
  /// sse: every drawn node of one module and level takes the smallest
  /// morph among them, so same-level neighbours share their edges (no
  /// crack, no skirt drawn between them) and merge into long draws; a node
  /// switching level then pops by at most pixelError (docs/VIEWER.md,
  /// "Level of detail").
  bool shareMorph = true;
};

/// Quadtree nodes per side at `level` of a module with `levels` levels.
inline std::uint32_t nodesPerSide(std::uint32_t level, std::uint32_t levels) {
  return 1u << (levels - 1 - level);
}
/// Morton index of node (a, b): a in the even bits, b in the odd ones, so
/// child c (a bit 0 = c & 1, b bit 0 = c >> 1) of node n is 4 n + c and
/// every coarser node is a contiguous range of finer indices.
inline std::uint32_t mortonIndex(std::uint32_t a, std::uint32_t b) { return morton::encode(a, b); }
/// Morton index of the node holding row-major `square` of `level`.
std::uint32_t nodeOfSquare(const module::Level& level, std::uint32_t square,
                           std::uint32_t nodeSquares, std::uint32_t nodesPerSide);
/// Whether culture cut the level's skin (more than two triangles a square):
/// then the renderer draws the plain lattice under it (docs/VIEWER.md, "Seams").
bool needsUnderlay(const module::Level& level);
/// Triangles drawn per node in Morton order as prefix sums (size nodes + 1):
/// skin, skirts, decals and the underlay where needsUnderlay.
std::vector<std::uint64_t> nodeTrianglePrefix(const module::Level& level, std::uint32_t nodeSquares,
                                              std::uint32_t nodesPerSide);

/// "" or why the options are unusable (rings not ascending or not positive,
/// pixel error not positive).
std::string checkLodOptions(const LodOptions& o);

/// Height of a level's skin at module-local (x, z) on its lattice posts
/// (posts are the first vertices of every level, row by row; each square
/// splits along its SW-NE diagonal). nullopt when the level has no lattice.
std::optional<double> levelHeightAt(const module::Level& level, double x, double z);

/// Geometric error of every level against level `finest` (0 for it and for
/// finer ones), measured at `finest`'s posts: max |y_l(x, z) - y|.
std::vector<double> levelErrors(std::span<const module::Level> levels, std::uint32_t finest);

/// The same, per cell of the finest node grid (cellsPerSide = 2^(L-1)
/// cells of `cellSize` metres, Morton order): [level][cell]. A post on a
/// cell edge counts for every cell it touches; each cell's errors are made
/// monotonic over the levels. A node's error is the largest of its cells'.
std::vector<std::vector<double>> cellErrors(std::span<const module::Level> levels,
                                            std::uint32_t finest, double cellSize,
                                            std::uint32_t cellsPerSide);
/// Highest vertex of any level over each cell (Morton order), from the
/// levels' per-square maxHeight.
std::vector<float> cellMaxHeights(std::span<const module::Level> levels, std::uint32_t finest,
                                  double cellSize, std::uint32_t cellsPerSide);

/// Pixels per metre of error at distance 1 m: height / (2 tan(vfov / 2)).
double pixelsPerRadian(double vfovDeg, std::uint32_t imageHeight);

/// Projected error of `errorMetres` seen at `distance` metres, pixels.
double projectedError(double errorMetres, double distance, double pixelsPerRadian);

/// Ring level for a node whose nearest ground point is `distance` away.
std::uint32_t ringLevel(const LodOptions& o, double distance, double viewDistance,
                        std::uint32_t levels);

/// SSE level: the coarsest l >= finest whose error projects within the
/// pixel budget at `distance` (finest when none does).
std::uint32_t sseLevel(std::span<const double> errors, double distance, double pixelsPerRadian,
                       double pixelError, std::uint32_t finest);

/// Morph factor towards level + 1 in [0, 1].
/// Rings: ramps over the outer quarter of the level's bin, 1 at its edge.
double ringMorph(const LodOptions& o, std::uint32_t level, double distance, double viewDistance,
                 std::uint32_t levels);
/// SSE: the largest m with (1 - m) e_l + m e_{l+1} still within the
/// budget, which bounds the morphed surface's error; 1 where l + 1 is
/// itself good enough (where the node switches).
double sseMorph(std::span<const double> errors, std::uint32_t level, double distance,
                double pixelsPerRadian, double pixelError);

}  // namespace sandtable::scene
