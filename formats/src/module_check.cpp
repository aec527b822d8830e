#include "sandtable/formats/module_check.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>

#include "sandtable/base/capped_problems.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::module {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------- reporting

/// Kinds of problem; at most CheckOptions::maxPerKind of each are listed
/// per module (or per neighbour pair), the rest summarised in one line.
enum Kind : std::size_t {
  kStructure,
  kNonFinite,
  kMaterial,
  kOutside,
  kPlane,
  kOrientation,
  kCoverage,
  kPost,
  kMaxHeight,
  kSkirt,
  kSkirtCoverage,
  kSkirtDepth,
  kNeighbour,
  kTexture,
  kObject,
  kKindCount
};
constexpr const char* kKindNames[kKindCount] = {
    "structure", "non-finite",      "material",    "outside-triangle", "off-plane",
    "orientation", "skin-coverage", "lattice-post", "max-height",      "skirt",
    "skirt-coverage", "skirt-depth", "neighbour-edge", "texture", "object"};

/// One module's problems, written to `out` as found, at most `cap` of each
/// kind (0: all).
class Report {
 public:
  Report(const std::string& file, std::string who, std::uint32_t cap, Status& out)
      : file_(file), who_(std::move(who)), capped_(cap), out_(out) {}
  /// Counts one problem of `k`; true when it should be written out (so the
  /// message is only formatted when it will be listed).
  bool want(Kind k) { return capped_.want(k, file_); }
  void add(std::uint64_t offset, const std::string& msg) {
    out_.add({file_, offset, "module check: " + msg});
  }
  void finish(std::uint64_t offset) {
    capped_.appendSummary(out_, "module check: " + who_, offset, [](Kind k) { return std::string(kKindNames[k]); });
  }

 private:
  const std::string& file_;
  std::string who_;
  CappedProblems<Kind> capped_;
  Status& out_;
};

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}
/// Metres at millimetre resolution.
std::string m3(double v) { return fmt("%.3f", v); }
/// Six significant digits (areas, fractions).
std::string g6(double v) { return fmt("%.6g", v); }
/// Enough digits to tell two floats apart.
std::string g9(double v) { return fmt("%.9g", v); }
std::string str(std::uint64_t v) { return std::to_string(v); }

/// Spacing of float32 values near |v| (one unit in the last place).
double ulpOf(double v) {
  const float f = static_cast<float>(std::fabs(v));
  if (!std::isfinite(f)) return 0;
  return double(std::nextafter(f, std::numeric_limits<float>::infinity())) - double(f);
}

const char* sideName(Side s) {
  switch (s) {
    case Side::north: return "north";
    case Side::south: return "south";
    case Side::west: return "west";
    case Side::east: return "east";
  }
  return "?";
}
/// The coordinate that runs along a side: x on north/south, z on west/east.
const char* alongName(Side s) { return s == Side::north || s == Side::south ? "x" : "z"; }

// ---------------------------------------------------------------- lattice

/// One axis of one level's lattice: grid posts first, first + step, ...,
/// clamped at last, and their module-local coordinates.
struct Axis {
  std::vector<std::uint32_t> posts;
  std::vector<double> local;
  double cell = 0;  ///< nominal step, metres

  std::size_t segments() const { return posts.size() - 1; }
  /// Lattice line within `tol` of coordinate v, or -1. v must be finite.
  long line(double v, double tol) const {
    const long n = long(segments());
    const double k = std::floor(v / cell + 0.5);
    const long c = k < 0 ? 0 : (k > double(n) ? n : long(k));
    if (std::fabs(local[std::size_t(c)] - v) <= tol) return c;
    if (std::fabs(local[std::size_t(n)] - v) <= tol) return n;  // a narrow last segment
    return -1;
  }
  /// Segment holding coordinate v (clamped). v must be finite.
  std::size_t segment(double v) const {
    const double k = std::floor(v / cell);
    const double n = double(segments() - 1);
    return std::size_t(k < 0 ? 0 : (k > n ? n : k));
  }
};

Axis makeAxis(std::uint32_t first, std::uint32_t last, std::uint32_t step, double spacing) {
  Axis a;
  a.cell = double(step) * spacing;
  for (std::uint64_t p = first; p < last; p += step) a.posts.push_back(std::uint32_t(p));
  a.posts.push_back(last);
  for (const std::uint32_t p : a.posts) a.local.push_back(double(p - first) * spacing);
  return a;
}

/// Where a module lies in the grid.
struct Frame {
  std::uint32_t i0 = 0, i1 = 0, j0 = 0, j1 = 0;  ///< level-0 post range, inclusive
  double width = 0, height = 0;                   ///< metres east and south
  double tolXZ = 0;                               ///< 1 mm + float ulp of the extent
  double s0 = 0, t0 = 0;                          ///< skin texture offsets, metres (module.h)
  double tolST = 0;                               ///< tolerance of s, t times the repeat, metres
};

/// The required skirt depth of one level and where it is attained.
struct Need {
  double depth = 0;
  Side side = Side::north;
  double t = 0;
  std::size_t otherLevel = 0;
};

/// A grid triangle of one level in up-facing order (counter-clockwise seen
/// from above, normal.y > 0), with its inward edge normals and its plane.
struct GridTriangle {
  double x[3], z[3], y[3];
  double nx[3], nz[3], c[3];  ///< inward distance of (x, z) from edge k: nx x + nz z + c
  double gx = 0, gz = 0;      ///< plane: y = y[0] + gx (x - x[0]) + gz (z - z[0])
  double area = 0, perimeter = 0;

  void set(int k, double px, double pz, double py) { x[k] = px, z[k] = pz, y[k] = py; }
  void finish() {
    perimeter = 0;
    for (int k = 0; k < 3; ++k) {
      const int a = k, b = (k + 1) % 3, o = (k + 2) % 3;
      const double ex = x[b] - x[a], ez = z[b] - z[a];
      const double len = std::sqrt(ex * ex + ez * ez);
      perimeter += len;
      double ux = -ez / len, uz = ex / len;
      if (ux * (x[o] - x[a]) + uz * (z[o] - z[a]) < 0) ux = -ux, uz = -uz;
      nx[k] = ux, nz[k] = uz, c[k] = -(ux * x[a] + uz * z[a]);
    }
    const double dx1 = x[1] - x[0], dz1 = z[1] - z[0], dy1 = y[1] - y[0];
    const double dx2 = x[2] - x[0], dz2 = z[2] - z[0], dy2 = y[2] - y[0];
    const double det = dx1 * dz2 - dz1 * dx2;
    gx = (dy1 * dz2 - dz1 * dy2) / det;
    gz = (dx1 * dy2 - dy1 * dx2) / det;
    area = 0.5 * std::fabs(det);
  }
  /// How far (x, z) lies outside the triangle (<= 0 inside).
  double outside(double px, double pz) const {
    double worst = -kInf;
    for (int k = 0; k < 3; ++k) worst = std::max(worst, -(nx[k] * px + nz[k] * pz + c[k]));
    return worst;
  }
  double planeY(double px, double pz) const { return y[0] + gx * (px - x[0]) + gz * (pz - z[0]); }
};

/// Signed map area of a triangle: positive when it faces up.
double signedArea(const Vertex& a, const Vertex& b, const Vertex& c) {
  const double d1x = double(b.x) - a.x, d1z = double(b.z) - a.z;
  const double d2x = double(c.x) - a.x, d2z = double(c.z) - a.z;
  return 0.5 * (d1z * d2x - d1x * d2z);
}

bool finiteVertex(const Vertex& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && std::isfinite(v.s) &&
         std::isfinite(v.t);
}

bool groupLess(const Group& a, const Group& b) {
  if (a.priority != b.priority) return a.priority < b.priority;
  if (a.square != b.square) return a.square < b.square;
  if (a.half != b.half) return a.half < b.half;
  return a.material < b.material;
}

const char* halfName(Half h) {
  switch (h) {
    case Half::upper: return "upper";
    case Half::lower: return "lower";
    case Half::skirt: return "skirt";
  }
  return "?";
}

// ---------------------------------------------------------------- one module

class ModuleRun {
 public:
  ModuleRun(const grid::HeightField& g, const pack::IndexHeader& h, const CheckOptions& o,
            const std::vector<int>& classIndex, const Module& m, std::uint64_t offset, Report& r)
      : g_(g), h_(h), o_(o), classIndex_(classIndex), m_(m), offset_(offset), r_(r) {
    who_ = "module (" + str(m.kx) + "," + str(m.kz) + ")";
  }

  void run(ModuleEdges* edges) {
    if (edges) {
      edges->kx = m_.kx;
      edges->kz = m_.kz;
      edges->offset = offset_;
      edges->levels.clear();
    }
    if (!frame()) return;
    if (m_.levels.size() != h_.levels && r_.want(kStructure)) {
      r_.add(offset_, who_ + " has " + str(m_.levels.size()) + " levels; the pack index says " +
                          str(h_.levels));
    }
    const std::size_t levels = std::min<std::size_t>(m_.levels.size(), 31);
    requiredDepths(levels);
    if (edges) edges->levels.resize(levels);
    for (std::size_t l = 0; l < levels; ++l) level(l, edges ? &edges->levels[l] : nullptr);
  }

 private:
  const grid::HeightField& g_;
  const pack::IndexHeader& h_;
  const CheckOptions& o_;
  const std::vector<int>& classIndex_;
  const Module& m_;
  std::uint64_t offset_;
  Report& r_;
  std::string who_;
  Frame f_;
  std::vector<Need> need_;

  // Per-level state (reused across levels).
  std::string at_;  ///< "module (kx,kz) level l"
  Axis xs_, zs_;
  std::vector<float> heights_;  ///< lattice elevations, row-major (zs x xs)
  double tolY_ = 0, ulpXZ_ = 0, quantY_ = 0;
  std::vector<double> skinArea_;       ///< [2 * square + half]
  std::vector<float> highest_;         ///< highest skin/decal vertex per square
  std::vector<std::uint8_t> used_;     ///< per vertex: 1 skin, 2 decal
  std::array<std::vector<double>, 4> edgeArea_;        ///< skirt area per edge segment
  std::array<std::vector<std::uint8_t>, 4> corners_;  ///< band corners seen per edge segment

  float height(std::size_t col, std::size_t row) const { return heights_[row * xs_.posts.size() + col]; }

  bool frame() {
    const std::uint32_t sq = h_.moduleSquares;
    const std::uint64_t i0 = std::uint64_t(m_.kx) * sq, j0 = std::uint64_t(m_.kz) * sq;
    if (sq == 0 || m_.kx >= h_.modulesX || m_.kz >= h_.modulesZ || i0 >= g_.postsX() - 1 ||
        j0 >= g_.postsZ() - 1) {
      if (r_.want(kStructure)) {
        r_.add(offset_, who_ + " lies outside the database (" + str(h_.modulesX) + " x " +
                            str(h_.modulesZ) + " modules of " + str(sq) + " squares over " +
                            str(g_.postsX()) + " x " + str(g_.postsZ()) + " posts)");
      }
      return false;
    }
    f_.i0 = std::uint32_t(i0);
    f_.j0 = std::uint32_t(j0);
    f_.i1 = std::uint32_t(std::min<std::uint64_t>(i0 + sq, g_.postsX() - 1));
    f_.j1 = std::uint32_t(std::min<std::uint64_t>(j0 + sq, g_.postsZ() - 1));
    f_.width = double(f_.i1 - f_.i0) * g_.spacing();
    f_.height = double(f_.j1 - f_.j0) * g_.spacing();
    f_.tolXZ = kCheckTolerance + ulpOf(std::max(f_.width, f_.height));
    f_.s0 = skinTextureOffset(double(f_.i0) * g_.spacing());
    f_.t0 = skinTextureOffset(double(f_.j0) * g_.spacing());
    // s * repeat carries the rounding of s (half an ulp of S0 + x) and of x.
    f_.tolST = f_.tolXZ + ulpOf(kSkinTextureWrap + std::max(f_.width, f_.height));
    return true;
  }

  /// For every level, how far its edge profile rises above the lowest
  /// profile of any level at any level-0 post along the module's edges: a
  /// neighbour drawn at that other level leaves a crack that deep, and this
  /// level's skirt is what hides it.
  void requiredDepths(std::size_t levels) {
    need_.assign(levels, Need{});
    if (levels == 0) return;
    std::vector<double> prof, lowest;
    for (int s = 0; s < 4; ++s) {
      const Side side = Side(s);
      const bool alongX = side == Side::north || side == Side::south;
      const std::uint32_t first = alongX ? f_.i0 : f_.j0, last = alongX ? f_.i1 : f_.j1;
      const std::uint32_t fixed = side == Side::north ? f_.j0
                                  : side == Side::south ? f_.j1
                                  : side == Side::west  ? f_.i0
                                                        : f_.i1;
      const std::size_t n = last - first + 1;
      prof.assign(levels * n, 0.0);
      lowest.assign(n, kInf);
      for (std::size_t k = 0; k < n; ++k) {
        const auto p = std::uint32_t(first + k);
        prof[k] = alongX ? g_.elevation(p, fixed) : g_.elevation(fixed, p);
      }
      for (std::size_t l = 1; l < levels; ++l) {
        const std::size_t step = std::size_t(1) << l;
        for (std::size_t k = 0; k < n; ++k) {
          const std::size_t a = std::min(k / step * step, n - 1), b = std::min(a + step, n - 1);
          const double fr = b == a ? 0.0 : double(k - a) / double(b - a);
          prof[l * n + k] = prof[a] + fr * (prof[b] - prof[a]);
        }
      }
      for (std::size_t l = 0; l < levels; ++l) {
        for (std::size_t k = 0; k < n; ++k) lowest[k] = std::min(lowest[k], prof[l * n + k]);
      }
      for (std::size_t l = 0; l < levels; ++l) {
        for (std::size_t k = 0; k < n; ++k) {
          const double d = prof[l * n + k] - lowest[k];
          if (d > need_[l].depth) {
            std::size_t other = 0;
            for (std::size_t o = 0; o < levels; ++o) {
              if (prof[o * n + k] == lowest[k]) other = o;
            }
            need_[l] = {d, side, double(k) * g_.spacing(), other};
          }
        }
      }
    }
  }

  void level(std::size_t l, std::array<std::vector<ModuleEdges::Point>, 4>* edges) {
    const Level& lv = m_.levels[l];
    at_ = who_ + " level " + str(l);
    const std::uint32_t step = 1u << l;
    xs_ = makeAxis(f_.i0, f_.i1, step, g_.spacing());
    zs_ = makeAxis(f_.j0, f_.j1, step, g_.spacing());
    if (lv.squaresX != xs_.segments() || lv.squaresZ != zs_.segments()) {
      if (r_.want(kStructure)) {
        r_.add(offset_, at_ + " has " + str(lv.squaresX) + " x " + str(lv.squaresZ) +
                            " squares; the lattice of posts every " + str(step) + " has " +
                            str(xs_.segments()) + " x " + str(zs_.segments()));
      }
      return;  // nothing below can be located
    }
    const double spacing = g_.spacing() * double(step);
    if (!(std::fabs(lv.spacing - spacing) <= 1e-9 * spacing) && r_.want(kStructure)) {
      r_.add(offset_, at_ + " spacing is " + g9(lv.spacing) + " m; posts every " + str(step) +
                          " at " + g9(g_.spacing()) + " m give " + g9(spacing) + " m");
    }
    const std::size_t squares = xs_.segments() * zs_.segments();
    const bool maxHeightSized = lv.maxHeight.size() == squares;
    if (!maxHeightSized && r_.want(kStructure)) {
      r_.add(offset_, at_ + " maxHeight has " + str(lv.maxHeight.size()) + " entries for " +
                          str(squares) + " squares");
    }
    const bool depthOk = std::isfinite(lv.skirtDepth) && lv.skirtDepth > 0;
    if (!depthOk && r_.want(kSkirtDepth)) {
      r_.add(offset_, at_ + ": skirt depth " + g6(lv.skirtDepth) + " m must be a positive number");
    }

    heights_.resize(xs_.posts.size() * zs_.posts.size());
    double maxAbs = 0;
    for (std::size_t b = 0; b < zs_.posts.size(); ++b) {
      for (std::size_t a = 0; a < xs_.posts.size(); ++a) {
        const float e = g_.elevation(xs_.posts[a], zs_.posts[b]);
        heights_[b * xs_.posts.size() + a] = e;
        maxAbs = std::max(maxAbs, std::fabs(double(e)));
      }
    }
    ulpXZ_ = ulpOf(std::max(f_.width, f_.height));
    // A quantised level (module v2) moves every height by up to half its step.
    quantY_ = lv.heightStep > 0 ? 0.5 * lv.heightStep + ulpOf(maxAbs) : 0.0;
    tolY_ = kCheckTolerance + ulpOf(maxAbs + (depthOk ? double(lv.skirtDepth) : 0.0)) + quantY_;
    skinArea_.assign(2 * squares, 0.0);
    highest_.assign(squares, -std::numeric_limits<float>::infinity());
    used_.assign(lv.vertices.size(), 0);
    for (int s = 0; s < 4; ++s) {
      const Axis& ax = (Side(s) == Side::north || Side(s) == Side::south) ? xs_ : zs_;
      edgeArea_[std::size_t(s)].assign(ax.segments(), 0.0);
      corners_[std::size_t(s)].assign(ax.segments(), 0);
    }

    groups(lv);
    coverage();
    posts(lv);
    if (maxHeightSized) maxHeights(lv);
    if (depthOk) skirtCoverage(double(lv.skirtDepth));
    if (depthOk && double(lv.skirtDepth) + tolY_ < need_[l].depth && r_.want(kSkirtDepth)) {
      const Need& n = need_[l];
      r_.add(offset_, at_ + ": skirt depth " + m3(lv.skirtDepth) + " m is less than " + m3(n.depth) +
                          " m, how far this level's edge lies above level " + str(n.otherLevel) +
                          "'s on the " + sideName(n.side) + " edge at " + alongName(n.side) + " " +
                          m3(n.t) + " (a neighbour drawn at that level would leave a crack)");
    }
    objects(lv, l);
    if (edges) collectEdges(lv, *edges);
  }

  // ------------------------------------------------------------ objects

  /// Grid triangle height of this level's lattice at module-local (x, z):
  /// from the grid's posts, not the module's triangles.
  double latticeHeight(double x, double z) const {
    const std::size_t a = xs_.segment(x), b = zs_.segment(z);
    const double x0 = xs_.local[a], x1 = xs_.local[a + 1], z0 = zs_.local[b], z1 = zs_.local[b + 1];
    const double u = (x - x0) / (x1 - x0), v = (z - z0) / (z1 - z0);
    const double nw = height(a, b), ne = height(a + 1, b), sw = height(a, b + 1), se = height(a + 1, b + 1);
    return terrain::planeHeight(u, v, nw, ne, sw, se);
  }

  /// Every object stands inside the module, names an icon of icons.pack and
  /// has its base on this level's surface (seed Figure 87).
  void objects(const Level& lv, std::size_t l) {
    if (lv.objectY.size() != m_.objects.size()) {
      if (r_.want(kObject)) {
        r_.add(offset_, at_ + " has " + str(lv.objectY.size()) + " object elevations for the module's " +
                            str(m_.objects.size()) + " objects");
      }
      return;
    }
    for (std::size_t k = 0; k < m_.objects.size(); ++k) {
      const Object& o = m_.objects[k];
      const std::string who = at_ + " object " + str(k);
      if (l == 0 && o_.iconCount && o.icon >= *o_.iconCount && r_.want(kObject)) {
        r_.add(offset_, who + " icon " + str(o.icon) + " is not in icons.pack, which holds " + str(*o_.iconCount));
      }
      if (!(o.x >= -f_.tolXZ && o.x <= f_.width + f_.tolXZ && o.z >= -f_.tolXZ && o.z <= f_.height + f_.tolXZ)) {
        if (l == 0 && r_.want(kObject)) {
          r_.add(offset_, who + " at (" + m3(o.x) + ", " + m3(o.z) + ") lies outside the module's " + m3(f_.width) +
                              " x " + m3(f_.height) + " m");
        }
        continue;
      }
      const double want = latticeHeight(o.x, o.z);
      if (!(std::fabs(double(lv.objectY[k]) - want) <= kCheckObjectTolerance + ulpOf(want)) && r_.want(kObject)) {
        r_.add(offset_, who + " base y " + g9(lv.objectY[k]) + " is " + m3(double(lv.objectY[k]) - want) +
                            " m off the level's surface at (" + m3(o.x) + ", " + m3(o.z) + "), " + g9(want) +
                            " (it would float or sink)");
      }
    }
  }

  // ------------------------------------------------------------ groups

  void groups(const Level& lv) {
    bool unsorted = false;
    for (std::size_t gi = 0; gi < lv.groups.size(); ++gi) {
      const Group& g = lv.groups[gi];
      auto where = [&] { return at_ + " group " + str(gi); };
      if (gi > 0 && groupLess(g, lv.groups[gi - 1]) && !unsorted) {
        unsorted = true;
        if (r_.want(kStructure)) {
          r_.add(offset_, where() + " is out of (priority, square, half, material) order");
        }
      }
      if (g.indexCount % 3 != 0 || std::uint64_t(g.firstIndex) + g.indexCount > lv.indices.size()) {
        if (r_.want(kStructure)) {
          r_.add(offset_, where() + " indices " + str(g.firstIndex) + " + " + str(g.indexCount) +
                              " are not whole triangles within the " + str(lv.indices.size()) +
                              " indices");
        }
        continue;
      }
      if (g.square >= highest_.size() || std::uint8_t(g.half) > std::uint8_t(Half::skirt)) {
        if (r_.want(kStructure)) {
          r_.add(offset_, where() + " square " + str(g.square) + " half " + str(std::uint8_t(g.half)) +
                              " is not a grid triangle of the level (" + str(highest_.size()) +
                              " squares)");
        }
        continue;
      }
      const bool skin = g.priority == kPrioritySkin;
      const bool decal = g.priority > kPrioritySkin && g.priority < kPriorityObject;
      const bool object = g.priority == kPriorityObject;
      if (!skin && !decal && !object) {
        if (r_.want(kStructure)) {
          r_.add(offset_, where() + " priority " + str(g.priority) +
                              " is none of skin (1), decal (2..98) or object (99)");
        }
        continue;
      }
      material(g, gi);
      if (g.half == Half::skirt) {
        skirtGroup(lv, g);
      } else if (object) {
        indicesOnly(lv, g);
      } else {
        faceGroup(lv, g, skin);
      }
    }
  }

  std::string squareName(const Group& g) const {
    return at_ + " square " + str(g.square) + " " + halfName(g.half);
  }

  void material(const Group& g, std::size_t gi) {
    if (!o_.materials) return;
    auto where = [&] { return at_ + " group " + str(gi); };
    const int ci = g.material < classIndex_.size() ? classIndex_[g.material] : -1;
    if (ci < 0) {
      if (r_.want(kMaterial)) {
        r_.add(offset_, where() + " (" + halfName(g.half) + ", priority " + str(g.priority) +
                            ") uses material " + str(g.material) + ", which " + materials::kFileName +
                            " does not define");
      }
      return;
    }
    if (g.half == Half::skirt || g.priority == kPriorityObject) return;
    const materials::Class& c = o_.materials->classes[std::size_t(ci)];
    if (g.priority == kPrioritySkin && c.kind != materials::Kind::area) {
      if (r_.want(kMaterial)) {
        r_.add(offset_, where() + " is skin but uses line class '" + c.name + "' (" +
                            str(g.material) + "); skin uses area classes");
      }
    } else if (g.priority != kPrioritySkin &&
               (c.kind != materials::Kind::line || c.priority != g.priority)) {
      if (r_.want(kMaterial)) {
        r_.add(offset_, where() + " is a decal of priority " + str(g.priority) + " but uses " +
                            (c.kind == materials::Kind::line ? "line" : "area") + " class '" +
                            c.name + "' (" + str(g.material) + ") of priority " + str(c.priority));
      }
    }
  }

  /// Fetches triangle k of group g; false (reported) when an index or a
  /// coordinate is bad.
  bool triangle(const Level& lv, const Group& g, std::uint32_t k, const Vertex*& a,
                const Vertex*& b, const Vertex*& c) {
    const std::uint32_t at = g.firstIndex + 3 * k;
    const std::uint32_t ia = lv.indices[at], ib = lv.indices[at + 1], ic = lv.indices[at + 2];
    const std::size_t n = lv.vertices.size();
    if (ia >= n || ib >= n || ic >= n) {
      if (r_.want(kStructure)) {
        r_.add(offset_, at_ + " index " + str(at) + " refers past the " + str(n) + " vertices");
      }
      return false;
    }
    a = &lv.vertices[ia], b = &lv.vertices[ib], c = &lv.vertices[ic];
    for (const std::uint32_t v : {ia, ib, ic}) {
      if (!finiteVertex(lv.vertices[v])) {
        if (r_.want(kNonFinite)) {
          const Vertex& p = lv.vertices[v];
          r_.add(offset_, at_ + " vertex " + str(v) + " (" + g9(p.x) + ", " + g9(p.y) + ", " +
                              g9(p.z) + ", s " + g9(p.s) + ", t " + g9(p.t) +
                              ") is not finite");
        }
        return false;
      }
    }
    return true;
  }

  void indicesOnly(const Level& lv, const Group& g) {
    const Vertex *a, *b, *c;
    for (std::uint32_t k = 0; k < g.indexCount / 3; ++k) triangle(lv, g, k, a, b, c);
  }

  GridTriangle gridTriangle(std::uint32_t square, Half half) const {
    const std::size_t sx = square % xs_.segments(), sz = square / xs_.segments();
    const double xw = xs_.local[sx], xe = xs_.local[sx + 1];
    const double zn = zs_.local[sz], zs = zs_.local[sz + 1];
    GridTriangle t;
    const auto corners = terrain::halfCorners(half, std::array{terrain::kNW, terrain::kNE, terrain::kSW, terrain::kSE});
    for (int k = 0; k < 3; ++k) {
      const terrain::Corner c = corners[std::size_t(k)];
      const std::uint32_t east = terrain::east(c), south = terrain::south(c);
      t.set(k, east ? xe : xw, south ? zs : zn, height(sx + east, sz + south));
    }
    t.finish();
    return t;
  }

  /// Skin (priority 1) or decal (2..98) triangles of one grid triangle.
  void faceGroup(const Level& lv, const Group& g, bool skin) {
    const GridTriangle gt = gridTriangle(g.square, g.half);
    const char* what = skin ? "skin" : "decal";
    float& top = highest_[g.square];
    double area = 0;
    for (std::uint32_t k = 0; k < g.indexCount / 3; ++k) {
      const Vertex *v[3];
      if (!triangle(lv, g, k, v[0], v[1], v[2])) continue;
      const std::uint32_t at = g.firstIndex + 3 * k;
      double worstOut = 0, worstPlane = 0;
      int outV = -1, planeV = -1;
      for (int q = 0; q < 3; ++q) {
        const double out = gt.outside(v[q]->x, v[q]->z);
        if (out > f_.tolXZ && out > worstOut) worstOut = out, outV = q;
        const double dy = std::fabs(double(v[q]->y) - gt.planeY(v[q]->x, v[q]->z));
        if (dy > tolY_ && dy > worstPlane) worstPlane = dy, planeV = q;
        top = std::max(top, v[q]->y);
        const std::uint32_t vi = lv.indices[at + std::uint32_t(q)];
        const auto role = std::uint8_t(skin ? 1 : 2);
        if (!(used_[vi] & role)) texture(g, vi, *v[q], skin);
        used_[vi] |= role;
      }
      if (outV >= 0 && r_.want(kOutside)) {
        const Vertex& p = *v[outV];
        r_.add(offset_, squareName(g) + ": " + what + " triangle at index " + str(at) + " vertex " +
                            str(lv.indices[at + std::uint32_t(outV)]) + " (x " + m3(p.x) + ", z " +
                            m3(p.z) + ") lies " + m3(worstOut) + " m outside the grid triangle");
      }
      if (planeV >= 0 && r_.want(kPlane)) {
        const Vertex& p = *v[planeV];
        r_.add(offset_, squareName(g) + ": " + what + " triangle at index " + str(at) + " vertex " +
                            str(lv.indices[at + std::uint32_t(planeV)]) + " (x " + m3(p.x) + ", z " +
                            m3(p.z) + ") has y " + m3(p.y) + ", " + m3(worstPlane) +
                            " m off the grid triangle's plane (" + m3(gt.planeY(p.x, p.z)) + ")");
      }
      const double s = signedArea(*v[0], *v[1], *v[2]);
      double longest2 = 0;
      for (int q = 0; q < 3; ++q) {
        const Vertex& p = *v[q];
        const Vertex& n = *v[(q + 1) % 3];
        const double dx = double(n.x) - p.x, dz = double(n.z) - p.z;
        longest2 = std::max(longest2, dx * dx + dz * dz);
      }
      // Signed height of the triangle over its longest edge. Slivers within
      // the tolerance either way are accepted: rounding exact geometry to
      // float32 leaves some with no area or a tiny negative one, they cover
      // no pixel, and the area sum (coverage) still counts them.
      const double thick = longest2 > 0 ? 2 * s / std::sqrt(longest2) : 0;
      if (thick < -kCheckTolerance && r_.want(kOrientation)) {
        r_.add(offset_, squareName(g) + ": " + what + " triangle at index " + str(at) +
                            " faces down (clockwise seen from above, area " + g6(s) + " m^2)");
      }
      area += s;
    }
    if (skin) skinArea_[2 * std::size_t(g.square) + std::uint8_t(g.half)] += area;
  }

  /// Texture coordinates of a skin or decal vertex (module.h), once per
  /// vertex and role.
  void texture(const Group& g, std::uint32_t vi, const Vertex& v, bool skin) {
    if (skin) {
      const double ds = double(v.s) * kSkinTextureRepeat - (f_.s0 + v.x);
      const double dt = double(v.t) * kSkinTextureRepeat - (f_.t0 + v.z);
      if ((std::fabs(ds) > f_.tolST || std::fabs(dt) > f_.tolST) && r_.want(kTexture)) {
        r_.add(offset_, squareName(g) + ": skin vertex " + str(vi) + " at x " + m3(v.x) + ", z " + m3(v.z) +
                            " has texture s " + g9(v.s) + ", t " + g9(v.t) + "; its position gives s " +
                            g9((f_.s0 + v.x) / kSkinTextureRepeat) + ", t " + g9((f_.t0 + v.z) / kSkinTextureRepeat) +
                            " (skin repeats every " + m3(kSkinTextureRepeat) + " m from offsets " + m3(f_.s0) +
                            ", " + m3(f_.t0) + " m)");
      }
      return;
    }
    if (!(v.s >= 0.0f && v.t >= 0.0f && v.t <= 1.0f) && r_.want(kTexture)) {
      r_.add(offset_, squareName(g) + ": decal vertex " + str(vi) + " has texture s " + g9(v.s) + ", t " +
                          g9(v.t) + "; a line's s (along, in widths) must be >= 0 and its t (across) in [0, 1]");
    }
  }

  /// Skirt triangles: vertical, on one lattice line, within one lattice
  /// segment, inside the band from the level's edge down skirtDepth.
  void skirtGroup(const Level& lv, const Group& g) {
    const double d = std::isfinite(lv.skirtDepth) ? double(lv.skirtDepth) : 0.0;
    const double tol = f_.tolXZ;
    for (std::uint32_t k = 0; k < g.indexCount / 3; ++k) {
      const Vertex *v[3];
      if (!triangle(lv, g, k, v[0], v[1], v[2])) continue;
      const std::uint32_t at = g.firstIndex + 3 * k;
      // On a column line (x fixed, t = z) or a row line (z fixed, t = x)?
      const long col = xs_.line(v[0]->x, tol), row = zs_.line(v[0]->z, tol);
      auto onCol = [&] {
        if (col < 0) return false;
        for (auto* p : v) if (std::fabs(p->x - xs_.local[std::size_t(col)]) > tol) return false;
        return true;
      };
      auto onRow = [&] {
        if (row < 0) return false;
        for (auto* p : v) if (std::fabs(p->z - zs_.local[std::size_t(row)]) > tol) return false;
        return true;
      };
      const bool c = onCol(), r = onRow();
      if (c && r) continue;  // all on one vertical: no area, nothing to hang
      if (!c && !r) {
        if (r_.want(kSkirt)) {
          r_.add(offset_, at_ + " skirt group of square " + str(g.square) + ": triangle at index " +
                              str(at) + " is not vertical on a lattice line of the level");
        }
        continue;
      }
      const Axis& along = c ? zs_ : xs_;
      const std::size_t line = std::size_t(c ? col : row);
      double t[3];
      for (int q = 0; q < 3; ++q) t[q] = c ? v[q]->z : v[q]->x;
      const double tmin = std::min({t[0], t[1], t[2]}), tmax = std::max({t[0], t[1], t[2]});
      const std::size_t seg = along.segment(0.5 * (tmin + tmax));
      const double t0 = along.local[seg], t1 = along.local[seg + 1];
      if (tmin < t0 - tol || tmax > t1 + tol) {
        if (r_.want(kSkirt)) {
          r_.add(offset_, at_ + " skirt triangle at index " + str(at) + " spans " + (c ? "z " : "x ") +
                              m3(tmin) + ".." + m3(tmax) + ", more than one lattice segment");
        }
        continue;
      }
      const double hA = c ? height(line, seg) : height(seg, line);
      const double hB = c ? height(line, seg + 1) : height(seg + 1, line);
      double worst = 0;
      int worstV = -1;
      for (int q = 0; q < 3; ++q) {
        const double top = hA + (t[q] - t0) / (t1 - t0) * (hB - hA);
        const double y = v[q]->y;
        const double out = std::max(y - top, (top - d) - y);
        if (out > tolY_ && out > worst) worst = out, worstV = q;
      }
      if (worstV >= 0 && r_.want(kSkirt)) {
        const Vertex& p = *v[worstV];
        r_.add(offset_, at_ + " skirt triangle at index " + str(at) + " vertex (x " + m3(p.x) + ", z " +
                            m3(p.z) + ", y " + m3(p.y) + ") lies " + m3(worst) +
                            " m outside the band from the edge down " + m3(d) + " m");
        continue;
      }
      // Module edges: accumulate coverage.
      int side = -1;
      if (c && line == 0) side = int(Side::west);
      if (c && line == xs_.segments()) side = int(Side::east);
      if (!c && line == 0) side = int(Side::north);
      if (!c && line == zs_.segments()) side = int(Side::south);
      if (side < 0) continue;
      const double ya = v[0]->y, yb = v[1]->y, yc = v[2]->y;
      edgeArea_[std::size_t(side)][seg] +=
          0.5 * std::fabs((t[1] - t[0]) * (yc - ya) - (t[2] - t[0]) * (yb - ya));
      std::uint8_t& seen = corners_[std::size_t(side)][seg];
      for (int q = 0; q < 3; ++q) {
        const double y = v[q]->y;
        if (std::fabs(t[q] - t0) <= tol) {
          if (std::fabs(y - hA) <= tolY_) seen |= 1;
          if (std::fabs(y - (hA - d)) <= tolY_) seen |= 2;
        }
        if (std::fabs(t[q] - t1) <= tol) {
          if (std::fabs(y - hB) <= tolY_) seen |= 4;
          if (std::fabs(y - (hB - d)) <= tolY_) seen |= 8;
        }
      }
    }
  }

  // ------------------------------------------------------------ per level

  void coverage() {
    const std::size_t squares = highest_.size();
    for (std::size_t sq = 0; sq < squares; ++sq) {
      for (const Half half : {Half::upper, Half::lower}) {
        const double got = skinArea_[2 * sq + std::uint8_t(half)];
        const GridTriangle gt = gridTriangle(std::uint32_t(sq), half);
        const double tol = kCheckAreaTolerance * gt.area + 2 * gt.perimeter * ulpXZ_;
        if (std::fabs(got - gt.area) > tol && r_.want(kCoverage)) {
          r_.add(offset_, at_ + " square " + str(sq) + " " + halfName(half) + ": skin covers " +
                              g6(got / gt.area) + " of the triangle (area " + g6(got) + " of " +
                              g6(gt.area) + " m^2)");
        }
      }
    }
  }

  /// Skin and decal vertices on a lattice post carry the grid's elevation
  /// exactly.
  void posts(const Level& lv) {
    for (std::size_t v = 0; v < used_.size(); ++v) {
      if (!used_[v]) continue;
      const Vertex& p = lv.vertices[v];
      const long a = xs_.line(p.x, f_.tolXZ), b = zs_.line(p.z, f_.tolXZ);
      if (a < 0 || b < 0) continue;
      const float e = height(std::size_t(a), std::size_t(b));
      if (p.y != e && !(std::fabs(double(p.y) - e) <= quantY_) && r_.want(kPost)) {
        r_.add(offset_, at_ + " vertex " + str(v) + " at lattice post (" + str(a) + "," + str(b) +
                            ") = grid post (" + str(xs_.posts[std::size_t(a)]) + "," +
                            str(zs_.posts[std::size_t(b)]) + ") has y " + g9(p.y) +
                            "; the grid says " + g9(e));
      }
    }
  }

  void maxHeights(const Level& lv) {
    for (std::size_t sq = 0; sq < highest_.size(); ++sq) {
      const float hi = highest_[sq];
      if (hi == -std::numeric_limits<float>::infinity()) continue;  // no skin: reported above
      const float mh = lv.maxHeight[sq];
      if (!(mh >= hi) || !(double(mh) - hi <= kCheckMaxHeightTolerance)) {
        if (r_.want(kMaxHeight)) {
          r_.add(offset_, at_ + " square " + str(sq) + ": maxHeight " + g9(mh) +
                              " but the highest vertex is " + g9(hi));
        }
      }
    }
  }

  /// Every segment of the module's edges is hung with skirt down to the
  /// level's skirtDepth: the band's area is covered and its four corners
  /// are vertices.
  void skirtCoverage(double d) {
    for (int s = 0; s < 4; ++s) {
      const Side side = Side(s);
      const Axis& ax = (side == Side::north || side == Side::south) ? xs_ : zs_;
      for (std::size_t seg = 0; seg < ax.segments(); ++seg) {
        const double len = ax.local[seg + 1] - ax.local[seg];
        const double want = len * d;
        const double got = edgeArea_[std::size_t(s)][seg];
        const double tol =
            kCheckAreaTolerance * want + 4 * (len + d) * std::max(ulpXZ_, tolY_ - kCheckTolerance);
        auto where = [&] {
          return at_ + " " + sideName(side) + " edge " + alongName(side) + " " + m3(ax.local[seg]) + ".." +
                 m3(ax.local[seg + 1]);
        };
        if (got < want - tol) {
          if (r_.want(kSkirtCoverage)) {
            r_.add(offset_, where() + ": skirt covers " + g6(got / want) + " of the band " + m3(d) +
                                " m below the edge (area " + g6(got) + " of " + g6(want) + " m^2)");
          }
        } else if (corners_[std::size_t(s)][seg] != 15 && r_.want(kSkirtCoverage)) {
          r_.add(offset_, where() + ": skirt does not reach every corner of the band " + m3(d) +
                              " m below the edge");
        }
      }
    }
  }

  void collectEdges(const Level& lv, std::array<std::vector<ModuleEdges::Point>, 4>& e) {
    for (auto& side : e) side.clear();
    const double tol = f_.tolXZ;
    for (std::size_t v = 0; v < used_.size(); ++v) {
      if (!(used_[v] & 1)) continue;
      const Vertex& p = lv.vertices[v];
      if (std::fabs(p.z) <= tol) e[std::size_t(Side::north)].push_back({p.x, p.y});
      if (std::fabs(p.z - f_.height) <= tol) e[std::size_t(Side::south)].push_back({p.x, p.y});
      if (std::fabs(p.x) <= tol) e[std::size_t(Side::west)].push_back({p.z, p.y});
      if (std::fabs(p.x - f_.width) <= tol) e[std::size_t(Side::east)].push_back({p.z, p.y});
    }
    for (auto& side : e) {
      std::sort(side.begin(), side.end(), [](const auto& a, const auto& b) {
        return a.t < b.t || (a.t == b.t && a.y < b.y);
      });
      std::size_t w = 0;
      for (std::size_t k = 0; k < side.size(); ++k) {
        if (w > 0 && std::fabs(side[k].t - side[w - 1].t) <= tol &&
            std::fabs(side[k].y - side[w - 1].y) <= tolY_) {
          continue;
        }
        side[w++] = side[k];
      }
      side.resize(w);
    }
  }
};

}  // namespace

ModuleChecker::ModuleChecker(const grid::GridFile& grid, const pack::IndexHeader& header,
                             std::string file, CheckOptions options)
    : owned_(std::make_unique<const grid::GridHeightField>(grid)),
      grid_(*owned_),
      header_(header),
      file_(std::move(file)),
      options_(options) {
  indexClasses();
}

ModuleChecker::~ModuleChecker() = default;

ModuleChecker::ModuleChecker(const grid::HeightField& grid, const pack::IndexHeader& header,
                             std::string file, CheckOptions options)
    : grid_(grid), header_(header), file_(std::move(file)), options_(options) {
  indexClasses();
}

void ModuleChecker::indexClasses() {
  if (options_.materials) {
    for (std::size_t k = 0; k < options_.materials->classes.size(); ++k) {
      const std::uint16_t id = options_.materials->classes[k].id;
      if (classIndex_.size() <= id) classIndex_.resize(std::size_t(id) + 1, -1);
      classIndex_[id] = int(k);
    }
  }
}

Status ModuleChecker::check(const Module& m, std::uint64_t offset, ModuleEdges* edges) const {
  Status out;
  Report r(file_, "module (" + str(m.kx) + "," + str(m.kz) + ")", options_.maxPerKind, out);
  ModuleRun run(grid_, header_, options_, classIndex_, m, offset, r);
  run.run(edges);
  r.finish(offset);
  return out;
}

Status ModuleChecker::neighbours(const ModuleEdges& a, const ModuleEdges& b) const {
  const bool eastOf = b.kx == a.kx + 1 && b.kz == a.kz;
  const bool southOf = b.kz == a.kz + 1 && b.kx == a.kx;
  assert((eastOf || southOf) && "neighbours: b must lie east or south of a");
  if (!eastOf && !southOf) return {};
  const Side sa = eastOf ? Side::east : Side::south;
  const Side sb = eastOf ? Side::west : Side::north;
  const std::string nameA = "module (" + str(a.kx) + "," + str(a.kz) + ")";
  const std::string nameB = "module (" + str(b.kx) + "," + str(b.kz) + ")";
  Status out;
  Report r(file_, "modules (" + str(a.kx) + "," + str(a.kz) + ") and (" + str(b.kx) + "," +
                      str(b.kz) + ")",
           options_.maxPerKind, out);
  const double tolT = kCheckTolerance + ulpOf(header_.moduleSize);
  const char* t = alongName(sa);
  const std::size_t levels = std::min(a.levels.size(), b.levels.size());
  for (std::size_t l = 0; l < levels; ++l) {
    const auto& pa = a.levels[l][std::size_t(sa)];
    const auto& pb = b.levels[l][std::size_t(sb)];
    auto lonely = [&](const ModuleEdges& me, const std::string& name, Side side,
                      const std::string& otherName, Side otherSide, const ModuleEdges::Point& p) {
      if (r.want(kNeighbour)) {
        r.add(me.offset, name + " level " + str(l) + " " + sideName(side) + " edge: skin vertex at " +
                             t + " " + m3(p.t) + " y " + m3(p.y) + " has no twin on the " +
                             sideName(otherSide) + " edge of " + otherName);
      }
    };
    std::size_t i = 0, j = 0;
    while (i < pa.size() || j < pb.size()) {
      if (i < pa.size() && j < pb.size() && std::fabs(pa[i].t - pb[j].t) <= tolT) {
        const double tolY = kCheckTolerance + ulpOf(std::max(std::fabs(pa[i].y), std::fabs(pb[j].y)));
        if (std::fabs(pa[i].y - pb[j].y) > tolY && r.want(kNeighbour)) {
          r.add(a.offset, nameA + " level " + str(l) + " " + sideName(sa) + " edge: skin vertex at " +
                              t + " " + m3(pa[i].t) + " has y " + m3(pa[i].y) + " but " + m3(pb[j].y) +
                              " on the " + sideName(sb) + " edge of " + nameB);
        }
        ++i, ++j;
      } else if (j >= pb.size() || (i < pa.size() && pa[i].t < pb[j].t)) {
        lonely(a, nameA, sa, nameB, sb, pa[i++]);
      } else {
        lonely(b, nameB, sb, nameA, sa, pb[j++]);
      }
    }
  }
  r.finish(a.offset);
  return out;
}

Status checkModule(const Module& m, const grid::GridFile& g, const pack::IndexHeader& h, const std::string& file,
                   std::uint64_t offset, const CheckOptions& o) {
  return ModuleChecker(g, h, file, o).check(m, offset);
}

Status checkNeighbours(const Module& a, std::uint64_t offsetA, const Module& b, std::uint64_t offsetB,
                       const grid::GridFile& g, const pack::IndexHeader& h, const std::string& file,
                       const CheckOptions& o) {
  const ModuleChecker checker(g, h, file, o);
  ModuleEdges ea, eb;
  checker.check(a, offsetA, &ea);
  checker.check(b, offsetB, &eb);
  return checker.neighbours(ea, eb);
}

}  // namespace sandtable::module
