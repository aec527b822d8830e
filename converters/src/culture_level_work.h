#pragma once
// Private to the culture decaler (culture_decal.cpp and the files below): one
// level of one module cut to its grid triangles (docs/CULTURE.md, "Cutting to
// the triangles"). LevelWork's methods live by concern:
//   culture_decal.cpp     the level's run, one grid triangle, one draw pass
//   culture_lookup.cpp    per-level lookups: squares, labels, candidate pieces
//   culture_clip.cpp      a grid triangle (Tri) and a piece clipped to it
//   culture_merge.cpp     points unified, merged within the tolerance, triangulated
//   culture_emit.cpp      groups, vertices and road texture coordinates written
// Thread safety: a LevelWork belongs to one thread.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "culture_internal.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::convert {
namespace culture {

using module::Group;
using module::Half;
using module::Level;
using module::Vertex;

inline constexpr double kSkinRepeat = 64.0;   ///< metres per repeat of a skin texture
inline constexpr double kSkinWrap = 4096.0;   ///< skin s, t offsets reduced modulo this (a multiple of the repeat)
inline constexpr double kDecalTextureSteps = 256;  ///< decal s and t are multiples of 1 / this
inline constexpr double kAreaEps = 1e-9;      ///< twice the area (m^2) below which a triangle is degenerate
inline constexpr double kTouchEps = 1e-7;     ///< metres: a boundary this close to a triangle edge does not cut it

inline constexpr std::uint8_t kVert = 1, kHorz = 2, kDiag = 4;

inline int bits(std::uint8_t v) { return (v & 1) + ((v >> 1) & 1) + ((v >> 2) & 1); }

/// One grid triangle of the level.
struct Tri {
  double x0 = 0, x1 = 0, z0 = 0, z1 = 0;
  bool upper = true;
  double xe = 0, ze = 0;  ///< its vertical and horizontal edge lines
  Vec2 c[3];              ///< corners, positive order
  std::uint8_t cb[3] = {};
  std::uint32_t cv[3] = {};  ///< lattice vertex of each corner
  double hNW = 0, hNE = 0, hSW = 0, hSE = 0;
  bool exactDiag = false;
  double quantum = 0;
  double ratioM = 1, ratioN = 1;  ///< dx : dz in lowest terms (exactDiag)
  Box box;

  /// > 0 on the SE side of the SW-NE diagonal, < 0 on the NW side.
  double f(Vec2 p) const { return (x1 - x0) * (p.z - z1) + (z1 - z0) * (p.x - x0); }
  bool insideDiag(double fv) const { return upper ? fv <= 0 : fv >= 0; }
  /// The point at fraction u from SW to NE on the diagonal's line (u may
  /// lie outside 0..1: later clips cut such points away). When the square's
  /// sides are in a small whole ratio dx : dz = m : n (lattice squares
  /// always are: posts apart) and its corners are multiples of `quantum`
  /// (the float spacing of the module's largest coordinate), the point is
  /// taken on the grid of steps (m, n) * quantum along the diagonal, so it
  /// is exactly on the diagonal in float too.
  Vec2 diagPoint(double u) const {
    const double dx = x1 - x0, dz = z1 - z0;
    if (exactDiag) {
      const double t = std::round(u * dx / (quantum * ratioM));
      return {x0 + t * quantum * ratioM, z1 - t * quantum * ratioN};
    }
    if (u == 0) return {x0, z1};
    if (u == 1) return {x1, z0};
    return {x0 + u * dx, z1 - u * dz};
  }
  double height(Vec2 p) const {
    const double fx = (p.x - x0) / (x1 - x0), fz = (p.z - z0) / (z1 - z0);
    return terrain::halfPlane(upper ? module::Half::upper : module::Half::lower, fx, fz, hNW, hNE, hSW, hSE);
  }
  Vec2 cornerOf(std::uint8_t b) const {
    for (int k = 0; k < 3; ++k) {
      if ((cb[k] & b) == b) return c[k];
    }
    return c[0];
  }
};


/// Does segment a-b cross the open interior of t (by more than kTouchEps)?
bool touches(const Seg& s, const Tri& t);
bool convexContains(const Ring& pts, Vec2 p);

struct CP {
  Vec2 p;
  std::uint8_t on = 0;
};

/// Clips a convex piece to the triangle: diagonal first, then its vertical
/// and horizontal edges. Crossing points depend only on the (ordered)
/// segment and the line, so neighbouring pieces and triangles agree.
void clipPiece(const Ring& piece, const Tri& t, std::vector<CP>& out, std::vector<CP>& tmp);

/// Per-level, per-layer lookups: which squares each piece may overlap and
/// which triangles a boundary crosses.
struct LevelLayer {
  std::vector<std::uint32_t> start;   ///< CSR over squares
  std::vector<std::uint32_t> pieces;
  std::vector<std::uint8_t> touched;  ///< per square: bit 0 upper, bit 1 lower
};

/// Nearest centreline for road texture coordinates: a bucket grid.
struct CentreIndex {
  double x0 = 0, z0 = 0, cell = 1;
  std::uint32_t cols = 1, rows = 1;
  std::vector<std::vector<std::uint32_t>> buckets;
};

CentreIndex indexCentre(const ModuleCell::Layer& layer, const Box& rect);

class LevelWork {
 public:
  LevelWork(const CultureImpl& culture, const ModuleCell& cell, const LevelLattice& lat, Level& out);


  DecalStats run();

 private:
  static double wrap(double v) { return v - kSkinWrap * std::floor(v / kSkinWrap); }
  float skinS(double x) const { return float((skinS0_ + x) / kSkinRepeat); }
  float skinT(double z) const { return float((skinT0_ + z) / kSkinRepeat); }
  /// v rounded to float. Through a volatile: GCC 12.2 at -O2 and above
  /// folds {double(float(x)), double(float(z))} into {x, z} (an SLP
  /// vectorizer bug; a two-line reproducer returns its input unchanged).
  static double toFloat(double v) {
    volatile float f = static_cast<float>(v);
    return f;
  }

  std::size_t colOf(double x) const;
  std::size_t rowOf(double z) const;

  Tri tri(std::size_t sq, int half) const;

  void prepare(std::size_t l);

  /// Label at a point of an untouched triangle: the piece that holds it.
  std::uint16_t labelAt(std::size_t l, std::size_t sq, Vec2 p) const;

  // ------------------------------------------------------------ one grid triangle

  struct SnapPoint {
    Vec2 p;                 ///< rounded to float: what is written
    std::uint8_t on = 0;    ///< kVert | kHorz | kDiag
    bool fixed = false;     ///< may not move (a merge here folded a polygon)
    std::uint32_t rep = 0;  ///< the point it merges into
  };
  struct Poly {
    std::uint32_t layer = 0;
    std::uint16_t label = 0;
    std::vector<std::uint32_t> ids;  ///< into points_, positive order
  };
  struct OutTri {
    std::uint32_t poly;
    std::uint32_t a, b, c;  ///< into points_, positive order
  };
  /// A decal layer's triangles in one grid triangle, indices in runIndices_.
  struct Run {
    std::uint32_t sq = 0;
    std::uint8_t half = 0;
    std::uint32_t first = 0, count = 0;
  };

  enum class Mode { none, whole, cut };

  void gridTriangle(std::size_t sq, int half);

  /// Cuts, merges and writes layers [first, end) of one grid triangle.
  void passTriangle(std::size_t sq, int half, const Tri& t, Vec2 centroid, std::size_t first, std::size_t end);

  static Vec2 round(Vec2 p) { return {toFloat(p.x), toFloat(p.z)}; }
  double roundStep(double v) const { return std::round(v / quantum_) * quantum_; }

  /// p as written: on the vertex step where the level has one, else
  /// rounded to float. Edge points keep their edge's coordinate (a
  /// multiple of the step); an inner point that the step would carry
  /// across the diagonal goes onto it (the step's points on the diagonal
  /// are exact) and becomes a diagonal point.
  CP placed(CP p, const Tri& t) const;
  double area2(const OutTri& o) const;

  /// Adds a point of the last polygon, as written (placed()).
  void addPoint(CP p, const Tri& t) { flat_.push_back({placed(p, t), polys_.size() - 1}); }

  /// Polygons of layers [first, end) in the triangle, points unified.
  void gather(std::size_t sq, const Tri& t, std::size_t first, std::size_t end);

  /// Merges points closer than the tolerance: corners never move, edge
  /// points move only along their edge (or onto its corners), inner points
  /// anywhere. Deterministic: by kind, then position. What happens to a
  /// point on an edge depends only on the points on that edge, so the two
  /// grid triangles sharing it (in this module or the next) agree.
  void snap(const Tri& t);

  /// The point at a corner of the triangle (added when no polygon has it).
  std::uint32_t cornerPoint(Vec2 corner, std::uint8_t on);

  /// Triangulates every merged polygon into tris_ (a fan when that is
  /// valid, else ear clipping). Returns false when a merge left a polygon
  /// that cannot be triangulated (folded); its merged points are then fixed
  /// for the next attempt.
  bool triangulate();

  /// Triangulates one merged polygon, keeping every vertex where it can:
  /// a vertex on a straight stretch of the outline (after a neighbouring
  /// sliver merged away) still lies on the grid triangle's edge that the
  /// next triangle, or the next module, has a vertex on.
  bool fanOrClip(std::uint32_t poly, std::vector<std::uint32_t>& m);

  /// Counts points left closer than the tolerance (a merge was refused).
  void countClose();

  // ------------------------------------------------------------ output

  void beginGroup(std::size_t sq, int half, std::uint8_t priority, std::uint16_t material);
  void endGroup();
  /// Appends a triangle given in positive order, flipped to the renderer's
  /// winding (counter-clockwise seen from above).
  static void triangle(std::vector<std::uint32_t>& to, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    to.insert(to.end(), {a, c, b});
  }

  /// Corner k of the triangle at point p, or -1.
  static int cornerAt(const Tri& t, const SnapPoint& s);

  void emit(std::size_t sq, int half, const Tri& t, bool skinOk, Vec2 centroid);

  /// Decal groups after all skin: per priority, square, half, class. Their
  /// vertices follow all skin vertices, so the module format can store
  /// their texture coordinates apart from the skin's derived ones.
  void flushDecals();

  /// Road texture coordinates (seed Figure 17): S along the nearest
  /// centreline in road widths, T across, 0 at the left edge (as the road
  /// runs, seen from above) and 1 at the right.
  void roadST(std::size_t l, Vec2 p, float& s, float& t) const;

  const CultureImpl& culture_;
  const ModuleCell& cell_;
  const LevelLattice& lat_;
  Level& out_;
  std::size_t nx_ = 0, nz_ = 0;
  double tol_ = 0.1;
  double quantum_ = 0;
  bool gridMultiple_ = false;
  bool stepped_ = false;  ///< vertices on CultureOptions::vertexStep
  double skinS0_ = 0, skinT0_ = 0;
  DecalStats stats_;
  std::vector<LevelLayer> layers_;
  std::vector<CentreIndex> centre_;
  std::vector<std::vector<Run>> runs_;
  std::vector<std::vector<std::uint32_t>> runIndices_;  ///< into decalVertices_
  std::vector<Vertex> decalVertices_;                   ///< appended after all skin
  // Scratch, reused across grid triangles.
  std::vector<Mode> modes_;
  std::vector<std::uint16_t> labels_;
  std::vector<CP> clipped_, clipTmp_;
  std::vector<std::pair<CP, std::size_t>> flat_;
  std::vector<std::size_t> order_;
  std::vector<std::uint32_t> pointOf_;
  std::vector<SnapPoint> points_;
  std::vector<Poly> polys_;
  std::vector<std::uint32_t> snapOrder_, reps_, mapped_, vertexOf_;
  std::vector<OutTri> tris_;
  std::vector<bool> polyUsed_;
};

}  // namespace culture
}  // namespace sandtable::convert
