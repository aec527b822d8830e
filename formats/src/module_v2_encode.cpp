// Load modules, versions 2 to 5: the encoder (module.h "layout, version
// 2"; docs/FORMAT.md §9.7 to §9.9). A plan per level says which rules the
// level allows (lattice, quantised heights, derived maxHeight, implicit
// skirts, plane heights and offsets, raw texture); encodeLevel writes it.
#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>

#include "module_v2_internal.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::module::detail {
namespace {

void putVarint(std::vector<std::byte>& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(std::byte(std::uint8_t(v) | 0x80));
    v >>= 7;
  }
  out.push_back(std::byte(std::uint8_t(v)));
}

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

/// The vertices after the lattice (and before implicit skirts) as
/// meshopt's vertex stream: x, z and height codes (from the lattice plane
/// in versions 3 and 4), texture (XOR the skin's with the lattice) and
/// normal.
std::vector<unsigned char> vertexStream(const Level& l, const Plan& p, std::size_t E) {
  const auto& v = l.vertices;
  const std::size_t P = std::size_t(p.posts);
  const bool normals = p.flags & kLevel2Normals;
  std::vector<float> latticeY(P);  // as decoded
  for (std::size_t k = 0; k < P; ++k) latticeY[k] = heightValue(p, heightCode(p, v[k].y));
  const bool plane = p.flags & kLevel3PlaneHeights;
  const bool exact = p.flags & kLevel2ExactHeights;
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
  return vstream;
}

/// The indices the index stream holds. Version 3: a group that is one grid
/// triangle of the lattice, in the builder's vertex order, stores no
/// indices (plain[g] = 1; its run says so).
std::vector<std::uint32_t> streamIndices(const Level& l, bool lattice, const std::vector<Group>& groups,
                                         const std::vector<std::uint32_t>& indices, std::vector<std::uint8_t>& plain) {
  plain.assign(groups.size(), 0);
  if (!lattice) return indices;
  std::vector<std::uint32_t> streamIdx;
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
  return streamIdx;
}

/// The stored groups as runs (LEB128: slot delta, priority, material, index
/// count, length; version 3 marks a lattice run in bit 0 of the length);
/// returns the run count.
std::uint32_t groupRuns(const std::vector<Group>& groups, const std::vector<std::uint8_t>& plain, bool v3,
                        std::vector<std::byte>& runs) {
  std::uint32_t runCount = 0;
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
  return runCount;
}

/// What a level's bytes are made of, besides its plan.
struct LevelStreams {
  std::vector<unsigned char> vertices, indices;
  std::vector<std::byte> runs;
  std::uint32_t runCount = 0;
  std::size_t streamIndices = 0;
};

/// Appends the level: header, lattice planes, maxHeight plane, streams.
void writeLevel(const Level& l, const Plan& p, std::uint32_t version, const LevelStreams& st,
                std::vector<std::byte>& out) {
  const auto& v = l.vertices;
  const std::size_t P = std::size_t(p.posts), V = v.size(), w = std::size_t(l.squaresX) + 1;
  const bool normals = p.flags & kLevel2Normals;
  const std::vector<unsigned char>& vstream = st.vertices;
  const std::vector<unsigned char>& istream = st.indices;
  const std::vector<std::byte>& runs = st.runs;
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
  storeLE<std::uint32_t>(h + levelField2::runCount, st.runCount);
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
    storeLE<std::uint32_t>(h + levelField3::streamIndices, std::uint32_t(st.streamIndices));
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

void encodeLevel(const Level& l, double heightStep, std::uint32_t version, std::vector<std::byte>& out) {
  Plan p = plan(l, heightStep);
  if (version >= kVersion3 && p.posts) {
    p.flags |= kLevel3PlaneHeights;
    planSkirts(l, p);
    p.xzExp = xzExponent(l.vertices, std::size_t(p.posts), l.vertices.size() - std::size_t(p.skirts.vertices));
  }
  const std::size_t P = std::size_t(p.posts), E = l.vertices.size() - P - std::size_t(p.skirts.vertices);
  if (version >= kVersion4 && P > 0) planVersion4(l, E, p);
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
  // Vertex and index streams first (their sizes go in the header).
  LevelStreams st;
  st.vertices = vertexStream(l, p, E);
  std::vector<std::uint8_t> plain;
  const bool v3 = version >= kVersion3;
  const std::vector<std::uint32_t> stream = streamIndices(l, v3 && P > 0, groups, indices, plain);
  if (!stream.empty()) {
    st.indices.resize(meshopt_encodeIndexSequenceBound(stream.size(), l.vertices.size()));
    st.indices.resize(meshopt_encodeIndexSequence(st.indices.data(), st.indices.size(), stream.data(), stream.size()));
  }
  st.streamIndices = stream.size();
  st.runCount = groupRuns(groups, plain, v3, st.runs);
  writeLevel(l, p, version, st, out);
}

}  // namespace

std::vector<std::byte> encodeV2(const Module& m, const EncodeOptions& options) {
  const double heightStep = options.heightStep;
  std::vector<std::byte> out(kHeaderBytes, std::byte{0});
  const std::uint32_t v = std::clamp(options.version, kVersion2, kVersion6);
  const std::uint32_t levelVersion = std::min(v, kVersion4);  // version 5's and 6's levels are version 4's
  for (const Level& l : m.levels) encodeLevel(l, heightStep, levelVersion, out);
  if (v == kVersion5) encodeObjects(m, out);
  if (v == kVersion6) encodeObjectsV6(m, options.regenerateRules, out);
  std::byte* const h = out.data();
  const auto& magic = v == kVersion6   ? kMagic6
                      : v == kVersion5 ? kMagic5
                      : v == kVersion4 ? kMagic4
                      : v == kVersion3 ? kMagic3
                                       : kMagic2;
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

}  // namespace sandtable::module::detail
