// sandtable sim: run a scenario headless, faster than real time, and
// report what happened (docs/SIM.md).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <optional>
#include <span>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "db_util.h"
#include "dis_link.h"
#include "progress.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/sim/collision_response.h"
#include "sandtable/sim/report.h"
#include "sandtable/sim/step_host.h"
#include "journal_util.h"
#include "sim_setup.h"
#include "terrain_link.h"

namespace sandtable::cli {
namespace {

// A week of simulated time: longer runs are a typing slip (1e18 would
// step for ever), and a week of 60 Hz steps still fits any counter.
constexpr double kMaxDurationS = 7 * 24 * 3600.0;

std::atomic<bool> gCancel{false};
void onSignal(int) { gCancel.store(true); }

struct SimArgs {
  std::string db, scenario, record, collisions, journal;
  double duration = 120;
  std::optional<std::uint64_t> seed;
  bool json = false, bruteForce = false, realTime = false;
  DisArgs dis;
};

/// The recorded script: the played scripts' lines merged with the driven
/// entity's, so that recording while playing compounds scripts (seed VIII.B.2).
Status writeRecording(const sim::Simulation& s, const std::string& path) {
  std::vector<sim::ScriptLine> played;
  for (const auto& file : s.playedScripts()) played.insert(played.end(), file.begin(), file.end());
  std::stable_sort(played.begin(), played.end(),
                   [](const sim::ScriptLine& a, const sim::ScriptLine& b) { return a.timeS < b.timeS; });
  const std::string text = sim::mergeScripts(played, s.recorder()->lines());
  return writeFileAtomic(path, std::as_bytes(std::span(text.data(), text.size())));
}

int runSim(const SimArgs& a) {
  if (!(a.duration > 0 && a.duration <= kMaxDurationS)) {
    return usageError("sim", "--duration must be a number of simulated seconds above 0 and at most " +
                                 std::to_string(static_cast<long>(kMaxDurationS)) + " (7 days, docs/SIM.md)");
  }
  sim::SimOptions options;
  options.bruteForce = a.bruteForce;
  if (!a.collisions.empty()) {
    auto table = sim::readCollisionTable(a.collisions);
    if (!table) return reportProblems("sim", table.problems());
    options.table = std::move(table.value());
  }
  // On a network every process orders edits by (time, origin, id): the
  // origin is this simulation's DIS site and application.
  if (!a.dis.endpoint.empty()) options.editOrigin = edit::Origin(a.dis.site << 16 | a.dis.application);
  // The ground the journal left (the database's own edits.journal when
  // there is one); the run's edits are appended only to a --journal given.
  const bool append = !a.journal.empty() && a.journal != "none";
  auto ew = openEditedWorld("sim", a.db, a.journal, append, editorOptions(true, false));
  if (!ew) return kUsage;
  const std::shared_ptr<const paging::World> world = ew->world();
  auto setup = setUpSimulation("sim", *world, a.scenario, a.seed, options);
  if (!setup) return kUsage;
  sim::Simulation& s = *setup->sim;
  if (!a.record.empty()) {
    if (!s.driven) return usageError("sim", "--record needs a driven entity: mark one `driven` in " + a.scenario);
    s.record(*s.driven, *s.driven + 1, s.entity(*s.driven).icon);
  }
  std::unique_ptr<DisLink> link;
  if (!a.dis.endpoint.empty()) {
    link = openDisLink("sim", world->manifest(), s, a.dis);
    if (!link) return kUsage;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  Progress progress(a.json);
  const auto start = std::chrono::steady_clock::now();
  sim::StepHost host(s);
  host.setCancel(&gCancel);
  if (a.realTime || link) host.setPacing(sim::Pacing::realTime);  // a networked run keeps the exercise's time
  if (link) link->gateway->attach(host);
  const auto terrain = linkTerrain(s, *ew->editor, link.get(), setup->terrainEdits);
  terrain->attach(host);
  const std::uint64_t steps = host.stepsFor(a.duration);
  host.addAfterStep([&](const sim::Simulation& at) {
    const std::uint64_t k = at.steps();
    if (k % 60 != 0 && k != steps) return;
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const sim::Census n = sim::census(at);
    char detail[160];
    std::snprintf(detail, sizeof detail, "%.0f/%.0f s  %u entities alive  %u munitions in flight  %.1fx real time",
                  at.timeS(), a.duration, n.alive, n.munitionsInFlight, wall > 0 ? at.timeS() / wall : 0.0);
    progress.update(double(k) / double(steps), "simulating", detail);
  });
  const bool cancelled = host.runToStep(steps).cancelled;
  if (link) link->gateway->retireAll();  // receivers drop our entities now, not 12 s later
  if (cancelled) {
    progress.done();
    return usageError("sim", "cancelled at " + std::to_string(s.timeS()) + " s; nothing was written");
  }
  progress.done();
  ew->editor->wait();
  if (Status st = ew->editor->flush(); !st) return reportProblems("sim", st.problems());
  const std::string journal = append ? ew->journal : std::string();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!a.record.empty()) {
    s.finishRecording();
    if (Status st = writeRecording(s, a.record); !st) return reportProblems("sim", st.problems());
  }
  if (a.json) {
    nlohmann::json j = {{"database", a.db}, {"scenario", a.scenario}, {"seed", s.options().seed},
                        {"wall_s", wall},   {"summary", sim::summaryJson(s)}, {"events", sim::eventsJson(s)}};
    if (!a.record.empty()) j["recorded"] = a.record;
    if (link) j["dis"] = disJson(*link, s);
    j["terrain"] = terrainJson(*terrain, *ew->editor, journal);
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    std::printf("%s", sim::summaryText(s).c_str());
    std::printf("wall time %.2f s (%.1fx real time)\n", wall, wall > 0 ? s.timeS() / wall : 0.0);
    if (!a.record.empty()) std::printf("recorded %s\n", a.record.c_str());
    if (link) std::printf("%s", disSummary(*link).c_str());
    if (terrain->counters().applied || !ew->editor->edits().empty()) {
      std::printf("%s", terrainSummary(*terrain, *ew->editor, journal).c_str());
    }
  }
  return kOk;
}

}  // namespace

void registerSim(CLI::App& root, Commands& c) {
  auto a = std::make_shared<SimArgs>();
  auto* sub = root.add_subcommand("sim", "Run a scenario headless, faster than real time, and report what happened");
  sub->footer(
      "Entities with dynamics, collisions (Table 6, Figure 64), munitions, the computer-generated forces'\n"
      "behaviours and scripts (docs/SIM.md). Progress goes to stderr; Ctrl-C stops (exit 2, nothing written).\n"
      "Examples:\n"
      "  sandtable sim db --scenario samples/demo.scenario --duration 300\n"
      "  sandtable sim db --scenario s.scenario --record drive.script --json > events.json\n"
      "  sandtable sim db --scenario s.scenario --dis 3000 --site 2 --duration 600   (a DIS participant)");
  sub->add_option("DB", a->db, "Database directory")->required();
  sub->add_option("--scenario", a->scenario, "Scenario file (docs/SCRIPTS.md)")->required();
  sub->add_option("--duration", a->duration, "Simulated seconds, above 0 and at most 604800 (7 days; default 120)");
  sub->add_option("--record", a->record,
                  "Write the driven entity's script here, merged with the scripts the scenario plays");
  sub->add_option("--seed", a->seed, "Random seed (default: the scenario's seed line, else 1)");
  sub->add_option("--collisions", a->collisions, "Collision response table (default: seed Table 6, samples/collisions.txt)");
  sub->add_flag("--brute-force", a->bruteForce, "Test every object and entity pair (a baseline; same results, slower)");
  sub->add_flag("--json", a->json, "Print the summary and the event log as JSON");
  sub->add_flag("--real-time", a->realTime,
                "Pace the steps to the wall clock instead of running as fast as possible (always, with --dis)");
  addDisOptions(sub, a->dis);
  sub->add_option("--journal", a->journal,
                  "Terrain edits: start from FILE and append the run's edits to it (default: start from "
                  "DB/edits.journal when present and keep the run's edits in memory; none: the ground as built)");
  c.add(sub, [a] { return runSim(*a); });
}

}  // namespace sandtable::cli
