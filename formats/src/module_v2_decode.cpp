// Load modules, versions 2 to 5: the decoder of one level (module.h
// "layout, version 2"; docs/FORMAT.md §9.7 to §9.9). Every count is
// checked against the bytes that remain before anything is sized; scratch
// is per thread, so a loader decoding module after module allocates
// nothing once warm.
#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "module_v2_internal.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::module::detail {
namespace {

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

/// One level of a version 2, 3 or 4 module (version 5's levels are version
/// 4's), decoded in steps: the header's fields, the counts they imply
/// (each checked against the bytes before anything is sized), the lattice,
/// the maxHeight plane, the stream vertices, the implicit skirts, the index
/// stream, the group runs, and last the lattice runs' indices, the skirt
/// groups and the derived maxHeight. The fields keep the header's names.
class LevelDecoder {
 public:
  LevelDecoder(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base, std::size_t li,
               std::size_t at, Level& level, std::uint32_t version)
      : bytes_(bytes), file_(file), base_(base), li_(li), pos(at), l(level),
        v3(version >= kVersion3), v4(version >= kVersion4),
        headerBytes(v4 ? kLevelHeaderBytes4 : v3 ? kLevelHeaderBytes3 : kLevelHeaderBytes2) {}

  /// Decodes the level; `end` is then the offset just past it.
  Status run(std::size_t& end) {
    if (Status s = readHeader(); !s) return s;
    if (Status s = checkFlags(); !s) return s;
    if (Status s = checkValues(); !s) return s;
    if (Status s = checkCounts(); !s) return s;
    if (Status s = checkStreams(); !s) return s;
    p = pos + headerBytes;
    l.vertices.resize(nv);
    if (normals) l.normals.resize(nv);
    else l.normals.clear();
    l.heightStep = exact ? 0.0 : step;
    decodeLattice();
    readMaxHeights();
    if (Status s = decodeStreamVertices(); !s) return s;
    p += vBytes;
    addImplicitSkirts();
    if (Status s = decodeIndexStream(); !s) return s;
    p += iBytes;
    if (Status s = decodeRuns(); !s) return s;
    finishGroups();
    end = p + rBytes;
    return {};
  }

 private:
  Status fail(std::uint64_t off, const std::string& msg) const {
    return Status(Problem{file_, base_ + off, "module: level " + str(li_) + msg});
  }

  /// The decoded height of a height code.
  static float heightOf(bool exact, double step, std::int64_t base, std::uint32_t code) {
    return exact ? std::bit_cast<float>(code) : float(double(base + std::int64_t(code)) * step);
  }
  float height(std::uint32_t code) const { return heightOf(exact, step, hbase, code); }

  Status readHeader() {
    const std::size_t left = bytes_.size() - pos;
    if (left < headerBytes) {
      return fail(pos, ": truncated: the level header needs " + str(headerBytes) + " bytes, only " +
                           str(left) + " remain");
    }
    h = bytes_.data() + pos;
    l.spacing = loadLE<double>(h + levelField2::spacing);
    l.squaresX = loadLE<std::uint32_t>(h + levelField2::squaresX);
    l.squaresZ = loadLE<std::uint32_t>(h + levelField2::squaresZ);
    l.skirtDepth = loadLE<float>(h + levelField2::skirtDepth);
    flags = loadLE<std::uint32_t>(h + levelField2::flags);
    nv = loadLE<std::uint32_t>(h + levelField2::vertexCount);
    ni = loadLE<std::uint32_t>(h + levelField2::indexCount);
    ng = loadLE<std::uint32_t>(h + levelField2::groupCount);
    nr = loadLE<std::uint32_t>(h + levelField2::runCount);
    step = loadLE<double>(h + levelField2::heightStep);
    hbase = loadLE<std::int64_t>(h + levelField2::heightBase);
    lastX = loadLE<double>(h + levelField2::lastX), lastZ = loadLE<double>(h + levelField2::lastZ);
    s0 = loadLE<double>(h + levelField2::skinS0), t0 = loadLE<double>(h + levelField2::skinT0);
    shift = loadLE<std::uint16_t>(h + levelField2::normalShift);
    xzExp = loadLE<std::int16_t>(h + kXZExponentField);
    vBytes = loadLE<std::uint32_t>(h + levelField2::vertexStreamBytes);
    iBytes = loadLE<std::uint32_t>(h + levelField2::indexStreamBytes);
    rBytes = loadLE<std::uint32_t>(h + levelField2::runBytes);
    node = v3 ? loadLE<std::uint32_t>(h + levelField3::skirtNode) : 0;
    skirtMaterial = v3 ? loadLE<std::uint16_t>(h + levelField3::skirtMaterial) : 0;
    rawTexture = v4 ? loadLE<std::uint32_t>(h + levelField4::rawTextureVertices) : 0;
    stExp = v4 ? loadLE<std::int16_t>(h + levelField4::stExponent) : kXZFloatBits;
    return {};
  }

  /// Spacing, squares, skirt depth and the flags the version allows.
  Status checkFlags() {
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
    lattice = flags & kLevel2Lattice;
    derived = flags & kLevel2DerivedMaxHeight;
    normals = flags & kLevel2Normals;
    exact = flags & kLevel2ExactHeights;
    implicitSkirts = flags & kLevel3ImplicitSkirts;
    plane = flags & kLevel3PlaneHeights;
    offsets = flags & kLevel4PlaneOffsets;
    if (offsets && (!plane || exact)) {
      return fail(pos + levelField2::flags, " flags " + str(flags) +
                                                ": plane offsets (bit 6) need plane heights (bit 5) and "
                                                "quantised heights (bit 3 clear)");
    }
    return {};
  }

  /// The fields each flag gives meaning to.
  Status checkValues() const {
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
    return {};
  }

  /// Lattice posts, squares, implicit skirts and stored indices and groups
  /// against the bytes that remain and the header's counts.
  Status checkCounts() {
    const std::size_t left = bytes_.size() - pos;
    squares = std::uint64_t(l.squaresX) * l.squaresZ;
    posts = lattice ? (std::uint64_t(l.squaresX) + 1) * (std::uint64_t(l.squaresZ) + 1) : 0;
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
    sk = implicitSkirts ? skirtCounts(l.squaresX, l.squaresZ, node) : SkirtCounts{};
    if (posts + sk.vertices > nv) {
      return fail(pos + levelField2::vertexCount, " has " + str(nv) + " vertices, fewer than its " + str(posts) +
                                                      " lattice posts and " + str(sk.vertices) + " skirt vertices");
    }
    if (sk.indices > ni || sk.groups > ng) {
      return fail(pos + levelField2::indexCount, " has " + str(ni) + " indices in " + str(ng) +
                                                     " groups, fewer than its " + str(sk.indices) +
                                                     " skirt indices in " + str(sk.groups) + " groups");
    }
    niS = ni - std::uint32_t(sk.indices), ngS = ng - std::uint32_t(sk.groups);
    // Version 3 lattice runs leave their indices out of the stream.
    niStream = v3 ? loadLE<std::uint32_t>(h + levelField3::streamIndices) : niS;
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
    return {};
  }

  /// Every count is now bounded by the bytes: the lattice by its planes,
  /// the other vertices by the stream's largest expansion, indices by one
  /// byte each, groups by 3 indices each, runs by 5 bytes each.
  Status checkStreams() {
    E = nv - posts - sk.vertices;
    stride = normals ? 24 : 20;
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
    return {};
  }

  /// The lattice posts: height codes first (in y's bits), then positions
  /// and heights, then normals.
  void decodeLattice() {
    const std::byte* b = bytes_.data();
    Vertex* v = l.vertices.data();
    const std::size_t P = std::size_t(posts), w = std::size_t(l.squaresX) + 1;
    if (P == 0) return;
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
    if (normals) decodeLatticeNormals(P, w);
  }

  /// u into the normals, v into scratch (16-bit shifted components,
  /// predicted like the heights), then widened and packed.
  void decodeLatticeNormals(std::size_t P, std::size_t w) {
    const std::byte* b = bytes_.data();
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
    const auto widen = [s = shift](std::uint32_t c) {
      return std::uint32_t(std::uint16_t(std::int32_t(std::int16_t(std::uint16_t(c))) * (1 << s)));
    };
    for (std::size_t k = 0; k < P; ++k) nrm[k] = widen(nrm[k]) | widen(vv[k]) << 16;
  }

  void readMaxHeights() {
    l.maxHeight.resize(std::size_t(squares));
    if (derived) return;
    float* mh = l.maxHeight.data();
    getPlane<4>(bytes_.data() + p, std::size_t(squares),
                [mh](std::size_t i, std::uint32_t u) { mh[i] = std::bit_cast<float>(u); });
    p += 4 * std::size_t(squares);
  }

  /// The vertices after the lattice: x, z, a height code (from the lattice
  /// plane in versions 3 and 4), texture and normal.
  Status decodeStreamVertices() {
    if (E == 0) return {};
    const std::byte* b = bytes_.data();
    Vertex* v = l.vertices.data();
    const std::size_t P = std::size_t(posts);
    tScratch.resize(std::size_t(E * stride / 4));
    if (meshopt_decodeVertexBuffer(tScratch.data(), std::size_t(E), std::size_t(stride),
                                   reinterpret_cast<const unsigned char*>(b + p), vBytes) != 0) {
      return fail(p, " vertex stream (" + str(vBytes) + " bytes, " + str(E) + " vertices) does not decode");
    }
    // The loop's values in locals: its stores could alias the fields.
    const auto latticeY = [v](std::size_t k) { return double(v[k].y); };
    const std::size_t firstRaw = std::size_t(E - rawTexture), n = std::size_t(E), words = std::size_t(stride / 4);
    const XZDecoder xzOf(xzExp), stOf(stExp);
    const bool withOffsets = offsets, withPlane = plane, exactHeights = exact;
    const double heightStep = step, spacing = l.spacing, skinS = s0, skinT = t0;
    const std::int64_t heightBase = hbase;
    const std::uint32_t sx = l.squaresX, sz = l.squaresZ;
    std::uint32_t* const nrm = normals ? l.normals.data() : nullptr;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t* r = tScratch.data() + i * words;
      const float x = xzOf(r[0]), z = xzOf(r[2]);
      float y = 0;
      if (withOffsets) {
        y = planeY(v, sx, sz, spacing, x, z, latticeY);
        if (r[1] != 0) y = float(double(y) + double(std::int32_t(r[1])) * heightStep);
      } else {
        std::uint32_t code = r[1];
        if (withPlane) {
          code += predictedCode(exactHeights, heightStep, heightBase, planeY(v, sx, sz, spacing, x, z, latticeY));
        }
        y = heightOf(exactHeights, heightStep, heightBase, code);
      }
      if (i >= firstRaw) {
        v[P + i] = {x, y, z, stOf(r[3]), stOf(r[4])};
      } else {
        v[P + i] = {x, y, z, std::bit_cast<float>(r[3] ^ (P ? skinBits(skinS, x) : 0u)),
                    std::bit_cast<float>(r[4] ^ (P ? skinBits(skinT, z) : 0u))};
      }
      if (nrm) nrm[P + i] = r[5];
    }
    return {};
  }

  void addImplicitSkirts() {
    if (!implicitSkirts) return;
    Vertex* v = l.vertices.data();
    const std::size_t P = std::size_t(posts);
    tSkirtIndices.resize(std::size_t(sk.indices));
    tSkirtSquares.resize(std::size_t(sk.groups));
    tSkirtCounts.resize(std::size_t(sk.groups));
    makeSkirts(v, normals ? l.normals.data() : nullptr, l.squaresX, l.squaresZ, node, l.skirtDepth,
               std::uint32_t(P + E),
               {v + P + E, normals ? l.normals.data() + P + E : nullptr, tSkirtIndices.data(), tSkirtSquares.data(),
                tSkirtCounts.data()});
  }

  /// Stream indices and stored groups go straight into the level unless
  /// lattice runs or skirts are filled in afterwards.
  std::vector<std::uint32_t>& storedIndices() { return implicitSkirts || niStream != niS ? tIndices : l.indices; }
  std::vector<Group>& storedGroups() { return implicitSkirts ? tGroups : l.groups; }

  Status decodeIndexStream() {
    const std::size_t indexStream = p;
    std::vector<std::uint32_t>& stored = storedIndices();
    stored.resize(niStream);
    if (niStream > 0 && meshopt_decodeIndexSequence(stored.data(), niStream, 4,
                                                    reinterpret_cast<const unsigned char*>(bytes_.data() + p),
                                                    iBytes) != 0) {
      return fail(p, " index stream (" + str(iBytes) + " bytes, " + str(niStream) + " indices) does not decode");
    }
    // The largest index first (a loop the compiler vectorises), the
    // offender only when there is one.
    const std::uint32_t largest = largestOf(stored.data(), niStream);
    for (std::uint32_t k = 0; largest >= nv && k < niStream; ++k) {
      if (stored[k] >= nv) {
        return fail(indexStream, " index " + str(k) + " is " + str(stored[k]) +
                                     ", not below the vertex count " + str(nv));
      }
    }
    return {};
  }

  /// The stored groups from their runs: each run's first and last group
  /// checked when every group between is sound, else every group.
  Status decodeRuns() {
    const std::byte* b = bytes_.data();
    std::vector<Group>& groups = storedGroups();
    groups.resize(ngS);
    Group* gr = groups.data();
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
    return {};
  }

  /// The lattice runs' indices, the skirt groups merged in, the derived
  /// maxHeight.
  void finishGroups() {
    const bool latticeRuns = niStream != niS;
    Group* gr = storedGroups().data();
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
      derivedMaxHeights(l.vertices.data(), l.indices.data(), gr, ng, l.maxHeight.data(), std::size_t(squares));
    }
  }

  const std::span<const std::byte> bytes_;
  const std::string& file_;
  const std::uint64_t base_;
  const std::size_t li_;
  const std::size_t pos;  ///< the level header
  Level& l;
  const bool v3, v4;
  const std::uint32_t headerBytes;
  const std::byte* h = nullptr;  ///< the level header's bytes
  // The header's fields.
  std::uint32_t flags = 0, nv = 0, ni = 0, ng = 0, nr = 0;
  double step = 0;
  std::int64_t hbase = 0;
  double lastX = 0, lastZ = 0, s0 = 0, t0 = 0;
  std::uint32_t shift = 0;
  std::int32_t xzExp = 0;
  std::uint32_t vBytes = 0, iBytes = 0, rBytes = 0, node = 0;
  std::uint16_t skirtMaterial = 0;
  std::uint32_t rawTexture = 0;
  std::int32_t stExp = 0;
  bool lattice = false, derived = false, normals = false, exact = false, implicitSkirts = false, plane = false,
       offsets = false;
  // What they imply.
  std::uint64_t squares = 0, posts = 0;
  SkirtCounts sk;
  std::uint32_t niS = 0, ngS = 0, niStream = 0;  ///< stored indices and groups; indices in the stream
  std::uint64_t E = 0, stride = 0;               ///< stream vertices and their bytes
  std::size_t p = 0;                             ///< the decoder's position in `bytes_`
};

}  // namespace

Status decodeLevelV2(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base,
                     std::size_t li, std::size_t& pos, Level& l, std::uint32_t version) {
  LevelDecoder d(bytes, file, base, li, pos, l, version);
  return d.run(pos);
}

}  // namespace sandtable::module::detail
