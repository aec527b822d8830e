#pragma once
// The simulation's terrain edits applied in step order (docs/DYNAMIC.md,
// "Who decides"): after every step, the edits the step made (craters where
// munitions hit the ground), then those received from elsewhere (the DIS
// network), go through the one editor; a crater also fells the trees in it
// (Simulation::objectsInCrater). `sandtable sim`, `fly --scenario` and the
// benchmark attach one of these to their StepHost, so the rule is in one
// place.
//
// Thread safety: the StepHost's thread only.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/edits/editor.h"
#include "sandtable/formats/edit.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"

namespace sandtable::sim {

struct TerrainEditHooks {
  /// Each local edit before it is applied; returns the edit to apply. The
  /// DIS gateway publishes it and returns what its receivers will make of
  /// it, so every process applies the same edit. Null: applied as made.
  std::function<Result<edit::Edit>(const edit::Edit&)> publish;
  /// Edits received since the last call, applied after the step's own.
  std::function<std::vector<edit::Edit>()> received;
};

struct TerrainEditCounters {
  std::uint64_t local = 0;       ///< made by this simulation
  std::uint64_t received = 0;    ///< from the hooks
  std::uint64_t applied = 0;
  std::uint64_t duplicates = 0;  ///< received again (a heartbeat): nothing changed
  std::uint64_t rebuilds = 0;    ///< arrived before an overlapping edit already applied
  std::uint64_t failed = 0;      ///< refused (outside the grid, a publish or journal error)
  std::uint64_t objectsFelled = 0;
  std::string lastError;
};

class TerrainEditing {
 public:
  /// Local edits get ids after the editor's largest for the simulation's
  /// origin (a journal replayed at open holds earlier ones).
  TerrainEditing(Simulation& simulation, edits::Editor& editor, TerrainEditHooks hooks = {});
  /// Adds afterStep to `host`'s after-step hooks.
  void attach(StepHost& host);
  void afterStep();
  /// Applies `e` as if the simulation had made it now (a scenario's
  /// pre-placed berms and craters before the first step): it takes the
  /// simulation's origin, its next id and the time now.
  void applyLocal(const edit::Edit& e);
  const TerrainEditCounters& counters() const { return counters_; }

 private:
  void applyMade(const edit::Edit& made);
  void applyOne(const edit::Edit& e);

  Simulation& sim_;
  edits::Editor& editor_;
  TerrainEditHooks hooks_;
  TerrainEditCounters counters_;
};

}  // namespace sandtable::sim
