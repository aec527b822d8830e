#pragma once
// Hand-made load modules for tests: a grid written with GridWriter and
// modules built straight from the contract in module.h (no converter), so
// the checks can be tested on sound modules and on one corruption at a time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/materials.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/pack.h"

namespace sandtable::module::handmade {

inline constexpr double kSpacing = 30.0;

/// Elevation of post (i, j): uneven, so coarser levels differ from finer.
inline float elevationAt(std::uint32_t i, std::uint32_t j) {
  return float(100.0 + 3.0 * i + 2.0 * j + double((i * 7 + j * 3) % 5) * 1.5);
}

/// Writes a grid of nx x nz posts into a fresh temp directory.
inline std::shared_ptr<const grid::GridFile> writeGrid(const std::string& dir, std::uint32_t nx,
                                                std::uint32_t nz) {
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/grid.stg";
  auto w = grid::GridWriter::create(path, grid::makeHeader(nx, nz, kSpacing, 500000.0, 4000000.0));
  EXPECT_TRUE(w.ok()) << w.error();
  const grid::Header& h = w.value()->header();
  auto b = std::make_unique<grid::BlockData>();
  for (std::uint32_t bz = 0; bz < h.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < h.blocksX; ++bx) {
      for (std::uint32_t k = 0; k < grid::kPostsPerBlock; ++k) {
        const std::uint32_t i = std::min(nx - 1, bx * grid::kBlockPosts + k % grid::kBlockPosts);
        const std::uint32_t j = std::min(nz - 1, bz * grid::kBlockPosts + k / grid::kBlockPosts);
        b->elevation[k] = elevationAt(i, j);
        b->normalX[k] = 0;
        b->normalY[k] = grid::toSnorm(1.0f);
        b->normalZ[k] = 0;
        b->material[k] = 0;
      }
      EXPECT_EQ(w.value()->writeBlock(bx, bz, *b).message(), "");
    }
  }
  EXPECT_EQ(w.value()->finish().message(), "");
  auto g = grid::GridFile::open(path);
  EXPECT_TRUE(g.ok()) << g.error();
  return g.value();
}

/// A skin vertex at module-local (x, z) of the module whose NW corner is
/// grid post (i0, j0), with the texture coordinates module.h prescribes.
inline Vertex skinTextured(std::uint32_t i0, std::uint32_t j0, double x, double y, double z) {
  const double s0 = skinTextureOffset(i0 * kSpacing), t0 = skinTextureOffset(j0 * kSpacing);
  return {float(x), float(y), float(z), float((s0 + x) / kSkinTextureRepeat), float((t0 + z) / kSkinTextureRepeat)};
}

struct BuildOptions {
  float skirtDepth = 20.0f;
  bool decal = true;
  bool nodeSkirts = false;    ///< also skirts on interior lattice lines (as the builder does)
  bool splitEastEdge = false; ///< an extra skin vertex halfway along each east-edge segment
};

/// A sound module built straight from the contract in module.h: the skin
/// of every upper triangle in two pieces (materials 0 and 1) meeting at the
/// diagonal's midpoint, the lower triangle whole, one road decal in square
/// 0, skirts (material 3) along the four edges.
/// Materials: table() below.
inline Module buildModule(const grid::GridFile& g, const pack::IndexHeader& h, std::uint32_t kx,
                   std::uint32_t kz, const BuildOptions& o = {}) {
  Module m;
  m.kx = kx;
  m.kz = kz;
  const std::uint32_t S = h.moduleSquares;
  const std::uint32_t i0 = kx * S, j0 = kz * S;
  const std::uint32_t i1 = std::min(i0 + S, g.postsX() - 1), j1 = std::min(j0 + S, g.postsZ() - 1);
  for (std::uint32_t l = 0; l < h.levels; ++l) {
    const std::uint32_t step = 1u << l;
    std::vector<std::uint32_t> cols, rows;
    for (std::uint32_t p = i0; p < i1; p += step) cols.push_back(p);
    cols.push_back(i1);
    for (std::uint32_t p = j0; p < j1; p += step) rows.push_back(p);
    rows.push_back(j1);
    Level lv;
    lv.spacing = kSpacing * step;
    lv.squaresX = std::uint32_t(cols.size() - 1);
    lv.squaresZ = std::uint32_t(rows.size() - 1);
    lv.skirtDepth = o.skirtDepth;
    const std::uint32_t nx = lv.squaresX, nz = lv.squaresZ;
    auto skinVertex = [&](double x, double z, double y) { return skinTextured(i0, j0, x, y, z); };
    for (std::uint32_t b = 0; b <= nz; ++b) {
      for (std::uint32_t a = 0; a <= nx; ++a) {
        lv.vertices.push_back(skinVertex((cols[a] - i0) * kSpacing, (rows[b] - j0) * kSpacing,
                                         g.elevation(cols[a], rows[b])));
      }
    }
    auto post = [&](std::uint32_t a, std::uint32_t b) { return b * (nx + 1) + a; };
    auto vertex = [&](double x, double z, double y) {
      lv.vertices.push_back(skinVertex(x, z, y));
      return std::uint32_t(lv.vertices.size() - 1);
    };
    auto mid = [&](std::uint32_t p, std::uint32_t q) {
      const Vertex &a = lv.vertices[p], &b = lv.vertices[q];
      return vertex((double(a.x) + b.x) / 2, (double(a.z) + b.z) / 2, (double(a.y) + b.y) / 2);
    };
    std::map<std::tuple<std::uint8_t, std::uint32_t, std::uint8_t, std::uint16_t>, std::vector<std::uint32_t>> groups;
    auto add = [&](std::uint32_t square, Half half, std::uint8_t priority, std::uint16_t material,
                   std::initializer_list<std::uint32_t> tri) {
      auto& v = groups[{priority, square, std::uint8_t(half), material}];
      v.insert(v.end(), tri);
    };
    for (std::uint32_t sz = 0; sz < nz; ++sz) {
      for (std::uint32_t sx = 0; sx < nx; ++sx) {
        const std::uint32_t sq = sz * nx + sx;
        const std::uint32_t nw = post(sx, sz), ne = post(sx + 1, sz), sw = post(sx, sz + 1),
                            se = post(sx + 1, sz + 1);
        const std::uint32_t md = mid(ne, sw);
        add(sq, Half::upper, kPrioritySkin, 0, {nw, sw, md});
        add(sq, Half::upper, kPrioritySkin, 1, {nw, md, ne});
        if (o.splitEastEdge && sx == nx - 1) {
          const std::uint32_t e = mid(ne, se);
          add(sq, Half::lower, kPrioritySkin, 0, {ne, sw, e});
          add(sq, Half::lower, kPrioritySkin, 0, {e, sw, se});
        } else {
          add(sq, Half::lower, kPrioritySkin, 0, {ne, sw, se});
        }
      }
    }
    if (o.decal) {  // a road crumb near the NW corner of square 0, in the upper plane
      const Vertex nw = lv.vertices[post(0, 0)], ne = lv.vertices[post(1, 0)], sw = lv.vertices[post(0, 1)];
      auto inPlane = [&](double dx, double dz) {
        const double y = nw.y + dx / (double(ne.x) - nw.x) * (double(ne.y) - nw.y) +
                         dz / (double(sw.z) - nw.z) * (double(sw.y) - nw.y);
        const std::uint32_t v = vertex(nw.x + dx, nw.z + dz, y);
        lv.vertices[v].s = float(dx / 4.0);  // a road 4 m wide running east: s along, t across
        lv.vertices[v].t = float(dz / 6.0);
        return v;
      };
      add(0, Half::upper, kPriorityRoad, 2, {inPlane(1, 1), inPlane(1, 5), inPlane(5, 1)});
    }
    // Skirts: along a lattice line, one quad per segment.
    auto hang = [&](std::uint32_t square, std::uint32_t top0, std::uint32_t top1) {
      Vertex b0 = lv.vertices[top0], b1 = lv.vertices[top1];
      b0.y -= o.skirtDepth;
      b1.y -= o.skirtDepth;
      lv.vertices.push_back(b0);
      lv.vertices.push_back(b1);
      const auto bb0 = std::uint32_t(lv.vertices.size() - 2), bb1 = bb0 + 1;
      add(square, Half::skirt, kPrioritySkin, 3, {top0, bb0, top1, top1, bb0, bb1});
    };
    for (std::uint32_t a = 0; a < nx; ++a) {
      for (std::uint32_t b = 0; b <= nz; ++b) {
        if (b == 0 || b == nz || (o.nodeSkirts && b % 2 == 0)) {
          hang(std::min(b, nz - 1) * nx + a, post(a, b), post(a + 1, b));
        }
      }
    }
    for (std::uint32_t b = 0; b < nz; ++b) {
      for (std::uint32_t a = 0; a <= nx; ++a) {
        if (a == 0 || a == nx || (o.nodeSkirts && a % 2 == 0)) {
          hang(b * nx + std::min(a, nx - 1), post(a, b), post(a, b + 1));
        }
      }
    }
    for (const auto& [key, idx] : groups) {
      Group gr;
      gr.priority = std::get<0>(key);
      gr.square = std::get<1>(key);
      gr.half = Half(std::get<2>(key));
      gr.material = std::get<3>(key);
      gr.firstIndex = std::uint32_t(lv.indices.size());
      gr.indexCount = std::uint32_t(idx.size());
      lv.indices.insert(lv.indices.end(), idx.begin(), idx.end());
      lv.groups.push_back(gr);
    }
    lv.maxHeight.assign(std::size_t(nx) * nz, -INFINITY);
    for (const Group& gr : lv.groups) {
      if (gr.half == Half::skirt) continue;
      for (std::uint32_t k = 0; k < gr.indexCount; ++k) {
        lv.maxHeight[gr.square] = std::max(lv.maxHeight[gr.square], lv.vertices[lv.indices[gr.firstIndex + k]].y);
      }
    }
    m.levels.push_back(std::move(lv));
  }
  return m;
}

inline materials::Table table() {
  materials::Table t;
  auto cls = [&](std::uint16_t id, const char* name, materials::Kind kind, std::uint8_t priority,
                 std::uint32_t rgb) {
    materials::Class c;
    c.id = id;
    c.name = name;
    c.kind = kind;
    c.priority = priority;
    c.rank = id;
    c.upperRgb = rgb;
    c.lowerRgb = rgb;
    c.material = id;
    c.width = kind == materials::Kind::line ? 6.0 : 0.0;
    t.classes.push_back(c);
  };
  cls(0, "grass", materials::Kind::area, 1, 0x55aa33);
  cls(1, "forest", materials::Kind::area, 1, 0x226622);
  cls(2, "road", materials::Kind::line, 10, 0x404040);
  cls(3, "rock", materials::Kind::area, 1, 0x998877);
  t.defaultArea = 0;
  t.defaultLine = 2;
  return t;
}

}  // namespace sandtable::module::handmade
