// The run's summary and event log.
#include "sandtable/sim/report.h"

#include <cmath>
#include <cstdio>
#include <map>

namespace sandtable::sim {

const char* forceName(std::uint8_t force) {
  switch (force) {
    case 0: return "neutral";
    case 1: return "blue";
    case 2: return "red";
    case 3: return "green";
    default: return "other";
  }
}

Census census(const Simulation& sim) {
  Census c;
  for (const Entity& e : sim.entities()) {
    if (e.domain == Domain::munition) {
      c.munitionsInFlight += e.alive;
      continue;
    }
    ++c.total;
    c.alive += e.alive;
  }
  return c;
}

namespace {

/// Rounded to the millimetre: the log stays readable and the bytes stay
/// the same wherever the run is repeated in the same binary.
double mm(double v) { return std::round(v * 1000.0) / 1000.0; }

std::map<std::string, std::uint64_t> countByForce(const Simulation& sim, bool alive) {
  std::map<std::string, std::uint64_t> m;
  for (const Entity& e : sim.entities()) {
    if (e.domain == Domain::munition || e.alive != alive) continue;
    ++m[forceName(e.force)];
  }
  return m;
}

std::uint64_t objectsChanged(const Simulation& sim) {
  std::uint64_t n = 0;
  for (const StaticObject& o : sim.world().objects()) n += o.state != ObjectState::standing;
  return n;
}

}  // namespace

nlohmann::json summaryJson(const Simulation& sim) {
  const SimCounters& c = sim.counters();
  return {{"time_s", mm(sim.timeS())},
          {"steps", sim.steps()},
          {"entities", census(sim).total},
          {"alive", countByForce(sim, true)},
          {"dead", countByForce(sim, false)},
          {"collisions",
           {{"entity_object", c.collisions.objects},
            {"entity_entity", c.collisions.entities},
            {"munition_object", c.collisions.munitionObjects},
            {"munition_entity", c.collisions.munitionEntities},
            {"munition_terrain", c.collisions.terrain}}},
          {"kills", c.kills},
          {"fired", c.fired},
          {"detonations", c.detonations},
          {"objects_changed", objectsChanged(sim)}};
}

nlohmann::json eventsJson(const Simulation& sim) {
  nlohmann::json out = nlohmann::json::array();
  auto name = [&](std::uint32_t id) {
    const std::string* n = sim.nameOf(id);  // removed entities keep their names here
    return n ? nlohmann::json(*n) : nlohmann::json();
  };
  for (const Event& ev : sim.events()) {
    nlohmann::json j = {{"t", mm(ev.timeS)},
                        {"kind", eventKindName(ev.kind)},
                        {"entity", ev.entity},
                        {"name", name(ev.entity)},
                        {"x", mm(ev.position.x())},
                        {"y", mm(ev.position.y())},
                        {"z", mm(ev.position.z())}};
    if (ev.other != UINT32_MAX) {
      j["other"] = ev.other;
      j["other_name"] = name(ev.other);
    }
    if (ev.object != UINT32_MAX) {
      j["object"] = ev.object;
      const StaticObject& o = sim.world().objects()[ev.object];
      j["object_kind"] = objectKindName(o.kind);
      j["object_state"] = objectStateName(o.state);
    }
    if (ev.contact) {
      j["contact_body"] = {{mm(ev.bodyA.x()), mm(ev.bodyA.y()), mm(ev.bodyA.z())},
                           {mm(ev.bodyB.x()), mm(ev.bodyB.y()), mm(ev.bodyB.z())}};
    }
    if (!ev.munition.empty()) j["munition"] = ev.munition;
    if (!ev.detail.empty()) j["detail"] = ev.detail;
    out.push_back(std::move(j));
  }
  return out;
}

std::string summaryText(const Simulation& sim) {
  const nlohmann::json s = summaryJson(sim);
  std::string out;
  char buf[256];
  std::snprintf(buf, sizeof buf, "simulated %.1f s (%llu steps), %llu entities\n", sim.timeS(),
                static_cast<unsigned long long>(sim.steps()),
                static_cast<unsigned long long>(s["entities"].get<std::uint64_t>()));
  out += buf;
  out += "alive by force:";
  for (const auto& [force, n] : s["alive"].items()) out += " " + force + " " + std::to_string(n.get<std::uint64_t>());
  out += "\ndead by force:";
  for (const auto& [force, n] : s["dead"].items()) out += " " + force + " " + std::to_string(n.get<std::uint64_t>());
  const auto& c = s["collisions"];
  std::snprintf(buf, sizeof buf,
                "\ncollisions: entity-object %llu, entity-entity %llu, munition-object %llu, "
                "munition-entity %llu, munition-terrain %llu\n",
                static_cast<unsigned long long>(c["entity_object"].get<std::uint64_t>()),
                static_cast<unsigned long long>(c["entity_entity"].get<std::uint64_t>()),
                static_cast<unsigned long long>(c["munition_object"].get<std::uint64_t>()),
                static_cast<unsigned long long>(c["munition_entity"].get<std::uint64_t>()),
                static_cast<unsigned long long>(c["munition_terrain"].get<std::uint64_t>()));
  out += buf;
  std::snprintf(buf, sizeof buf, "kills %llu, munitions fired %llu, detonations %llu, objects changed %llu\n",
                static_cast<unsigned long long>(s["kills"].get<std::uint64_t>()),
                static_cast<unsigned long long>(s["fired"].get<std::uint64_t>()),
                static_cast<unsigned long long>(s["detonations"].get<std::uint64_t>()),
                static_cast<unsigned long long>(s["objects_changed"].get<std::uint64_t>()));
  out += buf;
  return out;
}

}  // namespace sandtable::sim
