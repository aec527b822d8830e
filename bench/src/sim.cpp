// bench sim: the simulator's step with collisions against brute force, in
// the seed's Fort Hunter-Liggett case scaled up.
#include "sandtable/bench/sim.h"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "sandtable/base/hash.h"
#include "sandtable/base/stats.h"
#include "sandtable/formats/grid.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"
#include "synthetic_world.h"

namespace sandtable::bench {
namespace {

constexpr double kSquareM = 125;  // the seed's grid square

double rnd(std::uint64_t seed, std::uint64_t k) { return unitRandom(seed, k); }

/// The world's grid, written to a work file and mapped.
Result<std::shared_ptr<const grid::GridFile>> makeGrid(double sizeKm) { return makeHillsGrid(sizeKm, kSquareM, "sim"); }

/// Table 3's clumps: about 3.9 objects in each populated square.
std::vector<sim::StaticObject> makeObjects(const sim::SimWorld& w, std::uint32_t count, std::uint64_t seed) {
  std::vector<sim::StaticObject> out;
  const double size = w.widthM();
  std::uint64_t k = 0;
  while (out.size() < count) {
    const double sx = std::floor(rnd(seed, k++) * size / kSquareM) * kSquareM;
    const double sz = std::floor(rnd(seed, k++) * size / kSquareM) * kSquareM;
    const auto n = 1 + static_cast<std::uint32_t>(rnd(seed, k++) * 5.8);
    for (std::uint32_t m = 0; m < n && out.size() < count; ++m) {
      sim::StaticObject o;
      o.x = std::min(size, sx + rnd(seed, k++) * kSquareM);
      o.z = std::min(size, sz + rnd(seed, k++) * kSquareM);
      o.baseY = w.groundAt(o.x, o.z).value_or(0.0);
      const double r = rnd(seed, k++);
      o.kind = r < 0.7 ? sim::ObjectKind::tree : r < 0.9 ? sim::ObjectKind::house : sim::ObjectKind::rock;
      o.radius = o.kind == sim::ObjectKind::house ? 6 : o.kind == sim::ObjectKind::tree ? 2.5 : 1.5;
      o.height = o.kind == sim::ObjectKind::house ? 7 : o.kind == sim::ObjectKind::tree ? 12 : 1.5;
      out.push_back(o);
    }
  }
  return out;
}

sim::Entity makeEntity(const sim::SimWorld& w, std::uint64_t seed, std::uint32_t k) { return zigzagEntity(w, seed, k); }

double threadCpuS() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

struct Run {
  double wallMs = 0, cpuMs = 0;  ///< per step
  sim::SimCounters counters;
  std::uint64_t objectsTested = 0;
};

Result<Run> runOnce(const std::shared_ptr<const grid::GridFile>& grid, const std::vector<sim::StaticObject>& objects,
                    std::uint32_t entities, bool brute, double seconds, std::uint64_t seed) {
  auto world = std::make_shared<sim::SimWorld>(grid, 0, 1);
  world->setObjects(objects);
  sim::SimOptions o;
  o.seed = seed;
  sim::Simulation s(world, o);
  for (std::uint32_t k = 0; k < entities; ++k) {
    auto id = s.add(makeEntity(*world, seed, k));
    if (!id) return id.problems();
  }
  s.runFor(1.0);  // warm-up (with the grid: the same states, sooner): caches, first turns
  s.options().bruteForce = brute;
  const sim::SimCounters before = s.counters();
  sim::StepHost host(s);
  const std::uint64_t steps = std::max<std::uint64_t>(1, host.stepsFor(seconds));
  const double cpu0 = threadCpuS();
  const auto t0 = std::chrono::steady_clock::now();
  host.runToStep(s.steps() + steps);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu = threadCpuS() - cpu0;
  Run r;
  r.wallMs = 1000 * wall / double(steps);
  r.cpuMs = 1000 * cpu / double(steps);
  r.counters = s.counters();
  r.counters.collisions.objects -= before.collisions.objects;
  r.counters.collisions.entities -= before.collisions.entities;
  r.objectsTested = r.counters.search.objectsTested - before.search.objectsTested;
  r.counters.entitySteps -= before.entitySteps;
  r.counters.steps -= before.steps;
  return r;
}

nlohmann::json modeJson(const std::vector<Run>& runs, std::uint32_t entities) {
  std::vector<double> wall, cpu;
  nlohmann::json list = nlohmann::json::array();
  for (const Run& r : runs) {
    wall.push_back(r.wallMs);
    cpu.push_back(r.cpuMs);
    list.push_back(r.wallMs);
  }
  const double w = stats::median(wall), c = stats::median(cpu);
  return {{"step_ms", w},
          {"step_cpu_ms", c},
          {"hz", 1000 / w},
          {"entities_per_s", 1000 * entities / w},
          {"runs_ms", list},
          {"steps", runs.front().counters.steps},
          {"object_collisions", runs.front().counters.collisions.objects},
          {"entity_collisions", runs.front().counters.collisions.entities}};
}

}  // namespace

Result<SimBenchReport> runSimBench(const SimBenchOptions& o, const Notes& notes) {
  if (o.entities.empty()) return Problem{"", 0, "bench sim: SimBenchOptions::entities is empty; give at least one count"};
  for (std::uint32_t n : o.entities) {
    if (n < 1 || n > 1000000) return Problem{"", 0, "bench sim: SimBenchOptions::entities must be 1..1000000 each"};
  }
  if (!(o.sizeKm >= 1 && o.sizeKm <= 500)) return Problem{"", 0, "bench sim: SimBenchOptions::sizeKm must be 1..500"};
  if (o.objects > 10000000) return Problem{"", 0, "bench sim: SimBenchOptions::objects must be at most 10000000"};
  if (!(o.seconds > 0) || !(o.bruteSeconds > 0)) {
    return Problem{"", 0, "bench sim: SimBenchOptions::seconds and SimBenchOptions::bruteSeconds must be positive"};
  }
  if (o.repeat < 1 || o.repeat > 100) return Problem{"", 0, "bench sim: SimBenchOptions::repeat must be 1..100"};
  auto grid = makeGrid(o.sizeKm);
  if (!grid) return grid.problems();
  std::vector<sim::StaticObject> objects;
  {
    sim::SimWorld w(grid.value(), 0, 1);
    objects = makeObjects(w, o.objects, o.seed);
  }
  nlohmann::json cases = nlohmann::json::array();
  for (std::uint32_t n : o.entities) {
    std::vector<Run> grids, brutes;
    for (int r = 0; r < o.repeat; ++r) {
      // Alternate the two so that a change in the machine's load hits both.
      auto g = runOnce(grid.value(), objects, n, false, o.seconds, o.seed);
      if (!g) return g.problems();
      grids.push_back(g.value());
      auto b = runOnce(grid.value(), objects, n, true, o.bruteSeconds, o.seed);
      if (!b) return b.problems();
      brutes.push_back(b.value());
      char line[200];
      std::snprintf(line, sizeof line, "%u entities, run %d: grid %.3f ms/step, brute force %.3f ms/step", n, r + 1,
                    g->wallMs, b->wallMs);
      notes.say(line);
    }
    nlohmann::json c = {{"entities", n}, {"grid", modeJson(grids, n)}, {"brute", modeJson(brutes, n)}};
    const double gms = c["grid"]["step_ms"].get<double>(), bms = c["brute"]["step_ms"].get<double>();
    c["brute_over_grid"] = bms / gms;
    c["meets_60hz"] = gms <= 1000.0 / 60.0;
    c["objects_tested_per_entity_step"] =
        double(grids.front().objectsTested) / std::max<double>(1.0, double(grids.front().counters.entitySteps));
    cases.push_back(std::move(c));
  }
  SimBenchReport rep;
  rep.json = {{"size_km", o.sizeKm},       {"square_m", kSquareM}, {"objects", o.objects},
              {"seconds", o.seconds},      {"brute_seconds", o.bruteSeconds},
              {"repeat", o.repeat},        {"cases", cases}};
  return rep;
}

}  // namespace sandtable::bench
