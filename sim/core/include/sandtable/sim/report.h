#pragma once
// What a run of the simulation did, for people and for scripts: the
// summary (entities alive per force, collisions by kind, kills, munitions
// fired, detonations) and the event log (docs/SIM.md, "Event log").
//
// The JSON is deterministic: the same run gives the same bytes, which is
// how the determinism test compares two runs.
//
// Thread safety: pure functions of a Simulation between steps.
#include <string>

#include <nlohmann/json.hpp>

#include "sandtable/sim/simulation.h"

namespace sandtable::sim {

const char* forceName(std::uint8_t force);

/// Entities (munitions apart) alive and in all, and munitions in flight.
struct Census {
  std::uint32_t alive = 0, total = 0, munitionsInFlight = 0;
};
Census census(const Simulation& sim);

/// {"time_s", "steps", "entities", "alive": {force: n}, "dead": {...},
///  "collisions": {...}, "kills", "fired", "detonations", "objects_changed"}
nlohmann::json summaryJson(const Simulation& sim);
/// One object per event, in order.
nlohmann::json eventsJson(const Simulation& sim);
/// The summary as a few plain lines.
std::string summaryText(const Simulation& sim);

}  // namespace sandtable::sim
