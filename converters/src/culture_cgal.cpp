// The exact part of the culture pipeline, and the only file that includes
// CGAL (docs/CULTURE.md, "Exact partition"). Two jobs:
//  - unionRings: the union of oriented rings by nonzero winding (widened
//    roads: the outline of a polyline has winding = number of segment
//    rectangles and joins covering a point);
//  - buildCell: one module's planar partition. Every ring of every class is
//    inserted into one arrangement (Epeck: exact predicates and
//    constructions) whose edges carry per-class winding deltas; a walk over
//    the faces gives each face its winding per class, hence its skin label
//    (highest rank wins) and decal coverage. Per layer, the edges where the
//    label changes become constraints of a Delaunay triangulation, whose
//    faces are labelled from the constraint sides and merged greedily into
//    strictly convex pieces (Hertel-Mehlhorn).
#include <CGAL/Arr_curve_data_traits_2.h>
#include <CGAL/Arr_extended_dcel.h>
#include <CGAL/Arr_segment_traits_2.h>
#include <CGAL/Arrangement_2.h>
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <boost/container/small_vector.hpp>

#include <algorithm>
#include <deque>
#include <numeric>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

#include "culture_internal.h"

namespace sandtable::convert::culture {
namespace {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using Point = K::Point_2;

/// Winding deltas of one x-monotone curve, per class slot, for the curve
/// traversed from its lexicographically smaller end to the larger one.
struct Winding {
  boost::container::small_vector<std::pair<std::uint16_t, std::int32_t>, 2> v;
  bool operator==(const Winding& o) const { return v == o.v; }
};

/// Overlapping curves add their deltas.
struct MergeWinding {
  Winding operator()(const Winding& a, const Winding& b) const {
    Winding r = a;
    for (const auto& [slot, d] : b.v) {
      auto it = std::find_if(r.v.begin(), r.v.end(), [s = slot](const auto& e) { return e.first == s; });
      if (it == r.v.end()) r.v.push_back({slot, d});
      else it->second += d;
    }
    return r;
  }
};

using BaseTraits = CGAL::Arr_segment_traits_2<K>;
using Traits = CGAL::Arr_curve_data_traits_2<BaseTraits, Winding, MergeWinding>;
using Dcel = CGAL::Arr_face_extended_dcel<Traits, std::size_t>;
using Arrangement = CGAL::Arrangement_2<Traits, Dcel>;
using Halfedge = Arrangement::Halfedge_const_handle;
using Face = Arrangement::Face_const_handle;

constexpr std::uint16_t kOutside = 0xFFFE;  // label of the unbounded face (skin)

Point toPoint(Vec2 p) { return Point(p.x, p.z); }
/// Rounded from the exact value: the lazy kernel's own approximation of a
/// constructed point depends on which predicates happened to force it, so
/// rounding it would make the output vary from run to run. But when the
/// approximation is one double ([v, v]: every input point, and every
/// constructed one whose interval collapsed), the exact value is that
/// double, so the exact rounding is known without computing it. Forcing
/// the exact value (GMP rationals, a call_once per point) was 40 % of the
/// module partition's time (docs/CULTURE.md, "Profile").
///
/// pointInterval: sets v when the interval is one double, which is then
/// the exact value (0 as +0, as the exact 0 rounds).
bool pointInterval(const CGAL::Interval_nt<false>& a, double& v) {
  if (a.inf() != a.sup()) return false;
  v = a.inf() == 0 ? 0.0 : a.inf();
  return true;
}
Vec2 toVec(const Point& p) {
  const auto& a = CGAL::approx(p);
  double x = 0, z = 0;
  if (pointInterval(a.x(), x) && pointInterval(a.y(), z)) return {x, z};
  const auto& e = CGAL::exact(p);
  return {CGAL::to_double(e.x()), CGAL::to_double(e.y())};
}

/// Adds the edges of `ring` with delta +1 per traversal, for slot `slot`.
void addRing(const Ring& ring, std::uint16_t slot, std::vector<Traits::Curve_2>& curves) {
  const std::size_t n = ring.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Vec2 a = ring[k], b = ring[(k + 1) % n];
    if (a == b) continue;
    Winding w;
    w.v.push_back({slot, lexLess(a, b) ? 1 : -1});
    curves.emplace_back(BaseTraits::Curve_2(toPoint(a), toPoint(b)), w);
  }
}

/// Faces in walk order with their per-slot windings (row f * slots + s);
/// face->data() is the row. The unbounded face has winding 0.
struct FaceWindings {
  std::size_t slots = 0;
  std::vector<std::int32_t> w;
  std::vector<Face> faces;
  const std::int32_t* of(Face f) const { return w.data() + f->data() * slots; }
};

FaceWindings windFaces(Arrangement& arr, std::size_t slots) {
  FaceWindings fw;
  fw.slots = std::max<std::size_t>(slots, 1);
  const std::size_t none = std::numeric_limits<std::size_t>::max();
  for (auto f = arr.faces_begin(); f != arr.faces_end(); ++f) f->set_data(none);
  std::deque<Face> queue;
  auto visit = [&](Face f, const std::int32_t* from, Halfedge h) {
    // h has `from`'s face on its left; f lies on its right.
    fw.faces.push_back(f);
    const std::size_t row = fw.faces.size() - 1;
    arr.non_const_handle(f)->set_data(row);
    fw.w.resize(fw.w.size() + fw.slots);
    std::int32_t* to = fw.w.data() + row * fw.slots;
    if (from) {
      std::copy(from, from + fw.slots, to);
      const bool leftToRight = h->direction() == CGAL::ARR_LEFT_TO_RIGHT;
      for (const auto& [slot, d] : h->curve().data().v) to[slot] += leftToRight ? -d : d;
    }
    queue.push_back(f);
  };
  visit(arr.unbounded_face(), nullptr, Halfedge());
  while (!queue.empty()) {
    const Face f = queue.front();
    queue.pop_front();
    auto cross = [&](Arrangement::Ccb_halfedge_const_circulator first) {
      auto h = first;
      do {
        const Face g = h->twin()->face();
        if (g->data() == none) {
          // Copy: visit() may grow fw.w.
          std::vector<std::int32_t> from(fw.of(f), fw.of(f) + fw.slots);
          visit(g, from.data(), h);
        }
      } while (++h != first);
    };
    for (auto c = f->outer_ccbs_begin(); c != f->outer_ccbs_end(); ++c) cross(*c);
    for (auto c = f->inner_ccbs_begin(); c != f->inner_ccbs_end(); ++c) cross(*c);
  }
  return fw;
}

/// Drops vertices where the ring goes straight on (exactly collinear).
std::vector<Point> dropCollinear(std::vector<Point> pts) {
  bool changed = true;
  while (changed && pts.size() > 3) {
    changed = false;
    std::vector<Point> out;
    const std::size_t n = pts.size();
    for (std::size_t k = 0; k < n; ++k) {
      const Point& a = out.empty() ? pts[(k + n - 1) % n] : out.back();
      const Point& c = pts[(k + 1) % n];
      // Exact: b is dropped only when it lies strictly between its neighbours.
      if (CGAL::orientation(a, pts[k], c) == CGAL::COLLINEAR && CGAL::collinear_are_strictly_ordered_along_line(a, pts[k], c)) {
        changed = true;
        continue;
      }
      out.push_back(pts[k]);
    }
    pts = std::move(out);
  }
  return pts;
}

// ------------------------------------------------------------ triangulation

struct FaceInfo {
  std::uint16_t label = kNone;
  bool labelled = false;
  std::uint32_t poly = 0;
};
using Vb = CGAL::Triangulation_vertex_base_with_info_2<std::uint32_t, K>;
using Fb = CGAL::Triangulation_face_base_with_info_2<FaceInfo, K, CGAL::Constrained_triangulation_face_base_2<K>>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;

std::uint64_t edgeKey(std::uint32_t a, std::uint32_t b) { return (std::uint64_t(a) << 32) | b; }

/// A constraint of one layer: arrangement vertices u -> v (a chain of
/// collinear arrangement edges), with `left` the label on its left.
struct Constraint {
  const void* u = nullptr;
  const void* v = nullptr;
  Point pu, pv;
  std::uint16_t left = kNone, right = kNone;
};

/// Label-change edges of one layer, with chains of collinear edges through
/// vertices of degree 2 joined into one constraint.
std::vector<Constraint> layerConstraints(const Arrangement& arr, const std::vector<std::uint16_t>& faceLabel) {
  std::vector<Halfedge> edges;
  std::unordered_map<const void*, std::vector<std::size_t>> at;  // vertex -> incident edge ids
  for (auto e = arr.edges_begin(); e != arr.edges_end(); ++e) {
    const std::uint16_t l = faceLabel[e->face()->data()], r = faceLabel[e->twin()->face()->data()];
    if (l == r) continue;
    at[&*e->source()].push_back(edges.size());
    at[&*e->target()].push_back(edges.size());
    edges.push_back(e);
  }
  // A vertex of degree 2 whose two edges continue straight with the same
  // labels on each side is not a corner of this layer.
  auto through = [&](const void* vtx) {
    const auto& inc = at[vtx];
    if (inc.size() != 2) return false;
    const Halfedge a = edges[inc[0]], b = edges[inc[1]];
    const Point& pa = &*a->source() == vtx ? a->target()->point() : a->source()->point();
    const Point& pb = &*b->source() == vtx ? b->target()->point() : b->source()->point();
    const Point& pv = &*a->source() == vtx ? a->source()->point() : a->target()->point();
    return CGAL::orientation(pa, pv, pb) == CGAL::COLLINEAR;
  };
  std::vector<bool> used(edges.size(), false);
  std::vector<Constraint> out;
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (used[k]) continue;
    // Walk backwards to the chain's start (or around a closed chain).
    Halfedge h = edges[k];
    std::size_t id = k;
    for (std::size_t guard = 0; guard < edges.size() && through(&*h->source()); ++guard) {
      const auto& inc = at[&*h->source()];
      const std::size_t prev = inc[0] == id ? inc[1] : inc[0];
      Halfedge p = edges[prev];
      // Orient p so that it ends where h starts.
      if (&*p->target() != &*h->source()) p = p->twin();
      if (prev == k) break;
      h = p;
      id = prev;
    }
    // h (edge id) starts the chain; orient consistently and walk forward.
    Constraint c;
    c.u = &*h->source();
    c.pu = h->source()->point();
    c.left = faceLabel[h->face()->data()];
    c.right = faceLabel[h->twin()->face()->data()];
    for (std::size_t guard = 0; guard <= edges.size(); ++guard) {
      used[id] = true;
      const void* t = &*h->target();
      if (!through(t)) break;
      const auto& inc = at[t];
      const std::size_t next = inc[0] == id ? inc[1] : inc[0];
      if (used[next]) break;
      Halfedge n = edges[next];
      if (&*n->source() != t) n = n->twin();
      h = n;
      id = next;
    }
    c.v = &*h->target();
    c.pv = h->target()->point();
    if (c.u == c.v) {
      // A closed collinear chain cannot exist; keep the edge as is.
      c.v = &*h->source();
      c.pv = h->source()->point();
    }
    out.push_back(c);
  }
  // Canonical order (ends in lexicographic order, then by position), so
  // the triangulation and the pieces do not depend on the arrangement's
  // internal order, which follows memory addresses: the same input gives
  // the same bytes on every run.
  for (Constraint& c : out) {
    if (CGAL::compare_xy(c.pv, c.pu) == CGAL::SMALLER) std::swap(c.u, c.v), std::swap(c.pu, c.pv), std::swap(c.left, c.right);
  }
  std::sort(out.begin(), out.end(), [](const Constraint& a, const Constraint& b) {
    const auto c = CGAL::compare_xy(a.pu, b.pu);
    if (c != CGAL::EQUAL) return c == CGAL::SMALLER;
    return CGAL::compare_xy(a.pv, b.pv) == CGAL::SMALLER;
  });
  return out;
}

/// Triangulates one layer's constraints and merges same-label triangles
/// into strictly convex pieces.
std::vector<Piece> piecesOf(const std::vector<Constraint>& cons) {
  Cdt cdt;
  std::unordered_map<const void*, Cdt::Vertex_handle> vh;
  std::uint32_t nextId = 0;
  auto vertex = [&](const void* key, const Point& p) {
    auto it = vh.find(key);
    if (it != vh.end()) return it->second;
    Cdt::Vertex_handle v = cdt.insert(p);
    v->info() = nextId++;
    vh.emplace(key, v);
    return v;
  };
  std::unordered_map<std::uint64_t, std::uint16_t> leftOf;
  for (const Constraint& c : cons) {
    const auto a = vertex(c.u, c.pu), b = vertex(c.v, c.pv);
    if (a == b) continue;
    cdt.insert_constraint(a, b);
    leftOf[edgeKey(a->info(), b->info())] = c.left;
    leftOf[edgeKey(b->info(), a->info())] = c.right;
  }
  // Label faces from their constrained edges, then flood the rest.
  std::deque<Cdt::Face_handle> queue;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    for (int i = 0; i < 3 && !f->info().labelled; ++i) {
      if (!f->is_constrained(i)) continue;
      const auto it = leftOf.find(edgeKey(f->vertex(f->ccw(i))->info(), f->vertex(f->cw(i))->info()));
      if (it == leftOf.end()) continue;
      f->info().label = it->second;
      f->info().labelled = true;
      queue.push_back(f);
    }
  }
  while (!queue.empty()) {
    const auto f = queue.front();
    queue.pop_front();
    for (int i = 0; i < 3; ++i) {
      const auto g = f->neighbor(i);
      if (cdt.is_infinite(g) || g->info().labelled || f->is_constrained(i)) continue;
      g->info().label = f->info().label;
      g->info().labelled = true;
      queue.push_back(g);
    }
  }
  // Hertel-Mehlhorn: polygons start as triangles; a diagonal between two
  // polygons of one label is removed when both its ends stay strictly
  // convex.
  std::vector<std::vector<Cdt::Vertex_handle>> polys;
  std::vector<std::uint16_t> polyLabel;
  std::vector<std::uint32_t> parent;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    const std::uint16_t l = f->info().label;
    if (l == kNone || l == kOutside) continue;
    f->info().poly = std::uint32_t(polys.size());
    polys.push_back({f->vertex(0), f->vertex(1), f->vertex(2)});
    polyLabel.push_back(l);
    parent.push_back(std::uint32_t(parent.size()));
  }
  auto find = [&](std::uint32_t p) {
    while (parent[p] != p) p = parent[p] = parent[parent[p]];
    return p;
  };
  auto indexOf = [](const std::vector<Cdt::Vertex_handle>& poly, Cdt::Vertex_handle v, Cdt::Vertex_handle next) {
    const std::size_t n = poly.size();
    for (std::size_t k = 0; k < n; ++k) {
      if (poly[k] == v && poly[(k + 1) % n] == next) return k;
    }
    return n;
  };
  // Diagonals in a canonical order (by the vertices' insertion ids), not
  // the triangulation's storage order, which varies from run to run.
  struct Diagonal {
    std::uint32_t lo, hi;
    Cdt::Face_handle f;
    int i;
  };
  std::vector<Diagonal> diagonals;
  for (auto e = cdt.finite_edges_begin(); e != cdt.finite_edges_end(); ++e) {
    const auto f = e->first;
    const int i = e->second;
    const auto g = f->neighbor(i);
    if (cdt.is_infinite(g) || f->is_constrained(i)) continue;
    const std::uint16_t l = f->info().label;
    if (l == kNone || l == kOutside || g->info().label != l) continue;
    const std::uint32_t x = f->vertex(f->ccw(i))->info(), y = f->vertex(f->cw(i))->info();
    diagonals.push_back({std::min(x, y), std::max(x, y), f, i});
  }
  std::sort(diagonals.begin(), diagonals.end(),
            [](const Diagonal& a, const Diagonal& b) { return a.lo != b.lo ? a.lo < b.lo : a.hi < b.hi; });
  for (const Diagonal& d : diagonals) {
    const auto f = d.f;
    const int i = d.i;
    const auto g = f->neighbor(i);
    const std::uint32_t P = find(f->info().poly), Q = find(g->info().poly);
    if (P == Q) continue;
    const auto a = f->vertex(f->ccw(i)), b = f->vertex(f->cw(i));  // a -> b in P, b -> a in Q
    auto& pp = polys[P];
    auto& qq = polys[Q];
    const std::size_t ia = indexOf(pp, a, b), ib = indexOf(qq, b, a);
    if (ia == pp.size() || ib == qq.size()) continue;
    const std::size_t np = pp.size(), nq = qq.size();
    const auto& pPrev = pp[(ia + np - 1) % np];  // before a in P
    const auto& pNext = pp[(ia + 2) % np];       // after b in P
    const auto& qPrev = qq[(ib + nq - 1) % nq];  // before b in Q
    const auto& qNext = qq[(ib + 2) % nq];       // after a in Q
    if (CGAL::orientation(pPrev->point(), a->point(), qNext->point()) != CGAL::LEFT_TURN) continue;
    if (CGAL::orientation(qPrev->point(), b->point(), pNext->point()) != CGAL::LEFT_TURN) continue;
    std::vector<Cdt::Vertex_handle> merged;
    merged.reserve(np + nq - 2);
    for (std::size_t k = 0; k < np; ++k) merged.push_back(pp[(ia + 1 + k) % np]);  // b ... a
    for (std::size_t k = 2; k < nq; ++k) merged.push_back(qq[(ib + k) % nq]);      // after a ... before b
    pp = std::move(merged);
    qq.clear();
    parent[Q] = P;
  }
  // Each piece starts at its first-inserted vertex; pieces in a canonical
  // order too.
  for (auto& poly : polys) {
    if (poly.empty()) continue;
    std::rotate(poly.begin(), std::min_element(poly.begin(), poly.end(), [](const auto& x, const auto& y) {
                  return x->info() < y->info();
                }), poly.end());
  }
  std::vector<std::size_t> order;
  for (std::size_t p = 0; p < polys.size(); ++p) {
    if (!polys[p].empty() && parent[p] == p) order.push_back(p);
  }
  std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    const auto& px = polys[x];
    const auto& py = polys[y];
    for (std::size_t k = 0; k < std::min(px.size(), py.size()); ++k) {
      if (px[k]->info() != py[k]->info()) return px[k]->info() < py[k]->info();
    }
    return px.size() < py.size();
  });
  std::vector<Piece> out;
  for (std::size_t p : order) {
    Piece piece;
    piece.label = polyLabel[p];
    for (const auto& v : polys[p]) {
      piece.pts.push_back(toVec(v->point()));
      piece.box.add(piece.pts.back());
    }
    out.push_back(std::move(piece));
  }
  return out;
}

}  // namespace

std::vector<Ring> unionRings(const std::vector<Ring>& rings) {
  std::vector<Traits::Curve_2> curves;
  for (const Ring& r : rings) addRing(r, 0, curves);
  Arrangement arr;
  CGAL::insert(arr, curves.begin(), curves.end());
  const FaceWindings fw = windFaces(arr, 1);
  auto covered = [&](Face f) { return !f->is_unbounded() && fw.of(f)[0] != 0; };
  auto boundary = [&](Halfedge h) { return covered(h->face()) && !covered(h->twin()->face()); };
  std::unordered_set<const void*> used;
  std::vector<Ring> out;
  for (auto h = arr.halfedges_begin(); h != arr.halfedges_end(); ++h) {
    if (!boundary(h) || used.count(&*h)) continue;
    std::vector<Point> pts;
    Halfedge cur = h;
    for (std::size_t guard = 0; guard < 4 * arr.number_of_halfedges() + 4; ++guard) {
      used.insert(&*cur);
      pts.push_back(cur->source()->point());
      Halfedge e = cur->next();
      for (std::size_t spin = 0; !boundary(e) && spin < arr.number_of_halfedges(); ++spin) e = e->twin()->next();
      if (!boundary(e)) throw std::runtime_error("culture: union boundary is not closed");
      cur = e;
      if (cur == Halfedge(h)) break;
    }
    pts = dropCollinear(std::move(pts));
    if (pts.size() < 3) continue;
    Ring r;
    r.reserve(pts.size());
    for (const Point& p : pts) r.push_back(toVec(p));
    out.push_back(std::move(r));
  }
  return out;
}

std::vector<LayerGeometry> buildCell(const CellInput& in, CellTimes* times) {
  const double t0 = threadCpuSeconds();
  std::vector<Traits::Curve_2> curves;
  for (const CellRing& r : in.rings) addRing(r.pts, r.slot, curves);
  const Ring rect = {{in.rect.x0, in.rect.z0}, {in.rect.x1, in.rect.z0}, {in.rect.x1, in.rect.z1}, {in.rect.x0, in.rect.z1}};
  for (std::size_t k = 0; k < 4; ++k) {
    curves.emplace_back(BaseTraits::Curve_2(toPoint(rect[k]), toPoint(rect[(k + 1) % 4])), Winding{});
  }
  Arrangement arr;
  CGAL::insert(arr, curves.begin(), curves.end());
  const FaceWindings fw = windFaces(arr, in.slots.size());
  const std::size_t nf = fw.faces.size();
  const double t1 = threadCpuSeconds();

  std::vector<LayerGeometry> layers;
  // The skin: the highest-rank area class with winding != 0, else default.
  {
    std::vector<std::uint16_t> label(nf, kOutside);
    for (std::size_t f = 0; f < nf; ++f) {
      if (fw.faces[f]->is_unbounded()) continue;
      const std::int32_t* w = fw.w.data() + f * fw.slots;
      int best = -1;
      for (std::size_t s = 0; s < in.slots.size(); ++s) {
        if (!in.slots[s].skin || w[s] == 0) continue;
        const auto& c = in.slots[s];
        if (best < 0 || c.rank > in.slots[std::size_t(best)].rank ||
            (c.rank == in.slots[std::size_t(best)].rank && c.classId > in.slots[std::size_t(best)].classId)) {
          best = int(s);
        }
      }
      label[f] = best < 0 ? in.defaultClass : in.slots[std::size_t(best)].classId;
    }
    LayerGeometry g;
    g.skin = true;
    const auto cons = layerConstraints(arr, label);
    bool inner = false;
    for (const Constraint& c : cons) inner |= c.left != kOutside && c.right != kOutside;
    if (!inner) {
      g.uniform = cons.empty() ? in.defaultClass : (cons.front().left == kOutside ? cons.front().right : cons.front().left);
      g.pieces.push_back({g.uniform, boxOf(rect), rect});
    } else {
      g.pieces = piecesOf(cons);
      for (const Constraint& c : cons) {
        if (c.left != kOutside && c.right != kOutside) g.bounds.push_back({toVec(c.pu), toVec(c.pv)});
      }
    }
    layers.push_back(std::move(g));
  }
  // One decal layer per line class: covered where its winding != 0.
  for (std::size_t s = 0; s < in.slots.size(); ++s) {
    if (in.slots[s].skin) continue;
    std::vector<std::uint16_t> label(nf, kNone);
    for (std::size_t f = 0; f < nf; ++f) {
      if (!fw.faces[f]->is_unbounded() && fw.w[f * fw.slots + s] != 0) label[f] = in.slots[s].classId;
    }
    LayerGeometry g;
    g.skin = false;
    g.classId = in.slots[s].classId;
    const auto cons = layerConstraints(arr, label);
    const bool onRect = [&] {
      auto onEdge = [&](const Point& p) {
        return p.x() == in.rect.x0 || p.x() == in.rect.x1 || p.y() == in.rect.z0 || p.y() == in.rect.z1;
      };
      for (const Constraint& c : cons) {
        const bool sameSide = (c.pu.x() == c.pv.x() && (c.pu.x() == in.rect.x0 || c.pu.x() == in.rect.x1)) ||
                              (c.pu.y() == c.pv.y() && (c.pu.y() == in.rect.z0 || c.pu.y() == in.rect.z1));
        if (!sameSide || !onEdge(c.pu)) return false;
      }
      return true;
    }();
    if (cons.empty()) {
      g.uniform = kNone;
    } else if (onRect) {
      g.uniform = g.classId;  // covers the whole module
      g.pieces.push_back({g.classId, boxOf(rect), rect});
    } else {
      g.pieces = piecesOf(cons);
      for (const Constraint& c : cons) {
        const bool sameSide = (c.pu.x() == c.pv.x() && (c.pu.x() == in.rect.x0 || c.pu.x() == in.rect.x1)) ||
                              (c.pu.y() == c.pv.y() && (c.pu.y() == in.rect.z0 || c.pu.y() == in.rect.z1));
        if (!sameSide) g.bounds.push_back({toVec(c.pu), toVec(c.pv)});
      }
    }
    layers.push_back(std::move(g));
  }
  if (times) times->arrangement = t1 - t0, times->pieces = threadCpuSeconds() - t1;
  return layers;
}

// ------------------------------------------------------------ roofs

namespace {

struct RoofInfo {
  int nesting = -1;  ///< constraints crossed from outside; odd is inside the footprint
};
using RoofFb = CGAL::Triangulation_face_base_with_info_2<RoofInfo, K, CGAL::Constrained_triangulation_face_base_2<K>>;
using RoofTds = CGAL::Triangulation_data_structure_2<CGAL::Triangulation_vertex_base_2<K>, RoofFb>;
// Exact intersections: a repaired footprint may still touch itself at a point.
using RoofCdt = CGAL::Constrained_Delaunay_triangulation_2<K, RoofTds, CGAL::Exact_intersections_tag>;

/// Nesting levels by flood fill from the infinite face: crossing a
/// constrained edge goes one level in.
void markNesting(RoofCdt& cdt) {
  std::deque<std::pair<RoofCdt::Face_handle, int>> todo{{cdt.infinite_face(), 0}};
  while (!todo.empty()) {
    auto [start, level] = todo.front();
    todo.pop_front();
    if (start->info().nesting != -1) continue;
    std::deque<RoofCdt::Face_handle> same{start};
    start->info().nesting = level;
    while (!same.empty()) {
      const RoofCdt::Face_handle f = same.front();
      same.pop_front();
      for (int i = 0; i < 3; ++i) {
        const RoofCdt::Face_handle n = f->neighbor(i);
        if (n->info().nesting != -1) continue;
        if (cdt.is_constrained({f, i})) {
          todo.emplace_back(n, level + 1);
        } else {
          n->info().nesting = level;
          same.push_back(n);
        }
      }
    }
  }
}

}  // namespace

std::vector<std::array<Vec2, 3>> roofTriangles(const std::vector<Ring>& rings) {
  RoofCdt cdt;
  for (const Ring& r : rings) {
    for (std::size_t k = 0; k < r.size(); ++k) {
      const Vec2 a = r[k], b = r[(k + 1) % r.size()];
      if (!(a == b)) cdt.insert_constraint(Point(a.x, a.z), Point(b.x, b.z));
    }
  }
  markNesting(cdt);
  std::vector<std::array<Vec2, 3>> out;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (f->info().nesting % 2 != 1) continue;
    std::array<Vec2, 3> t;
    for (int i = 0; i < 3; ++i) t[std::size_t(i)] = toVec(f->vertex(i)->point());
    out.push_back(t);
  }
  return out;
}

}  // namespace sandtable::convert::culture
