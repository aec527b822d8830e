#pragma once
// What the encoder (module_v2_encode.cpp) and the decoder
// (module_v2_decode.cpp) of load modules versions 2 to 5 share (module.h
// "layout, version 2"; docs/FORMAT.md §9.7 to §9.9): the codec's small
// primitives, the level header's extra fields, and the rules both sides
// must apply bit for bit (implicit skirts, the derived maxHeight, lattice
// triangles, plane heights). Both files are built with -ffp-contract=off.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "module_internal.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::module::detail {

// ------------------------------------------------------------ primitives

inline std::string str(std::uint64_t v) { return std::to_string(v); }
inline std::uint32_t bits(float f) { return std::bit_cast<std::uint32_t>(f); }
inline std::uint32_t zigzag32(std::uint32_t d) { return (d << 1) ^ ((d >> 31) ? 0xffffffffu : 0u); }
inline std::uint32_t unzigzag32(std::uint32_t z) { return (z >> 1) ^ ((z & 1) ? 0xffffffffu : 0u); }
inline std::uint32_t zigzag16(std::uint32_t d) {
  d &= 0xffffu;
  return ((d << 1) & 0xffffu) ^ ((d >> 15) ? 0xffffu : 0u);
}
inline std::uint32_t unzigzag16(std::uint32_t z) { return ((z >> 1) ^ ((z & 1) ? 0xffffu : 0u)) & 0xffffu; }

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

inline std::uint64_t zigzag64(std::int64_t d) { return (std::uint64_t(d) << 1) ^ std::uint64_t(d >> 63); }
inline std::int64_t unzigzag64(std::uint64_t z) { return std::int64_t(z >> 1) ^ -std::int64_t(z & 1); }

/// Group position for runs: square * 4 + half.
inline std::uint64_t slotOf(std::uint32_t square, std::uint8_t half) { return std::uint64_t(square) * 4 + half; }
/// The slot of grid triangle h = 2 * square + half (half 0 or 1).
inline std::uint64_t halfSlot(std::uint64_t h) { return (h >> 1) * 4 + (h & 1); }
/// The slot that follows `slot` inside a run.
inline std::uint64_t nextSlot(std::uint64_t slot) {
  const std::uint64_t half = slot & 3;
  if (half == 0) return slot + 1;      // upper -> lower of the same square
  if (half == 1) return slot + 3;      // lower -> upper of the next square
  return slot + 4;                     // skirt -> skirt of the next square
}

// ------------------------------------------------------ header and values

/// Sentinel of kXZExponentField: stream x and z are float bits.
constexpr std::int32_t kXZFloatBits = 0x7fff;
/// Version 3 and later: lattice-run groups a level may have per square.
constexpr std::uint64_t kMaxLatticeGroupsPerSquare = 2;
/// i16 at level offset 90, the upper half of the u32 that module.h names
/// levelField2::normalShift (u16 normal shift, i16 x/z exponent; kept out of
/// module.h so the layout change recompiles one file; docs/FORMAT.md §9.7.2).
constexpr std::size_t kXZExponentField = 90;

inline std::uint32_t xzCode(std::int32_t e, float c) {
  return e == kXZFloatBits ? bits(c) : std::uint32_t(std::int32_t(std::ldexp(double(c), -e)));
}

inline float xzValue(std::int32_t e, std::uint32_t code) {
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
inline std::uint32_t skinBits(double o, float x) { return bits(float((o + double(x)) / kSkinTextureRepeat)); }

/// Module-local x of lattice column a (the builder's (post - i0) * spacing,
/// the last column clamped to the level's edge).
inline double latticeCoord(std::uint32_t a, std::uint32_t n, double spacing, double last) {
  return a < n ? double(a) * spacing : last;
}

// ------------------------------------------------ rules shared bit for bit

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
                std::uint32_t node, float depth, std::uint32_t base, SkirtSink out);

/// The highest y over the indices of every non-skirt group, per square
/// (derived maxHeight; -infinity where a square has none). The square's
/// running maximum stays in a register while its groups follow each other
/// (the usual order), and a group's three heights are reduced before they
/// meet it, so the loop is not one long chain of dependent max operations
/// through memory. Encoder and decoder both call this, so they agree even
/// on the sign of a zero maximum.
void derivedMaxHeights(const Vertex* v, const std::uint32_t* idx, const Group* gr, std::size_t ng, float* mh,
                       std::size_t squares);

/// Height of the lattice triangle's plane (module.h "Grid triangles") at
/// (x, z), from the lattice posts' decoded x, z and `height(k)`. IEEE double
/// with no contraction (both codec files are built with -ffp-contract=off), so that
/// encoder and decoder agree bit for bit on every machine.
template <typename Height>
float planeY(const Vertex* lat, std::uint32_t sx, std::uint32_t sz, double spacing, float x, float z,
             Height height) {
  const std::size_t w = std::size_t(sx) + 1, a = terrain::latticeCell(x, spacing, sx);
  const std::size_t b = terrain::latticeCell(z, spacing, sz);
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
                     std::uint32_t out[3]);

/// The code of a predicted height: its bits, or its step count (0 where
/// the prediction has none).
inline std::uint32_t predictedCode(bool exact, double step, std::int64_t base, float y) {
  if (exact) return bits(y);
  const double q = double(y) / step;
  if (!(std::fabs(q) < 0x1p52)) return 0;
  return std::uint32_t(std::int64_t(std::nearbyint(q)) - base);
}

}  // namespace sandtable::module::detail
