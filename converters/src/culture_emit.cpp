// The decaler's output: skin groups as each grid triangle is done, decal
// groups after all skin, and road texture coordinates (seed Figure 17).
#include <algorithm>
#include <cmath>
#include <limits>

#include "culture_level_work.h"

namespace sandtable::convert {
namespace culture {

void LevelWork::beginGroup(std::size_t sq, int half, std::uint8_t priority, std::uint16_t material) {
  Group g;
  g.square = std::uint32_t(sq);
  g.half = half == 0 ? Half::upper : Half::lower;
  g.priority = priority;
  g.material = material;
  g.firstIndex = std::uint32_t(out_.indices.size());
  out_.groups.push_back(g);
}


void LevelWork::endGroup() {
  Group& g = out_.groups.back();
  g.indexCount = std::uint32_t(out_.indices.size()) - g.firstIndex;
  if (g.indexCount == 0) out_.groups.pop_back();
}


/// Corner k of the triangle at point p, or -1.
int LevelWork::cornerAt(const Tri& t, const SnapPoint& s) {
  if (bits(s.on) < 2) return -1;
  for (int k = 0; k < 3; ++k) {
    if ((t.cb[k] & s.on) == t.cb[k]) return k;
  }
  return -1;
}


void LevelWork::emit(std::size_t sq, int half, const Tri& t, bool skinOk, Vec2 centroid) {
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
void LevelWork::flushDecals() {
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
void LevelWork::roadST(std::size_t l, Vec2 p, float& s, float& t) const {
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


}  // namespace culture
}  // namespace sandtable::convert
