// Per-level lookups of the decaler: which square holds a point, each grid
// triangle, the candidate pieces per square, the triangles a boundary
// crosses, the label at a point and the nearest road centreline.
#include <algorithm>
#include <array>
#include <cmath>

#include "culture_level_work.h"

namespace sandtable::convert {
namespace culture {

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


std::size_t LevelWork::colOf(double x) const {
  const auto it = std::upper_bound(lat_.xs.begin(), lat_.xs.end(), x);
  const std::size_t k = std::size_t(it - lat_.xs.begin());
  return std::min(k == 0 ? 0 : k - 1, nx_ - 1);
}


std::size_t LevelWork::rowOf(double z) const {
  const auto it = std::upper_bound(lat_.zs.begin(), lat_.zs.end(), z);
  const std::size_t k = std::size_t(it - lat_.zs.begin());
  return std::min(k == 0 ? 0 : k - 1, nz_ - 1);
}


Tri LevelWork::tri(std::size_t sq, int half) const {
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


void LevelWork::prepare(std::size_t l) {
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
std::uint16_t LevelWork::labelAt(std::size_t l, std::size_t sq, Vec2 p) const {
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


}  // namespace culture
}  // namespace sandtable::convert
