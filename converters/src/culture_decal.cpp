// Culture::decalLevel: the module's exact partition (culture_cgal.cpp,
// cached across levels) cut to one level's grid triangles in double
// precision (docs/CULTURE.md, "Cutting to the triangles").
//
// A grid triangle that no label boundary of a layer crosses is one
// triangle (the fast path: the skin reuses the lattice vertices). Any
// other triangle gets every convex piece that may overlap it clipped to it
// (Sutherland-Hodgman against its three edges, diagonal first), the
// vertices merged within the tolerance without leaving its edges, and the
// pieces fanned into triangles in its plane.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <numbers>
#include <numeric>
#include <unordered_map>

#include "culture_internal.h"
#include "sandtable/converters/elevation.h"  // cancelRequested
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::convert {
namespace culture {
namespace {

using module::Group;
using module::Half;
using module::Level;
using module::Vertex;

constexpr double kSkinRepeat = 64.0;   ///< metres per repeat of a skin texture
constexpr double kSkinWrap = 4096.0;   ///< skin s, t offsets reduced modulo this (a multiple of the repeat)
constexpr double kDecalTextureSteps = 256;  ///< decal s and t are multiples of 1 / this
constexpr double kAreaEps = 1e-9;      ///< twice the area (m^2) below which a triangle is degenerate
constexpr double kTouchEps = 1e-7;     ///< metres: a boundary this close to a triangle edge does not cut it

constexpr std::uint8_t kVert = 1, kHorz = 2, kDiag = 4;

int bits(std::uint8_t v) { return (v & 1) + ((v >> 1) & 1) + ((v >> 2) & 1); }

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
    return terrain::halfPlane(upper ? Half::upper : Half::lower, fx, fz, hNW, hNE, hSW, hSE);
  }
  Vec2 cornerOf(std::uint8_t b) const {
    for (int k = 0; k < 3; ++k) {
      if ((cb[k] & b) == b) return c[k];
    }
    return c[0];
  }
};

/// Does segment a-b cross the open interior of t (by more than kTouchEps)?
bool touches(const Seg& s, const Tri& t) {
  double lo = 0, hi = 1;
  for (int k = 0; k < 3; ++k) {
    const Vec2 e = t.c[(k + 1) % 3] - t.c[k];
    const double len = length(e);
    const double fa = cross(e, s.a - t.c[k]) / len - kTouchEps, fb = cross(e, s.b - t.c[k]) / len - kTouchEps;
    if (fa <= 0 && fb <= 0) return false;
    if (fa > 0 && fb > 0) continue;
    const double r = fa / (fa - fb);
    if (fa <= 0) lo = std::max(lo, r);
    else hi = std::min(hi, r);
    if (lo >= hi) return false;
  }
  return lo < hi;
}

bool convexContains(const Ring& pts, Vec2 p) {
  const std::size_t n = pts.size();
  for (std::size_t k = 0; k < n; ++k) {
    if (cross(pts[(k + 1) % n] - pts[k], p - pts[k]) < -1e-9) return false;
  }
  return true;
}

struct CP {
  Vec2 p;
  std::uint8_t on = 0;
};

/// Clips a convex piece to the triangle: diagonal first, then its vertical
/// and horizontal edges. Crossing points depend only on the (ordered)
/// segment and the line, so neighbouring pieces and triangles agree.
void clipPiece(const Ring& piece, const Tri& t, std::vector<CP>& out, std::vector<CP>& tmp) {
  out.clear();
  tmp.clear();
  const double dx = t.x1 - t.x0, dz = t.z1 - t.z0, dd = dx * dx + dz * dz;
  {
    const std::size_t n = piece.size();
    Vec2 prev = piece[n - 1];
    double fp = t.f(prev);
    bool pin = t.insideDiag(fp);
    auto cut = [&](Vec2 p, double fpv, Vec2 q, double fqv) {
      if (lexLess(q, p)) std::swap(p, q), std::swap(fpv, fqv);
      const double s = fpv / (fpv - fqv);
      const Vec2 x = s == 0 ? p : s == 1 ? q : p + s * (q - p);
      const double u = ((x.x - t.x0) * dx + (t.z1 - x.z) * dz) / dd;
      return CP{t.diagPoint(u), kDiag};
    };
    for (std::size_t k = 0; k < n; ++k) {
      const Vec2 cur = piece[k];
      const double fc = t.f(cur);
      const bool cin = t.insideDiag(fc);
      if (cin) {
        if (!pin) tmp.push_back(cut(prev, fp, cur, fc));
        tmp.push_back({cur, std::uint8_t(fc == 0 ? kDiag : 0)});
      } else if (pin) {
        tmp.push_back(cut(prev, fp, cur, fc));
      }
      prev = cur, fp = fc, pin = cin;
    }
  }
  auto axis = [&](const std::vector<CP>& in, std::vector<CP>& res, bool xAxis, double v, bool keepGreater) {
    res.clear();
    const std::size_t n = in.size();
    if (n == 0) return;
    auto c = [&](Vec2 p) { return xAxis ? p.x : p.z; };
    auto inside = [&](Vec2 p) { return keepGreater ? c(p) >= v : c(p) <= v; };
    const std::uint8_t bit = xAxis ? kVert : kHorz;
    auto cut = [&](CP p, CP q) {
      if (lexLess(q.p, p.p)) std::swap(p, q);
      const double s = (v - c(p.p)) / (c(q.p) - c(p.p));
      const double o = s == 0 ? (xAxis ? p.p.z : p.p.x) : s == 1 ? (xAxis ? q.p.z : q.p.x)
                              : (xAxis ? p.p.z + s * (q.p.z - p.p.z) : p.p.x + s * (q.p.x - p.p.x));
      return CP{xAxis ? Vec2{v, o} : Vec2{o, v}, std::uint8_t(bit | (p.on & q.on))};
    };
    CP prev = in[n - 1];
    bool pin = inside(prev.p);
    for (std::size_t k = 0; k < n; ++k) {
      const CP cur = in[k];
      const bool cin = inside(cur.p);
      if (cin) {
        if (!pin) res.push_back(cut(prev, cur));
        res.push_back(cur);
      } else if (pin) {
        res.push_back(cut(prev, cur));
      }
      prev = cur, pin = cin;
    }
  };
  axis(tmp, out, true, t.xe, t.upper);
  axis(out, tmp, false, t.ze, t.upper);
  // Edge flags from the coordinates too; points on two edges are corners.
  out.clear();
  for (CP p : tmp) {
    if (p.p.x == t.xe) p.on |= kVert;
    if (p.p.z == t.ze) p.on |= kHorz;
    if (t.f(p.p) == 0) p.on |= kDiag;
    if (bits(p.on) >= 2) p.p = t.cornerOf(p.on), p.on = std::uint8_t(p.on & 7);
    if (!out.empty() && out.back().p == p.p) {
      out.back().on |= p.on;
      continue;
    }
    out.push_back(p);
  }
  while (out.size() > 1 && out.front().p == out.back().p) {
    out.front().on |= out.back().on;
    out.pop_back();
  }
  if (out.size() < 3) out.clear();
}

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

CentreIndex indexCentre(const ModuleCell::Layer& layer, const Box& rect) {
  CentreIndex ix;
  ix.x0 = rect.x0, ix.z0 = rect.z0;
  ix.cell = std::max({(rect.x1 - rect.x0) / 32.0, (rect.z1 - rect.z0) / 32.0, 1.0});
  ix.cols = std::uint32_t(std::ceil((rect.x1 - rect.x0) / ix.cell)) + 1;
  ix.rows = std::uint32_t(std::ceil((rect.z1 - rect.z0) / ix.cell)) + 1;
  ix.buckets.assign(std::size_t(ix.cols) * ix.rows, {});
  for (std::uint32_t k = 0; k < layer.centre.size(); ++k) {
    const CentreSeg& s = layer.centre[k];
    Box b;
    b.add(s.a), b.add(s.b);
    b = b.grown(s.width + 1.0);
    const auto col = [&](double x) { return std::uint32_t(std::clamp(std::floor((x - ix.x0) / ix.cell), 0.0, double(ix.cols - 1))); };
    const auto row = [&](double z) { return std::uint32_t(std::clamp(std::floor((z - ix.z0) / ix.cell), 0.0, double(ix.rows - 1))); };
    for (std::uint32_t r = row(b.z0); r <= row(b.z1); ++r) {
      for (std::uint32_t c = col(b.x0); c <= col(b.x1); ++c) ix.buckets[std::size_t(r) * ix.cols + c].push_back(k);
    }
  }
  return ix;
}

/// The level being decaled.
class LevelWork {
 public:
  LevelWork(const CultureImpl& culture, const ModuleCell& cell, const LevelLattice& lat, Level& out)
      : culture_(culture), cell_(cell), lat_(lat), out_(out) {
    nx_ = lat.xs.size() - 1;
    nz_ = lat.zs.size() - 1;
    tol_ = culture.options.mergeTolerance;
    double maxCoord = 0;
    for (double x : lat.xs) maxCoord = std::max(maxCoord, std::fabs(x));
    for (double z : lat.zs) maxCoord = std::max(maxCoord, std::fabs(z));
    // Spacing of floats at the largest coordinate.
    quantum_ = maxCoord > 0 ? std::ldexp(1.0, std::ilogb(maxCoord) - 23) : 0;
    auto multiple = [&](double v) { return quantum_ > 0 && std::fmod(v, quantum_) == 0; };
    // Vertices on a coarser step of whole powers of two give the module
    // format small integer x and z codes (FORMAT.md 9.8) instead of float
    // mantissas that do not compress. Only where every lattice line is on
    // that step, so that edge points stay exactly on their edge.
    const double step = culture.options.vertexStep;
    if (step > quantum_ && quantum_ > 0) {
      const double floatQuantum = quantum_;
      quantum_ = step;
      stepped_ = std::all_of(lat.xs.begin(), lat.xs.end(), multiple) &&
                 std::all_of(lat.zs.begin(), lat.zs.end(), multiple);
      if (!stepped_) quantum_ = floatQuantum;
    }
    gridMultiple_ = std::all_of(lat.xs.begin(), lat.xs.end(), multiple) &&
                    std::all_of(lat.zs.begin(), lat.zs.end(), multiple);
    skinS0_ = wrap(lat.moduleX);
    skinT0_ = wrap(lat.moduleZ);
  }

  DecalStats run() {
    out_.vertices.clear();
    out_.indices.clear();
    out_.groups.clear();
    out_.spacing = lat_.spacing;
    out_.squaresX = std::uint32_t(nx_);
    out_.squaresZ = std::uint32_t(nz_);
    // The lattice posts, shared by every skin triangle with a corner there.
    out_.vertices.reserve((nx_ + 1) * (nz_ + 1) * 2);
    for (std::size_t j = 0; j <= nz_; ++j) {
      for (std::size_t i = 0; i <= nx_; ++i) {
        out_.vertices.push_back({float(lat_.xs[i]), lat_.heights[j * (nx_ + 1) + i], float(lat_.zs[j]),
                                 skinS(lat_.xs[i]), skinT(lat_.zs[j])});
      }
    }
    const std::size_t nl = cell_.layers.size();
    layers_.resize(nl);
    centre_.resize(nl);
    runs_.assign(nl, {});
    runIndices_.assign(nl, {});
    for (std::size_t l = 0; l < nl; ++l) prepare(l);
    stats_.failures = cell_.failures;
    // Skin groups are written as each grid triangle is done (their order is
    // the square order); decal groups are kept per layer and appended after
    // all skin, in (priority, square, half, material) order.
    for (std::size_t sq = 0; sq < nx_ * nz_; ++sq) {
      for (int half = 0; half < 2; ++half) gridTriangle(sq, half);
    }
    flushDecals();
    stats_.triangles = out_.indices.size() / 3;
    return stats_;
  }

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

  std::size_t colOf(double x) const {
    const auto it = std::upper_bound(lat_.xs.begin(), lat_.xs.end(), x);
    const std::size_t k = std::size_t(it - lat_.xs.begin());
    return std::min(k == 0 ? 0 : k - 1, nx_ - 1);
  }
  std::size_t rowOf(double z) const {
    const auto it = std::upper_bound(lat_.zs.begin(), lat_.zs.end(), z);
    const std::size_t k = std::size_t(it - lat_.zs.begin());
    return std::min(k == 0 ? 0 : k - 1, nz_ - 1);
  }

  Tri tri(std::size_t sq, int half) const {
    const std::size_t sx = sq % nx_, sz = sq / nx_;
    Tri t;
    t.x0 = lat_.xs[sx], t.x1 = lat_.xs[sx + 1], t.z0 = lat_.zs[sz], t.z1 = lat_.zs[sz + 1];
    t.upper = half == 0;
    const std::size_t w = nx_ + 1;
    const std::uint32_t nw = std::uint32_t(sz * w + sx), ne = nw + 1, sw = std::uint32_t((sz + 1) * w + sx), se = sw + 1;
    t.hNW = lat_.heights[nw], t.hNE = lat_.heights[ne], t.hSW = lat_.heights[sw], t.hSE = lat_.heights[se];
    const Vec2 NW{t.x0, t.z0}, NE{t.x1, t.z0}, SW{t.x0, t.z1}, SE{t.x1, t.z1};
    if (t.upper) {
      t.xe = t.x0, t.ze = t.z0;
      t.c[0] = NW, t.c[1] = NE, t.c[2] = SW;
      t.cb[0] = kVert | kHorz, t.cb[1] = kHorz | kDiag, t.cb[2] = kVert | kDiag;
      t.cv[0] = nw, t.cv[1] = ne, t.cv[2] = sw;
    } else {
      t.xe = t.x1, t.ze = t.z1;
      t.c[0] = NE, t.c[1] = SE, t.c[2] = SW;
      t.cb[0] = kVert | kDiag, t.cb[1] = kVert | kHorz, t.cb[2] = kHorz | kDiag;
      t.cv[0] = ne, t.cv[1] = se, t.cv[2] = sw;
    }
    t.quantum = quantum_;
    if (gridMultiple_) {
      const double dx = t.x1 - t.x0, dz = t.z1 - t.z0;
      if (dx == dz) {
        t.exactDiag = true;
      } else {
        // dx * n == dz * m for small whole m, n (dx and dz are whole
        // numbers of posts).
        for (int n = 1; n <= 64 && !t.exactDiag; ++n) {
          const double m = dx * n / dz;
          if (m == std::round(m) && m >= 1 && m <= 4096 && dx * n == dz * m) {
            t.exactDiag = true, t.ratioM = m, t.ratioN = n;
          }
        }
      }
    }
    t.box = {t.x0, t.z0, t.x1, t.z1};
    return t;
  }

  void prepare(std::size_t l) {
    const ModuleCell::Layer& layer = cell_.layers[l];
    LevelLayer& ll = layers_[l];
    const std::size_t squares = nx_ * nz_;
    ll.touched.assign(squares, 0);
    for (const Seg& s : layer.geo.bounds) {
      Box b;
      b.add(s.a), b.add(s.b);
      const std::size_t c0 = colOf(b.x0), c1 = colOf(b.x1), r0 = rowOf(b.z0), r1 = rowOf(b.z1);
      for (std::size_t r = r0; r <= r1; ++r) {
        for (std::size_t c = c0; c <= c1; ++c) {
          const std::size_t sq = r * nx_ + c;
          if ((ll.touched[sq] & 3) == 3) continue;
          for (int half = 0; half < 2; ++half) {
            if (!(ll.touched[sq] & (1 << half)) && touches(s, tri(sq, half))) ll.touched[sq] |= std::uint8_t(1 << half);
          }
        }
      }
    }
    // Candidate pieces per square (CSR).
    ll.start.assign(squares + 1, 0);
    const auto& pieces = layer.geo.pieces;
    std::vector<std::array<std::size_t, 4>> range(pieces.size());
    for (std::size_t p = 0; p < pieces.size(); ++p) {
      const Box& b = pieces[p].box;
      range[p] = {colOf(b.x0), colOf(b.x1), rowOf(b.z0), rowOf(b.z1)};
      for (std::size_t r = range[p][2]; r <= range[p][3]; ++r) {
        for (std::size_t c = range[p][0]; c <= range[p][1]; ++c) ++ll.start[r * nx_ + c + 1];
      }
    }
    for (std::size_t k = 0; k < squares; ++k) ll.start[k + 1] += ll.start[k];
    ll.pieces.assign(ll.start[squares], 0);
    std::vector<std::uint32_t> fill(ll.start.begin(), ll.start.end() - 1);
    for (std::size_t p = 0; p < pieces.size(); ++p) {
      for (std::size_t r = range[p][2]; r <= range[p][3]; ++r) {
        for (std::size_t c = range[p][0]; c <= range[p][1]; ++c) ll.pieces[fill[r * nx_ + c]++] = std::uint32_t(p);
      }
    }
    if (!layer.geo.skin) centre_[l] = indexCentre(layer, cell_.rect);
  }

  /// Label at a point of an untouched triangle: the piece that holds it.
  std::uint16_t labelAt(std::size_t l, std::size_t sq, Vec2 p) const {
    const ModuleCell::Layer& layer = cell_.layers[l];
    if (layer.geo.bounds.empty()) return layer.geo.uniform;
    const LevelLayer& ll = layers_[l];
    for (std::uint32_t k = ll.start[sq]; k < ll.start[sq + 1]; ++k) {
      const Piece& piece = layer.geo.pieces[ll.pieces[k]];
      if (p.x < piece.box.x0 || p.x > piece.box.x1 || p.z < piece.box.z0 || p.z > piece.box.z1) continue;
      if (convexContains(piece.pts, p)) return piece.label;
    }
    return layer.geo.skin ? culture_.table.defaultArea : kNone;
  }

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

  void gridTriangle(std::size_t sq, int half) {
    const Tri t = tri(sq, half);
    const Vec2 centroid = (1.0 / 3.0) * (t.c[0] + t.c[1] + t.c[2]);
    const std::size_t nl = cell_.layers.size();
    modes_.assign(nl, Mode::none);
    labels_.assign(nl, kNone);
    bool anyCut = false;
    for (std::size_t l = 0; l < nl; ++l) {
      const LevelLayer& ll = layers_[l];
      const bool touched = ll.touched[sq] & (1 << half);
      if (l > 0 && (cell_.layers[l].geo.pieces.empty() || ll.start[sq] == ll.start[sq + 1])) continue;
      if (touched) {
        modes_[l] = Mode::cut;
        anyCut = true;
        continue;
      }
      const std::uint16_t label = labelAt(l, sq, centroid);
      if (l == 0 || label != kNone) modes_[l] = Mode::whole, labels_[l] = label;
    }
    if (!anyCut) {
      // The fast path: one triangle per layer, the skin on the lattice posts.
      beginGroup(sq, half, module::kPrioritySkin, labels_[0]);
      triangle(out_.indices, t.cv[0], t.cv[1], t.cv[2]);
      endGroup();
      ++stats_.skinPolygons;
      for (std::size_t l = 1; l < nl; ++l) {
        if (modes_[l] != Mode::whole) continue;
        const std::uint32_t base = std::uint32_t(decalVertices_.size());
        for (int k = 0; k < 3; ++k) {
          Vertex v{float(t.c[k].x), lat_.heights[t.cv[k]], float(t.c[k].z), 0, 0};
          roadST(l, t.c[k], v.s, v.t);
          decalVertices_.push_back(v);
        }
        Run run{std::uint32_t(sq), std::uint8_t(half), std::uint32_t(runIndices_[l].size()), 3};
        triangle(runIndices_[l], base, base + 1, base + 2);
        runs_[l].push_back(run);
        ++stats_.decalPolygons;
      }
      return;
    }
    ++stats_.slowTriangles;
    // Each priority is one draw pass: its layers are merged together.
    std::size_t l = 0;
    while (l < nl) {
      std::size_t end = l + 1;
      while (end < nl && l > 0 && cell_.layers[end].priority == cell_.layers[l].priority) ++end;
      passTriangle(sq, half, t, centroid, l, end);
      l = end;
    }
  }

  /// Cuts, merges and writes layers [first, end) of one grid triangle.
  void passTriangle(std::size_t sq, int half, const Tri& t, Vec2 centroid, std::size_t first, std::size_t end) {
    bool cutHere = false, anyHere = false;
    for (std::size_t l = first; l < end; ++l) cutHere |= modes_[l] == Mode::cut, anyHere |= modes_[l] != Mode::none;
    if (!anyHere) return;
    gather(sq, t, first, end);
    if (cutHere) {
      for (int attempt = 0;; ++attempt) {
        snap(t);
        if (triangulate() || attempt == 64) break;
      }
      countClose();
    } else {
      for (SnapPoint& p : points_) p.rep = std::uint32_t(&p - points_.data());
      triangulate();
    }
    bool skinOk = true;
    if (first == 0) {
      // The skin must tile the triangle; if rounding ever defeats that,
      // the triangle keeps one skin triangle (counted as a failure).
      double skin2 = 0;
      for (const OutTri& o : tris_) skin2 += area2(o);
      const double want2 = cross(round(t.c[1]) - round(t.c[0]), round(t.c[2]) - round(t.c[0]));
      skinOk = std::fabs(skin2 - want2) <= 1e-6 * want2;
      if (!skinOk) ++stats_.failures;
    }
    emit(sq, half, t, skinOk, centroid);
  }

  static Vec2 round(Vec2 p) { return {toFloat(p.x), toFloat(p.z)}; }
  double roundStep(double v) const { return std::round(v / quantum_) * quantum_; }

  /// p as written: on the vertex step where the level has one, else
  /// rounded to float. Edge points keep their edge's coordinate (a
  /// multiple of the step); an inner point that the step would carry
  /// across the diagonal goes onto it (the step's points on the diagonal
  /// are exact) and becomes a diagonal point.
  CP placed(CP p, const Tri& t) const {
    if (!stepped_ || (p.on == 0 && !t.exactDiag)) {
      p.p = round(p.p);
      return p;
    }
    if (p.on & kDiag) {
      p.p = round(p.p);  // diagPoint put it on the step already
      return p;
    }
    const Vec2 q{roundStep(p.p.x), roundStep(p.p.z)};
    if (p.on == 0 && !t.insideDiag(t.f(q))) {
      const double dx = t.x1 - t.x0;
      p.p = round(t.diagPoint(std::clamp((q.x - t.x0) / dx, 0.0, 1.0)));
      p.on = kDiag;
      return p;
    }
    p.p = round(q);
    return p;
  }
  double area2(const OutTri& o) const {
    return cross(points_[o.b].p - points_[o.a].p, points_[o.c].p - points_[o.a].p);
  }

  /// Adds a point of the last polygon, as written (placed()).
  void addPoint(CP p, const Tri& t) { flat_.push_back({placed(p, t), polys_.size() - 1}); }

  /// Polygons of layers [first, end) in the triangle, points unified.
  void gather(std::size_t sq, const Tri& t, std::size_t first, std::size_t end) {
    polys_.clear();
    flat_.clear();
    for (std::size_t l = first; l < end; ++l) {
      if (modes_[l] == Mode::whole) {
        polys_.push_back({std::uint32_t(l), labels_[l], {}});
        for (int k = 0; k < 3; ++k) addPoint({t.c[k], t.cb[k]}, t);
        continue;
      }
      if (modes_[l] != Mode::cut) continue;
      const ModuleCell::Layer& layer = cell_.layers[l];
      const LevelLayer& ll = layers_[l];
      bool any = false;
      for (std::uint32_t k = ll.start[sq]; k < ll.start[sq + 1]; ++k) {
        const Piece& piece = layer.geo.pieces[ll.pieces[k]];
        if (!piece.box.overlaps(t.box)) continue;
        clipPiece(piece.pts, t, clipped_, clipTmp_);
        if (clipped_.empty()) continue;
        any = true;
        polys_.push_back({std::uint32_t(l), piece.label, {}});
        for (const CP& p : clipped_) addPoint(p, t);
      }
      if (!any && l == 0) {
        // No skin piece reached the triangle (never expected): the label
        // at its centroid covers it.
        polys_.push_back({0, labelAt(0, sq, (1.0 / 3.0) * (t.c[0] + t.c[1] + t.c[2])), {}});
        for (int k = 0; k < 3; ++k) addPoint({t.c[k], t.cb[k]}, t);
      }
    }
    // Points are rounded to float (what is written) as they are added;
    // equal points are unified. Points that rounding puts on two edges
    // are that corner.
    for (int pass = 0; pass < 2; ++pass) {
      order_.resize(flat_.size());
      std::iota(order_.begin(), order_.end(), 0);
      std::sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) {
        return lexLess(flat_[a].first.p, flat_[b].first.p) || (flat_[a].first.p == flat_[b].first.p && a < b);
      });
      points_.clear();
      pointOf_.assign(flat_.size(), 0);
      for (std::size_t k = 0; k < order_.size(); ++k) {
        const CP& cp = flat_[order_[k]].first;
        if (points_.empty() || !(points_.back().p == cp.p)) points_.push_back({cp.p, cp.on, false, 0});
        else points_.back().on |= cp.on;
        pointOf_[order_[k]] = std::uint32_t(points_.size() - 1);
      }
      bool moved = false;
      for (auto& f : flat_) {
        const SnapPoint& sp = points_[pointOf_[&f - flat_.data()]];
        if (bits(sp.on) < 2) continue;
        const Vec2 corner = round(t.cornerOf(sp.on));
        if (!(f.first.p == corner)) f.first.p = corner, moved = true;
        f.first.on = sp.on;
      }
      if (!moved) break;
    }
    for (std::size_t k = 0; k < flat_.size(); ++k) {
      auto& ids = polys_[flat_[k].second].ids;
      if (ids.empty() || ids.back() != pointOf_[k]) ids.push_back(pointOf_[k]);
    }
    for (Poly& p : polys_) {
      while (p.ids.size() > 1 && p.ids.front() == p.ids.back()) p.ids.pop_back();
    }
  }

  /// Merges points closer than the tolerance: corners never move, edge
  /// points move only along their edge (or onto its corners), inner points
  /// anywhere. Deterministic: by kind, then position. What happens to a
  /// point on an edge depends only on the points on that edge, so the two
  /// grid triangles sharing it (in this module or the next) agree.
  void snap(const Tri& t) {
    const std::size_t n = points_.size();
    std::vector<std::uint32_t>& ord = snapOrder_;
    ord.resize(n);
    std::iota(ord.begin(), ord.end(), 0u);
    std::stable_sort(ord.begin(), ord.end(), [&](std::uint32_t a, std::uint32_t b) {
      return bits(points_[a].on) > bits(points_[b].on);
    });
    reps_.clear();
    const double tol2 = tol_ * tol_;
    // An edge point this close to an end of its edge goes to that end, so
    // that two points on the two edges of a corner of 45 degrees or more
    // are never left closer than the tolerance: 2 R sin(22.5 deg) = tol.
    const double cornerR = tol_ / (2.0 * std::sin(std::numbers::pi / 8));
    points_.reserve(n + 3);  // cornerPoint adds at most the three corners: `p` stays valid
    for (std::uint32_t i : ord) {
      SnapPoint& p = points_[i];
      p.rep = i;
      if (p.fixed || bits(p.on) >= 2 || tol_ <= 0) {
        reps_.push_back(i);
        continue;
      }
      if (bits(p.on) == 1) {
        for (int k = 0; k < 3 && p.rep == i; ++k) {
          if ((t.cb[k] & p.on) != p.on) continue;
          const Vec2 corner = round(t.c[k]);
          const Vec2 d = corner - p.p;
          if (dot(d, d) < cornerR * cornerR) p.rep = cornerPoint(corner, t.cb[k]);
        }
        if (p.rep != i) continue;
      }
      double best = tol2;
      for (std::uint32_t r : reps_) {
        const SnapPoint& q = points_[r];
        if ((p.on & ~q.on) != 0) continue;
        const Vec2 d = q.p - p.p;
        const double d2 = dot(d, d);
        if (d2 < best) best = d2, p.rep = r;
      }
      if (p.rep == i) reps_.push_back(i);
    }
  }

  /// The point at a corner of the triangle (added when no polygon has it).
  std::uint32_t cornerPoint(Vec2 corner, std::uint8_t on) {
    for (std::uint32_t r : reps_) {
      if (points_[r].p == corner) return r;
    }
    const std::uint32_t ci = std::uint32_t(points_.size());
    points_.push_back({corner, on, false, ci});
    reps_.push_back(ci);
    return ci;
  }

  /// Triangulates every merged polygon into tris_ (a fan when that is
  /// valid, else ear clipping). Returns false when a merge left a polygon
  /// that cannot be triangulated (folded); its merged points are then fixed
  /// for the next attempt.
  bool triangulate() {
    tris_.clear();
    bool ok = true;
    for (std::uint32_t k = 0; k < polys_.size(); ++k) {
      std::vector<std::uint32_t>& m = mapped_;
      m.clear();
      for (std::uint32_t id : polys_[k].ids) {
        const std::uint32_t r = points_[id].rep;
        if (m.empty() || m.back() != r) m.push_back(r);
      }
      while (m.size() > 1 && m.front() == m.back()) m.pop_back();
      if (m.size() < 3) continue;
      if (!fanOrClip(k, m)) {
        ok = false;
        for (std::uint32_t id : polys_[k].ids) {
          if (points_[id].rep != id) points_[id].fixed = true;
        }
      }
    }
    return ok;
  }

  /// Triangulates one merged polygon, keeping every vertex where it can:
  /// a vertex on a straight stretch of the outline (after a neighbouring
  /// sliver merged away) still lies on the grid triangle's edge that the
  /// next triangle, or the next module, has a vertex on.
  bool fanOrClip(std::uint32_t poly, std::vector<std::uint32_t>& m) {
    auto a2 = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
      return cross(points_[b].p - points_[a].p, points_[c].p - points_[a].p);
    };
    const std::size_t before = tris_.size();
    // A fan from some vertex (for a convex polygon with one straight
    // vertex, from that one).
    const std::size_t n0 = m.size();
    for (std::size_t k = 0; k < n0; ++k) {
      bool fanOk = true;
      for (std::size_t i = 1; i + 1 < n0 && fanOk; ++i) fanOk = a2(m[k], m[(k + i) % n0], m[(k + i + 1) % n0]) > kAreaEps;
      if (!fanOk) continue;
      for (std::size_t i = 1; i + 1 < n0; ++i) tris_.push_back({poly, m[k], m[(k + i) % n0], m[(k + i + 1) % n0]});
      return true;
    }
    // Ear clipping: cut a positive ear with no other vertex in it or on
    // it; only when there is none, drop a flat vertex.
    auto inOrOn = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t q) {
      const Vec2 p = points_[q].p;
      if (p == points_[a].p || p == points_[b].p || p == points_[c].p) return false;
      return a2(a, b, q) >= 0 && a2(b, c, q) >= 0 && a2(c, a, q) >= 0;
    };
    while (m.size() >= 3) {
      const std::size_t n = m.size();
      bool cutOne = false;
      for (std::size_t i = 0; i < n && !cutOne; ++i) {
        const std::uint32_t a = m[(i + n - 1) % n], b = m[i], c = m[(i + 1) % n];
        if (a2(a, b, c) <= kAreaEps) continue;
        bool empty = true;
        for (std::uint32_t q : m) {
          if (q != a && q != b && q != c && inOrOn(a, b, c, q)) {
            empty = false;
            break;
          }
        }
        if (!empty) continue;
        tris_.push_back({poly, a, b, c});
        m.erase(m.begin() + std::ptrdiff_t(i));
        cutOne = true;
      }
      if (cutOne) continue;
      for (std::size_t i = 0; i < n && !cutOne; ++i) {
        const std::uint32_t a = m[(i + n - 1) % n], b = m[i], c = m[(i + 1) % n];
        if (std::fabs(a2(a, b, c)) <= kAreaEps) {
          m.erase(m.begin() + std::ptrdiff_t(i));
          cutOne = true;
        }
      }
      if (!cutOne) {
        tris_.resize(before);
        return false;
      }
    }
    return true;
  }

  /// Counts points left closer than the tolerance (a merge was refused).
  void countClose() {
    const double tol2 = tol_ * tol_;
    for (std::size_t a = 0; a < reps_.size(); ++a) {
      for (std::size_t b = a + 1; b < reps_.size(); ++b) {
        const SnapPoint& p = points_[reps_[a]];
        const SnapPoint& q = points_[reps_[b]];
        if (p.rep != reps_[a] || q.rep != reps_[b]) continue;
        const Vec2 d = q.p - p.p;
        if (dot(d, d) < tol2) ++stats_.unmerged;
      }
    }
  }

  // ------------------------------------------------------------ output

  void beginGroup(std::size_t sq, int half, std::uint8_t priority, std::uint16_t material) {
    Group g;
    g.square = std::uint32_t(sq);
    g.half = half == 0 ? Half::upper : Half::lower;
    g.priority = priority;
    g.material = material;
    g.firstIndex = std::uint32_t(out_.indices.size());
    out_.groups.push_back(g);
  }
  void endGroup() {
    Group& g = out_.groups.back();
    g.indexCount = std::uint32_t(out_.indices.size()) - g.firstIndex;
    if (g.indexCount == 0) out_.groups.pop_back();
  }
  /// Appends a triangle given in positive order, flipped to the renderer's
  /// winding (counter-clockwise seen from above).
  static void triangle(std::vector<std::uint32_t>& to, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    to.insert(to.end(), {a, c, b});
  }

  /// Corner k of the triangle at point p, or -1.
  static int cornerAt(const Tri& t, const SnapPoint& s) {
    if (bits(s.on) < 2) return -1;
    for (int k = 0; k < 3; ++k) {
      if ((t.cb[k] & s.on) == t.cb[k]) return k;
    }
    return -1;
  }

  void emit(std::size_t sq, int half, const Tri& t, bool skinOk, Vec2 centroid) {
    // Skin: grouped by class; corners are the lattice posts.
    std::stable_sort(tris_.begin(), tris_.end(), [&](const OutTri& a, const OutTri& b) {
      const Poly& pa = polys_[a.poly];
      const Poly& pb = polys_[b.poly];
      return pa.layer != pb.layer ? pa.layer < pb.layer : pa.label < pb.label;
    });
    polyUsed_.assign(polys_.size(), false);
    vertexOf_.assign(points_.size(), UINT32_MAX);
    std::size_t k = 0;
    if (!skinOk) {
      beginGroup(sq, half, module::kPrioritySkin, labelAt(0, sq, centroid));
      triangle(out_.indices, t.cv[0], t.cv[1], t.cv[2]);
      endGroup();
      ++stats_.skinPolygons;
      while (k < tris_.size() && polys_[tris_[k].poly].layer == 0) ++k;
    }
    while (k < tris_.size() && polys_[tris_[k].poly].layer == 0) {
      const std::uint16_t label = polys_[tris_[k].poly].label;
      beginGroup(sq, half, module::kPrioritySkin, label);
      for (; k < tris_.size() && polys_[tris_[k].poly].layer == 0 && polys_[tris_[k].poly].label == label; ++k) {
        const OutTri& o = tris_[k];
        if (!polyUsed_[o.poly]) polyUsed_[o.poly] = true, ++stats_.skinPolygons;
        std::uint32_t idx[3];
        int n = 0;
        for (std::uint32_t id : {o.a, o.b, o.c}) {
          if (vertexOf_[id] == UINT32_MAX) {
            const SnapPoint& s = points_[id];
            const int corner = cornerAt(t, s);
            if (corner >= 0) {
              vertexOf_[id] = t.cv[corner];
            } else {
              vertexOf_[id] = std::uint32_t(out_.vertices.size());
              out_.vertices.push_back({float(s.p.x), float(t.height(s.p)), float(s.p.z), skinS(s.p.x), skinT(s.p.z)});
            }
          }
          idx[n++] = vertexOf_[id];
        }
        triangle(out_.indices, idx[0], idx[1], idx[2]);
      }
      endGroup();
    }
    // Decals: kept per layer until all skin is written.
    while (k < tris_.size()) {
      const std::uint32_t l = polys_[tris_[k].poly].layer;
      vertexOf_.assign(points_.size(), UINT32_MAX);
      Run run{std::uint32_t(sq), std::uint8_t(half), std::uint32_t(runIndices_[l].size()), 0};
      for (; k < tris_.size() && polys_[tris_[k].poly].layer == l; ++k) {
        const OutTri& o = tris_[k];
        if (!polyUsed_[o.poly]) polyUsed_[o.poly] = true, ++stats_.decalPolygons;
        std::uint32_t idx[3];
        int n = 0;
        for (std::uint32_t id : {o.a, o.b, o.c}) {
          if (vertexOf_[id] == UINT32_MAX) {
            vertexOf_[id] = std::uint32_t(decalVertices_.size());
            const SnapPoint& s = points_[id];
            const int corner = cornerAt(t, s);
            Vertex v{float(s.p.x), corner >= 0 ? lat_.heights[t.cv[corner]] : float(t.height(s.p)), float(s.p.z), 0, 0};
            roadST(l, s.p, v.s, v.t);
            decalVertices_.push_back(v);
          }
          idx[n++] = vertexOf_[id];
        }
        triangle(runIndices_[l], idx[0], idx[1], idx[2]);
      }
      run.count = std::uint32_t(runIndices_[l].size()) - run.first;
      if (run.count > 0) runs_[l].push_back(run);
    }
  }

  /// Decal groups after all skin: per priority, square, half, class. Their
  /// vertices follow all skin vertices, so the module format can store
  /// their texture coordinates apart from the skin's derived ones.
  void flushDecals() {
    const std::size_t nl = cell_.layers.size();
    const auto base = std::uint32_t(out_.vertices.size());
    out_.vertices.insert(out_.vertices.end(), decalVertices_.begin(), decalVertices_.end());
    decalVertices_.clear();
    std::size_t l = 1;
    while (l < nl) {
      std::size_t end = l;
      while (end < nl && cell_.layers[end].priority == cell_.layers[l].priority) ++end;
      std::vector<std::size_t> cursor(end - l, 0);
      for (std::size_t sq = 0; sq < nx_ * nz_; ++sq) {
        for (int half = 0; half < 2; ++half) {
          for (std::size_t k = l; k < end; ++k) {
            std::size_t& c = cursor[k - l];
            if (c >= runs_[k].size() || runs_[k][c].sq != sq || runs_[k][c].half != half) continue;
            const Run& r = runs_[k][c++];
            beginGroup(sq, half, cell_.layers[k].priority, cell_.layers[k].geo.classId);
            for (std::uint32_t i = r.first; i < r.first + r.count; ++i) out_.indices.push_back(base + runIndices_[k][i]);
            endGroup();
          }
        }
      }
      l = end;
    }
  }

  /// Road texture coordinates (seed Figure 17): S along the nearest
  /// centreline in road widths, T across, 0 at the left edge (as the road
  /// runs, seen from above) and 1 at the right.
  void roadST(std::size_t l, Vec2 p, float& s, float& t) const {
    const ModuleCell::Layer& layer = cell_.layers[l];
    const CentreIndex& ix = centre_[l];
    s = t = 0;
    if (layer.centre.empty()) return;
    const auto c = std::uint32_t(std::clamp(std::floor((p.x - ix.x0) / ix.cell), 0.0, double(ix.cols - 1)));
    const auto r = std::uint32_t(std::clamp(std::floor((p.z - ix.z0) / ix.cell), 0.0, double(ix.rows - 1)));
    const auto& bucket = ix.buckets[std::size_t(r) * ix.cols + c];
    double best = std::numeric_limits<double>::infinity();
    const CentreSeg* seg = nullptr;
    double along = 0;
    auto consider = [&](const CentreSeg& cs) {
      const Vec2 d = cs.b - cs.a;
      const double len2 = dot(d, d);
      const double u = len2 > 0 ? std::clamp(dot(p - cs.a, d) / len2, 0.0, 1.0) : 0.0;
      const double dist = length(p - (cs.a + u * d));
      if (dist < best) best = dist, seg = &cs, along = u * std::sqrt(len2);
    };
    for (std::uint32_t k : bucket) consider(layer.centre[k]);
    if (!seg) {
      for (const CentreSeg& cs : layer.centre) consider(cs);
    }
    const Vec2 d = seg->b - seg->a;
    const double len = length(d);
    const Vec2 left = len > 0 ? Vec2{d.z / len, -d.x / len} : Vec2{0, 0};  // the driver's left
    const double off = dot(p - seg->a, left);
    // On a step of 1/256 of the width (under 4 cm on a 10 m road), which
    // the module format stores as small integers.
    s = float(std::round((seg->along + along) / seg->width * kDecalTextureSteps) / kDecalTextureSteps);
    t = float(std::round(std::clamp(0.5 - off / seg->width, 0.0, 1.0) * kDecalTextureSteps) / kDecalTextureSteps);
  }

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

std::string cacheKey(double a, double b, const Box& r) {
  std::string k(6 * sizeof(double), '\0');
  const double v[6] = {a, b, r.x0, r.z0, r.x1, r.z1};
  std::memcpy(k.data(), v, sizeof v);
  return k;
}

}  // namespace

std::shared_ptr<const ModuleCell> CultureImpl::cellFor(const LevelLattice& lat, bool* built) const {
  const Box rect{lat.xs.front(), lat.zs.front(), lat.xs.back(), lat.zs.back()};
  const std::string key = cacheKey(lat.moduleX, lat.moduleZ, rect);
  std::unique_lock lock(cacheMutex_);
  for (;;) {
    auto it = std::find_if(cache_.begin(), cache_.end(), [&](const auto& e) { return e.first == key; });
    if (it == cache_.end()) break;
    if (it->second.cell) {
      cache_.splice(cache_.begin(), cache_, it);
      return it->second.cell;
    }
    cacheReady_.wait(lock);  // another thread is building it
  }
  cache_.push_front({key, {}});
  const auto mine = cache_.begin();
  if (built) *built = true;
  lock.unlock();
  std::shared_ptr<const ModuleCell> cell = computeCell(lat.moduleX, lat.moduleZ, rect);
  lock.lock();
  mine->second.cell = cell;
  for (auto it = std::prev(cache_.end()); cache_.size() > cacheCapacity_ && it != cache_.begin();) {
    auto victim = it--;
    if (victim->second.cell && victim != mine) cache_.erase(victim);
  }
  cacheReady_.notify_all();
  return cell;
}

std::shared_ptr<const ModuleCell> CultureImpl::computeCell(double mx, double mz, const Box& rect) const {
  const double t0 = threadCpuSeconds();
  auto cell = std::make_shared<ModuleCell>();
  cell->moduleX = mx, cell->moduleZ = mz, cell->rect = rect;
  const Box world{mx + rect.x0, mz + rect.z0, mx + rect.x1, mz + rect.z1};
  auto gather = [&](const std::vector<std::vector<std::uint32_t>>& index) {
    std::vector<std::uint32_t> ids;
    const auto col = [&](double x) { return std::uint32_t(std::clamp(std::floor(x / indexCell), 0.0, double(indexCols - 1))); };
    const auto row = [&](double z) { return std::uint32_t(std::clamp(std::floor(z / indexCell), 0.0, double(indexRows - 1))); };
    for (std::uint32_t r = row(world.z0); r <= row(world.z1); ++r) {
      for (std::uint32_t c = col(world.x0); c <= col(world.x1); ++c) {
        const auto& v = index[std::size_t(r) * indexCols + c];
        ids.insert(ids.end(), v.begin(), v.end());
      }
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    return ids;
  };
  CellInput in;
  in.rect = rect;
  in.defaultClass = table.defaultArea;
  std::unordered_map<std::uint16_t, std::uint16_t> slotOf;
  auto slot = [&](std::uint16_t cls, bool skin) {
    auto [it, fresh] = slotOf.try_emplace(cls, std::uint16_t(in.slots.size()));
    if (fresh) {
      const materials::Class* c = table.find(cls);
      in.slots.push_back({cls, skin, c ? c->rank : std::uint16_t(0)});
    }
    return it->second;
  };
  // Into module-local metres; points on the rectangle's edges exactly on them.
  auto local = [&](Ring r) {
    for (Vec2& p : r) {
      p = {p.x - mx, p.z - mz};
      for (double e : {rect.x0, rect.x1}) {
        if (std::fabs(p.x - e) < 1e-9) p.x = e;
      }
      for (double e : {rect.z0, rect.z1}) {
        if (std::fabs(p.z - e) < 1e-9) p.z = e;
      }
    }
    return r;
  };
  // A cancelled build discards the module: stop early, leave it default skin.
  bool cancelled = cancelRequested();
  std::uint32_t seen = 0;
  auto stop = [&] { return cancelled || (++seen % 256 == 0 && (cancelled = cancelRequested())); };
  for (std::uint32_t id : gather(areaIndex)) {
    if (stop()) break;
    const AreaFeature& f = areas[id];
    if (!f.box.overlaps(world)) continue;
    for (const Ring& r : f.rings) {
      Ring c = clipRingToRect(r, world);
      if (!c.empty()) in.rings.push_back({local(std::move(c)), slot(f.classId, true)});
    }
  }
  const std::vector<std::uint32_t> lineIds = gather(lineIndex);
  for (std::uint32_t id : lineIds) {
    if (stop()) break;
    const LineFeature& f = lines[id];
    if (!f.box.overlaps(world)) continue;
    for (const Ring& r : f.outline) {
      Ring c = clipRingToRect(r, world);
      if (!c.empty()) in.rings.push_back({local(std::move(c)), slot(f.classId, false)});
    }
  }
  std::vector<LayerGeometry> geo;
  cell->gatherSeconds = threadCpuSeconds() - t0;
  if (!in.rings.empty() && !cancelled && !cancelRequested()) {
    try {
      geo = buildCell(in, &cell->times);
    } catch (const std::exception&) {
      geo.clear();
      cell->failures = 1;
    }
  }
  if (geo.empty()) {
    LayerGeometry skin;
    skin.uniform = table.defaultArea;
    const Ring r = {{rect.x0, rect.z0}, {rect.x1, rect.z0}, {rect.x1, rect.z1}, {rect.x0, rect.z1}};
    skin.pieces.push_back({skin.uniform, boxOf(r), r});
    geo.push_back(std::move(skin));
  }
  for (LayerGeometry& g : geo) {
    ModuleCell::Layer layer;
    if (!g.skin) {
      if (g.pieces.empty()) continue;
      const materials::Class* c = table.find(g.classId);
      layer.priority = c ? c->priority : module::kPriorityRoad;
      // Centrelines near the module, for texture coordinates.
      for (std::uint32_t id : lineIds) {
        const LineFeature& f = lines[id];
        if (f.classId != g.classId || !f.box.overlaps(world)) continue;
        for (const Polyline& p : f.parts) {
          double along = 0;
          for (std::size_t k = 0; k + 1 < p.size(); ++k) {
            const Vec2 a = p[k], b = p[k + 1];
            const double len = length(b - a);
            Box sb;
            sb.add(a), sb.add(b);
            if (sb.overlaps(world.grown(2 * f.width + 1))) {
              layer.centre.push_back({{a.x - mx, a.z - mz}, {b.x - mx, b.z - mz}, along, f.width});
            }
            along += len;
          }
        }
      }
    }
    layer.geo = std::move(g);
    cell->layers.push_back(std::move(layer));
  }
  std::stable_sort(cell->layers.begin() + 1, cell->layers.end(), [](const auto& a, const auto& b) {
    return a.priority != b.priority ? a.priority < b.priority : a.geo.classId < b.geo.classId;
  });
  return cell;
}

DecalStats CultureImpl::decalLevel(const LevelLattice& lat, module::Level& out) const {
  assert(lat.xs.size() >= 2 && lat.zs.size() >= 2 && lat.heights.size() == lat.xs.size() * lat.zs.size());
  if (lat.xs.size() < 2 || lat.zs.size() < 2 || lat.heights.size() != lat.xs.size() * lat.zs.size()) return {};
  const double t0 = threadCpuSeconds();
  bool built = false;
  const std::shared_ptr<const ModuleCell> cell = cellFor(lat, &built);
  const double t1 = threadCpuSeconds();
  DecalStats st = LevelWork(*this, *cell, lat, out).run();
  addBuildings(lat, out, st);
  st.cutSeconds = threadCpuSeconds() - t1;
  if (built) {
    st.partitionSeconds = t1 - t0;
    st.gatherSeconds = cell->gatherSeconds;
    st.arrangementSeconds = cell->times.arrangement;
    st.piecesSeconds = cell->times.pieces;
  }
  return st;
}

}  // namespace culture
}  // namespace sandtable::convert
