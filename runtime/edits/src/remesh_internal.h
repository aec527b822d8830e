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
#include <map>
#include <memory>
#include <optional>
#include <tuple>
#include <unordered_map>
#include <span>
#include <utility>
#include <vector>

#include "remesh_cgal.h"
#include "sandtable/edits/modules.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/scatter.h"

namespace sandtable::edits::detail {

// ------------------------------------------------- squares that take patches

/// Height at fraction t (0..1) along the level-0 grid edge from post (i, j)
/// to (i, j + 1) (vertical) or (i + 1, j): the west (north) square's patch
/// where it reaches the edge at t, else the east (south) square's, else the
/// straight line between the posts. The one rule for a point on a grid
/// edge, so the squares on both sides (in one module or two) give the same
/// bits.
double edgeHeight(const grid::HeightField& h, std::uint32_t i, std::uint32_t j, bool vertical, double t);

/// How far a level may leave out a patch's detail: a lattice square takes
/// its patches when their largest departure from the grid squares' planes
/// exceeds both this and the square's own geometric error (docs/DYNAMIC.md).
inline constexpr double kDetailFloor = 0.01;

/// Sides of a square as bits.
enum SideBit : std::uint8_t { kNorth = 1, kSouth = 2, kWest = 4, kEast = 8 };

/// A lattice square of one level that takes the refined patches inside it
/// (docs/DYNAMIC.md, "Re-meshing"): at level 0 every refined grid square;
/// at a coarser level a full lattice square whose patches' detail matters
/// by the levels' error rule. Its fine units: `cells` per grid square (the
/// finest patch in it), span * cells per side.
struct Target {
  int level = 0;
  std::uint32_t gi = 0, gj = 0;  ///< its north-west grid post
  std::uint32_t span = 1;        ///< grid squares a side (2^level)
  std::uint32_t cells = 0;       ///< fine units per grid square
  /// The fine region: disjoint rectangles of fine squares, a0 <= a < a1,
  /// b0 <= b < b1 in the target's fine units (each a patch, less the rows
  /// and columns along an edge whose far side draws no patch there).
  struct Rect {
    std::uint32_t a0 = 0, b0 = 0, a1 = 0, b1 = 0;
  };
  std::vector<Rect> rects;
  bool regionKnown = false;
  double n() const { return double(span) * cells; }
  /// Whether (u, v) (fine units) lies in the fine region, borders included.
  bool inRegion(double u, double v) const {
    for (const Rect& r : rects) {
      if (u >= r.a0 && u <= r.a1 && v >= r.b0 && v <= r.b1) return true;
    }
    return false;
  }
};

/// Which lattice squares take patches, and their fine regions and edge
/// points, from the heights alone (so neighbouring modules agree);
/// memoised for one rebuild. Not thread-safe.
class Patches {
 public:
  explicit Patches(const grid::HeightField& h) : h_(h) {}
  const grid::HeightField& heights() const { return h_; }
  /// The target of `level` whose north-west grid post is (gi, gj) (aligned
  /// to 2^level), or null when that lattice square takes no patch.
  Target* target(int level, std::uint32_t gi, std::uint32_t gj);
  /// Its fine region (computed on first use).
  const std::vector<Target::Rect>& region(Target& t);
  /// Fractions (0 < f < 1) along side `s` of `t` at which its fine region
  /// has posts, appended to `out`.
  void regionPostsOnSide(Target& t, SideBit s, std::vector<double>& out);
  /// The level-0 fine surface's departure from its grid square's planes at
  /// post coordinates (U, V): what a coarser level adds to its own planes.
  double detail(double U, double V) const;
  /// Height of side `s` of `t` at fraction f: level 0's edgeHeight; a
  /// coarser level's straight side plus the detail along it.
  double sideHeight(const Target& t, SideBit s, double f) const;
  /// Height of `t`'s surface at (u, v) fine units inside it: level 0 the
  /// patch's fine post; a coarser level its planes plus the detail.
  double interiorHeight(const Target& t, double u, double v) const;

 private:
  const grid::HeightField& h_;
  std::map<std::tuple<int, std::uint32_t, std::uint32_t>, std::optional<Target>> memo_;
};

/// A target's new triangles: the fine lattice inside its fine region and a
/// constrained triangulation of the rest of the square, along its diagonal.
struct SquareMesh {
  const Target* target = nullptr;
  double n = 1;  ///< fine units per side
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
  /// Triangles of each fine square: key a * 2^32 + b -> [first, end) in tris.
  std::unordered_map<std::uint64_t, std::pair<std::uint32_t, std::uint32_t>> fineTris;
  std::uint32_t restBegin = 0;  ///< tris[restBegin..] are the rest region's
};

/// The mesh of target `t`, its corners at heights `cornerY` (NW, NE, SW,
/// SE: the level's lattice vertices), or false when its triangles would be
/// the square's own (an empty fine region and no neighbour's edge points).
bool meshTarget(Patches& p, Target& t, const std::array<double, 4>& cornerY, SquareMesh& out);

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
  std::uint64_t refinedSquares = 0;  ///< level-0 targets meshed
  std::vector<std::uint64_t> patchSquares;  ///< per level, targets meshed
};

/// Module (kx, kz) rebuilt at every level from its base and the heights now.
module::Module rebuildModule(const RebuildInput& in, RebuildStats& stats);

/// Sets every level's objectY: module::placeBases, then, where a level
/// takes a patch, that level's surface there (its planes plus the detail).
void placeObjects(module::Module& m, const grid::HeightField& h, std::uint32_t squares);

}  // namespace sandtable::edits::detail
