// The re-mesher's only CGAL translation unit (remesh_cgal.h), built on its
// own with -frounding-math (runtime/CMakeLists.txt) as the converters'
// culture_cgal.cpp is: a refined square's rest-of-square triangulation and
// the clipping of decal triangles against the new ones.
//
// Exact predicates, inexact constructions (Epick): every input point is a
// fine post or a dyadic fraction of one (exact in double), the
// triangulation constructs nothing (its constraints meet only at their
// ends), and a clipped decal's corners only need to land on the target
// triangle's plane within rounding.
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/intersections.h>

#include <boost/variant/get.hpp>

#include "remesh_cgal.h"

namespace sandtable::edits::detail {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<std::uint32_t, K>;
using Fb = CGAL::Constrained_triangulation_face_base_2<K>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;

K::Point_2 point(const UV& p) { return {p.u, p.v}; }

}  // namespace

void constrainedTriangulation(std::span<const UV> points, std::span<const std::pair<std::uint32_t, std::uint32_t>> constraints,
                              std::vector<std::array<std::uint32_t, 3>>& faces) {
  faces.clear();
  Cdt cdt;
  std::vector<Cdt::Vertex_handle> handles(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    handles[k] = cdt.insert(point(points[k]));
    handles[k]->info() = std::uint32_t(k);
  }
  for (const auto& [a, b] : constraints) {
    if (handles[a] != handles[b]) cdt.insert_constraint(handles[a], handles[b]);
  }
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    faces.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
  }
}

void intersectTriangles(const std::array<UV, 3>& a, const std::array<UV, 3>& b, std::vector<UV>& out) {
  out.clear();
  const K::Triangle_2 ta(point(a[0]), point(a[1]), point(a[2]));
  const K::Triangle_2 tb(point(b[0]), point(b[1]), point(b[2]));
  if (ta.is_degenerate() || tb.is_degenerate()) return;
  const auto hit = CGAL::intersection(ta, tb);
  if (!hit) return;
  // A point or a segment shares no area; a triangle or a polygon does.
  if (const auto* t = boost::get<K::Triangle_2>(&*hit)) {
    for (int k = 0; k < 3; ++k) out.push_back({t->vertex(k).x(), t->vertex(k).y()});
  } else if (const auto* poly = boost::get<std::vector<K::Point_2>>(&*hit)) {
    for (const K::Point_2& p : *poly) out.push_back({p.x(), p.y()});
  }
}

}  // namespace sandtable::edits::detail
