#include "sandtable/edits/editor.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <utility>

#include "sandtable/edits/profile.h"

namespace sandtable::edits {

namespace {

/// Grid squares an edit's heights may depend on or change: its support box
/// widened to whole squares (a refined square is one patch, so two edits
/// in one square do not commute even when their supports are apart).
/// Empty for object edits.
grid::PostRect areaOf(const edit::Edit& e, const grid::HeightField& h) {
  if (!edit::changesHeights(e.kind)) return {};
  Box b = support(e);
  if (e.kind == edit::Kind::flatten) {
    // The reach depends on the ground under the polygon: bound it by the
    // whole field's elevation range, which only widens the area.
    const auto [lo, hi] = h.elevationBounds();
    const double gap = std::max(std::abs(e.height - double(lo)), std::abs(double(hi) - e.height));
    const double r = flattenReach(e, gap);
    b = {b.x0 - r, b.z0 - r, b.x1 + r, b.z1 + r};
  }
  const double s = h.spacing();
  const auto clampPost = [](double v, std::uint32_t n) {
    return std::uint32_t(std::clamp(v, 0.0, double(n)));
  };
  grid::PostRect r;
  r.i0 = clampPost(std::floor(b.x0 / s) - 1, h.postsX());
  r.j0 = clampPost(std::floor(b.z0 / s) - 1, h.postsZ());
  r.i1 = clampPost(std::ceil(b.x1 / s) + 2, h.postsX());
  r.j1 = clampPost(std::ceil(b.z1 / s) + 2, h.postsZ());
  return r;
}

}  // namespace

Result<std::unique_ptr<Editor>> Editor::open(std::shared_ptr<const paging::World> base, EditorOptions options) {
  if (!base) return Problem{"", 0, "editor: no world"};
  std::unique_ptr<Editor> ed(new Editor());
  ed->base_ = base;
  ed->options_ = std::move(options);
  // What the caller left unset comes from the database.
  const RemeshOptions implied = remeshOptionsFor(*base);
  if (!ed->options_.remesh.craterMaterial) ed->options_.remesh.craterMaterial = implied.craterMaterial;
  if (ed->options_.remesh.iconCylinders.empty()) ed->options_.remesh.iconCylinders = implied.iconCylinders;
  ed->heights_ = std::make_shared<EditedHeights>(base->heights());
  if (base->modules() && ed->options_.meshModules) {
    ed->modules_ = std::make_shared<EditedModules>(base->modules(), base->heights(), ed->heights_, ed->options_.remesh);
  }
  std::shared_ptr<const paging::ModuleSource> modules = ed->modules_;
  if (!modules) modules = base->modules();
  ed->world_ = std::make_shared<const paging::World>(base->database(), ed->heights_, modules);
  if (!ed->options_.journal.empty() && std::filesystem::exists(ed->options_.journal)) {
    if (Status st = ed->replay(ed->options_.journal); !st) return st.problems();
  }
  return ed;
}

Editor::~Editor() {
  queue_.wait();
  if (writer_) static_cast<void>(writer_->close());
}

Status Editor::replay(const std::string& path) {
  auto j = journal::readJournal(path);
  if (!j) return j.problems();
  for (const auto& w : j.value().warnings) warnings_.push_back(w);
  // Key order up front: a journal written by a networked run holds edits
  // in arrival order, and sorting here spares a rebuild per late one.
  std::vector<edit::Edit> all = std::move(j.value().edits);
  std::stable_sort(all.begin(), all.end(), [](const edit::Edit& a, const edit::Edit& b) { return keyOf(a) < keyOf(b); });
  for (const edit::Edit& e : all) {
    Applied a;
    if (Status st = applyInOrder(e, a); !st) {
      Problem p = st.problems().front();
      p.file = path;
      p.message = "replaying the journal: edit " + std::to_string(e.id) + " (" + std::string(edit::kindName(e.kind)) +
                  "): " + p.message;
      return p;
    }
    std::lock_guard lock(statsMutex_);
    ++stats_.replayed;
  }
  return {};
}

Status Editor::openWriter() {
  if (writer_ || options_.journal.empty() || options_.readOnly) return {};
  auto w = journal::JournalWriter::open(options_.journal, options_.journalOptions);
  if (!w) return w.problems();
  writer_ = std::move(w.value());
  return {};
}

Result<Applied> Editor::apply(const edit::Edit& e) {
  Applied out;
  if (Status st = applyInOrder(e, out); !st) return st.problems();
  if (out.duplicate) return out;
  if (Status st = openWriter(); !st) return st.problems();
  if (writer_) {
    if (Status st = writer_->append(e); !st) return st.problems();
  }
  return out;
}

Status Editor::applyInOrder(const edit::Edit& e, Applied& out) {
  if (const std::string bad = edit::checkEdit(e); !bad.empty()) return Problem{"", 0, bad};
  const std::pair<edit::Origin, std::uint64_t> name{e.origin, e.id};
  const auto seen = std::lower_bound(seen_.begin(), seen_.end(), name);
  if (seen != seen_.end() && *seen == name) {
    out.duplicate = true;
    std::lock_guard lock(statsMutex_);
    ++stats_.duplicates;
    return {};
  }
  const EditKey key = keyOf(e);
  const auto at = std::upper_bound(edits_.begin(), edits_.end(), key,
                                   [](const EditKey& k, const edit::Edit& x) { return k < keyOf(x); });
  // Later edits whose area meets this one's would have seen its heights.
  bool overlaps = false;
  const grid::PostRect mine = areaOf(e, *heights_);
  for (auto it = at; it != edits_.end() && !mine.empty(); ++it) {
    if (areaOf(*it, *heights_).intersects(mine)) {
      overlaps = true;
      break;
    }
  }
  const std::size_t index = std::size_t(at - edits_.begin());
  if (!overlaps) {
    if (Status st = applyOne(e, &out.heights); !st) return st;
    edits_.insert(edits_.begin() + std::ptrdiff_t(index), e);
  } else {
    edits_.insert(edits_.begin() + std::ptrdiff_t(index), e);
    if (Status st = rebuild(); !st) {
      edits_.erase(edits_.begin() + std::ptrdiff_t(index));
      static_cast<void>(rebuild());  // back to the edits before this one
      return st;
    }
    out.rebuilt = true;
  }
  seen_.insert(seen, name);
  std::lock_guard lock(statsMutex_);
  ++stats_.applied;
  ++stats_.byKind[std::size_t(e.kind) <= edit::kMaxKind ? std::size_t(e.kind) : 0];
  if (out.rebuilt) ++stats_.rebuilds;
  return {};
}

Status Editor::applyOne(const edit::Edit& e, HeightsChange* change) {
  if (edit::changesHeights(e.kind)) {
    auto r = heights_->apply(e);
    if (!r) return r.problems();
    if (!r.value().empty()) queueRemesh(r.value());
    if (change) *change = std::move(r.value());
    return {};
  }
  if (!modules_) {
    if (!options_.meshModules) return {};  // heights only: objects are not kept
    return Problem{"", 0, "edit: " + std::string(edit::kindName(e.kind)) + ": the database has no load modules to hold objects"};
  }
  if (!options_.background) return modules_->editObject(e);
  queueObjectEdit(e);
  return {};
}

Status Editor::rebuild() {
  // Back to the ground as built, then every height edit in key order.
  const HeightsChange cleared = heights_->reset();
  if (!cleared.empty()) queueRemesh(cleared);
  for (const edit::Edit& e : edits_) {
    if (!edit::changesHeights(e.kind)) continue;
    auto r = heights_->apply(e);
    if (!r) return r.problems();
    if (!r.value().empty()) queueRemesh(r.value());
  }
  return {};
}

void Editor::queueRemesh(const HeightsChange& change) {
  if (!modules_) return;
  {
    std::lock_guard lock(pendingMutex_);
    pending_.push_back(change);
  }
  if (!options_.background) {
    runRemesh();
    return;
  }
  queue_.submit([this] { runRemesh(); });
}

void Editor::queueObjectEdit(const edit::Edit& e) {
  queue_.submit([this, e] {
    if (Status st = modules_->editObject(e); !st) {
      std::lock_guard lock(statsMutex_);
      ++stats_.remeshFailures;
      stats_.lastRemeshError = st.message();
    }
  });
}

void Editor::runRemesh() {
  std::vector<HeightsChange> changes;
  {
    std::lock_guard lock(pendingMutex_);
    changes.swap(pending_);
  }
  if (changes.empty()) return;  // an earlier run took them
  // One rebuild per module for everything pending: a burst of craters
  // (a battle) costs each module it touches one rebuild, however many of
  // them fell on it.
  std::vector<EditedModules::Change> list;
  list.reserve(changes.size());
  for (const HeightsChange& c : changes) {
    EditedModules::Change& l = list.emplace_back();
    l.posts = c.posts;
    for (const SquareIndex& s : c.squares) l.squares.emplace_back(s.i, s.j);
  }
  auto r = modules_->remesh(list);
  std::lock_guard lock(statsMutex_);
  ++stats_.remeshes;
  if (!r) {
    ++stats_.remeshFailures;
    stats_.lastRemeshError = r.error();
    return;
  }
  stats_.modulesRemeshed += r.value().modules.size();
  stats_.remeshSeconds += r.value().seconds;
}

Status Editor::tick() {
  if (!writer_) return {};
  return writer_->flushIfDue();
}

Status Editor::flush() {
  if (!writer_) return {};
  return writer_->flush();
}

void Editor::wait() { queue_.wait(); }

std::uint64_t Editor::nextId(edit::Origin origin) const {
  const auto from = std::lower_bound(seen_.begin(), seen_.end(), std::pair<edit::Origin, std::uint64_t>{origin, 0});
  std::uint64_t next = 1;
  for (auto it = from; it != seen_.end() && it->first == origin; ++it) next = it->second + 1;
  return next;
}

EditorStats Editor::stats() const {
  std::lock_guard lock(statsMutex_);
  EditorStats s = stats_;
  s.heights = heights_->stats();
  return s;
}

}  // namespace sandtable::edits
