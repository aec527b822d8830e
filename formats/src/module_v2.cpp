// Load modules, version 2 (module.h "layout, version 2"; docs/FORMAT.md
// §9.7): lattice vertices carry only a height code, heights are quantised,
// normals octahedral, everything else goes through meshoptimizer's codecs.
#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>

#include "module_internal.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::module {

// ------------------------------------------------------------ octahedral

namespace {

float signNotZero(float v) { return v < 0.0f ? -1.0f : 1.0f; }

std::uint32_t snorm16(float c) {
  const long q = std::lround(std::clamp(c, -1.0f, 1.0f) * 32767.0f);
  return std::uint32_t(std::uint16_t(std::int16_t(q)));
}

float unsnorm16(std::uint32_t bits) {
  return std::max(float(std::int16_t(std::uint16_t(bits))) / 32767.0f, -1.0f);
}

}  // namespace

std::uint32_t octEncode(float x, float y, float z) {
  const float n = std::fabs(x) + std::fabs(y) + std::fabs(z);
  if (!(n > 0.0f) || !std::isfinite(n)) return 0;  // no direction: up
  float u = x / n, v = z / n;
  if (y < 0.0f) {  // fold the lower hemisphere onto the corners
    const float fu = (1.0f - std::fabs(v)) * signNotZero(u);
    const float fv = (1.0f - std::fabs(u)) * signNotZero(v);
    u = fu, v = fv;
  }
  return snorm16(u) | snorm16(v) << 16;
}

std::array<float, 3> octDecode(std::uint32_t packed) {
  float u = unsnorm16(packed & 0xffffu), v = unsnorm16(packed >> 16);
  const float y = 1.0f - std::fabs(u) - std::fabs(v);
  if (y < 0.0f) {
    const float fu = (1.0f - std::fabs(v)) * signNotZero(u);
    const float fv = (1.0f - std::fabs(u)) * signNotZero(v);
    u = fu, v = fv;
  }
  const float len = std::sqrt(u * u + y * y + v * v);
  return {u / len, y / len, v / len};
}

namespace detail {
namespace {

std::string str(std::uint64_t v) { return std::to_string(v); }
std::uint32_t bits(float f) { return std::bit_cast<std::uint32_t>(f); }

std::uint32_t zigzag32(std::uint32_t d) { return (d << 1) ^ ((d >> 31) ? 0xffffffffu : 0u); }
std::uint32_t unzigzag32(std::uint32_t z) { return (z >> 1) ^ ((z & 1) ? 0xffffffffu : 0u); }
std::uint32_t zigzag16(std::uint32_t d) {
  d &= 0xffffu;
  return ((d << 1) & 0xffffu) ^ ((d >> 15) ? 0xffffu : 0u);
}
std::uint32_t unzigzag16(std::uint32_t z) { return ((z >> 1) ^ ((z & 1) ? 0xffffu : 0u)) & 0xffffu; }

/// Parallelogram prediction of post (a, b) of a (nx+1)-wide row-major
/// lattice from its west, north and north-west neighbours, modulo 2^32
/// (callers mask to 16 bits for normals): exact on planes, so smooth
/// terrain leaves small residuals.
template <typename Get>
std::uint32_t predict(std::size_t a, std::size_t b, std::size_t w, Get get) {
  if (a > 0 && b > 0) return get(b * w + a - 1) + get((b - 1) * w + a) - get((b - 1) * w + a - 1);
  if (a > 0) return get(b * w + a - 1);
  if (b > 0) return get((b - 1) * w + a);
  return 0;
}

// ---------------------------------------------------------------- LEB128

void putVarint(std::vector<std::byte>& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(std::byte(std::uint8_t(v) | 0x80));
    v >>= 7;
  }
  out.push_back(std::byte(std::uint8_t(v)));
}

/// Reads a LEB128 value of at most 10 bytes from [p, end); false when it
/// runs past the end or overflows 64 bits.
bool getVarint(const std::byte*& p, const std::byte* end, std::uint64_t& v) {
  v = 0;
  for (unsigned shift = 0; shift < 64 && p < end; shift += 7) {
    const auto b = std::uint8_t(*p++);
    if (shift == 63 && b > 1) return false;
    v |= std::uint64_t(b & 0x7f) << shift;
    if (!(b & 0x80)) return true;
  }
  return false;
}

std::uint64_t zigzag64(std::int64_t d) { return (std::uint64_t(d) << 1) ^ std::uint64_t(d >> 63); }
std::int64_t unzigzag64(std::uint64_t z) { return std::int64_t(z >> 1) ^ -std::int64_t(z & 1); }

/// Group position for runs: square * 4 + half.
std::uint64_t slotOf(std::uint32_t square, std::uint8_t half) { return std::uint64_t(square) * 4 + half; }
/// The slot of grid triangle h = 2 * square + half (half 0 or 1).
std::uint64_t halfSlot(std::uint64_t h) { return (h >> 1) * 4 + (h & 1); }
/// The slot that follows `slot` inside a run.
std::uint64_t nextSlot(std::uint64_t slot) {
  const std::uint64_t half = slot & 3;
  if (half == 0) return slot + 1;      // upper -> lower of the same square
  if (half == 1) return slot + 3;      // lower -> upper of the next square
  return slot + 4;                     // skirt -> skirt of the next square
}

// ---------------------------------------------------------------- encode

/// Sentinel of kXZExponentField: stream x and z are float bits.
constexpr std::int32_t kXZFloatBits = 0x7fff;
/// Version 3 and later: lattice-run groups a level may have per square.
constexpr std::uint64_t kMaxLatticeGroupsPerSquare = 2;
/// i16 at level offset 90, the upper half of the u32 that module.h names
/// levelField2::normalShift (u16 normal shift, i16 x/z exponent; kept out of
/// module.h so the layout change recompiles one file; docs/FORMAT.md §9.7.2).
constexpr std::size_t kXZExponentField = 90;

/// The largest e such that every stream x and z is an integer multiple of
/// 2^e that fits in 31 bits (the decaler snaps points to the float spacing
/// at the module's largest coordinate, so e is about -14 at 1 km); else
/// kXZFloatBits. Lossless either way; integers delta-code far better than
/// float bits in meshopt's vertex codec.
template <typename Pair>
std::int32_t integerExponent(std::size_t from, std::size_t to, Pair pair) {
  int e = 1000;
  double hi = 0;
  for (std::size_t i = from; i < to; ++i) {
    for (const float c : pair(i)) {
      if (!std::isfinite(c) || (c == 0.0f && std::signbit(c))) return kXZFloatBits;
      if (c == 0.0f) continue;
      int ex = 0;
      const double frac = std::frexp(double(c), &ex);
      const auto m = std::uint32_t(std::ldexp(std::fabs(frac), 24));
      e = std::min(e, ex - 24 + std::countr_zero(m));
      hi = std::max(hi, std::fabs(double(c)));
    }
  }
  if (e == 1000) return 0;  // all zero
  if (e < -149 || std::ldexp(hi, -e) >= 0x1p31) return kXZFloatBits;
  return e;
}
std::int32_t xzExponent(const std::vector<Vertex>& v, std::size_t from, std::size_t to) {
  return integerExponent(from, to, [&v](std::size_t i) { return std::array<float, 2>{v[i].x, v[i].z}; });
}
/// Version 4: the same for the s and t of the raw-texture vertices.
std::int32_t stExponent(const std::vector<Vertex>& v, std::size_t from, std::size_t to) {
  return integerExponent(from, to, [&v](std::size_t i) { return std::array<float, 2>{v[i].s, v[i].t}; });
}

std::uint32_t xzCode(std::int32_t e, float c) {
  return e == kXZFloatBits ? bits(c) : std::uint32_t(std::int32_t(std::ldexp(double(c), -e)));
}
float xzValue(std::int32_t e, std::uint32_t code) {
  return e == kXZFloatBits ? std::bit_cast<float>(code) : float(std::ldexp(double(std::int32_t(code)), e));
}
/// xzValue for one exponent, decoded many times: 2^e is a double and every
/// i32 times it is exact in double (|code| < 2^31, -149 <= e <= 127), so a
/// multiply gives ldexp's value without a libm call per coordinate.
struct XZDecoder {
  bool floatBits;
  double scale;
  explicit XZDecoder(std::int32_t e) : floatBits(e == kXZFloatBits), scale(floatBits ? 1.0 : std::ldexp(1.0, e)) {}
  float operator()(std::uint32_t code) const {
    return floatBits ? std::bit_cast<float>(code) : float(double(std::int32_t(code)) * scale);
  }
};

/// Bits of the skin texture coordinate at module-local x (or z) from offset o.
std::uint32_t skinBits(double o, float x) { return bits(float((o + double(x)) / kSkinTextureRepeat)); }

/// Module-local x of lattice column a (the builder's (post - i0) * spacing,
/// the last column clamped to the level's edge).
double latticeCoord(std::uint32_t a, std::uint32_t n, double spacing, double last) {
  return a < n ? double(a) * spacing : last;
}

/// An offset o with float((o + coord(k)) / repeat) == tex(k) for every k in
/// [0, n], searched near tex(0) * repeat (coord(0) is 0): the builder's
/// exact offset is not in the module, but any offset that reproduces every
/// value will do. False when none of the candidates does.
template <typename Coord, typename Tex>
bool findSkinOffset(std::uint32_t n, Coord coord, Tex tex, double& offset) {
  const float t0 = tex(0);
  if (!std::isfinite(t0)) return false;
  const double centre = double(t0) * kSkinTextureRepeat;
  const double ulp = double(std::nextafter(std::fabs(t0), std::numeric_limits<float>::infinity()) - std::fabs(t0)) *
                     kSkinTextureRepeat;
  for (int k = 0; k <= 32; ++k) {
    const int step = (k % 2 == 0) ? k / 2 : -(k + 1) / 2;  // 0, -1, 1, -2, 2, ...
    const double o = centre + step * ulp / 16.0;
    bool ok = true;
    for (std::uint32_t a = 0; a <= n && ok; ++a) {
      ok = bits(float((o + coord(a)) / kSkinTextureRepeat)) == bits(tex(a));
    }
    if (ok) {
      offset = o;
      return true;
    }
  }
  return false;
}

// ------------------------------------------------------- version 3 rules

/// Skirt vertices, indices and groups that implicit skirts add to a level
/// (terrain_rule.h, the rule meshing::addSkirts follows).
using terrain::SkirtCounts;
using terrain::skirtCounts;

/// The skirts of terrain_rule.h below a lattice whose posts are vertices
/// 0 .. (sx+1)(sz+1)-1 of `v`: bottom vertices written from v[base], and
/// per node (row-major) its group square and 12 * side squares indices.
/// The order is the builder's (meshing::addSkirts), so that an encoder can
/// compare bit for bit and a decoder rebuild the same level.
struct SkirtSink {
  Vertex* vertices;                   ///< room for SkirtCounts::vertices
  std::uint32_t* normals;             ///< null, or per vertex like `vertices`
  std::uint32_t* indices;             ///< room for SkirtCounts::indices
  std::uint32_t* squares;             ///< room for SkirtCounts::groups
  std::uint32_t* counts;              ///< index count per group
};

void makeSkirts(const Vertex* v, const std::uint32_t* normals, std::uint32_t sx, std::uint32_t sz,
                std::uint32_t node, float depth, std::uint32_t base, SkirtSink out) {
  const std::size_t w = std::size_t(sx) + 1;
  std::uint32_t next = base;
  std::size_t vi = 0, ii = 0, gi = 0;
  const auto side = [&](const terrain::SkirtSide& s) {
    const std::size_t n = s.posts() - 1;
    const std::size_t along = s.b0 == s.b1 ? 1 : w;  // post stride along the side
    const std::size_t from = s.b0 * w + s.a0;
    const std::uint32_t first = next;
    for (std::size_t k = 0, top = from; k <= n; ++k, top += along) {
      out.vertices[vi + k] = terrain::skirtBottom(v[top], depth);
    }
    if (out.normals) {
      for (std::size_t k = 0, top = from; k <= n; ++k, top += along) out.normals[vi + k] = normals[top];
    }
    for (std::size_t k = 1, top = from + along; k <= n; ++k, top += along) {
      const auto quad = terrain::skirtQuad(std::uint32_t(top - along), std::uint32_t(top),
                                           first + std::uint32_t(k) - 1, first + std::uint32_t(k));
      std::memcpy(out.indices + ii, quad.data(), sizeof quad);
      ii += quad.size();
    }
    vi += n + 1, next += std::uint32_t(n + 1);
  };
  terrain::forEachSkirtNode(sx, sz, node, [&](std::uint32_t square, const std::array<terrain::SkirtSide, 4>& sides) {
    const std::size_t start = ii;
    for (const terrain::SkirtSide& s : sides) side(s);
    out.squares[gi] = square;
    out.counts[gi] = std::uint32_t(ii - start);
    ++gi;
  });
}

/// The highest y over the indices of every non-skirt group, per square
/// (derived maxHeight; -infinity where a square has none). The square's
/// running maximum stays in a register while its groups follow each other
/// (the usual order), and a group's three heights are reduced before they
/// meet it, so the loop is not one long chain of dependent max operations
/// through memory. Encoder and decoder both call this, so they agree even
/// on the sign of a zero maximum.
void derivedMaxHeights(const Vertex* v, const std::uint32_t* idx, const Group* gr, std::size_t ng, float* mh,
                       std::size_t squares) {
  std::fill(mh, mh + squares, -std::numeric_limits<float>::infinity());
  const auto larger = [](float a, float b) { return a < b ? b : a; };  // std::max's choice
  std::uint32_t square = 0;
  float t = -std::numeric_limits<float>::infinity();
  for (std::size_t k = 0; k < ng; ++k) {
    if (gr[k].half == Half::skirt) continue;
    if (gr[k].square != square) {
      mh[square] = t;
      square = gr[k].square;
      t = mh[square];
    }
    const std::uint32_t* i = idx + gr[k].firstIndex;
    const std::uint32_t* const end = i + gr[k].indexCount;
    for (; i + 3 <= end; i += 3) t = larger(t, larger(larger(v[i[0]].y, v[i[1]].y), v[i[2]].y));
    for (; i < end; ++i) t = larger(t, v[*i].y);
  }
  if (squares > 0) mh[square] = t;
}

/// The lattice square (column or row) holding coordinate c: the nominal
/// spacing decides, clamped to 0 .. n-1 (the last square may be narrower).
std::size_t cellOf(float c, double spacing, std::uint32_t n) {
  const double f = double(c) / spacing;
  if (!(f > 0)) return 0;
  if (f >= double(n)) return n - 1;
  return std::size_t(f);
}

/// Height of the lattice triangle's plane (module.h "Grid triangles") at
/// (x, z), from the lattice posts' decoded x, z and `height(k)`. IEEE double
/// with no contraction (this file is built with -ffp-contract=off), so that
/// encoder and decoder agree bit for bit on every machine.
template <typename Height>
float planeY(const Vertex* lat, std::uint32_t sx, std::uint32_t sz, double spacing, float x, float z,
             Height height) {
  const std::size_t w = std::size_t(sx) + 1, a = cellOf(x, spacing, sx), b = cellOf(z, spacing, sz);
  const std::size_t nw = b * w + a, ne = nw + 1, sw = nw + w, se = sw + 1;
  const double u = (double(x) - lat[nw].x) / (double(lat[ne].x) - lat[nw].x);
  const double t = (double(z) - lat[nw].z) / (double(lat[sw].z) - lat[nw].z);
  return float(terrain::planeHeight(u, t, double(height(nw)), double(height(ne)), double(height(sw)),
                                    double(height(se))));
}

/// The lattice vertices of grid triangle (square, half) in the builder's
/// order: upper (NW, SW, NE), lower (NE, SW, SE) (module.h "Grid
/// triangles"). False for a skirt half or a square outside the level.
bool latticeTriangle(std::uint32_t square, std::uint8_t half, std::uint32_t sx, std::uint32_t sz,
                     std::uint32_t out[3]) {
  if (half > 1 || square >= std::uint64_t(sx) * sz) return false;
  const std::uint32_t w = sx + 1, nw = (square / sx) * w + square % sx;
  const auto tri = terrain::halfCorners(static_cast<Half>(half), std::array{nw, nw + 1, nw + w, nw + w + 1});
  std::copy(tri.begin(), tri.end(), out);
  return true;
}

struct Plan {
  std::uint32_t flags = 0;
  std::uint64_t posts = 0;  ///< P
  double step = 0;
  std::int64_t base = 0;
  double lastX = 0, lastZ = 0, s0 = 0, t0 = 0;
  std::uint32_t shift = 0;
  std::int32_t xzExp = kXZFloatBits;  ///< stream x, z stored as integers times 2^xzExp
  std::uint32_t rawTexture = 0;       ///< v4: trailing stream vertices with s, t stored apart
  std::int32_t stExp = kXZFloatBits;  ///< v4: their s, t as integers times 2^stExp
  std::uint32_t node = 0;             ///< v3 implicit skirts: node squares (else 0)
  std::uint16_t skirtMaterial = 0;
  SkirtCounts skirts;                 ///< what the implicit skirts stand for (else 0)
};

Plan plan(const Level& l, double heightStep) {
  Plan p;
  const std::uint32_t nx = l.squaresX, nz = l.squaresZ;
  const std::size_t w = std::size_t(nx) + 1;
  const std::uint64_t posts = std::uint64_t(w) * (std::uint64_t(nz) + 1);
  const auto& v = l.vertices;
  if (posts <= v.size()) {
    p.lastX = double(v[nx].x);
    p.lastZ = double(v[std::size_t(nz) * w].z);
    bool ok = true;
    for (std::uint32_t b = 0; b <= nz && ok; ++b) {
      const float z = float(latticeCoord(b, nz, l.spacing, p.lastZ));
      for (std::uint32_t a = 0; a <= nx && ok; ++a) {
        const Vertex& q = v[b * w + a];
        ok = bits(q.x) == bits(float(latticeCoord(a, nx, l.spacing, p.lastX))) && bits(q.z) == bits(z);
      }
    }
    ok = ok && findSkinOffset(
                   nx, [&](std::uint32_t a) { return latticeCoord(a, nx, l.spacing, p.lastX); },
                   [&](std::uint32_t a) { return v[a].s; }, p.s0);
    ok = ok && findSkinOffset(
                   nz, [&](std::uint32_t b) { return latticeCoord(b, nz, l.spacing, p.lastZ); },
                   [&](std::uint32_t b) { return v[b * w].t; }, p.t0);
    for (std::uint32_t b = 0; b <= nz && ok; ++b) {
      const float t = float((p.t0 + latticeCoord(b, nz, l.spacing, p.lastZ)) / kSkinTextureRepeat);
      for (std::uint32_t a = 0; a <= nx && ok; ++a) {
        const Vertex& q = v[b * w + a];
        ok = bits(q.t) == bits(t) &&
             bits(q.s) == bits(float((p.s0 + latticeCoord(a, nx, l.spacing, p.lastX)) / kSkinTextureRepeat));
      }
    }
    if (ok) p.flags |= kLevel2Lattice, p.posts = posts;
  }
  if (!p.posts) p.lastX = p.lastZ = p.s0 = p.t0 = 0;  // not used: written as 0

  // Heights: quantised unless a value is not finite or the range too wide.
  bool exact = !(heightStep > 0) || !std::isfinite(heightStep);
  std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = std::numeric_limits<std::int64_t>::min();
  for (std::size_t i = 0; i < v.size() && !exact; ++i) {
    const double q = std::nearbyint(double(v[i].y) / heightStep);
    if (!(std::fabs(q) < 0x1p52)) {
      exact = true;
      break;
    }
    lo = std::min(lo, std::int64_t(q));
    hi = std::max(hi, std::int64_t(q));
  }
  if (!exact && !v.empty() && std::uint64_t(hi - lo) > 0xffffffffu) exact = true;
  if (exact) {
    p.flags |= kLevel2ExactHeights;
  } else {
    p.step = heightStep;
    p.base = v.empty() ? 0 : lo;
  }

  // maxHeight follows from the vertices where it is what computeMaxHeights
  // gives (the builder's rule); only the lattice bounds the squares.
  if (p.posts && l.maxHeight.size() == std::uint64_t(nx) * nz) {
    bool ok = true;
    for (const Group& g : l.groups) {
      if (g.half == Half::skirt) continue;
      ok = ok && g.square < l.maxHeight.size() && std::uint64_t(g.firstIndex) + g.indexCount <= l.indices.size();
      for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount && ok; ++k) ok = l.indices[k] < v.size();
    }
    std::vector<float> top(l.maxHeight.size());
    if (ok) derivedMaxHeights(v.data(), l.indices.data(), l.groups.data(), l.groups.size(), top.data(), top.size());
    for (std::size_t k = 0; k < top.size() && ok; ++k) ok = bits(top[k]) == bits(l.maxHeight[k]);
    if (ok) p.flags |= kLevel2DerivedMaxHeight;
  }

  p.xzExp = xzExponent(v, std::size_t(p.posts), v.size());
  if (!l.normals.empty() && l.normals.size() == v.size()) {
    p.flags |= kLevel2Normals;
    // The builder may round normals; the low bits every lattice normal
    // leaves zero are not stored.
    std::uint32_t any = 0;
    for (std::uint64_t k = 0; k < p.posts; ++k) any |= l.normals[k] | l.normals[k] >> 16;
    p.shift = std::min<std::uint32_t>(15, any & 0xffffu ? std::uint32_t(std::countr_zero(any & 0xffffu)) : 15);
  }
  return p;
}


/// Whether the level's skirts are exactly makeSkirts' (the lattice in use,
/// every skirt group one material and priority 1, their bottom vertices
/// the level's last): then sets the plan's node, material and counts.
void planSkirts(const Level& l, Plan& p) {
  if (!p.posts) return;
  std::vector<const Group*> skirt;
  for (const Group& g : l.groups) {
    if (g.half == Half::skirt) skirt.push_back(&g);
  }
  if (skirt.empty()) return;
  const std::uint32_t sx = l.squaresX, sz = l.squaresZ;
  // The node follows from the first two groups' squares (one node per row
  // or column when there is a single group).
  std::uint32_t node = std::max(sx, sz);
  if (skirt.size() > 1) {
    const std::uint32_t a = skirt[0]->square, b = skirt[1]->square;
    node = b / sx == a / sx ? b - a : b / sx - a / sx;
  }
  if (node == 0) return;
  const SkirtCounts c = skirtCounts(sx, sz, node);
  const std::size_t V = l.vertices.size();
  if (c.groups != skirt.size() || c.vertices > V - p.posts) return;
  const bool normals = !l.normals.empty();
  std::vector<Vertex> vs(c.vertices);
  std::vector<std::uint32_t> ns(normals ? c.vertices : 0), is(c.indices), squares(c.groups), counts(c.groups);
  const auto base = std::uint32_t(V - c.vertices);
  makeSkirts(l.vertices.data(), normals ? l.normals.data() : nullptr, sx, sz, node, l.skirtDepth, base,
             {vs.data(), normals ? ns.data() : nullptr, is.data(), squares.data(), counts.data()});
  for (std::size_t k = 0; k < c.vertices; ++k) {
    const Vertex& a = vs[k];
    const Vertex& b = l.vertices[base + k];
    if (bits(a.x) != bits(b.x) || bits(a.y) != bits(b.y) || bits(a.z) != bits(b.z) || bits(a.s) != bits(b.s) ||
        bits(a.t) != bits(b.t) || (normals && ns[k] != l.normals[base + k])) {
      return;
    }
  }
  std::size_t at = 0;
  for (std::size_t g = 0; g < skirt.size(); ++g) {
    const Group& k = *skirt[g];
    if (k.priority != kPrioritySkin || k.material != skirt[0]->material || k.square != squares[g] ||
        k.indexCount != counts[g] || std::uint64_t(k.firstIndex) + k.indexCount > l.indices.size() ||
        !std::equal(is.begin() + std::ptrdiff_t(at), is.begin() + std::ptrdiff_t(at + counts[g]),
                    l.indices.begin() + k.firstIndex)) {
      return;
    }
    at += counts[g];
  }
  p.flags |= kLevel3ImplicitSkirts;
  p.node = node;
  p.skirtMaterial = skirt[0]->material;
  p.skirts = c;
}

std::uint32_t heightCode(const Plan& p, float y) {
  if (p.flags & kLevel2ExactHeights) return bits(y);
  return std::uint32_t(std::int64_t(std::nearbyint(double(y) / p.step)) - p.base);
}

/// Decoded y of a height code.
float heightValue(const Plan& p, std::uint32_t code) {
  if (p.flags & kLevel2ExactHeights) return std::bit_cast<float>(code);
  return float(double(p.base + std::int64_t(code)) * p.step);
}

/// The code of a predicted height: its bits, or its step count (0 where
/// the prediction has none).
std::uint32_t predictedCode(bool exact, double step, std::int64_t base, float y) {
  if (exact) return bits(y);
  const double q = double(y) / step;
  if (!(std::fabs(q) < 0x1p52)) return 0;
  return std::uint32_t(std::int64_t(std::nearbyint(q)) - base);
}

/// Version 4 height code of a stream vertex: whole steps from the plane's
/// height p (decoded as f32(p + code * step), exactly p for code 0). A
/// vertex less than one step from the plane goes onto it: culture is built
/// on the plane, and a vertex that an earlier quantisation moved off it
/// (a version 2 or 3 module being upgraded) would otherwise stay a step off.
std::uint32_t planeOffset(double step, float p, float y) {
  const double k = (double(y) - double(p)) / step;
  return std::fabs(k) < 1.0 ? 0u : std::uint32_t(std::int32_t(std::nearbyint(k)));
}

/// Version 4 rules the level allows: plane offsets wherever heights are
/// quantised and every offset fits in 31 bits; the raw-texture suffix is
/// the longest run of trailing stream vertices whose texture does not
/// follow the skin's.
void planVersion4(const Level& l, std::size_t E, Plan& p) {
  const std::size_t P = std::size_t(p.posts);
  if ((p.flags & kLevel3PlaneHeights) && !(p.flags & kLevel2ExactHeights)) {
    // Planes lie within the lattice's height range, so no offset exceeds
    // the range of all the level's heights.
    double lo = 0, hi = 0;
    for (std::size_t i = 0; i < P + E; ++i) {
      lo = std::min(lo, double(l.vertices[i].y)), hi = std::max(hi, double(l.vertices[i].y));
    }
    if ((hi - lo) / p.step < 0x1p30) p.flags |= kLevel4PlaneOffsets;
  }
  std::size_t d = 0;
  while (d < E) {
    const Vertex& q = l.vertices[P + E - 1 - d];
    if (bits(q.s) == skinBits(p.s0, q.x) && bits(q.t) == skinBits(p.t0, q.z)) break;
    ++d;
  }
  p.rawTexture = std::uint32_t(d);
  p.stExp = stExponent(l.vertices, P + E - d, P + E);
}

void encodeLevel(const Level& l, double heightStep, std::uint32_t version, std::vector<std::byte>& out) {
  Plan p = plan(l, heightStep);
  if (version >= kVersion3 && p.posts) {
    p.flags |= kLevel3PlaneHeights;
    planSkirts(l, p);
    p.xzExp = xzExponent(l.vertices, std::size_t(p.posts), l.vertices.size() - std::size_t(p.skirts.vertices));
  }
  const auto& v = l.vertices;
  const std::size_t P = std::size_t(p.posts), V = v.size(), E = V - P - std::size_t(p.skirts.vertices);
  if (version >= kVersion4 && P > 0) planVersion4(l, E, p);
  const std::size_t w = std::size_t(l.squaresX) + 1;
  const bool normals = p.flags & kLevel2Normals;
  const bool implicitSkirts = p.flags & kLevel3ImplicitSkirts;
  // The groups and indices stored: all but implicit skirts.
  std::vector<Group> keptGroups;
  std::vector<std::uint32_t> keptIndices;
  if (implicitSkirts) {
    keptGroups.reserve(l.groups.size() - std::size_t(p.skirts.groups));
    keptIndices.reserve(l.indices.size() - std::size_t(p.skirts.indices));
    for (const Group& g : l.groups) {
      if (g.half == Half::skirt) continue;
      keptGroups.push_back(g);
      keptIndices.insert(keptIndices.end(), l.indices.begin() + g.firstIndex,
                         l.indices.begin() + g.firstIndex + g.indexCount);
    }
  }
  const std::vector<Group>& groups = implicitSkirts ? keptGroups : l.groups;
  const std::vector<std::uint32_t>& indices = implicitSkirts ? keptIndices : l.indices;
  std::vector<float> latticeY(P);  // as decoded
  for (std::size_t k = 0; k < P; ++k) latticeY[k] = heightValue(p, heightCode(p, v[k].y));
  const bool plane = p.flags & kLevel3PlaneHeights;
  const bool exact = p.flags & kLevel2ExactHeights;

  // Vertex and index streams first (their sizes go in the header).
  const std::size_t stride = normals ? 24 : 20;
  std::vector<std::uint32_t> raw(E * stride / 4);
  for (std::size_t i = 0; i < E; ++i) {
    const Vertex& q = v[P + i];
    std::uint32_t* r = raw.data() + i * stride / 4;
    r[0] = xzCode(p.xzExp, q.x), r[1] = heightCode(p, q.y), r[2] = xzCode(p.xzExp, q.z);
    if (plane) {
      const float x = xzValue(p.xzExp, r[0]), z = xzValue(p.xzExp, r[2]);
      const float y = planeY(v.data(), l.squaresX, l.squaresZ, l.spacing, x, z,
                             [&](std::size_t k) { return double(latticeY[k]); });
      if (p.flags & kLevel4PlaneOffsets) r[1] = planeOffset(p.step, y, q.y);
      else r[1] -= predictedCode(exact, p.step, p.base, y);
    }
    if (i >= E - p.rawTexture) {
      r[3] = xzCode(p.stExp, q.s), r[4] = xzCode(p.stExp, q.t);
    } else {
      // With the lattice, s and t are stored XOR the skin texture of x
      // and z: 0 for every skin vertex (lossless for any).
      r[3] = bits(q.s) ^ (P ? skinBits(p.s0, q.x) : 0u);
      r[4] = bits(q.t) ^ (P ? skinBits(p.t0, q.z) : 0u);
    }
    if (normals) r[5] = l.normals[P + i];
  }
  std::vector<unsigned char> vstream;
  if (E > 0) {
    vstream.resize(meshopt_encodeVertexBufferBound(E, stride));
    vstream.resize(meshopt_encodeVertexBuffer(vstream.data(), vstream.size(), raw.data(), E, stride));
  }
  // Version 3: a group that is one grid triangle of the lattice, in the
  // builder's vertex order, stores no indices (its run says so).
  std::vector<std::uint8_t> plain(groups.size(), 0);
  std::vector<std::uint32_t> streamIdx;
  const bool v3 = version >= kVersion3;
  if (v3 && P > 0) {
    streamIdx.reserve(indices.size());
    std::size_t at = 0;
    for (std::size_t g = 0; g < groups.size(); ++g) {
      const Group& k = groups[g];
      std::uint32_t tri[3];
      plain[g] = k.indexCount == 3 && latticeTriangle(k.square, std::uint8_t(k.half), l.squaresX, l.squaresZ, tri) &&
                 std::equal(tri, tri + 3, indices.begin() + std::ptrdiff_t(at));
      if (!plain[g]) streamIdx.insert(streamIdx.end(), indices.begin() + std::ptrdiff_t(at),
                                      indices.begin() + std::ptrdiff_t(at + k.indexCount));
      at += k.indexCount;
    }
    // Readers allow at most two lattice groups a square (kMaxLatticeGroupsPerSquare),
    // which bounds what they allocate; past that every index is stored.
    const std::size_t latticeGroups = std::size_t(std::count(plain.begin(), plain.end(), std::uint8_t{1}));
    if (latticeGroups > kMaxLatticeGroupsPerSquare * std::size_t(l.squaresX) * l.squaresZ) {
      std::fill(plain.begin(), plain.end(), std::uint8_t{0});
      streamIdx = indices;
    }
  }
  const std::vector<std::uint32_t>& stream = v3 && P > 0 ? streamIdx : indices;
  std::vector<unsigned char> istream;
  if (!stream.empty()) {
    istream.resize(meshopt_encodeIndexSequenceBound(stream.size(), V));
    istream.resize(meshopt_encodeIndexSequence(istream.data(), istream.size(), stream.data(), stream.size()));
  }
  std::vector<std::byte> runs;
  std::uint32_t runCount = 0;
  {
    std::uint64_t prev = 0;
    for (std::size_t g = 0; g < groups.size();) {
      const Group& a = groups[g];
      const std::uint64_t start = slotOf(a.square, std::uint8_t(a.half));
      std::size_t n = 1;
      std::uint64_t slot = start;
      while (g + n < groups.size()) {
        const Group& b = groups[g + n];
        if (b.priority != a.priority || b.material != a.material || b.indexCount != a.indexCount ||
            slotOf(b.square, std::uint8_t(b.half)) != nextSlot(slot) || plain[g + n] != plain[g]) {
          break;
        }
        slot = nextSlot(slot);
        ++n;
      }
      putVarint(runs, zigzag64(std::int64_t(start - prev)));
      putVarint(runs, a.priority);
      putVarint(runs, a.material);
      putVarint(runs, a.indexCount);
      putVarint(runs, v3 ? std::uint64_t(n) << 1 | plain[g] : n);
      prev = slot;
      g += n;
      ++runCount;
    }
  }

  const std::size_t S = std::size_t(l.squaresX) * l.squaresZ;
  const std::uint32_t headerBytes = version >= kVersion4   ? kLevelHeaderBytes4
                                    : version >= kVersion3 ? kLevelHeaderBytes3
                                                           : kLevelHeaderBytes2;
  const std::size_t size = headerBytes + 4 * P + (normals ? 4 * P : 0) +
                           ((p.flags & kLevel2DerivedMaxHeight) ? 0 : 4 * S) + vstream.size() + istream.size() +
                           runs.size();
  const std::size_t at = out.size();
  out.resize(at + size, std::byte{0});
  std::byte* h = out.data() + at;
  storeLE<double>(h + levelField2::spacing, l.spacing);
  storeLE<std::uint32_t>(h + levelField2::squaresX, l.squaresX);
  storeLE<std::uint32_t>(h + levelField2::squaresZ, l.squaresZ);
  storeLE<float>(h + levelField2::skirtDepth, l.skirtDepth);
  storeLE<std::uint32_t>(h + levelField2::flags, p.flags);
  storeLE<std::uint32_t>(h + levelField2::vertexCount, std::uint32_t(V));
  storeLE<std::uint32_t>(h + levelField2::indexCount, std::uint32_t(l.indices.size()));
  storeLE<std::uint32_t>(h + levelField2::groupCount, std::uint32_t(l.groups.size()));
  storeLE<std::uint32_t>(h + levelField2::runCount, runCount);
  storeLE<double>(h + levelField2::heightStep, p.step);
  storeLE<std::int64_t>(h + levelField2::heightBase, p.base);
  storeLE<double>(h + levelField2::lastX, p.lastX);
  storeLE<double>(h + levelField2::lastZ, p.lastZ);
  storeLE<double>(h + levelField2::skinS0, p.s0);
  storeLE<double>(h + levelField2::skinT0, p.t0);
  storeLE<std::uint16_t>(h + levelField2::normalShift, std::uint16_t(p.shift));
  storeLE<std::int16_t>(h + kXZExponentField, std::int16_t(p.xzExp));
  storeLE<std::uint32_t>(h + levelField2::vertexStreamBytes, std::uint32_t(vstream.size()));
  storeLE<std::uint32_t>(h + levelField2::indexStreamBytes, std::uint32_t(istream.size()));
  storeLE<std::uint32_t>(h + levelField2::runBytes, std::uint32_t(runs.size()));
  if (version >= kVersion3) {
    storeLE<std::uint32_t>(h + levelField3::skirtNode, p.node);
    storeLE<std::uint16_t>(h + levelField3::skirtMaterial, p.skirtMaterial);
    storeLE<std::uint32_t>(h + levelField3::streamIndices, std::uint32_t(stream.size()));
  }
  if (version >= kVersion4) {
    storeLE<std::uint32_t>(h + levelField4::rawTextureVertices, p.rawTexture);
    storeLE<std::int16_t>(h + levelField4::stExponent, std::int16_t(p.stExp));
  }
  std::byte* q = h + headerBytes;
  if (P > 0) {
    std::vector<std::uint32_t> code(P);
    for (std::size_t k = 0; k < P; ++k) code[k] = heightCode(p, v[k].y);
    const auto get = [&](std::size_t k) { return code[k]; };
    q = putPlane<4>(q, P, [&](std::size_t k) {
      return zigzag32(code[k] - predict(k % w, k / w, w, get));
    });
    if (normals) {
      for (int half = 0; half < 2; ++half) {
        const auto comp = [&](std::size_t k) {
          const auto c = std::int16_t(std::uint16_t(l.normals[k] >> (16 * half)));
          return std::uint32_t(std::uint16_t(std::int16_t(c >> p.shift)));
        };
        q = putPlane<2>(q, P, [&](std::size_t k) { return zigzag16(comp(k) - predict(k % w, k / w, w, comp)); });
      }
    }
  }
  if (!(p.flags & kLevel2DerivedMaxHeight)) {
    // Rounded like the vertices (monotone), so it stays >= every decoded
    // vertex of its square.
    const auto round = [&](float y) {
      if ((p.flags & kLevel2ExactHeights) || !std::isfinite(y) || !(std::fabs(double(y) / p.step) < 0x1p52)) return y;
      return float(double(std::int64_t(std::nearbyint(double(y) / p.step))) * p.step);
    };
    q = putPlane<4>(q, S, [&](std::size_t k) { return k < l.maxHeight.size() ? bits(round(l.maxHeight[k])) : 0u; });
  }
  if (!vstream.empty()) std::memcpy(q, vstream.data(), vstream.size());
  q += vstream.size();
  if (!istream.empty()) std::memcpy(q, istream.data(), istream.size());
  q += istream.size();
  if (!runs.empty()) std::memcpy(q, runs.data(), runs.size());
  q += runs.size();
  assert(q == out.data() + out.size());
}

}  // namespace

std::vector<std::byte> encodeV2(const Module& m, double heightStep, std::uint32_t version) {
  std::vector<std::byte> out(kHeaderBytes, std::byte{0});
  const std::uint32_t v = std::clamp(version, kVersion2, kVersion5);
  const std::uint32_t levelVersion = std::min(v, kVersion4);  // version 5's levels are version 4's
  for (const Level& l : m.levels) encodeLevel(l, heightStep, levelVersion, out);
  if (v >= kVersion5) encodeObjects(m, out);
  std::byte* const h = out.data();
  const auto& magic = v == kVersion5 ? kMagic5 : v == kVersion4 ? kMagic4 : v == kVersion3 ? kMagic3 : kMagic2;
  std::memcpy(h + field::magic, magic.data(), magic.size());
  storeLE<std::uint32_t>(h + field::version, v);
  storeLE<std::uint32_t>(h + field::headerBytes, kHeaderBytes);
  storeLE<std::uint32_t>(h + field::kx, m.kx);
  storeLE<std::uint32_t>(h + field::kz, m.kz);
  storeLE<std::uint32_t>(h + field::levelCount, static_cast<std::uint32_t>(m.levels.size()));
  storeLE<std::uint32_t>(h + field::flags, 0);
  storeLE<std::uint64_t>(h + field::totalBytes, out.size());
  storeLE<std::uint32_t>(h + field::payloadCrc, crc32(std::span(out).subspan(kHeaderBytes)));
  storeLE<std::uint32_t>(h + field::headerCrc, crc32(std::span(out).first(field::headerCrc)));
  return out;
}

// ---------------------------------------------------------------- decode

namespace {
/// Scratch for the meshopt vertex stream, per thread: a loader decoding
/// module after module allocates nothing once warm.
thread_local std::vector<std::uint32_t> tScratch;
thread_local std::vector<std::uint32_t> tComponent;
/// Stored indices and groups of a level with implicit skirts, and the
/// skirts' own, before they are merged into the level's order.
thread_local std::vector<std::uint32_t> tIndices, tSkirtIndices, tSkirtSquares, tSkirtCounts;
thread_local std::vector<Group> tGroups;
thread_local std::vector<float> tColumns;  ///< lattice column x and s
/// A run of lattice groups: its first stored group and length.
struct LatticeRun {
  std::uint32_t first, count;
};
thread_local std::vector<LatticeRun> tLatticeRuns;
thread_local std::vector<std::uint32_t> tFull;  ///< stored indices with the lattice runs' filled in

/// The stored groups' indices in group order into `out`: a lattice run's
/// from its grid triangles, the others' in turn from the index stream.
void fillLatticeRuns(const Group* gr, std::size_t ng, const std::uint32_t* stream, std::uint32_t sx, std::uint32_t sz,
                     std::uint32_t* out) {
  std::size_t g = 0;
  const auto copyUpTo = [&](std::size_t end) {
    for (; g < end; ++g) {
      std::memcpy(out + gr[g].firstIndex, stream, sizeof(std::uint32_t) * gr[g].indexCount);
      stream += gr[g].indexCount;
    }
  };
  const std::uint32_t w = sx + 1;
  for (const LatticeRun& run : tLatticeRuns) {
    copyUpTo(run.first);
    // A run walks the squares in order: one division per run, not per group.
    std::uint32_t col = gr[g].square % sx, nw = (gr[g].square / sx) * w + col;
    std::uint32_t square = gr[g].square;
    for (; g < std::size_t(run.first) + run.count; ++g) {
      while (square < gr[g].square) {  // the next square, wrapping to the next row
        ++square, ++nw;
        if (++col == sx) col = 0, ++nw;
      }
      const auto tri = terrain::halfCorners(gr[g].half, std::array{nw, nw + 1, nw + w, nw + w + 1});
      std::memcpy(out + gr[g].firstIndex, tri.data(), sizeof tri);
    }
  }
  (void)sz;
  copyUpTo(ng);
}

/// The largest of n values (0 for none). Apart from the decoder's body,
/// whose lambdas capture its locals by reference, so that the loop keeps
/// its operands in registers and vectorises.
std::uint32_t largestOf(const std::uint32_t* v, std::size_t n) {
  std::uint32_t m = 0;
  for (std::size_t k = 0; k < n; ++k) m = v[k] > m ? v[k] : m;
  return m;
}

/// Merges the stored groups (indices in `stored`) with the skirt groups
/// (squares and counts, indices in tSkirtIndices) into the level's groups
/// and indices, in (priority, square, half, material) order, the stored
/// group first among equal keys. Stored groups between two skirt groups
/// are one stretch: their indices are contiguous, so each stretch is one
/// copy and its groups shift by one offset.
void mergeSkirts(const std::vector<Group>& stored, std::size_t storedCount, const std::uint32_t* storedIdx,
                 std::size_t skirtGroups, std::uint16_t material, Level& l) {
  const std::uint32_t* skirtIdx = tSkirtIndices.data();
  Group* out = l.groups.data();
  std::uint32_t* idx = l.indices.data();
  std::size_t a = 0, g = 0, at = 0, skirtAt = 0;
  const auto stretch = [&](std::size_t end) {
    if (end == a) return;
    const std::uint32_t from = stored[a].firstIndex;
    const std::uint32_t n = stored[end - 1].firstIndex + stored[end - 1].indexCount - from;
    std::memcpy(idx + at, storedIdx + from, sizeof(std::uint32_t) * n);
    const auto shift = std::uint32_t(at) - from;  // mod 2^32
    for (; a < end; ++a, ++g) {
      out[g] = stored[a];
      out[g].firstIndex += shift;
    }
    at += n;
  };
  for (std::size_t b = 0; b < skirtGroups; ++b) {
    const std::uint64_t key = groupKey(kPrioritySkin, tSkirtSquares[b], std::uint8_t(Half::skirt), material);
    std::size_t end = a;
    while (end < storedCount &&
           groupKey(stored[end].priority, stored[end].square, std::uint8_t(stored[end].half), stored[end].material) <=
               key) {
      ++end;
    }
    stretch(end);
    const std::uint32_t n = tSkirtCounts[b];
    std::memcpy(idx + at, skirtIdx + skirtAt, sizeof(std::uint32_t) * n);
    out[g++] = {tSkirtSquares[b], Half::skirt, kPrioritySkin, material, std::uint32_t(at), n};
    at += n;
    skirtAt += n;
  }
  stretch(storedCount);
}
}  // namespace

Status decodeLevelV2(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base,
                     std::size_t li, std::size_t& pos, Level& l, std::uint32_t version) {
  const bool v3 = version >= kVersion3, v4 = version >= kVersion4;
  const std::uint32_t headerBytes = v4 ? kLevelHeaderBytes4 : v3 ? kLevelHeaderBytes3 : kLevelHeaderBytes2;
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Status(Problem{file, base + off, "module: level " + str(li) + msg});
  };
  const std::size_t left = bytes.size() - pos;
  if (left < headerBytes) {
    return fail(pos, ": truncated: the level header needs " + str(headerBytes) + " bytes, only " +
                         str(left) + " remain");
  }
  const std::byte* h = bytes.data() + pos;
  l.spacing = loadLE<double>(h + levelField2::spacing);
  l.squaresX = loadLE<std::uint32_t>(h + levelField2::squaresX);
  l.squaresZ = loadLE<std::uint32_t>(h + levelField2::squaresZ);
  l.skirtDepth = loadLE<float>(h + levelField2::skirtDepth);
  const auto flags = loadLE<std::uint32_t>(h + levelField2::flags);
  const auto nv = loadLE<std::uint32_t>(h + levelField2::vertexCount);
  const auto ni = loadLE<std::uint32_t>(h + levelField2::indexCount);
  const auto ng = loadLE<std::uint32_t>(h + levelField2::groupCount);
  const auto nr = loadLE<std::uint32_t>(h + levelField2::runCount);
  const auto step = loadLE<double>(h + levelField2::heightStep);
  const auto hbase = loadLE<std::int64_t>(h + levelField2::heightBase);
  const auto lastX = loadLE<double>(h + levelField2::lastX), lastZ = loadLE<double>(h + levelField2::lastZ);
  const auto s0 = loadLE<double>(h + levelField2::skinS0), t0 = loadLE<double>(h + levelField2::skinT0);
  const std::uint32_t shift = loadLE<std::uint16_t>(h + levelField2::normalShift);
  const std::int32_t xzExp = loadLE<std::int16_t>(h + kXZExponentField);
  const auto vBytes = loadLE<std::uint32_t>(h + levelField2::vertexStreamBytes);
  const auto iBytes = loadLE<std::uint32_t>(h + levelField2::indexStreamBytes);
  const auto rBytes = loadLE<std::uint32_t>(h + levelField2::runBytes);
  const std::uint32_t node = v3 ? loadLE<std::uint32_t>(h + levelField3::skirtNode) : 0;
  const std::uint16_t skirtMaterial = v3 ? loadLE<std::uint16_t>(h + levelField3::skirtMaterial) : 0;
  const std::uint32_t rawTexture = v4 ? loadLE<std::uint32_t>(h + levelField4::rawTextureVertices) : 0;
  const std::int32_t stExp = v4 ? loadLE<std::int16_t>(h + levelField4::stExponent) : kXZFloatBits;
  if (!(std::isfinite(l.spacing) && l.spacing > 0)) {
    return fail(pos + levelField2::spacing,
                " spacing " + std::to_string(l.spacing) + " is not a finite positive number");
  }
  for (const std::size_t f : {levelField2::squaresX, levelField2::squaresZ}) {
    const std::uint32_t n = loadLE<std::uint32_t>(h + f);
    if (n < 1 || n > kMaxSquaresPerAxis) {
      return fail(pos + f, " squares " + str(l.squaresX) + " x " + str(l.squaresZ) +
                               " are out of range (1 to 65536 each)");
    }
  }
  if (!(std::isfinite(l.skirtDepth) && l.skirtDepth >= 0)) {
    return fail(pos + levelField2::skirtDepth,
                " skirt depth " + std::to_string(l.skirtDepth) + " is not a finite number >= 0");
  }
  if ((flags & ~(v4 ? kLevel4KnownFlags : v3 ? kLevel3KnownFlags : kLevel2KnownFlags)) != 0) {
    return fail(pos + levelField2::flags,
                " flags " + str(flags) + " has bits other than 0.." + (v4 ? "6" : v3 ? "5" : "3") + " set");
  }
  const bool lattice = flags & kLevel2Lattice, derived = flags & kLevel2DerivedMaxHeight,
             normals = flags & kLevel2Normals, exact = flags & kLevel2ExactHeights,
             implicitSkirts = flags & kLevel3ImplicitSkirts, plane = flags & kLevel3PlaneHeights,
             offsets = flags & kLevel4PlaneOffsets;
  if (offsets && (!plane || exact)) {
    return fail(pos + levelField2::flags, " flags " + str(flags) +
                                              ": plane offsets (bit 6) need plane heights (bit 5) and "
                                              "quantised heights (bit 3 clear)");
  }
  if (v4 && ((rawTexture != 0 && !lattice) || loadLE<std::uint16_t>(h + levelField4::reserved) != 0)) {
    return fail(pos + levelField4::rawTextureVertices,
                " raw-texture vertices need the lattice (bit 0), and the reserved bytes must be 0");
  }
  if (stExp != kXZFloatBits && (stExp < -149 || stExp > 127)) {
    return fail(pos + levelField4::stExponent,
                " s, t exponent " + std::to_string(stExp) + " is neither -149..127 nor 32767 (float bits)");
  }
  if ((derived || implicitSkirts || plane) && !lattice) {
    return fail(pos + levelField2::flags,
                " flags " + str(flags) + ": a derived maxHeight (bit 1), implicit skirts (bit 4) and plane "
                                         "heights (bit 5) need the lattice (bit 0)");
  }
  if (v3 && (implicitSkirts ? node < 1 || node > kMaxSquaresPerAxis : node != 0)) {
    return fail(pos + levelField3::skirtNode,
                " skirt node " + str(node) +
                    (implicitSkirts ? " is out of range (1 to 65536)" : " must be 0 without implicit skirts"));
  }
  if (v3 && ((!implicitSkirts && skirtMaterial != 0) || loadLE<std::uint16_t>(h + levelField3::reserved) != 0)) {
    return fail(pos + levelField3::skirtMaterial,
                " skirt material and reserved bytes must be 0 (the material without implicit skirts)");
  }
  if (exact ? step != 0.0 : !(std::isfinite(step) && step > 0)) {
    return fail(pos + levelField2::heightStep, " height step " + std::to_string(step) +
                                                   (exact ? " must be 0 with exact heights"
                                                          : " is not a finite positive number"));
  }
  if (lattice && !(std::isfinite(lastX) && std::isfinite(lastZ) && std::isfinite(s0) && std::isfinite(t0))) {
    return fail(pos + levelField2::lastX, " lattice lastX, lastZ, skinS0 or skinT0 is not finite");
  }
  if (shift > 15) return fail(pos + levelField2::normalShift, " normal shift " + str(shift) + " is above 15");
  if (xzExp != kXZFloatBits && (xzExp < -149 || xzExp > 127)) {
    return fail(pos + kXZExponentField,
                " x, z exponent " + std::to_string(xzExp) + " is neither -149..127 nor 32767 (float bits)");
  }
  const std::uint64_t squares = std::uint64_t(l.squaresX) * l.squaresZ;
  const std::uint64_t posts = lattice ? (std::uint64_t(l.squaresX) + 1) * (std::uint64_t(l.squaresZ) + 1) : 0;
  const std::uint64_t need = 4 * posts + (normals ? 4 * posts : 0) + (derived ? 0 : 4 * squares) +
                             std::uint64_t(vBytes) + iBytes + rBytes;
  if (need > left - headerBytes) {
    return fail(pos + levelField2::vertexStreamBytes,
                ": " + str(posts) + " lattice posts, " + str(squares) + " squares and streams of " + str(vBytes) +
                    " + " + str(iBytes) + " + " + str(rBytes) + " bytes need " + str(need) +
                    " bytes after the level header, only " + str(left - headerBytes) + " remain");
  }
  // Implicit skirts are bounded by the lattice (at most 8 vertices and 24
  // indices a post), which the bytes bound.
  const SkirtCounts sk = implicitSkirts ? skirtCounts(l.squaresX, l.squaresZ, node) : SkirtCounts{};
  if (posts + sk.vertices > nv) {
    return fail(pos + levelField2::vertexCount, " has " + str(nv) + " vertices, fewer than its " + str(posts) +
                                                    " lattice posts and " + str(sk.vertices) + " skirt vertices");
  }
  if (sk.indices > ni || sk.groups > ng) {
    return fail(pos + levelField2::indexCount, " has " + str(ni) + " indices in " + str(ng) + " groups, fewer than its " +
                                                   str(sk.indices) + " skirt indices in " + str(sk.groups) + " groups");
  }
  const std::uint32_t niS = ni - std::uint32_t(sk.indices), ngS = ng - std::uint32_t(sk.groups);
  // Version 3 lattice runs leave their indices out of the stream.
  const std::uint32_t niStream = v3 ? loadLE<std::uint32_t>(h + levelField3::streamIndices) : niS;
  if (niStream > niS || (niStream != niS && !lattice)) {
    return fail(pos + levelField3::streamIndices,
                " index stream count " + str(niStream) + " is above the " + str(niS) +
                    " stored indices, or below them without the lattice (bit 0)");
  }
  // Lattice runs store no indices, so their groups are bounded by the
  // grid instead: at most two a square (the lattice plane bounds squares).
  if (std::uint64_t(niS) - niStream > 3 * kMaxLatticeGroupsPerSquare * squares) {
    return fail(pos + levelField2::indexCount,
                " has " + str(niS) + " stored indices, more than the " + str(niStream) +
                    " of the index stream and 3 for each of two lattice groups a square (" + str(squares) +
                    " squares)");
  }
  // Every count is now bounded by the bytes: the lattice by its planes, the
  // other vertices by the stream's largest expansion, indices by one byte
  // each, groups by 3 indices each, runs by 5 bytes each.
  const std::uint64_t E = nv - posts - sk.vertices;
  const std::uint64_t stride = normals ? 24 : 20;
  if (E * stride > kMaxVertexStreamExpansion * vBytes || (E == 0) != (vBytes == 0)) {
    return fail(pos + levelField2::vertexStreamBytes,
                " vertex stream of " + str(vBytes) + " bytes cannot hold " + str(E) + " vertices of " +
                    str(stride) + " bytes");
  }
  if (rawTexture > E) {
    return fail(pos + levelField4::rawTextureVertices,
                " has " + str(rawTexture) + " raw-texture vertices, more than its " + str(E) + " stream vertices");
  }
  if (niStream > iBytes || (niStream == 0) != (iBytes == 0)) {
    return fail(pos + levelField2::indexStreamBytes,
                " index stream of " + str(iBytes) + " bytes cannot hold " + str(niStream) + " indices");
  }
  if (std::uint64_t(ngS) * 3 > niS || std::uint64_t(nr) * 5 > rBytes || nr > ngS || (ngS == 0) != (nr == 0)) {
    return fail(pos + levelField2::groupCount, " " + str(ngS) + " stored groups in " + str(nr) + " runs of " +
                                                   str(rBytes) + " bytes do not fit its " + str(niS) +
                                                   " stored indices");
  }

  const std::byte* b = bytes.data();
  std::size_t p = pos + headerBytes;
  l.vertices.resize(nv);
  Vertex* v = l.vertices.data();
  if (normals) l.normals.resize(nv);
  else l.normals.clear();
  l.heightStep = exact ? 0.0 : step;
  const auto height = [&](std::uint32_t code) {
    return exact ? std::bit_cast<float>(code) : float(double(hbase + std::int64_t(code)) * step);
  };
  const std::size_t P = std::size_t(posts), w = std::size_t(l.squaresX) + 1;
  if (P > 0) {
    // Codes first (in y's bits), then positions and heights.
    getPlane<4>(b + p, P, [&](std::size_t k, std::uint32_t z) {
      const auto get = [v](std::size_t j) { return std::bit_cast<std::uint32_t>(v[j].y); };
      v[k].y = std::bit_cast<float>(unzigzag32(z) + predict(k % w, k / w, w, get));
    });
    p += 4 * P;
    // Each column's x and s once, then row by row.
    tColumns.resize(2 * w);
    float* const colX = tColumns.data();
    float* const colS = colX + w;
    for (std::size_t a = 0; a < w; ++a) {
      const double xd = latticeCoord(std::uint32_t(a), l.squaresX, l.spacing, lastX);
      colX[a] = float(xd), colS[a] = float((s0 + xd) / kSkinTextureRepeat);
    }
    for (std::size_t j = 0, k = 0; j <= l.squaresZ; ++j) {
      const double zd = latticeCoord(std::uint32_t(j), l.squaresZ, l.spacing, lastZ);
      const float z = float(zd), t = float((t0 + zd) / kSkinTextureRepeat);
      for (std::size_t a = 0; a < w; ++a, ++k) {
        v[k] = {colX[a], height(std::bit_cast<std::uint32_t>(v[k].y)), z, colS[a], t};
      }
    }
    if (normals) {
      // u into the normals, v into scratch (16-bit shifted components,
      // predicted like the heights), then widened and packed.
      std::uint32_t* nrm = l.normals.data();
      tComponent.resize(P);
      std::uint32_t* vv = tComponent.data();
      for (std::uint32_t* dst : {nrm, vv}) {
        getPlane<2>(b + p, P, [&](std::size_t k, std::uint32_t z) {
          const auto get = [dst](std::size_t j) { return dst[j]; };
          dst[k] = (unzigzag16(z) + predict(k % w, k / w, w, get)) & 0xffffu;
        });
        p += 2 * P;
      }
      const auto widen = [shift](std::uint32_t c) {
        return std::uint32_t(std::uint16_t(std::int32_t(std::int16_t(std::uint16_t(c))) * (1 << shift)));
      };
      for (std::size_t k = 0; k < P; ++k) nrm[k] = widen(nrm[k]) | widen(vv[k]) << 16;
    }
  }
  const std::size_t maxHeightPlane = p;
  l.maxHeight.resize(std::size_t(squares));
  if (!derived) {
    float* mh = l.maxHeight.data();
    getPlane<4>(b + p, std::size_t(squares),
                [mh](std::size_t i, std::uint32_t u) { mh[i] = std::bit_cast<float>(u); });
    p += 4 * std::size_t(squares);
  }
  if (E > 0) {
    tScratch.resize(std::size_t(E * stride / 4));
    if (meshopt_decodeVertexBuffer(tScratch.data(), std::size_t(E), std::size_t(stride),
                                   reinterpret_cast<const unsigned char*>(b + p), vBytes) != 0) {
      return fail(p, " vertex stream (" + str(vBytes) + " bytes, " + str(E) + " vertices) does not decode");
    }
    const auto latticeY = [v](std::size_t k) { return double(v[k].y); };
    const std::size_t firstRaw = std::size_t(E - rawTexture);
    const XZDecoder xzOf(xzExp), stOf(stExp);
    for (std::size_t i = 0; i < E; ++i) {
      const std::uint32_t* r = tScratch.data() + i * std::size_t(stride / 4);
      const float x = xzOf(r[0]), z = xzOf(r[2]);
      float y = 0;
      if (offsets) {
        y = planeY(v, l.squaresX, l.squaresZ, l.spacing, x, z, latticeY);
        if (r[1] != 0) y = float(double(y) + double(std::int32_t(r[1])) * step);
      } else {
        std::uint32_t code = r[1];
        if (plane) code += predictedCode(exact, step, hbase, planeY(v, l.squaresX, l.squaresZ, l.spacing, x, z, latticeY));
        y = height(code);
      }
      if (i >= firstRaw) {
        v[P + i] = {x, y, z, stOf(r[3]), stOf(r[4])};
      } else {
        v[P + i] = {x, y, z, std::bit_cast<float>(r[3] ^ (P ? skinBits(s0, x) : 0u)),
                    std::bit_cast<float>(r[4] ^ (P ? skinBits(t0, z) : 0u))};
      }
      if (normals) l.normals[P + i] = r[5];
    }
  }
  p += vBytes;
  if (implicitSkirts) {
    tSkirtIndices.resize(std::size_t(sk.indices));
    tSkirtSquares.resize(std::size_t(sk.groups));
    tSkirtCounts.resize(std::size_t(sk.groups));
    makeSkirts(v, normals ? l.normals.data() : nullptr, l.squaresX, l.squaresZ, node, l.skirtDepth,
               std::uint32_t(P + E),
               {v + P + E, normals ? l.normals.data() + P + E : nullptr, tSkirtIndices.data(), tSkirtSquares.data(),
                tSkirtCounts.data()});
  }
  const std::size_t indexStream = p;
  // Stream indices and stored groups go straight into the level unless
  // lattice runs or skirts are filled in afterwards.
  const bool latticeRuns = niStream != niS;
  std::vector<std::uint32_t>& storedIndices = implicitSkirts || latticeRuns ? tIndices : l.indices;
  std::vector<Group>& storedGroups = implicitSkirts ? tGroups : l.groups;
  storedIndices.resize(niStream);
  if (niStream > 0 && meshopt_decodeIndexSequence(storedIndices.data(), niStream, 4,
                                                  reinterpret_cast<const unsigned char*>(b + p), iBytes) != 0) {
    return fail(p, " index stream (" + str(iBytes) + " bytes, " + str(niStream) + " indices) does not decode");
  }
  // The largest index first (a loop the compiler vectorises), the
  // offender only when there is one.
  const std::uint32_t largest = largestOf(storedIndices.data(), niStream);
  for (std::uint32_t k = 0; largest >= nv && k < niStream; ++k) {
    if (storedIndices[k] >= nv) {
      return fail(indexStream, " index " + str(k) + " is " + str(storedIndices[k]) +
                                   ", not below the vertex count " + str(nv));
    }
  }
  p += iBytes;

  // Groups from runs.
  storedGroups.resize(ngS);
  Group* gr = storedGroups.data();
  const std::byte* r = b + p;
  const std::byte* const rEnd = r + rBytes;
  std::uint64_t slot = 0, first = 0, prevKey = 0, latticeGroups = 0;
  std::uint32_t g = 0;
  tLatticeRuns.clear();
  for (std::uint32_t run = 0; run < nr; ++run) {
    const std::size_t at = std::size_t(r - b);
    std::uint64_t f[5];
    for (auto& x : f) {
      if (!getVarint(r, rEnd, x)) {
        return fail(at, " group run " + str(run) + " is truncated or not LEB128 (the runs end at byte " +
                            str(p + rBytes) + ")");
      }
    }
    const std::uint64_t start = slot + std::uint64_t(unzigzag64(f[0]));
    // Version 3: bit 0 of the length marks a lattice run.
    const bool latticeRun = v3 && (f[4] & 1);
    if (v3) f[4] >>= 1;
    if (latticeRun && (!lattice || (start & 3) > 1 || f[3] != 3)) {
      return fail(at, " group run " + str(run) + " is a lattice run (length bit 0) but the level has no lattice, "
                                                  "it starts on a skirt or its index count " + str(f[3]) + " is not 3");
    }
    if (f[1] > 0xff || f[2] > 0xffff || f[3] > 0xffffffffu || f[4] == 0 || f[4] > ngS - g) {
      return fail(at, " group run " + str(run) + " (priority " + str(f[1]) + ", material " + str(f[2]) +
                          ", index count " + str(f[3]) + ", length " + str(f[4]) + ") is out of range (" +
                          str(ngS - g) + " groups left)");
    }
    slot = start;
    if (latticeRun) {
      tLatticeRuns.push_back({g, std::uint32_t(f[4])});
      latticeGroups += f[4];
    }
    // A run whose every group is sound needs its first and last checked
    // only: squares and keys rise through it.
    const auto count = std::uint32_t(f[3]);
    const std::uint64_t n = f[4];
    const std::uint64_t startHalf = start & 3;
    const std::uint64_t last = startHalf == 2 ? start + 4 * (n - 1) : halfSlot(2 * (start >> 2) + startHalf + n - 1);
    const std::uint64_t firstKey = groupKey(std::uint8_t(f[1]), std::uint32_t(start >> 2), std::uint8_t(startHalf),
                                            std::uint16_t(f[2]));
    if (startHalf <= 2 && (start >> 2) < squares && (last >> 2) < squares && count > 0 && count % 3 == 0 &&
        count <= niS - first && n <= (niS - first) / count && (g == 0 || firstKey >= prevKey)) {
      for (std::uint64_t k = 0; k < n; ++k, ++g) {
        if (k > 0) slot = nextSlot(slot);
        gr[g] = {std::uint32_t(slot >> 2), static_cast<Half>(slot & 3), std::uint8_t(f[1]), std::uint16_t(f[2]),
                 std::uint32_t(first), count};
        first += count;
      }
      prevKey = groupKey(std::uint8_t(f[1]), std::uint32_t(slot >> 2), std::uint8_t(slot & 3), std::uint16_t(f[2]));
      continue;
    }
    for (std::uint64_t k = 0; k < f[4]; ++k, ++g) {
      if (k > 0) slot = nextSlot(slot);
      const auto gs = [g] { return " group " + str(g); };
      const std::uint64_t half = slot & 3, square = slot >> 2;
      if (half > 2) return fail(at, gs() + " half " + str(half) + " is not 0 (upper), 1 (lower) or 2 (skirt)");
      if (square >= squares) {
        return fail(at, gs() + " square " + str(square) + " is not below the level's " + str(squares) + " squares");
      }
      if (count == 0 || count % 3 != 0) {
        return fail(at, gs() + " index count " + str(count) + " is not a positive multiple of 3");
      }
      if (first + count > niS) {
        return fail(at, gs() + " indices " + str(first) + ".." + str(first + count - 1) + " run past the level's " +
                            str(niS) + " stored indices");
      }
      gr[g].square = std::uint32_t(square);
      gr[g].half = static_cast<Half>(half);
      gr[g].priority = std::uint8_t(f[1]);
      gr[g].material = std::uint16_t(f[2]);
      gr[g].indexCount = count;
      gr[g].firstIndex = std::uint32_t(first);
      const std::uint64_t key = groupKey(gr[g].priority, gr[g].square, std::uint8_t(half), gr[g].material);
      if (g > 0 && key < prevKey) {
        return fail(at, gs() + " (priority " + str(gr[g].priority) + ", square " + str(square) + ", half " +
                            str(half) + ", material " + str(gr[g].material) + ") does not follow group " +
                            str(g - 1) + " in (priority, square, half, material) order");
      }
      prevKey = key;
      first += count;
    }
  }
  if (g != ngS) {
    return fail(p, " runs give " + str(g) + " groups, the level header says " + str(ngS) + " are stored");
  }
  if (niS - 3 * latticeGroups != niStream) {
    return fail(p, " runs take " + str(niS - 3 * latticeGroups) + " indices from the index stream, which holds " +
                       str(niStream));
  }
  if (r != rEnd) {
    return fail(std::size_t(r - b), " " + str(std::size_t(rEnd - r)) + " bytes follow the last group run");
  }
  if (first != niS) {
    return fail(p, " groups cover " + str(first) + " of the level's " + str(niS) + " stored indices");
  }
  if (latticeRuns) {
    std::vector<std::uint32_t>& full = implicitSkirts ? tFull : l.indices;
    full.resize(niS);
    fillLatticeRuns(gr, ngS, tIndices.data(), l.squaresX, l.squaresZ, full.data());
  }
  if (implicitSkirts) {
    l.groups.resize(ng);
    l.indices.resize(ni);
    mergeSkirts(tGroups, ngS, (latticeRuns ? tFull : tIndices).data(), std::size_t(sk.groups), skirtMaterial, l);
    gr = l.groups.data();
  }
  if (derived) {
    derivedMaxHeights(v, l.indices.data(), gr, ng, l.maxHeight.data(), std::size_t(squares));
  }
  (void)maxHeightPlane;
  pos = p + rBytes;
  return {};
}

}  // namespace detail
}  // namespace sandtable::module
