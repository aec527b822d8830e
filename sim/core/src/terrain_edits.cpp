#include "sandtable/sim/terrain_edits.h"

#include <utility>

namespace sandtable::sim {

TerrainEditing::TerrainEditing(Simulation& simulation, edits::Editor& editor, TerrainEditHooks hooks)
    : sim_(simulation), editor_(editor), hooks_(std::move(hooks)) {
  sim_.setNextEditId(editor_.nextId(sim_.options().editOrigin));
}

void TerrainEditing::attach(StepHost& host) {
  host.addAfterStep([this](Simulation&) { afterStep(); });
}

void TerrainEditing::applyLocal(const edit::Edit& e) {
  edit::Edit made = e;
  made.origin = sim_.options().editOrigin;
  made.id = sim_.newEditId();
  made.time = sim_.timeS();
  applyMade(made);
}

void TerrainEditing::applyMade(const edit::Edit& made) {
  ++counters_.local;
  edit::Edit e = made;
  if (hooks_.publish) {
    auto p = hooks_.publish(made);
    if (!p) {
      ++counters_.failed;
      counters_.lastError = p.error();
      return;
    }
    e = std::move(p.value());
  }
  applyOne(e);
}

void TerrainEditing::afterStep() {
  for (const edit::Edit& e : sim_.takeTerrainEdits()) applyMade(e);
  if (hooks_.received) {
    for (const edit::Edit& e : hooks_.received()) {
      ++counters_.received;
      applyOne(e);
    }
  }
  if (Status st = editor_.tick(); !st) {
    ++counters_.failed;
    counters_.lastError = st.message();
  }
}

void TerrainEditing::applyOne(const edit::Edit& e) {
  auto r = editor_.apply(e);
  if (!r) {
    ++counters_.failed;
    counters_.lastError = r.error();
    return;
  }
  if (r.value().duplicate) {
    ++counters_.duplicates;
    return;
  }
  ++counters_.applied;
  if (r.value().rebuilt) ++counters_.rebuilds;
  if (e.kind == edit::Kind::crater) counters_.objectsFelled += sim_.objectsInCrater(e);
}

}  // namespace sandtable::sim
