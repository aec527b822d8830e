#pragma once
// Culture internals shared by culture_load.cpp (OGR reading, repair,
// widening, index), culture_cgal.cpp (the only file that includes CGAL:
// exact unions and the per-module planar partition) and culture_decal.cpp
// (cutting the partition to the terrain triangles in double precision).
// The pipeline is described in docs/CULTURE.md.
//
// Frames. Load works in world metres: X = easting - originEasting (east),
// Z = originNorthing - northing (south). Per-module work is in
// module-local metres (x = X - moduleX, z = Z - moduleZ). Orientation is
// always the mathematical one of the (x, z) plane taken as (x, y): a ring
// is positive ("counter-clockwise") when its shoelace area is positive.
// Seen on a north-up map (z pointing down the page) positive rings run
// clockwise; output triangles are flipped to the renderer's winding only
// when they are emitted.
#include <algorithm>
#include <array>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <limits>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "sandtable/converters/culture.h"

namespace sandtable::convert::culture {

struct Vec2 {
  double x = 0, z = 0;
  bool operator==(const Vec2&) const = default;
};
inline Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.z + b.z}; }
inline Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.z - b.z}; }
inline Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.z}; }
inline double dot(Vec2 a, Vec2 b) { return a.x * b.x + a.z * b.z; }
inline double cross(Vec2 a, Vec2 b) { return a.x * b.z - a.z * b.x; }
inline double length(Vec2 a) { return std::sqrt(a.x * a.x + a.z * a.z); }
/// Lexicographic (x, then z), the order CGAL sorts segment ends in.
inline bool lexLess(Vec2 a, Vec2 b) { return a.x < b.x || (a.x == b.x && a.z < b.z); }

/// A closed ring without its repeated first point.
using Ring = std::vector<Vec2>;
using Polyline = std::vector<Vec2>;

struct Box {
  double x0 = std::numeric_limits<double>::infinity(), z0 = x0;
  double x1 = -std::numeric_limits<double>::infinity(), z1 = x1;
  void add(Vec2 p) {
    x0 = std::min(x0, p.x), z0 = std::min(z0, p.z), x1 = std::max(x1, p.x), z1 = std::max(z1, p.z);
  }
  void add(const Box& b) { x0 = std::min(x0, b.x0), z0 = std::min(z0, b.z0), x1 = std::max(x1, b.x1), z1 = std::max(z1, b.z1); }
  bool empty() const { return !(x0 <= x1 && z0 <= z1); }
  bool overlaps(const Box& b) const { return x0 <= b.x1 && b.x0 <= x1 && z0 <= b.z1 && b.z0 <= z1; }
  Box grown(double m) const { return {x0 - m, z0 - m, x1 + m, z1 + m}; }
};

/// Shoelace area: positive for counter-clockwise rings in (x, z).
double signedArea(const Ring& r);
Box boxOf(const Ring& r);

/// Sutherland-Hodgman clip of a ring to an axis-aligned rectangle. The
/// result may hold zero-width bridges along the rectangle's edges, but its
/// winding number equals the input's at every point strictly inside the
/// rectangle, which is all the planar partition needs. Crossing points are
/// computed from the segment's ends in lexicographic order, so a segment
/// clipped by two neighbouring rectangles yields the same point on their
/// shared edge, bit for bit.
Ring clipRingToRect(const Ring& ring, const Box& rect);

/// Closed outline of a polyline widened to `width` (butt ends; mitre joins
/// whose tip lies within one width of the vertex, else bevel), built so
/// that its nonzero-winding region is exactly the union of the segment
/// rectangles and the joins: the inner side of a bend runs through the
/// vertex. Closed polylines (first == last) give two rings, the road's two
/// sides. Appends to `out`.
void outlineOf(const Polyline& line, double width, std::vector<Ring>& out);

/// Segments per chunk of a widened line (see widenLine).
inline constexpr std::size_t kWidenChunk = 32;

/// Thrown by long culture work when the build is cancelled
/// (convert::requestCancel); callers turn it into "cancelled".
struct Cancelled {};

/// The widened polygon of one line feature: outlineOf for every part, and
/// an octagon at each end marked in joinStart/joinEnd, united by nonzero
/// winding. The outline is cut into chunks of kWidenChunk segments that
/// overlap by one segment (so every join lies inside a chunk); each chunk
/// is united on its own and the results are united pairwise. An
/// arrangement of one chunk is small whatever the line does, and each
/// pairwise union sees only two union boundaries, so a line that folds
/// back on itself within its width costs about n log n, not n^2
/// (docs/CULTURE.md, "Bounded work"). Checks the cancel flag between
/// unions and throws Cancelled. Throws std::exception on CGAL failure.
/// Each union's rings are simplified (simplifiedLine) before the next, at
/// tolerance / 2 for the chunks, / 4 for their unions, and so on: union
/// moves no boundary further than its inputs moved, so the result lies
/// within `tolerance` of the exact union.
std::vector<Ring> widenLine(const std::vector<Polyline>& parts, const std::vector<bool>& joinStart,
                            const std::vector<bool>& joinEnd, double width, double tolerance);

/// The size rule's base tolerance for a line of `width` (docs/CULTURE.md,
/// "Bounded work"): max(merge tolerance, width / 100).
inline double simplifyTolerance(double width, double mergeTolerance) { return std::max(mergeTolerance, width / 100.0); }

/// Douglas-Peucker (GEOS, through OGR's Simplify) of a polyline at `tol`:
/// a subset of its vertices, ends kept, no vertex more than `tol` from the
/// result. The line itself when simplifying would collapse it (a loop to
/// fewer than four points).
Polyline simplifiedLine(const Polyline& p, double tol);

/// The join piece where line ends meet (see culture_geometry.cpp).
Ring octagon(Vec2 c, Vec2 from, double width);

// ------------------------------------------------------------ CGAL side

/// Union by nonzero winding of positive rings (holes negative). Returns
/// the union's boundary: outer rings positive, holes negative, collinear
/// vertices removed. Exact (CGAL arrangement, Epeck), rounded once to
/// double at the end. Throws std::exception on CGAL failure.
std::vector<Ring> unionRings(const std::vector<Ring>& rings);

/// A footprint's interior as triangles (CGAL constrained Delaunay of every
/// ring's edges; a triangle is kept where an odd number of rings encloses
/// it, so holes such as courtyards stay open). Any orientation in, CGAL's
/// (counter-clockwise in (x, z)) out. Throws std::exception on CGAL failure.
std::vector<std::array<Vec2, 3>> roofTriangles(const std::vector<Ring>& rings);

/// Label of no class (decal layers: not covered).
inline constexpr std::uint16_t kNone = materials::kNoClass;

/// One class present in a module, and whether it is skin (area) or decal.
struct SlotInfo {
  std::uint16_t classId = 0;
  bool skin = true;
  std::uint16_t rank = 0;
};

/// A ring clipped to the module, tagged with its class slot.
struct CellRing {
  Ring pts;
  std::uint16_t slot = 0;
};

/// Everything the planar partition of one module needs, module-local.
struct CellInput {
  Box rect;
  std::uint16_t defaultClass = 0;
  std::vector<SlotInfo> slots;
  std::vector<CellRing> rings;
};

/// A strictly convex polygon of one label, positive orientation.
struct Piece {
  std::uint16_t label = kNone;
  Box box;
  Ring pts;
};

struct Seg {
  Vec2 a, b;
};

/// The partition of one layer (the skin, or one decal class) over a module.
struct LayerGeometry {
  bool skin = true;
  std::uint16_t classId = kNone;   ///< decal class (skin: unused)
  std::uint16_t uniform = kNone;   ///< label of the whole module when bounds is empty (kNone: nothing)
  std::vector<Piece> pieces;       ///< convex pieces tiling the labelled area
  std::vector<Seg> bounds;         ///< where the label changes inside the module
};

/// Builds every layer of one module: an exact arrangement of all rings
/// with per-class winding numbers on its faces, the skin label of each face
/// by rank, then per layer a constrained triangulation of the label
/// boundaries merged into convex pieces (Hertel-Mehlhorn). Throws
/// std::exception on CGAL failure. Layer 0 is the skin.
/// CPU seconds of buildCell's two parts (threadCpuSeconds).
struct CellTimes {
  double arrangement = 0;  ///< arrangement and face windings
  double pieces = 0;       ///< constraints, triangulation, convex merge, rounding
};
std::vector<LayerGeometry> buildCell(const CellInput& in, CellTimes* times = nullptr);

// ------------------------------------------------------------ loaded data

struct AreaFeature {
  std::uint16_t classId = 0;
  std::vector<Ring> rings;  ///< world metres, outer positive, holes negative
  Box box;
};

/// A footprint of an extruded class (materials::Class::extrude): walls and
/// a flat roof at priority 99 instead of skin (docs/CULTURE.md, "Buildings").
struct BuildingFeature {
  std::uint16_t classId = 0;
  std::vector<Ring> rings;  ///< world metres, outer positive, holes negative
  Box box;
  double height = 0;  ///< metres from its lowest ground to the roof
  double area = 0;    ///< m^2, holes taken out
  Vec2 centre() const { return {(box.x0 + box.x1) / 2, (box.z0 + box.z1) / 2}; }
};

struct LineFeature {
  std::uint16_t classId = 0;
  double width = 0;
  std::vector<Polyline> parts;  ///< centrelines, world metres, clipped near the database
  std::vector<Ring> outline;    ///< the widened polygon (union), world metres
  Box box;                      ///< of the outline
  std::vector<bool> joinStart, joinEnd;  ///< per part: end shared with another line's end
};

/// A centreline segment for texture coordinates, module-local.
struct CentreSeg {
  Vec2 a, b;
  double along = 0;  ///< metres along the part at a
  double width = 0;
};

/// One module's partition, ready for any level (cached across levels).
struct ModuleCell {
  double moduleX = 0, moduleZ = 0;
  Box rect;  ///< module-local
  struct Layer {
    LayerGeometry geo;
    std::uint8_t priority = 1;
    std::vector<CentreSeg> centre;  ///< decal layers
  };
  std::vector<Layer> layers;  ///< [0] skin; decals by (priority, class id)
  std::uint64_t failures = 0;  ///< 1 when CGAL failed and the module fell back to default skin
  double gatherSeconds = 0;    ///< CPU seconds building it: candidates clipped to the module
  CellTimes times;             ///< and buildCell
};

/// The Culture implementation: immutable after load except for the cache
/// of module partitions (mutex-protected).
class CultureImpl final : public Culture {
 public:
  CultureImpl(const materials::Table& table, const CultureFrame& frame, const CultureOptions& options);
  const CultureStats& stats() const override { return stats_; }
  const std::vector<PointFeature>& points() const override { return points_; }
  DecalStats decalLevel(const LevelLattice& lattice, module::Level& out) const override;

  // Filled by load().
  materials::Table table;
  CultureFrame frame;
  CultureOptions options;
  CultureStats stats_;
  std::vector<AreaFeature> areas;
  std::vector<LineFeature> lines;
  std::vector<PointFeature> points_;
  std::vector<BuildingFeature> buildings;
  /// Spatial index: features whose box overlaps each index cell; buildings
  /// by the cell of their centre (the module holding it draws them whole).
  double indexCell = 500.0;
  std::uint32_t indexCols = 0, indexRows = 0;
  std::vector<std::vector<std::uint32_t>> areaIndex, lineIndex, buildingIndex;
  /// Appends the walls and roofs of the buildings whose centre lies in the
  /// lattice's module to `out` at priority 99 (culture_buildings.cpp).
  void addBuildings(const LevelLattice& lattice, module::Level& out, DecalStats& st) const;
  void buildIndex();

  /// The partition of the module the lattice belongs to (cached).
  /// `built` (may be null) is set when this call computed it.
  std::shared_ptr<const ModuleCell> cellFor(const LevelLattice& lattice, bool* built = nullptr) const;

 private:
  std::shared_ptr<const ModuleCell> computeCell(double moduleX, double moduleZ, const Box& rect) const;

  struct CacheEntry {
    std::shared_ptr<const ModuleCell> cell;  ///< null while being computed
  };
  mutable std::mutex cacheMutex_;
  mutable std::condition_variable cacheReady_;
  mutable std::list<std::pair<std::string, CacheEntry>> cache_;  ///< most recent first
  std::size_t cacheCapacity_ = 16;
};

}  // namespace sandtable::convert::culture
