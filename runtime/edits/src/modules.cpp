// EditedModules: the base modules with every touched module rebuilt and
// published as a newer generation (modules.h; docs/DYNAMIC.md,
// "Re-meshing").
#include "sandtable/edits/modules.h"

#include <time.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>
#include <set>
#include <string>

#include "remesh_internal.h"
#include "sandtable/formats/scatter.h"

namespace sandtable::edits {

namespace {

double threadSeconds() {
  timespec ts{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

grid::PostRect unite(const grid::PostRect& a, const grid::PostRect& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return {std::min(a.i0, b.i0), std::min(a.j0, b.j0), std::max(a.i1, b.i1), std::max(a.j1, b.j1)};
}

Problem problem(const std::string& message) { return Problem{"", 0, "edits: " + message}; }

}  // namespace

struct EditedModules::Published {
  module::Module module;
  std::uint64_t generation = 0;
};

struct EditedModules::State {
  /// As built (decoded once); its objects are the base's.
  std::unique_ptr<const module::Module> base;
  /// The objects now, object edits applied (sorted as Module::objects).
  std::vector<module::Object> objects;
  /// Posts changed under this module since the base (normals recomputed there).
  grid::PostRect dirty;
  /// The last rebuilt geometry (null: the base's).
  std::shared_ptr<const Published> rebuilt;
};

EditedModules::EditedModules(std::shared_ptr<const paging::ModuleSource> base,
                             std::shared_ptr<const grid::HeightField> groundBefore,
                             std::shared_ptr<const grid::HeightField> heights, RemeshOptions options)
    : base_(std::move(base)), before_(std::move(groundBefore)), heights_(std::move(heights)), options_(std::move(options)) {
  assert(before_->postsX() == heights_->postsX() && before_->postsZ() == heights_->postsZ() &&
         before_->spacing() == heights_->spacing());
  const pack::IndexHeader& h = base_->header();
  generations_ = std::make_unique<std::atomic<std::uint64_t>[]>(std::size_t(h.modulesX) * h.modulesZ);
}

EditedModules::~EditedModules() = default;

std::vector<paging::ModuleKey> EditedModules::touched(
    const grid::PostRect& posts, std::span<const std::pair<std::uint32_t, std::uint32_t>> refined) const {
  const pack::IndexHeader& h = header();
  const std::uint32_t sq = h.moduleSquares;
  std::set<std::pair<std::uint32_t, std::uint32_t>> keys;  // (kz, kx): row-major order
  if (!posts.empty() && sq > 0) {
    // Module k's window is posts k * sq .. k * sq + sq (the last clamped
    // to the grid): it holds post p when k * sq <= p <= k * sq + sq.
    auto range = [&](std::uint32_t p0, std::uint32_t p1, std::uint32_t modules, std::uint32_t& k0, std::uint32_t& k1) {
      k0 = p0 >= sq ? (p0 + sq - 1) / sq - 1 : 0;
      k1 = std::min((p1 - 1) / sq, modules - 1);
    };
    std::uint32_t x0 = 0, x1 = 0, z0 = 0, z1 = 0;
    range(posts.i0, posts.i1, h.modulesX, x0, x1);
    range(posts.j0, posts.j1, h.modulesZ, z0, z1);
    for (std::uint32_t kz = z0; kz <= z1; ++kz) {
      for (std::uint32_t kx = x0; kx <= x1; ++kx) keys.insert({kz, kx});
    }
  }
  if (sq > 0) {
    // A refined square's fine edge decides its four neighbours' edges too.
    for (const auto& [i, j] : refined) {
      const std::int64_t around[5][2] = {{0, 0}, {-1, 0}, {1, 0}, {0, -1}, {0, 1}};
      for (const auto& d : around) {
        const std::int64_t a = std::int64_t(i) + d[0], b = std::int64_t(j) + d[1];
        if (a < 0 || b < 0 || a + 1 >= std::int64_t(heights_->postsX()) || b + 1 >= std::int64_t(heights_->postsZ())) continue;
        keys.insert({std::min(std::uint32_t(b) / sq, h.modulesZ - 1), std::min(std::uint32_t(a) / sq, h.modulesX - 1)});
      }
    }
  }
  std::vector<paging::ModuleKey> out;
  for (const auto& [kz, kx] : keys) out.push_back({kx, kz});
  return out;
}

Result<EditedModules::State*> EditedModules::state(std::uint32_t kx, std::uint32_t kz) {
  auto& slot = states_[index(kx, kz)];
  if (!slot) {
    auto m = std::make_unique<module::Module>();
    const Result<std::uint64_t> r = base_->read(kx, kz, *m);
    if (!r) return r.problems();
    auto st = std::make_unique<State>();
    st->objects = m->objects;
    st->base = std::move(m);
    slot = std::move(st);
  }
  return slot.get();
}

void EditedModules::publish(std::uint32_t kx, std::uint32_t kz, std::shared_ptr<const Published> p) {
  const std::size_t k = index(kx, kz);
  const std::lock_guard lock(mu_);
  published_[k] = p;
  // The generation before the log entry: a pager that takes the entry
  // must find the newer generation when it asks.
  generations_[k].store(p->generation, std::memory_order_release);
  log_.push_back({kx, kz});
}

void EditedModules::commit() {
  const std::lock_guard lock(mu_);
  changes_.store(log_.size(), std::memory_order_release);
}

Result<RemeshReport> EditedModules::remesh(const grid::PostRect& changedPosts,
                                           std::span<const std::pair<std::uint32_t, std::uint32_t>> changedRefinedSquares) {
  const Change one{changedPosts, {changedRefinedSquares.begin(), changedRefinedSquares.end()}};
  return remesh(std::span<const Change>(&one, 1));
}

Result<RemeshReport> EditedModules::remesh(std::span<const Change> changes) {
  const double t0 = threadSeconds();
  RemeshReport report;
  // Each touched module with the posts whose normals its changes moved:
  // the changed posts and the triangles beside them, and every changed
  // refined square's corners.
  std::map<std::pair<std::uint32_t, std::uint32_t>, grid::PostRect> dirtyOf;  // (kz, kx): row-major
  for (const Change& c : changes) {
    grid::PostRect dirty = c.posts;
    if (!dirty.empty()) {
      dirty.i0 = dirty.i0 > 0 ? dirty.i0 - 1 : 0;
      dirty.j0 = dirty.j0 > 0 ? dirty.j0 - 1 : 0;
      dirty.i1 = std::min(dirty.i1 + 1, heights_->postsX());
      dirty.j1 = std::min(dirty.j1 + 1, heights_->postsZ());
    }
    for (const auto& [i, j] : c.squares) dirty = unite(dirty, {i, j, i + 2, j + 2});
    for (const paging::ModuleKey& k : touched(c.posts, c.squares)) {
      grid::PostRect& d = dirtyOf[{k.kz, k.kx}];
      d = unite(d, dirty);
    }
  }
  std::vector<grid::PostRect> dirtyRects;
  for (const auto& [key, d] : dirtyOf) {
    report.modules.push_back({key.second, key.first});
    dirtyRects.push_back(d);
  }
  // Every base first: a module that does not read publishes nothing.
  std::vector<State*> states;
  for (const paging::ModuleKey& k : report.modules) {
    auto st = state(k.kx, k.kz);
    if (!st) return st.problems();
    states.push_back(st.value());
  }
  report.triangles.assign(header().levels, 0);
  report.patchSquares.assign(header().levels, 0);
  for (std::size_t n = 0; n < states.size(); ++n) {
    State& st = *states[n];
    const paging::ModuleKey k = report.modules[n];
    st.dirty = unite(st.dirty, dirtyRects[n]);
    detail::RebuildInput in;
    in.base = st.base.get();
    in.objects = &st.objects;
    in.before = before_.get();
    in.heights = heights_.get();
    in.squares = header().moduleSquares;
    in.kx = k.kx;
    in.kz = k.kz;
    in.options = &options_;
    in.dirty = st.dirty;
    detail::RebuildStats stats;
    auto p = std::make_shared<Published>();
    p->module = detail::rebuildModule(in, stats);
    p->generation = nextGeneration_++;
    report.refinedSquares += stats.refinedSquares;
    for (std::size_t l = 0; l < stats.patchSquares.size() && l < report.patchSquares.size(); ++l) {
      report.patchSquares[l] += stats.patchSquares[l];
    }
    for (std::size_t l = 0; l < p->module.levels.size() && l < report.triangles.size(); ++l) {
      report.triangles[l] += p->module.levels[l].indices.size() / 3;
    }
    st.rebuilt = p;
    publish(k.kx, k.kz, std::move(p));
  }
  commit();
  report.seconds = threadSeconds() - t0;
  return report;
}

Status EditedModules::editObject(const edit::Edit& e) {
  using edit::Kind;
  if (const std::string why = edit::checkEdit(e); !why.empty()) return problem(why);
  if (e.kind != Kind::addObject && e.kind != Kind::removeObject && e.kind != Kind::switchObject &&
      e.kind != Kind::scaleObject) {
    return problem(std::string(edit::kindName(e.kind)) + " is not an object edit");
  }
  const pack::IndexHeader& h = header();
  std::uint32_t kx = e.moduleX, kz = e.moduleZ;
  if (e.kind == Kind::addObject) {
    const double size = h.moduleSize;
    kx = std::min(std::uint32_t(std::max(0.0, e.points[0][0] / size)), h.modulesX - 1);
    kz = std::min(std::uint32_t(std::max(0.0, e.points[0][1] / size)), h.modulesZ - 1);
  } else if (kx >= h.modulesX || kz >= h.modulesZ) {
    return problem("object edit: module (" + std::to_string(kx) + ", " + std::to_string(kz) + ") is outside the " +
                   std::to_string(h.modulesX) + " x " + std::to_string(h.modulesZ) + " modules");
  }
  auto got = state(kx, kz);
  if (!got) return got.problems();
  State& st = *got.value();
  auto cylinder = [&](std::uint16_t icon) -> const std::array<float, 2>* {
    return icon < options_.iconCylinders.size() ? &options_.iconCylinders[icon] : nullptr;
  };
  if (e.kind == Kind::addObject) {
    module::Object o;
    o.icon = e.icon;
    o.cls = module::kObjectClassExplicit;
    o.x = float(e.points[0][0] - double(kx) * h.moduleSize);
    o.z = float(e.points[0][1] - double(kz) * h.moduleSize);
    o.heading = module::headingCode(e.heading);
    o.scale = float(e.scale);
    if (const auto* c = cylinder(e.icon)) o.radius = (*c)[0] * o.scale, o.height = (*c)[1] * o.scale;
    std::uint64_t id = 0;
    for (const module::Object& x : st.objects) {
      if (!module::isScattered(x.id)) id = std::max(id, x.id + 1);
    }
    o.id = id;
    st.objects.push_back(o);
  } else {
    const auto it = std::find_if(st.objects.begin(), st.objects.end(), [&](const module::Object& o) { return o.id == e.object; });
    if (it == st.objects.end()) {
      return problem("object edit: module (" + std::to_string(kx) + ", " + std::to_string(kz) + ") has no object " +
                     std::to_string(e.object));
    }
    if (e.kind == Kind::removeObject) {
      st.objects.erase(it);
    } else if (e.kind == Kind::switchObject) {
      it->icon = e.icon;
      if (const auto* c = cylinder(e.icon)) it->radius = (*c)[0] * it->scale, it->height = (*c)[1] * it->scale;
    } else {
      it->scale = float(double(it->scale) * e.scale);
      it->radius = float(double(it->radius) * e.scale);
      it->height = float(double(it->height) * e.scale);
    }
  }
  module::sortObjects(st.objects);
  auto p = std::make_shared<Published>();
  p->module = st.rebuilt ? st.rebuilt->module : *st.base;
  p->module.objects = st.objects;
  detail::placeObjects(p->module, *heights_, h.moduleSquares);
  p->generation = nextGeneration_++;
  st.rebuilt = p;
  publish(kx, kz, std::move(p));
  commit();
  return {};
}

std::shared_ptr<const EditedModules::Published> EditedModules::published(std::uint32_t kx, std::uint32_t kz) const {
  const std::lock_guard lock(mu_);
  const auto it = published_.find(index(kx, kz));
  return it == published_.end() ? nullptr : it->second;
}

paging::ModuleInfo EditedModules::info(std::uint32_t kx, std::uint32_t kz) const { return base_->info(kx, kz); }

std::uint64_t EditedModules::generation(std::uint32_t kx, std::uint32_t kz) const {
  return generations_[index(kx, kz)].load(std::memory_order_acquire);
}

Result<std::uint64_t> EditedModules::read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  const auto p = published(kx, kz);
  if (!p) return base_->read(kx, kz, into);
  into = p->module;  // copy-assigns every vector, reusing into's capacity
  return p->generation;
}

Result<std::uint64_t> EditedModules::readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  const auto p = published(kx, kz);
  if (!p) return base_->readCoarse(kx, kz, into);
  const module::Module& m = p->module;
  into.kx = m.kx;
  into.kz = m.kz;
  into.objects = m.objects;
  into.scattering = m.scattering;
  into.levels.resize(m.levels.size());
  for (std::size_t l = std::min<std::size_t>(coarseLevel(), m.levels.size()); l < m.levels.size(); ++l) {
    into.levels[l] = m.levels[l];
  }
  return p->generation;
}

Status EditedModules::readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  const auto p = published(kx, kz);
  if (!p) return base_->readFine(kx, kz, into);
  const module::Module& m = p->module;
  into.levels.resize(m.levels.size());
  for (std::size_t l = 0; l < std::min<std::size_t>(coarseLevel(), m.levels.size()); ++l) into.levels[l] = m.levels[l];
  return {};
}

bool EditedModules::missing(std::uint32_t kx, std::uint32_t kz) const {
  return !published(kx, kz) && base_->missing(kx, kz);
}

std::uint64_t EditedModules::changedSince(std::uint64_t since, std::vector<paging::ModuleKey>& out) const {
  const std::lock_guard lock(mu_);
  if (since < log_.size()) out.insert(out.end(), log_.begin() + std::ptrdiff_t(since), log_.end());
  return std::max<std::uint64_t>(since, log_.size());
}

RemeshOptions remeshOptionsFor(const paging::World& world) {
  RemeshOptions o;
  if (const auto& table = world.materials()) {
    for (const char* name : {"crater", "soil"}) {
      const materials::Class* c = table->findByName(name);
      if (c && c->kind == materials::Kind::area) {
        o.craterMaterial = c->id;
        break;
      }
    }
  }
  if (const auto& icons = world.icons()) {
    for (const iconpack::Icon& icon : icons->icons) o.iconCylinders.push_back({icon.cylinderRadius, icon.cylinderHeight});
  }
  return o;
}

}  // namespace sandtable::edits
