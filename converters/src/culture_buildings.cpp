// Buildings (docs/CULTURE.md, "Buildings"): the footprints of extruded
// classes become walls and a flat roof at priority 99 on every level, each
// level standing on its own lattice, instead of skin polygons.
#include <algorithm>
#include <cmath>
#include <exception>
#include <map>
#include <utility>

#include "culture_internal.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::convert::culture {
namespace {

/// Walls reach this far below the lowest ground under the footprint, so
/// that no gap shows on a slope (seed Figure 24).
constexpr double kWallFoot = 0.5;
/// Levels above 0 keep a footprint only when its area is at least
/// (level spacing * kKeepFraction)^2: a 15 x 15 m footprint on a 60 m level.
constexpr double kKeepFraction = 0.25;

/// Height of the lattice's surface (SW-NE split squares) at module-local
/// (x, z); clamped to the lattice at its edges.
/// The lattice interval holding c (clamped to the first and last).
std::size_t interval(const std::vector<double>& v, double c) {
  const auto it = std::upper_bound(v.begin(), v.end(), c);
  const std::size_t i = it == v.begin() ? 0 : std::size_t(it - v.begin()) - 1;
  return std::min(i, v.size() - 2);
}

double latticeHeight(const LevelLattice& lat, double x, double z) {
  const std::size_t i = interval(lat.xs, x), j = interval(lat.zs, z);
  const double u = std::clamp((x - lat.xs[i]) / (lat.xs[i + 1] - lat.xs[i]), 0.0, 1.0);
  const double v = std::clamp((z - lat.zs[j]) / (lat.zs[j + 1] - lat.zs[j]), 0.0, 1.0);
  const std::size_t cols = lat.xs.size();
  const auto h = [&](std::size_t a, std::size_t b) { return double(lat.heights[b * cols + a]); };
  const double nw = h(i, j), ne = h(i + 1, j), sw = h(i, j + 1), se = h(i + 1, j + 1);
  return terrain::planeHeight(u, v, nw, ne, sw, se);
}

std::uint32_t squareIndex(const LevelLattice& lat, Vec2 p) {
  return std::uint32_t(interval(lat.zs, p.z) * (lat.xs.size() - 1) + interval(lat.xs, p.x));
}

/// One building's triangles on one level, appended to `out` (vertices and
/// indices); returns the triangles added.
std::uint32_t emitBuilding(const BuildingFeature& b, const LevelLattice& lat, double step, module::Level& out) {
  const auto snap = [step](double v) { return step > 0 ? std::round(v / step) * step : v; };
  std::vector<Ring> local;
  double ground = INFINITY;
  for (const Ring& r : b.rings) {
    Ring l;
    for (const Vec2 p : r) {
      const Vec2 q{snap(p.x - lat.moduleX), snap(p.z - lat.moduleZ)};
      if (!l.empty() && l.back() == q) continue;
      l.push_back(q);
      ground = std::min(ground, latticeHeight(lat, q.x, q.z));
    }
    while (l.size() > 1 && l.front() == l.back()) l.pop_back();
    if (l.size() >= 3) local.push_back(std::move(l));
  }
  if (local.empty() || !std::isfinite(ground)) return 0;
  const auto roof = float(ground + b.height), foot = float(ground - kWallFoot);
  std::uint32_t triangles = 0;
  const auto vertex = [&](Vec2 p, float y) {
    out.vertices.push_back({float(p.x), y, float(p.z), 0, 0});
    return std::uint32_t(out.vertices.size() - 1);
  };
  // Walls: wound so that their normal points away from the solid, on
  // outer rings (positive) and courtyard rings (negative) alike.
  for (const Ring& r : local) {
    for (std::size_t k = 0; k < r.size(); ++k) {
      const Vec2 a = r[k], c = r[(k + 1) % r.size()];
      const std::uint32_t ab = vertex(a, foot), cb = vertex(c, foot), at = vertex(a, roof), ct = vertex(c, roof);
      out.indices.insert(out.indices.end(), {cb, ab, at, cb, at, ct});
      triangles += 2;
    }
  }
  std::map<std::pair<double, double>, std::uint32_t> roofVertex;
  const auto roofAt = [&](Vec2 p) {
    const auto [it, added] = roofVertex.try_emplace({p.x, p.z}, 0);
    if (added) it->second = vertex(p, roof);
    return it->second;
  };
  for (auto t : roofTriangles(local)) {
    // Facing up: clockwise in (x, z) taken as (x, y).
    if (cross(t[1] - t[0], t[2] - t[0]) > 0) std::swap(t[1], t[2]);
    out.indices.insert(out.indices.end(), {roofAt(t[0]), roofAt(t[1]), roofAt(t[2])});
    ++triangles;
  }
  return triangles;
}

}  // namespace

void CultureImpl::addBuildings(const LevelLattice& lat, module::Level& out, DecalStats& st) const {
  if (buildings.empty() || buildingIndex.empty()) return;
  const double x0 = lat.moduleX + lat.xs.front(), x1 = lat.moduleX + lat.xs.back();
  const double z0 = lat.moduleZ + lat.zs.front(), z1 = lat.moduleZ + lat.zs.back();
  const double keep = lat.level > 0 ? std::pow(lat.spacing * kKeepFraction, 2) : 0.0;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> mine;  // (square, building)
  const auto cell = [this](double v, std::uint32_t n) {
    return std::uint32_t(std::clamp(std::floor(v / indexCell), 0.0, double(n - 1)));
  };
  for (std::uint32_t r = cell(z0, indexRows); r <= cell(z1, indexRows); ++r) {
    for (std::uint32_t q = cell(x0, indexCols); q <= cell(x1, indexCols); ++q) {
      for (const std::uint32_t k : buildingIndex[std::size_t(r) * indexCols + q]) {
        const BuildingFeature& b = buildings[k];
        const Vec2 c = b.centre();
        // Half-open, so a centre on a module edge belongs to one module.
        if (c.x < x0 || c.x >= x1 || c.z < z0 || c.z >= z1 || b.area < keep) continue;
        mine.emplace_back(squareIndex(lat, {c.x - lat.moduleX, c.z - lat.moduleZ}), k);
      }
    }
  }
  std::sort(mine.begin(), mine.end());
  for (const auto& [square, k] : mine) {
    const BuildingFeature& b = buildings[k];
    const auto first = std::uint32_t(out.indices.size());
    const std::size_t vertices = out.vertices.size();
    std::uint32_t triangles = 0;
    try {
      triangles = emitBuilding(b, lat, options.vertexStep, out);
    } catch (const std::exception&) {
      ++st.failures;  // CGAL refused the footprint: it is left out of this level
      out.vertices.resize(vertices);
      out.indices.resize(first);
      continue;
    }
    if (triangles == 0) continue;
    module::Group* last = out.groups.empty() ? nullptr : &out.groups.back();
    if (last && last->priority == module::kPriorityObject && last->square == square && last->material == b.classId &&
        last->firstIndex + last->indexCount == first) {
      last->indexCount += 3 * triangles;
    } else {
      out.groups.push_back({square, module::Half::upper, module::kPriorityObject, b.classId, first, 3 * triangles});
    }
    ++st.buildings;
    st.buildingTriangles += triangles;
  }
}

}  // namespace sandtable::convert::culture
