#pragma once
// The editor: the one place terrain edits are applied (docs/DYNAMIC.md,
// "The editor"). It wraps a database's World in an edited one (the heights
// overlay and the re-meshed modules) that every reader shares: the pager,
// the renderer's caches, the map, the simulator's ground, soil, objects and
// collision squares.
//
// Order: every edit has a key (time, origin, id) and the ground is always
// the edits applied in key order. The simulation's step host applies its
// own edits in step order (keys increase); an edit from the network or a
// journal with a smaller key than one already applied whose area it shares
// (grid squares of the two supports meet) makes the editor re-apply every
// edit from the base in key order (`rebuilds`), so two processes that hold
// the same edits hold bit-identical heights whatever order they arrived in.
// An edit whose area meets no later one is applied at once: it commutes.
// The same (origin, id) twice is a duplicate and ignored.
//
// Work: heights change in apply() (the next ground query sees them);
// modules are re-meshed on a background queue (jobs::SerialQueue, off the
// render and simulation threads) and published as new generations, which
// the pager swaps in. wait() blocks until the queue is empty.
//
// Journal: with EditorOptions::journal, open() replays that file (a torn
// tail is cut with a warning) and apply() appends every edit it applies, in
// batches made durable by tick() (each step) and flush().
//
// Thread contract: one thread (the simulation's, or the CLI's) calls
// apply, tick, flush, wait and the accessors that return mutable state;
// world(), heights(), modules() and stats() are safe from any thread.
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/base/jobs.h"
#include "sandtable/base/result.h"
#include "sandtable/edits/heights.h"
#include "sandtable/edits/modules.h"
#include "sandtable/formats/edit.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/paging/world.h"

namespace sandtable::edits {

struct EditorOptions {
  /// The journal to replay at open and append to; "" keeps the edits in
  /// memory only.
  std::string journal;
  /// Replay only: apply() still applies, but writes nothing (a viewer with
  /// no simulation, `sample`, `export`).
  bool readOnly = false;
  journal::WriterOptions journalOptions;
  RemeshOptions remesh;
  /// Keep modules re-meshed (false: heights only, for `sample` and
  /// `export --grid`, which read no modules; world().modules() is then the
  /// base's).
  bool meshModules = true;
  /// Re-mesh on the background queue (true) or inside apply() (tests,
  /// benchmarks of the re-mesh itself, `edits apply`).
  bool background = true;
};

/// The key edits are applied in (docs/DYNAMIC.md, "Order").
struct EditKey {
  double time = 0;
  edit::Origin origin = 0;
  std::uint64_t id = 0;
  auto operator<=>(const EditKey&) const = default;
};
inline EditKey keyOf(const edit::Edit& e) { return {e.time, e.origin, e.id}; }

/// What apply() did with one edit.
struct Applied {
  bool duplicate = false;  ///< (origin, id) was applied before: nothing changed
  bool rebuilt = false;    ///< it came before an overlapping edit: everything was re-applied
  HeightsChange heights;   ///< height edits: what changed (empty for object edits and duplicates)
};

struct EditorStats {
  std::uint64_t applied = 0;       ///< edits applied (not counting re-applications)
  std::uint64_t byKind[edit::kMaxKind + 1] = {};
  std::uint64_t duplicates = 0;
  std::uint64_t rebuilds = 0;      ///< out-of-order edits that made the editor re-apply everything
  std::uint64_t replayed = 0;      ///< edits read from the journal at open
  std::uint64_t remeshes = 0;      ///< background re-mesh batches run
  std::uint64_t modulesRemeshed = 0;
  double remeshSeconds = 0;        ///< CPU seconds of the re-mesh batches
  std::uint64_t remeshFailures = 0;
  std::string lastRemeshError;
  HeightsStats heights;
};

class Editor {
 public:
  /// Over `base` (a World opened on a database). Replays options.journal
  /// when it exists; its problems (damage before the tail) fail the open,
  /// a torn tail is a warning in warnings().
  static Result<std::unique_ptr<Editor>> open(std::shared_ptr<const paging::World> base, EditorOptions options = {});
  ~Editor();
  Editor(const Editor&) = delete;
  Editor& operator=(const Editor&) = delete;

  /// The edited world: the base's database, the overlay, the re-meshed
  /// modules (null when the database has none).
  const std::shared_ptr<const paging::World>& world() const { return world_; }
  const std::shared_ptr<EditedHeights>& heights() const { return heights_; }
  const std::shared_ptr<EditedModules>& modules() const { return modules_; }

  /// Applies `e` (see the file comment); the journal gets it when applied.
  /// Problems: an invalid edit (the field named), one wholly outside the
  /// grid, an object edit naming no object, a journal write that failed.
  Result<Applied> apply(const edit::Edit& e);
  /// Makes the journal's batch durable when it is due (call once a step).
  Status tick();
  /// Makes every appended edit durable now.
  Status flush();
  /// Returns when every re-mesh queued so far is published.
  void wait();

  /// Every edit applied, in key order.
  const std::vector<edit::Edit>& edits() const { return edits_; }
  /// The next id for an edit of `origin`: one past the largest applied.
  std::uint64_t nextId(edit::Origin origin) const;
  EditorStats stats() const;
  /// Warnings of the open (a torn journal tail cut).
  const Warnings& warnings() const { return warnings_; }

 private:
  Editor() = default;
  Status replay(const std::string& path);
  Status applyInOrder(const edit::Edit& e, Applied& out);
  Status applyOne(const edit::Edit& e, HeightsChange* change);
  Status rebuild();
  void queueRemesh(const HeightsChange& change);
  void queueObjectEdit(const edit::Edit& e);
  void runRemesh();
  Status openWriter();

  std::shared_ptr<const paging::World> base_, world_;
  std::shared_ptr<EditedHeights> heights_;
  std::shared_ptr<EditedModules> modules_;
  EditorOptions options_;
  std::vector<edit::Edit> edits_;  ///< key order
  std::vector<std::pair<edit::Origin, std::uint64_t>> seen_;  ///< sorted (origin, id)
  std::unique_ptr<journal::JournalWriter> writer_;
  Warnings warnings_;

  mutable std::mutex statsMutex_;
  EditorStats stats_;

  std::mutex pendingMutex_;
  std::vector<HeightsChange> pending_;  ///< height changes waiting for the re-mesh
  jobs::SerialQueue queue_;
};

}  // namespace sandtable::edits
