// bench edits, the live half: an editor re-meshing in the background and a
// headless pager over its world, driven in 60 Hz frames. Latency from
// apply() to published and to resident; sustained rates; the battle.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <mutex>
#include <thread>

#include "edits_internal.h"
#include "sandtable/edits/editor.h"
#include "sandtable/paging/pager.h"

namespace sandtable::bench::editsbench {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0, Clock::time_point t1) { return std::chrono::duration<double, std::milli>(t1 - t0).count(); }

/// The editor and a pager following its world, the eye over the middle.
struct Rig {
  std::mutex logMutex;  ///< first: the pager's loaders log until it is destroyed
  std::vector<std::string> log;
  std::unique_ptr<edits::Editor> editor;
  std::unique_ptr<paging::Pager> pager;
  double eyeX = 0, eyeZ = 0;
  std::uint64_t nextId = 1;
  std::uint64_t sites = 0;  ///< crater sites used so far
  Clock::time_point start = Clock::now();

  double now() const { return std::chrono::duration<double>(Clock::now() - start).count(); }
  void update() { pager->update(eyeX, eyeZ, 0, 0, now()); }
};

Result<std::unique_ptr<Rig>> openRig(const std::shared_ptr<const paging::World>& world, const EditsBenchOptions& o) {
  auto rig = std::make_unique<Rig>();
  edits::EditorOptions eo;
  eo.background = true;
  auto ed = edits::Editor::open(world, eo);
  if (!ed) return ed.problems();
  rig->editor = std::move(ed.value());
  paging::PagerOptions po;
  po.viewDistance = o.viewDistance;
  po.loaderThreads = 1;
  Rig* r = rig.get();
  po.log = [r](const std::string& line) {
    std::lock_guard lock(r->logMutex);
    if (r->log.size() < 8) r->log.push_back(line);
  };
  auto pager = paging::Pager::open(*rig->editor->world(), po);
  if (!pager) return pager.problems();
  rig->pager = std::move(pager.value());
  const grid::HeightField& h = *world->heights();
  rig->eyeX = 0.5 * (h.postsX() - 1) * h.spacing();
  rig->eyeZ = 0.5 * (h.postsZ() - 1) * h.spacing();
  for (int k = 0; k < 3; ++k) {  // the window resident before anything is measured
    rig->update();
    rig->pager->waitIdle(30);
  }
  return rig;
}

/// One crater applied: the modules it touches and their generations then.
struct Tracked {
  std::vector<paging::ModuleKey> keys;
  std::vector<std::uint64_t> before;
  Clock::time_point at;
  std::uint64_t frame = 0;
  bool published = false;
};

/// Craters applied and not yet drawn. A module counts as drawn for a
/// crater when the pager holds level 0 of a generation newer than the one
/// published when the crater was applied (a re-mesh that began before the
/// apply and published after it would count too: the tracked latency can
/// only be shorter than the truth by one re-mesh, and is exact for the
/// one-at-a-time samples, where the worker is idle at the apply).
class Tracker {
 public:
  void add(const edits::Editor& ed, const edits::Applied& a, std::uint64_t frame) {
    Tracked t;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> squares;
    for (const auto& s : a.heights.squares) squares.emplace_back(s.i, s.j);
    t.keys = ed.modules()->touched(a.heights.posts, squares);
    for (const auto& k : t.keys) t.before.push_back(ed.modules()->generation(k.kx, k.kz));
    t.at = Clock::now();
    t.frame = frame;
    touched_ += t.keys.size();
    open_.push_back(std::move(t));
  }

  /// Records what got published and drawn by now (`frame`). Reads each
  /// module's generations once (a battle tracks thousands of craters).
  void poll(const edits::EditedModules& mods, const paging::Pager& pager, std::uint64_t frame) {
    const auto now = Clock::now();
    const std::uint32_t mx = mods.header().modulesX, mz = mods.header().modulesZ;
    published_.assign(std::size_t(mx) * mz, 0);
    drawn_.assign(std::size_t(mx) * mz, 0);
    for (std::uint32_t kz = 0; kz < mz; ++kz) {
      for (std::uint32_t kx = 0; kx < mx; ++kx) {
        published_[std::size_t(kz) * mx + kx] = mods.generation(kx, kz);
        const paging::ResidentRef ref = pager.resident(kx, kz, 0);
        if (ref && !ref.coarser()) drawn_[std::size_t(kz) * mx + kx] = ref.module().generation;
      }
    }
    const auto newer = [&](const std::vector<std::uint64_t>& gen, const Tracked& t) {
      for (std::size_t i = 0; i < t.keys.size(); ++i) {
        if (gen[std::size_t(t.keys[i].kz) * mx + t.keys[i].kx] <= t.before[i]) return false;
      }
      return true;
    };
    std::erase_if(open_, [&](Tracked& t) {
      if (!t.published && newer(published_, t)) {
        t.published = true;
        publishedMs_.push_back(msSince(t.at, now));
      }
      if (!t.published || !newer(drawn_, t)) return false;
      drawnMs_.push_back(msSince(t.at, now));
      drawnFrames_.push_back(double(frame - t.frame));
      return true;
    });
  }

  std::size_t open() const { return open_.size(); }
  std::uint64_t touched() const { return touched_; }
  const std::vector<double>& publishedMs() const { return publishedMs_; }
  const std::vector<double>& drawnMs() const { return drawnMs_; }
  const std::vector<double>& drawnFrames() const { return drawnFrames_; }

 private:
  std::vector<Tracked> open_;
  std::vector<std::uint64_t> published_, drawn_;  ///< per module, this poll
  std::vector<double> publishedMs_, drawnMs_, drawnFrames_;
  std::uint64_t touched_ = 0;
};

Status applyCrater(Rig& rig, const paging::World& w, const EditsBenchOptions& o, Tracker& tracker, std::uint64_t frame) {
  const auto p = site(w, o.seed ^ 0x30, rig.sites++);
  const std::uint64_t id = rig.nextId++;
  auto a = rig.editor->apply(crater(p[0], p[1], edits::kCraterMedium, id, double(id)));
  if (!a) return a.problems();
  if (!a->heights.empty()) tracker.add(*rig.editor, a.value(), frame);
  return {};
}

/// Holes now: window modules the pager does not hold.
std::uint64_t holes(const paging::Pager& pager) {
  const paging::ModuleRect w = pager.window();
  std::uint64_t n = 0;
  for (std::int64_t kz = w.z0; kz < w.z1; ++kz) {
    for (std::int64_t kx = w.x0; kx < w.x1; ++kx) {
      if (!pager.resident(std::uint32_t(kx), std::uint32_t(kz), 0)) ++n;
    }
  }
  return n;
}

struct FrameRun {
  std::uint64_t frames = 0, craters = 0, holes = 0, holeFrames = 0, overBudget = 0, undrawn = 0;
  std::vector<double> frameMs;
  double seconds = 0, applySeconds = 0, workerCpu = 0;
  double totalSeconds = 0;  ///< to the worker's last publication (after the drain's wait)
  std::uint64_t modulesRemeshed = 0, batches = 0;
};

/// Frames at 60 Hz: frame n applies cratersAt(n) craters while n <
/// applyFrames, updates the pager, counts holes and polls the tracker;
/// then frames go on until every crater is drawn or `drainSeconds` pass.
Result<FrameRun> runFrames(Rig& rig, const paging::World& w, const EditsBenchOptions& o,
                           const std::function<std::uint32_t(std::uint64_t)>& cratersAt, std::uint64_t applyFrames,
                           double drainSeconds, Tracker& tracker) {
  FrameRun run;
  const edits::EditorStats s0 = rig.editor->stats();
  const auto t0 = Clock::now();
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kFrameSeconds));
  Clock::time_point applyEnd = t0;
  for (std::uint64_t n = 0;; ++n) {
    const auto f0 = Clock::now();
    if (n < applyFrames) {
      for (std::uint32_t c = cratersAt(n); c > 0; --c, ++run.craters) {
        if (Status st = applyCrater(rig, w, o, tracker, n); !st) return st.problems();
      }
      applyEnd = Clock::now();
    }
    rig.update();
    const std::uint64_t h = holes(*rig.pager);
    run.holes += h;
    run.holeFrames += h > 0;
    // The frame's own work ends here; the tracker is the benchmark's.
    const double ms = msSince(f0, Clock::now());
    run.frameMs.push_back(ms);
    run.overBudget += ms > 1e3 * kFrameSeconds;
    tracker.poll(*rig.editor->modules(), *rig.pager, n);
    run.frames = n + 1;
    if (n + 1 >= applyFrames && (tracker.open() == 0 || msSince(applyEnd, Clock::now()) > 1e3 * drainSeconds)) break;
    std::this_thread::sleep_until(t0 + period * std::int64_t(n + 1));
  }
  run.seconds = msSince(t0, Clock::now()) / 1e3;
  run.applySeconds = msSince(t0, applyEnd) / 1e3;
  run.undrawn = tracker.open();
  rig.editor->wait();  // what is left, so the next run starts idle
  for (int k = 0; k < 3 && tracker.open() > 0; ++k) {
    rig.update();
    rig.pager->waitIdle(10);
    tracker.poll(*rig.editor->modules(), *rig.pager, run.frames);
  }
  run.totalSeconds = msSince(t0, Clock::now()) / 1e3;
  const edits::EditorStats s1 = rig.editor->stats();
  run.workerCpu = s1.remeshSeconds - s0.remeshSeconds;
  run.modulesRemeshed = s1.modulesRemeshed - s0.modulesRemeshed;
  run.batches = s1.remeshes - s0.remeshes;
  return run;
}

nlohmann::json frameJson(const FrameRun& r, const Tracker& t) {
  return {{"craters", r.craters},
          {"frames", r.frames},
          {"seconds", r.seconds},
          {"apply_seconds", r.applySeconds},
          {"holes", r.holes},
          {"hole_frames", r.holeFrames},
          {"frames_over_budget", r.overBudget},
          {"frame_ms", spread(r.frameMs)},
          {"latency_frames", spread(t.drawnFrames())},
          {"published_ms", spread(t.publishedMs())},
          {"undrawn", r.undrawn},
          {"worker_cpu_s", r.workerCpu},
          {"worker_cpu_per_crater_ms", r.craters ? 1e3 * r.workerCpu / double(r.craters) : 0.0},
          {"modules_remeshed", r.modulesRemeshed},
          {"batches", r.batches}};
}

/// One crater at a time, the worker idle before each: polled every
/// quarter millisecond with a pager update each time.
Result<nlohmann::json> latency(Rig& rig, const paging::World& w, const EditsBenchOptions& o, const Notes& notes) {
  Tracker t;
  std::vector<double> worker;
  for (std::uint32_t k = 0; k < o.latencySamples; ++k) {
    rig.editor->wait();
    const double cpu0 = rig.editor->stats().remeshSeconds;
    if (Status st = applyCrater(rig, w, o, t, 0); !st) return st.problems();
    const auto t0 = Clock::now();
    while (t.open() > 0 && msSince(t0, Clock::now()) < 5000) {
      rig.update();
      t.poll(*rig.editor->modules(), *rig.pager, 0);
      std::this_thread::sleep_for(std::chrono::microseconds(250));
    }
    rig.editor->wait();
    worker.push_back(1e3 * (rig.editor->stats().remeshSeconds - cpu0));
  }
  std::vector<double> frames;
  for (double ms : t.drawnMs()) frames.push_back(std::ceil(ms / (1e3 * kFrameSeconds)));
  const nlohmann::json j = {{"samples", o.latencySamples},
                            {"drawn", t.drawnMs().size()},
                            {"modules_touched_mean", double(t.touched()) / double(o.latencySamples)},
                            {"worker_cpu_ms", spread(worker)},
                            {"published_ms", spread(t.publishedMs())},
                            {"drawn_ms", spread(t.drawnMs())},
                            {"drawn_frames_60hz", spread(frames)}};
  char line[200];
  std::snprintf(line, sizeof line, "latency: published %.1f ms, drawn (resident at level 0) %.1f ms median, max %.1f ms",
                j["published_ms"]["p50"].get<double>(), j["drawn_ms"]["p50"].get<double>(), j["drawn_ms"]["max"].get<double>());
  notes.say(line);
  return j;
}

Result<nlohmann::json> sustained(Rig& rig, const paging::World& w, const EditsBenchOptions& o, const Notes& notes,
                                 double& best) {
  nlohmann::json out = nlohmann::json::array();
  best = 0;
  std::vector<double> rates = o.rates;
  std::sort(rates.begin(), rates.end());
  for (double rate : rates) {
    Tracker t;
    const auto at = [rate](std::uint64_t n) {
      return std::uint32_t(std::floor(double(n + 1) * rate * kFrameSeconds) - std::floor(double(n) * rate * kFrameSeconds));
    };
    auto r = runFrames(rig, w, o, at, std::uint64_t(std::llround(o.sustainSeconds / kFrameSeconds)), 1.0, t);
    if (!r) return r.problems();
    nlohmann::json j = frameJson(r.value(), t);
    j["rate_per_s"] = rate;
    j["worker_busy"] = r->workerCpu / r->totalSeconds;
    // Keeps up: every crater drawn within a second of the last one applied.
    j["keeps_up"] = r->undrawn == 0;
    const bool clean = r->holes == 0 && r->overBudget == 0 && r->undrawn == 0;
    if (clean) best = std::max(best, rate);
    char line[240];
    std::snprintf(line, sizeof line,
                  "sustained %.0f craters/s: %llu craters, %llu holes, %llu frames over budget, latency p95 %.0f frames, "
                  "worker %.0f%% busy, %s",
                  rate, static_cast<unsigned long long>(r->craters), static_cast<unsigned long long>(r->holes),
                  static_cast<unsigned long long>(r->overBudget), j["latency_frames"]["p95"].get<double>(),
                  100 * j["worker_busy"].get<double>(), r->undrawn == 0 ? "keeps up" : "falls behind");
    notes.say(line);
    out.push_back(std::move(j));
  }
  return out;
}

Result<nlohmann::json> battle(Rig& rig, const paging::World& w, const EditsBenchOptions& o, const Notes& notes) {
  Tracker t;
  const std::uint64_t per = o.battlePerFrame, total = o.battleCraters;
  const auto at = [per, total](std::uint64_t n) { return std::uint32_t(std::min(per, total - std::min(total, n * per))); };
  const std::uint64_t frames = (total + per - 1) / per;
  auto r = runFrames(rig, w, o, at, frames, 600.0, t);
  if (!r) return r.problems();
  nlohmann::json j = frameJson(r.value(), t);
  j["per_frame"] = per;
  char line[240];
  std::snprintf(line, sizeof line,
                "battle: %llu craters applied in %.2f s, all drawn after %.2f s; %llu holes, %llu frames over budget, "
                "worker %.2f s CPU, %llu modules re-meshed in %llu batches",
                static_cast<unsigned long long>(r->craters), r->applySeconds, r->seconds,
                static_cast<unsigned long long>(r->holes), static_cast<unsigned long long>(r->overBudget), r->workerCpu,
                static_cast<unsigned long long>(r->modulesRemeshed), static_cast<unsigned long long>(r->batches));
  notes.say(line);
  return j;
}

}  // namespace

Status runLive(const std::shared_ptr<const paging::World>& world, const EditsBenchOptions& o, const Notes& notes,
               nlohmann::json& out) {
  auto rig = openRig(world, o);
  if (!rig) return rig.problems();
  Rig& r = *rig.value();
  out["pager"] = {{"view_distance_m", o.viewDistance}, {"loaders", 1}, {"window_modules", r.pager->window().count()}};
  auto lat = latency(r, *world, o, notes);
  if (!lat) return lat.problems();
  out["latency"] = lat.value();
  double best = 0;
  auto sus = sustained(r, *world, o, notes, best);
  if (!sus) return sus.problems();
  out["sustained"] = sus.value();
  out["max_sustained_rate_per_s"] = best;
  if (o.battleCraters > 0) {
    auto b = battle(r, *world, o, notes);
    if (!b) return b.problems();
    out["battle"] = b.value();
  }
  std::lock_guard lock(r.logMutex);
  out["pager"]["log"] = r.log;
  r.pager->stop();
  return {};
}

}  // namespace sandtable::bench::editsbench
