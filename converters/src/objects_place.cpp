// Object placement (docs/ICONS.md §8): candidates from points and scatter
// cells, kept where their class's skin is, and given a base height on the
// triangles of every level, so nothing floats or sinks when the level
// changes (seed Figure 87's yloc per level).
#include "sandtable/converters/objects.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sandtable/base/hash.h"

namespace sandtable::convert {

namespace {

using hash::mix;
using hash::unit;

std::uint64_t cellKey(std::int64_t i, std::int64_t j) {
  return mix(std::uint64_t(i) * 0x100000001b3ull ^ mix(std::uint64_t(j)));
}

bool skinGroup(const module::Group& g) {
  return g.priority == module::kPrioritySkin && g.half != module::Half::skirt;
}
bool decalGroup(const module::Group& g) {
  return g.priority > module::kPrioritySkin && g.priority < module::kPriorityObject && g.half != module::Half::skirt;
}

/// The group indices of each square of a level that pass `keep`.
std::vector<std::vector<std::uint32_t>> groupsBySquare(const module::Level& l, bool (*keep)(const module::Group&)) {
  std::vector<std::vector<std::uint32_t>> out(std::size_t(l.squaresX) * l.squaresZ);
  for (std::size_t g = 0; g < l.groups.size(); ++g) {
    if (keep(l.groups[g]) && l.groups[g].square < out.size()) out[l.groups[g].square].push_back(std::uint32_t(g));
  }
  return out;
}

/// The triangle of `groups` that holds (x, z) best: the largest smallest
/// barycentric coordinate. Returns that coordinate (-inf: none).
struct Hit {
  double inside = -std::numeric_limits<double>::infinity();
  float y = std::numeric_limits<float>::quiet_NaN();
  std::uint16_t material = 0;
};

void search(const module::Level& l, const std::vector<std::uint32_t>& groups, double x, double z, Hit& best) {
  for (const std::uint32_t gi : groups) {
    const module::Group& g = l.groups[gi];
    for (std::uint32_t k = g.firstIndex; k + 3 <= g.firstIndex + g.indexCount; k += 3) {
      const module::Vertex& a = l.vertices[l.indices[k]];
      const module::Vertex& b = l.vertices[l.indices[k + 1]];
      const module::Vertex& c = l.vertices[l.indices[k + 2]];
      const double d = (double(b.z) - c.z) * (double(a.x) - c.x) + (double(c.x) - b.x) * (double(a.z) - c.z);
      if (d == 0) continue;
      const double wa = ((double(b.z) - c.z) * (x - c.x) + (double(c.x) - b.x) * (z - c.z)) / d;
      const double wb = ((double(c.z) - a.z) * (x - c.x) + (double(a.x) - c.x) * (z - c.z)) / d;
      const double wc = 1 - wa - wb;
      const double inside = std::min({wa, wb, wc});
      if (inside > best.inside) {
        best.inside = inside;
        best.y = float(wa * a.y + wb * b.y + wc * c.y);
        best.material = g.material;
      }
    }
  }
}

std::uint32_t squareOf(double c, double spacing, std::uint32_t n) {
  return std::uint32_t(std::clamp(std::floor(c / spacing), 0.0, double(n - 1)));
}

/// The best hit among the square holding (x, z) and, when the point is on
/// its edge or outside it, its neighbours.
Hit locate(const module::Level& l, const std::vector<std::vector<std::uint32_t>>& bySquare, double x, double z) {
  Hit best;
  if (l.squaresX == 0 || l.squaresZ == 0 || !(l.spacing > 0)) return best;
  const std::uint32_t sx = squareOf(x, l.spacing, l.squaresX), sz = squareOf(z, l.spacing, l.squaresZ);
  search(l, bySquare[std::size_t(sz) * l.squaresX + sx], x, z, best);
  constexpr double kEdge = 1e-7;
  if (best.inside >= kEdge) return best;
  for (std::uint32_t j = sz > 0 ? sz - 1 : 0; j <= std::min(sz + 1, l.squaresZ - 1); ++j) {
    for (std::uint32_t i = sx > 0 ? sx - 1 : 0; i <= std::min(sx + 1, l.squaresX - 1); ++i) {
      if (i != sx || j != sz) search(l, bySquare[std::size_t(j) * l.squaresX + i], x, z, best);
    }
  }
  return best;
}

constexpr double kOnTriangle = -1e-6;  ///< barycentric slack for points on an edge

/// A building's groups (priority 99: walls and roof) with their ground
/// extent: a building's groups sit in the square of its centre, not in
/// every square it covers, so they are found by box instead.
struct BuildingBox {
  float x0, z0, x1, z1;
  std::uint32_t group;
};

std::vector<BuildingBox> buildingBoxes(const module::Level& l) {
  std::vector<BuildingBox> out;
  for (std::uint32_t g = 0; g < l.groups.size(); ++g) {
    const module::Group& gr = l.groups[g];
    if (gr.priority != module::kPriorityObject || gr.half == module::Half::skirt) continue;
    BuildingBox b{std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                  std::numeric_limits<float>::lowest(), std::numeric_limits<float>::lowest(), g};
    for (std::uint32_t k = gr.firstIndex; k < gr.firstIndex + gr.indexCount && k < l.indices.size(); ++k) {
      const module::Vertex& v = l.vertices[l.indices[k]];
      b.x0 = std::min(b.x0, v.x), b.x1 = std::max(b.x1, v.x);
      b.z0 = std::min(b.z0, v.z), b.z1 = std::max(b.z1, v.z);
    }
    out.push_back(b);
  }
  return out;
}

/// Whether (x, z) lies under a building's roof (walls are edge-on from above).
bool underBuilding(const module::Level& l, const std::vector<BuildingBox>& boxes, double x, double z) {
  for (const BuildingBox& b : boxes) {
    if (x < b.x0 || x > b.x1 || z < b.z0 || z > b.z1) continue;
    Hit hit;
    search(l, {b.group}, x, z, hit);
    if (hit.inside >= kOnTriangle) return true;
  }
  return false;
}

}  // namespace

void vary(const materials::Variation& v, std::uint64_t seed, std::uint64_t key, float& scale, std::uint16_t& heading) {
  const std::uint64_t h = mix(seed ^ mix(key));
  scale = float(v.scaleMin + (v.scaleMax - v.scaleMin) * unit(h));
  heading = std::uint16_t(mix(h) & 0xffff);
}

void placeObjects(const ObjectPlan& plan, const std::vector<std::uint32_t>& points, double x0, double z0,
                  module::Module& m, ObjectTotals& totals) {
  if (m.levels.empty()) return;
  const module::Level& l0 = m.levels.front();
  std::vector<module::Object> objects;
  for (const std::uint32_t k : points) {
    const ObjectPlan::Point& p = plan.points[k];
    objects.push_back({p.icon, p.cls, float(p.x - x0), float(p.z - z0), p.heading, p.scale, 0, 0});
  }
  if (!plan.scatters.empty()) {
    const auto skin0 = groupsBySquare(l0, skinGroup), decals0 = groupsBySquare(l0, decalGroup);
    const auto buildings0 = buildingBoxes(l0);
    const double w = l0.spacing * l0.squaresX, h = l0.spacing * l0.squaresZ;
    for (std::size_t s = 0; s < plan.scatters.size(); ++s) {
      const ObjectPlan::Scatter& sc = plan.scatters[s];
      const auto i0 = std::int64_t(std::floor(x0 / sc.cell)), i1 = std::int64_t(std::floor((x0 + w) / sc.cell));
      const auto j0 = std::int64_t(std::floor(z0 / sc.cell)), j1 = std::int64_t(std::floor((z0 + h) / sc.cell));
      for (std::int64_t j = j0; j <= j1; ++j) {
        for (std::int64_t i = i0; i <= i1; ++i) {
          // One candidate per cell, jittered: the density is exact on average
          // and the candidates do not depend on where modules are cut.
          const std::uint64_t key = cellKey(i, j) ^ mix(sc.seed + s);
          const double X = (double(i) + unit(mix(key))) * sc.cell, Z = (double(j) + unit(mix(key + 1))) * sc.cell;
          const double x = X - x0, z = Z - z0;
          if (!(x >= 0 && x < w && z >= 0 && z < h)) continue;  // another module's
          const Hit skin = locate(l0, skin0, x, z);
          const bool covered =
              locate(l0, decals0, x, z).inside >= kOnTriangle || underBuilding(l0, buildings0, x, z);
          if (skin.inside < kOnTriangle || skin.material != sc.classId || covered) {
            ++totals.scatterRefused;
            continue;
          }
          module::Object o{sc.icon, sc.classId, float(x), float(z), 0, 1, 0, 0};
          vary(sc.variation, sc.seed, key, o.scale, o.heading);
          objects.push_back(o);
        }
      }
    }
  }
  for (module::Object& o : objects) {
    const auto& cyl = o.icon < plan.cylinders.size() ? plan.cylinders[o.icon] : std::array<float, 2>{0, 0};
    o.radius = cyl[0] * o.scale;
    o.height = cyl[1] * o.scale;
  }
  std::sort(objects.begin(), objects.end(), [](const module::Object& a, const module::Object& b) {
    return std::tie(a.icon, a.z, a.x) < std::tie(b.icon, b.z, b.x);
  });
  m.objects = std::move(objects);
  for (module::Level& l : m.levels) {
    const auto skin = groupsBySquare(l, skinGroup);
    l.objectY.resize(m.objects.size());
    for (std::size_t k = 0; k < m.objects.size(); ++k) {
      const Hit hit = locate(l, skin, m.objects[k].x, m.objects[k].z);
      l.objectY[k] = std::isfinite(hit.y) ? hit.y : 0.0f;
    }
  }
  totals.placed += m.objects.size();
  for (const module::Object& o : m.objects) ++totals.byClass[o.cls];
}

}  // namespace sandtable::convert
