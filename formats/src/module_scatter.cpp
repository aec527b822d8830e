// The scatter rule and object bases (scatter.h): moved from the
// converter's placement so that version 6 decodes the very trees the
// converter placed. Compiled without fused multiply-add (CMakeLists.txt):
// a tree's position and scale must come out the same on every build.
#include "sandtable/formats/scatter.h"

#include <algorithm>
#include <cmath>
#include <span>
#include <tuple>

#include "sandtable/base/hash.h"
#include "sandtable/formats/terrain_rule.h"
#include "module_v2_internal.h"

namespace sandtable::module {

namespace {

using hash::mix;
using hash::unit;

std::uint64_t cellKey(std::int64_t i, std::int64_t j) {
  return mix(std::uint64_t(i) * 0x100000001b3ull ^ mix(std::uint64_t(j)));
}

bool skinGroup(const Group& g) { return g.priority == kPrioritySkin && g.half != Half::skirt; }
bool decalGroup(const Group& g) {
  return g.priority > kPrioritySkin && g.priority < kPriorityObject && g.half != Half::skirt;
}

/// The group indices of each square of a level that pass `keep`, in group order.
Surface::Buckets groupsBySquare(const Level& l, bool (*keep)(const Group&)) {
  const std::size_t squares = std::size_t(l.squaresX) * l.squaresZ;
  Surface::Buckets b;
  b.start.assign(squares + 1, 0);
  for (const Group& g : l.groups) {
    if (keep(g) && g.square < squares) ++b.start[g.square + 1];
  }
  for (std::size_t s = 0; s < squares; ++s) b.start[s + 1] += b.start[s];
  b.groups.resize(b.start[squares]);
  std::vector<std::uint32_t> fill(b.start.begin(), b.start.end() - 1);
  for (std::size_t g = 0; g < l.groups.size(); ++g) {
    if (keep(l.groups[g]) && l.groups[g].square < squares) b.groups[fill[l.groups[g].square]++] = std::uint32_t(g);
  }
  return b;
}

using Hit = Surface::Hit;

void search(const Level& l, std::span<const std::uint32_t> groups, double x, double z, Hit& best) {
  for (const std::uint32_t gi : groups) {
    const Group& g = l.groups[gi];
    for (std::uint32_t k = g.firstIndex; k + 3 <= g.firstIndex + g.indexCount; k += 3) {
      const Vertex& a = l.vertices[l.indices[k]];
      const Vertex& b = l.vertices[l.indices[k + 1]];
      const Vertex& c = l.vertices[l.indices[k + 2]];
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

std::span<const std::uint32_t> square(const Surface::Buckets& b, std::size_t s) {
  return {b.groups.data() + b.start[s], b.start[s + 1] - b.start[s]};
}

std::uint32_t squareOf(double c, double spacing, std::uint32_t n) {
  return std::uint32_t(std::clamp(std::floor(c / spacing), 0.0, double(n - 1)));
}

/// The best hit among the square holding (x, z) and, when the point is on
/// its edge or outside it, its neighbours.
Hit locate(const Level& l, const Surface::Buckets& bySquare, double x, double z) {
  Hit best;
  if (l.squaresX == 0 || l.squaresZ == 0 || !(l.spacing > 0) || bySquare.groups.empty()) return best;
  const std::uint32_t sx = squareOf(x, l.spacing, l.squaresX), sz = squareOf(z, l.spacing, l.squaresZ);
  search(l, square(bySquare, std::size_t(sz) * l.squaresX + sx), x, z, best);
  constexpr double kEdge = 1e-7;
  if (best.inside >= kEdge) return best;
  for (std::uint32_t j = sz > 0 ? sz - 1 : 0; j <= std::min(sz + 1, l.squaresZ - 1); ++j) {
    for (std::uint32_t i = sx > 0 ? sx - 1 : 0; i <= std::min(sx + 1, l.squaresX - 1); ++i) {
      if (i != sx || j != sz) search(l, square(bySquare, std::size_t(j) * l.squaresX + i), x, z, best);
    }
  }
  return best;
}

/// Surface::nearMaterials_ (scatter.h): the 3 x 3 neighbourhood that
/// locate() searches, as a material bit set per square.
std::vector<std::uint64_t> nearMaterials(const Level& l, const Surface::Buckets& skin) {
  const std::size_t nx = l.squaresX, nz = l.squaresZ;
  std::vector<std::uint64_t> own(nx * nz, 0), out(nx * nz, 0);
  for (std::size_t s = 0; s < own.size(); ++s) {
    for (const std::uint32_t g : square(skin, s)) own[s] |= 1ull << (l.groups[g].material % 64);
  }
  for (std::size_t j = 0; j < nz; ++j) {
    for (std::size_t i = 0; i < nx; ++i) {
      std::uint64_t m = 0;
      for (std::size_t jj = j > 0 ? j - 1 : 0; jj <= std::min(j + 1, nz - 1); ++jj) {
        for (std::size_t ii = i > 0 ? i - 1 : 0; ii <= std::min(i + 1, nx - 1); ++ii) m |= own[jj * nx + ii];
      }
      out[j * nx + i] = m;
    }
  }
  return out;
}

constexpr double kOnTriangle = -1e-6;  ///< barycentric slack for points on an edge

/// Whether vertices 0 .. P-1 of `l` are its lattice posts, row by row: the
/// test the encoder makes before it flags a level's lattice (docs/FORMAT.md
/// §9), on x and z alone, which every version decodes bit for bit. Fills the
/// posts' column x and row z.
bool latticePosts(const Level& l, std::vector<double>& xs, std::vector<double>& zs) {
  const std::uint32_t nx = l.squaresX, nz = l.squaresZ;
  const std::size_t w = std::size_t(nx) + 1;
  if (nx == 0 || nz == 0 || !(l.spacing > 0) || w * (std::size_t(nz) + 1) > l.vertices.size()) return false;
  const auto& v = l.vertices;
  const double lastX = v[nx].x, lastZ = v[std::size_t(nz) * w].z;
  xs.resize(w);
  zs.resize(std::size_t(nz) + 1);
  for (std::uint32_t a = 0; a <= nx; ++a) xs[a] = detail::latticeCoord(a, nx, l.spacing, lastX);
  for (std::uint32_t b = 0; b <= nz; ++b) zs[b] = detail::latticeCoord(b, nz, l.spacing, lastZ);
  for (std::uint32_t b = 0; b <= nz; ++b) {
    const float z = float(zs[b]);
    for (std::uint32_t a = 0; a <= nx; ++a) {
      const Vertex& q = v[b * w + a];
      if (q.x != float(xs[a]) || q.z != z) return false;
    }
  }
  return xs[nx] > xs[nx - 1] && zs[nz] > zs[nz - 1];
}

/// Every object's base on the plane of the lattice triangle under it
/// (terrain::planeHeight, the rule the grid, the sampler and validate use):
/// one lookup per object instead of a search of the square's skin triangles,
/// which are pieces of that same plane (culture is cut into the lattice
/// triangles, its vertices' heights the plane's to the height step). The
/// difference from the skin's interpolation is float rounding; validate
/// holds bases to the grid's lattice plane within 1 cm. False when the
/// level has no lattice posts (the caller searches the skin then).
bool latticeBases(Level& l, const std::vector<Object>& objects) {
  thread_local std::vector<double> xs, zs;  // a loader decodes without allocating once warm
  if (!latticePosts(l, xs, zs)) return false;
  const std::uint32_t nx = l.squaresX, nz = l.squaresZ;
  const std::size_t w = std::size_t(nx) + 1;
  // Fractions by multiplying: every square but the last of a row or
  // column is `spacing` wide; the last may be narrower (an edge module).
  const double inv = 1.0 / l.spacing;
  const double lastX = 1.0 / (xs[nx] - xs[nx - 1]), lastZ = 1.0 / (zs[nz] - zs[nz - 1]);
  for (std::size_t k = 0; k < objects.size(); ++k) {
    const double x = std::clamp(double(objects[k].x), 0.0, xs[nx]);
    const double z = std::clamp(double(objects[k].z), 0.0, zs[nz]);
    const auto i = std::uint32_t(std::min(x * inv, double(nx - 1)));
    const auto j = std::uint32_t(std::min(z * inv, double(nz - 1)));
    const double fx = (x - xs[i]) * (i + 1 == nx ? lastX : inv);
    const double fz = (z - zs[j]) * (j + 1 == nz ? lastZ : inv);
    const Vertex* nw = &l.vertices[j * w + i];
    const Vertex* sw = nw + w;
    l.objectY[k] = float(terrain::planeHeight(fx, fz, nw[0].y, nw[1].y, sw[0].y, sw[1].y));
  }
  return true;
}

}  // namespace

CellRange cellRange(const ScatterRule& rule, const Scattering& s) {
  CellRange r;
  if (!(std::isfinite(rule.cell) && rule.cell > 0) || !std::isfinite(s.x0) || !std::isfinite(s.z0) ||
      !(std::isfinite(s.width) && s.width > 0) || !(std::isfinite(s.depth) && s.depth > 0)) {
    return r;
  }
  const double lo[2] = {std::floor(s.x0 / rule.cell), std::floor(s.z0 / rule.cell)};
  const double hi[2] = {std::floor((s.x0 + s.width) / rule.cell), std::floor((s.z0 + s.depth) / rule.cell)};
  for (int a = 0; a < 2; ++a) {
    // Compared as doubles before any conversion: an id holds 24-bit cells.
    if (!(lo[a] >= double(-kMaxCellIndex - 1) && hi[a] <= double(kMaxCellIndex))) return r;
  }
  return {std::int64_t(lo[0]), std::int64_t(hi[0]), std::int64_t(lo[1]), std::int64_t(hi[1])};
}

void vary(double scaleMin, double scaleMax, std::uint64_t seed, std::uint64_t key, float& scale,
          std::uint16_t& heading) {
  const std::uint64_t h = mix(seed ^ mix(key));
  scale = float(scaleMin + (scaleMax - scaleMin) * unit(h));
  heading = std::uint16_t(mix(h) & 0xffff);
}

Candidate candidate(const ScatterRule& rule, const Scattering& s, std::int64_t i, std::int64_t j) {
  // One candidate per cell, jittered: the density is exact on average and
  // the candidates do not depend on where modules are cut.
  const std::uint64_t key = cellKey(i, j) ^ mix(rule.seed + rule.index);
  const double X = (double(i) + unit(mix(key))) * rule.cell, Z = (double(j) + unit(mix(key + 1))) * rule.cell;
  Candidate c;
  c.x = X - s.x0;
  c.z = Z - s.z0;
  c.inside = c.x >= 0 && c.x < s.width && c.z >= 0 && c.z < s.depth;
  Object& o = c.object;
  o.icon = rule.icon;
  o.cls = rule.classId;
  o.x = float(c.x);
  o.z = float(c.z);
  vary(rule.scaleMin, rule.scaleMax, rule.seed, key, o.scale, o.heading);
  o.radius = rule.radius * o.scale;
  o.height = rule.height * o.scale;
  o.id = scatteredId(rule.index, i, j);
  return c;
}

Surface::Surface(const Level& level, bool cover) : level_(&level), skin_(groupsBySquare(level, skinGroup)) {
  if (!cover) return;
  decals_ = groupsBySquare(level, decalGroup);
  nearMaterials_ = nearMaterials(level, skin_);
  // A building's groups (priority 99: walls and roof) sit in the square of
  // its centre, not in every square it covers, so they are found by box.
  for (std::uint32_t g = 0; g < level.groups.size(); ++g) {
    const Group& gr = level.groups[g];
    if (gr.priority != kPriorityObject || gr.half == Half::skirt) continue;
    Box b{std::numeric_limits<float>::max(), std::numeric_limits<float>::max(), std::numeric_limits<float>::lowest(),
          std::numeric_limits<float>::lowest(), g};
    for (std::uint32_t k = gr.firstIndex; k < gr.firstIndex + gr.indexCount && k < level.indices.size(); ++k) {
      const Vertex& v = level.vertices[level.indices[k]];
      b.x0 = std::min(b.x0, v.x), b.x1 = std::max(b.x1, v.x);
      b.z0 = std::min(b.z0, v.z), b.z1 = std::max(b.z1, v.z);
    }
    buildings_.push_back(b);
  }
}

Surface::Hit Surface::skin(double x, double z) const { return locate(*level_, skin_, x, z); }

bool Surface::accepts(std::uint16_t cls, double x, double z) const {
  const Level& l = *level_;
  if (l.squaresX == 0 || l.squaresZ == 0 || !(l.spacing > 0)) return false;
  const std::size_t at = std::size_t(squareOf(z, l.spacing, l.squaresZ)) * l.squaresX + squareOf(x, l.spacing, l.squaresX);
  if (at < nearMaterials_.size() && !(nearMaterials_[at] >> (cls % 64) & 1)) return false;
  const Hit s = skin(x, z);
  if (s.inside < kOnTriangle || s.material != cls) return false;
  if (locate(*level_, decals_, x, z).inside >= kOnTriangle) return false;
  // Under a building's roof (walls are edge-on from above).
  for (const Box& b : buildings_) {
    if (x < b.x0 || x > b.x1 || z < b.z0 || z > b.z1) continue;
    Hit hit;
    search(*level_, std::span<const std::uint32_t>(&b.group, 1), x, z, hit);
    if (hit.inside >= kOnTriangle) return false;
  }
  return true;
}

float Surface::base(double x, double z) const {
  const Hit hit = skin(x, z);
  return std::isfinite(hit.y) ? hit.y : 0.0f;
}

std::vector<Object> scatter(const Scattering& s, std::size_t r, const Surface& surface, std::uint64_t* refused) {
  std::vector<Object> out;
  const ScatterRule& rule = s.rules[r];
  const CellRange range = cellRange(rule, s);
  for (std::int64_t j = range.j0; j <= range.j1; ++j) {
    for (std::int64_t i = range.i0; i <= range.i1; ++i) {
      const Candidate c = candidate(rule, s, i, j);
      if (!c.inside) continue;  // another module's
      if (surface.accepts(rule.classId, c.x, c.z)) out.push_back(c.object);
      else if (refused) ++*refused;
    }
  }
  return out;
}

void sortObjects(std::vector<Object>& objects) {
  const auto less = [](const Object& a, const Object& b) {
    return std::tie(a.icon, a.z, a.x, a.id) < std::tie(b.icon, b.z, b.x, b.id);
  };
  // A decoded rule's trees come in cell order, row by row, so they are
  // sorted by z but for the jitter within a row: an insertion sort moves
  // each only a few places. Any sort gives the same order (ids make it
  // total); past a budget of moves (explicit objects in any order, a
  // hostile module) the rest goes to std::sort.
  const std::size_t budget = 8 * objects.size() + 64;
  std::size_t moves = 0;
  for (std::size_t i = 1; i < objects.size(); ++i) {
    if (!less(objects[i], objects[i - 1])) continue;
    const Object t = objects[i];
    std::size_t j = i;
    do {
      objects[j] = objects[j - 1];
      --j;
      ++moves;
    } while (j > 0 && less(t, objects[j - 1]));
    objects[j] = t;
    if (moves > budget) {
      std::sort(objects.begin(), objects.end(), less);
      return;
    }
  }
}

void placeBases(Module& m) {
  for (Level& l : m.levels) {
    l.objectY.resize(m.objects.size());
    if (m.objects.empty()) continue;
    if (latticeBases(l, m.objects)) continue;
    const Surface surface(l, false);
    for (std::size_t k = 0; k < m.objects.size(); ++k) l.objectY[k] = surface.base(m.objects[k].x, m.objects[k].z);
  }
}

}  // namespace sandtable::module
