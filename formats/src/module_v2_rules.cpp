// The rules the module encoder and decoder (versions 3 and later) must
// apply bit for bit (module_v2_internal.h): implicit skirts and lattice
// triangles, from terrain_rule.h where the builder's own rules live, and
// the derived maxHeight.
#include <algorithm>
#include <array>
#include <cstring>
#include <limits>

#include "module_v2_internal.h"

namespace sandtable::module::detail {

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

bool latticeTriangle(std::uint32_t square, std::uint8_t half, std::uint32_t sx, std::uint32_t sz,
                     std::uint32_t out[3]) {
  if (half > 1 || square >= std::uint64_t(sx) * sz) return false;
  const std::uint32_t w = sx + 1, nw = (square / sx) * w + square % sx;
  const auto tri = terrain::halfCorners(static_cast<Half>(half), std::array{nw, nw + 1, nw + w, nw + w + 1});
  std::copy(tri.begin(), tri.end(), out);
  return true;
}

}  // namespace sandtable::module::detail
