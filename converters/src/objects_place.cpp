// Object placement (docs/ICONS.md §8): candidates from points and scatter
// cells, kept where their class's skin is, and given a base height on the
// triangles of every level, so nothing floats or sinks when the level
// changes (seed Figure 87's yloc per level). The scatter rule and the bases
// are module::scatter and module::placeBases (formats/scatter.h): module
// version 6 stores the rule and its decoder makes the same trees with them.
#include "sandtable/converters/objects.h"

#include <algorithm>
#include <cmath>

#include "sandtable/formats/scatter.h"

namespace sandtable::convert {

void vary(const materials::Variation& v, std::uint64_t seed, std::uint64_t key, float& scale, std::uint16_t& heading) {
  module::vary(v.scaleMin, v.scaleMax, seed, key, scale, heading);
}

namespace {

/// The plan's scatter lines as the rules of the module at (x0, z0): the
/// rule's index is its place in plan.scatters (every tree's key and id).
module::Scattering scattering(const ObjectPlan& plan, double x0, double z0, const module::Level& l0) {
  module::Scattering s{x0, z0, l0.spacing * l0.squaresX, l0.spacing * l0.squaresZ, {}};
  for (std::size_t k = 0; k < plan.scatters.size(); ++k) {
    const ObjectPlan::Scatter& sc = plan.scatters[k];
    const auto& cyl = sc.icon < plan.cylinders.size() ? plan.cylinders[sc.icon] : std::array<float, 2>{0, 0};
    s.rules.push_back({sc.icon, sc.classId, std::uint16_t(k), sc.cell, sc.seed, sc.variation.scaleMin,
                       sc.variation.scaleMax, cyl[0], cyl[1]});
  }
  return s;
}

}  // namespace

void placeObjects(const ObjectPlan& plan, const std::vector<std::uint32_t>& points, double x0, double z0,
                  module::Module& m, ObjectTotals& totals) {
  if (m.levels.empty()) return;
  const module::Level& l0 = m.levels.front();
  std::vector<module::Object> objects;
  for (const std::uint32_t k : points) {
    const ObjectPlan::Point& p = plan.points[k];
    const auto& cyl = p.icon < plan.cylinders.size() ? plan.cylinders[p.icon] : std::array<float, 2>{0, 0};
    // An explicit object's id is its rank among the module's points.
    objects.push_back({p.icon, p.cls, float(p.x - x0), float(p.z - z0), p.heading, p.scale, cyl[0] * p.scale,
                       cyl[1] * p.scale, objects.size()});
  }
  m.scattering = scattering(plan, x0, z0, l0);
  if (!plan.scatters.empty()) {
    const module::Surface surface(l0, true);
    for (std::size_t r = 0; r < m.scattering.rules.size(); ++r) {
      if (module::cellRange(m.scattering.rules[r], m.scattering).count() > module::kMaxObjects) continue;
      const auto trees = module::scatter(m.scattering, r, surface, &totals.scatterRefused);
      objects.insert(objects.end(), trees.begin(), trees.end());
    }
  }
  // Only the rules that placed a tree here are the module's.
  std::erase_if(m.scattering.rules, [&](const module::ScatterRule& rule) {
    return std::none_of(objects.begin(), objects.end(), [&](const module::Object& o) {
      return module::isScattered(o.id) && module::idRule(o.id) == rule.index;
    });
  });
  module::sortObjects(objects);
  m.objects = std::move(objects);
  module::placeBases(m);
  totals.placed += m.objects.size();
  for (const module::Object& o : m.objects) ++totals.byClass[o.cls];
}

}  // namespace sandtable::convert
