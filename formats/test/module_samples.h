#pragma once
// Sample load modules for the module and pack tests: a tiny one for golden
// bytes, and realistic ones built like the builder builds them (a skin of
// grid triangles with land-use boundaries splitting some of them, skirts
// along the four edges, a road decal) at several levels of detail. Fully
// deterministic: no std distributions, no clock.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <tuple>
#include <vector>

#include "sandtable/formats/module.h"

namespace sandtable::module::samples {

/// splitmix64: the same numbers on every platform.
inline std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
/// Uniform in [0, 1) from a hash of its arguments.
inline double unit(std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  return double(mix(a * 0x100000001b3ull ^ mix(b * 31 + c)) >> 11) * 0x1p-53;
}

/// One square, one level: the golden-bytes module.
inline Module tiny() {
  Module m;
  m.kx = 1;
  m.kz = 2;
  Level l;
  l.spacing = 30;
  l.squaresX = 1;
  l.squaresZ = 1;
  l.skirtDepth = 5;
  l.vertices = {{0, 10, 0, 0, 0}, {30, 11, 0, 1, 0}, {0, 12, 30, 0, 1}, {30, 13, 30, 1, 1}};
  l.indices = {0, 1, 2, 1, 3, 2};
  l.groups = {{0, Half::upper, kPrioritySkin, 3, 0, 3}, {0, Half::lower, kPrioritySkin, 4, 3, 3}};
  l.maxHeight = {13};
  m.levels.push_back(l);
  return m;
}

/// Terrain height at module-local (x, z) of module (kx, kz): smooth hills
/// plus per-post noise, so every float uses its whole mantissa.
inline float height(std::uint32_t kx, std::uint32_t kz, double x, double z, std::uint64_t post) {
  const double wx = x + 960.0 * kx, wz = z + 960.0 * kz;
  const double h = 420 + 90 * std::sin(wx / 310.0) * std::cos(wz / 270.0) +
                   35 * std::sin((wx + 2 * wz) / 97.0) + 6 * unit(kx, kz, post);
  return static_cast<float>(h);
}

/// One level of a realistic module: `squares` x `squares` grid squares.
inline Level realisticLevel(std::uint32_t kx, std::uint32_t kz, std::uint32_t squares,
                            double spacing, std::uint32_t level) {
  Level l;
  l.spacing = spacing;
  l.squaresX = squares;
  l.squaresZ = squares;
  l.skirtDepth = static_cast<float>(spacing * 0.5);
  const std::uint32_t n = squares + 1;
  auto vertex = [&](double x, double y, double z) {
    l.vertices.push_back({float(x), float(y), float(z), float(x / 64.0), float(z / 64.0)});
    return static_cast<std::uint32_t>(l.vertices.size() - 1);
  };
  for (std::uint32_t j = 0; j < n; ++j) {
    for (std::uint32_t i = 0; i < n; ++i) {
      const double x = i * spacing, z = j * spacing;
      vertex(x, height(kx, kz, x, z, (std::uint64_t(level) << 40) | (j << 20) | i), z);
    }
  }
  auto post = [n](std::uint32_t i, std::uint32_t j) { return j * n + i; };
  // Land use: patches of 4 classes, about 6 squares across at level 0.
  auto landUse = [&](std::uint32_t i, std::uint32_t j) {
    const double cell = 6.0 / (1u << level);
    return static_cast<std::uint16_t>(1 +
                                      mix(std::uint64_t(kx * 1000 + std::floor(i / cell)) * 7919 +
                                          std::uint64_t(kz * 1000 + std::floor(j / cell))) %
                                          4);
  };

  struct Tri {
    std::uint8_t priority;
    std::uint32_t square;
    std::uint8_t half;
    std::uint16_t material;
    std::uint32_t a, b, c;
  };
  std::vector<Tri> tris;
  for (std::uint32_t j = 0; j < squares; ++j) {
    for (std::uint32_t i = 0; i < squares; ++i) {
      const std::uint32_t sq = j * squares + i;
      const std::uint32_t nw = post(i, j), ne = post(i + 1, j), sw = post(i, j + 1),
                          se = post(i + 1, j + 1);
      const std::uint16_t mat = landUse(i, j), east = landUse(i + 1, j);
      if (mat != east) {
        // A land-use boundary crosses the upper triangle: split it at the
        // middle of the diagonal into two classes.
        const auto& vn = l.vertices[ne];
        const auto& vs = l.vertices[sw];
        const std::uint32_t mid =
            vertex((vn.x + vs.x) / 2.0, (vn.y + vs.y) / 2.0, (vn.z + vs.z) / 2.0);
        tris.push_back({kPrioritySkin, sq, 0, mat, nw, mid, sw});
        tris.push_back({kPrioritySkin, sq, 0, east, nw, ne, mid});
      } else {
        tris.push_back({kPrioritySkin, sq, 0, mat, nw, ne, sw});
      }
      tris.push_back({kPrioritySkin, sq, 1, mat, ne, se, sw});
    }
  }
  // Skirts along the four edges.
  auto skirt = [&](std::uint32_t p0, std::uint32_t p1, std::uint32_t sq, std::uint16_t mat) {
    const Vertex a = l.vertices[p0], b = l.vertices[p1];
    const std::uint32_t a2 = vertex(a.x, a.y - l.skirtDepth, a.z);
    const std::uint32_t b2 = vertex(b.x, b.y - l.skirtDepth, b.z);
    tris.push_back({kPrioritySkin, sq, 2, mat, p0, p1, b2});
    tris.push_back({kPrioritySkin, sq, 2, mat, p0, b2, a2});
  };
  for (std::uint32_t i = 0; i < squares; ++i) {
    skirt(post(i, 0), post(i + 1, 0), i, landUse(i, 0));
    skirt(post(i + 1, squares), post(i, squares), (squares - 1) * squares + i,
          landUse(i, squares - 1));
    skirt(post(0, i + 1), post(0, i), i * squares, landUse(0, i));
    skirt(post(squares, i), post(squares, i + 1), i * squares + squares - 1,
          landUse(squares - 1, i));
  }
  // A road: a 7 m wide decal running diagonally, one quad per square.
  for (std::uint32_t i = 0; i < squares; ++i) {
    const std::uint32_t j = std::min(squares - 1, (i * 3) / 4 + squares / 8);
    const double x0 = i * spacing, x1 = x0 + spacing, zc = (j + 0.5) * spacing;
    const double y0 = height(kx, kz, x0, zc, 1) + 0.05, y1 = height(kx, kz, x1, zc, 2) + 0.05;
    const std::uint32_t base = static_cast<std::uint32_t>(l.vertices.size());
    l.vertices.push_back({float(x0), float(y0), float(zc - 3.5), float(x0 / 7.0), 0});
    l.vertices.push_back({float(x1), float(y1), float(zc - 3.5), float(x1 / 7.0), 0});
    l.vertices.push_back({float(x0), float(y0), float(zc + 3.5), float(x0 / 7.0), 1});
    l.vertices.push_back({float(x1), float(y1), float(zc + 3.5), float(x1 / 7.0), 1});
    const std::uint32_t sq = j * squares + i;
    tris.push_back({kPriorityRoad, sq, 0, 20, base, base + 1, base + 2});
    tris.push_back({kPriorityRoad, sq, 1, 20, base + 1, base + 3, base + 2});
  }
  // Groups in (priority, square, half, material) order.
  std::stable_sort(tris.begin(), tris.end(), [](const Tri& a, const Tri& b) {
    return std::tie(a.priority, a.square, a.half, a.material) <
           std::tie(b.priority, b.square, b.half, b.material);
  });
  for (const Tri& t : tris) {
    if (l.groups.empty() || l.groups.back().priority != t.priority ||
        l.groups.back().square != t.square || std::uint8_t(l.groups.back().half) != t.half ||
        l.groups.back().material != t.material) {
      l.groups.push_back({t.square, Half(t.half), t.priority, t.material,
                          static_cast<std::uint32_t>(l.indices.size()), 0});
    }
    l.indices.insert(l.indices.end(), {t.a, t.b, t.c});
    l.groups.back().indexCount += 3;
  }
  l.maxHeight.assign(std::size_t(squares) * squares, -1e30f);
  for (const Tri& t : tris) {
    for (const std::uint32_t v : {t.a, t.b, t.c}) {
      if (t.half == 2) continue;  // skirts hang below the surface
      l.maxHeight[t.square] = std::max(l.maxHeight[t.square], l.vertices[v].y);
    }
  }
  return l;
}

/// A realistic module: level 0 has `squares` x `squares` squares of 30 m;
/// each further level halves the squares and doubles the spacing.
inline Module realistic(std::uint32_t kx, std::uint32_t kz, std::uint32_t squares = 32,
                        std::uint32_t levels = 4) {
  Module m;
  m.kx = kx;
  m.kz = kz;
  for (std::uint32_t l = 0; l < levels; ++l) {
    m.levels.push_back(realisticLevel(kx, kz, std::max(1u, squares >> l), 30.0 * (1u << l), l));
  }
  return m;
}

}  // namespace sandtable::module::samples
