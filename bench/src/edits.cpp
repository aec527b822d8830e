// bench edits: what a crater costs, from apply() to the ground drawn
// (issue 37's benchmark). This half: the database, the re-mesh cases
// against the builder's path, the journal replay and memory; the live runs
// with a pager are edits_live.cpp.
#include "sandtable/bench/edits.h"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

#include "edits_internal.h"
#include "sandtable/base/hash.h"
#include "sandtable/base/stats.h"
#include "sandtable/bench/make_db.h"
#include "sandtable/converters/culture.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/edits/editor.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/formats/pack.h"
#include "sandtable/meshing/assemble.h"

namespace sandtable::bench {
namespace editsbench {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

edit::Edit crater(double x, double z, edits::CraterSize size, std::uint64_t id, double time) {
  edit::Edit e;
  e.kind = edit::Kind::crater;
  e.id = id;
  e.time = time;
  e.origin = 1;
  e.points = {{x, z}};
  e.radius = size.radius;
  e.depth = size.depth;
  return e;
}

std::array<double, 2> site(const paging::World& w, std::uint64_t seed, std::uint64_t k) {
  const grid::HeightField& h = *w.heights();
  const double margin = 20, width = (h.postsX() - 1) * h.spacing(), depth = (h.postsZ() - 1) * h.spacing();
  const double u = hash::unit(hash::mix(seed * 0x9e3779b97f4a7c15ull + 2 * k));
  const double v = hash::unit(hash::mix(seed * 0x9e3779b97f4a7c15ull + 2 * k + 1));
  return {margin + u * (width - 2 * margin), margin + v * (depth - 2 * margin)};
}

nlohmann::json spread(const std::vector<double>& v) {
  if (v.empty()) return {{"p50", 0.0}, {"p95", 0.0}, {"max", 0.0}};
  return {{"p50", stats::median(v)}, {"p95", stats::percentile(v, 0.95)}, {"max", *std::max_element(v.begin(), v.end())}};
}

double threadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

std::uint64_t rssBytes() {
  std::ifstream f("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  f >> size >> resident;
  return resident * std::uint64_t(::sysconf(_SC_PAGESIZE));
}

namespace {

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The database and what the baseline builds with.
struct Setup {
  std::shared_ptr<const paging::World> world;
  std::shared_ptr<const convert::Culture> culture;  ///< null: the baseline skins with the plain triangles
  std::uint16_t skirtMaterial = 0;
  std::string baseline;  ///< in words, for the report
};

Status checkOptions(const EditsBenchOptions& o) {
  const auto bad = [](const char* what) { return Problem{"", 0, std::string("bench edits: ") + what}; };
  if (o.database.empty() && !(o.sizeKm >= 3 && o.sizeKm <= 100)) return bad("EditsBenchOptions::sizeKm must be 3..100");
  if (o.repeat < 1 || o.repeat > 101) return bad("EditsBenchOptions::repeat must be 1..101");
  if (o.journalEdits < 1 || o.journalEdits > 10000000) return bad("EditsBenchOptions::journalEdits must be 1..10000000");
  if (o.memoryCraters < 1 || o.memoryCraters > 1000000) return bad("EditsBenchOptions::memoryCraters must be 1..1000000");
  if (o.latencySamples < 1 || o.latencySamples > 10000) return bad("EditsBenchOptions::latencySamples must be 1..10000");
  for (double r : o.rates) {
    if (!(r > 0)) return bad("EditsBenchOptions::rates must each be > 0");
  }
  if (!(o.sustainSeconds >= 0.1 && o.sustainSeconds <= 600)) return bad("EditsBenchOptions::sustainSeconds must be 0.1..600");
  if (o.battlePerFrame < 1) return bad("EditsBenchOptions::battlePerFrame must be >= 1");
  if (!(o.viewDistance >= 500 && o.viewDistance <= 100000)) return bad("EditsBenchOptions::viewDistance must be 500..100000");
  return {};
}

/// The culture the database was built with (its manifest's sources), with
/// one module partition cached: each baseline module computes its own, as
/// the build does once per module.
std::shared_ptr<const convert::Culture> buildCulture(const paging::World& w, std::string& why) {
  const auto& build = w.manifest().build;
  if (!w.materials() || !build.contains("culture") || !build["culture"].contains("sources")) {
    why = "no culture in the manifest";
    return nullptr;
  }
  convert::CultureOptions co;
  for (const auto& s : build["culture"]["sources"]) {
    if (!fs::exists(s.get<std::string>())) {
      why = "culture source " + s.get<std::string>() + " is gone";
      return nullptr;
    }
    co.sources.push_back(s.get<std::string>());
  }
  co.cacheModules = 1;
  const auto& m = w.manifest();
  const convert::CultureFrame frame{m.crsWkt, m.originEasting, m.originNorthing, m.spacing * (m.postsX - 1),
                                    m.spacing * (m.postsZ - 1)};
  auto c = convert::Culture::load(co, *w.materials(), frame);
  if (!c) {
    why = c.error();
    return nullptr;
  }
  return c.value();
}

Result<Setup> openSetup(const EditsBenchOptions& o, const fs::path& work, const Notes& notes, nlohmann::json& out) {
  std::string dir = o.database;
  out["synthesized"] = dir.empty();
  if (dir.empty()) {
    notes.say("synthesizing a " + std::to_string(int(o.sizeKm)) + " km square with roads (not timed)");
    MakeDbOptions mo;
    mo.output = (work / "db").string();
    mo.sizeKm = o.sizeKm;
    mo.seed = o.seed;
    mo.keepInputs = true;  // the baseline's culture
    auto r = makeBenchDatabase(mo, {});
    if (!r) return r.problems();
    dir = mo.output;
  }
  auto w = paging::World::open(dir);
  if (!w) return w.problems();
  Setup s;
  s.world = w.value();
  const auto& mods = s.world->modules();
  if (!mods) return Problem{"bench edits", 0, dir + ": the database has no load modules"};
  const pack::IndexHeader& hd = mods->header();
  if (hd.modulesX < 2 || hd.modulesZ < 2) return Problem{"bench edits", 0, dir + ": needs at least 2 x 2 modules"};
  std::string why;
  s.culture = buildCulture(*s.world, why);
  s.skirtMaterial = s.world->materials() ? s.world->materials()->defaultArea : 0;
  s.baseline = s.culture ? "assembleModule + the build's culture decals + pack compression"
                         : "assembleModule + plain triangles + pack compression (" + why + ")";
  out["database"] = dir;
  out["spacing_m"] = s.world->heights()->spacing();
  out["module_size_m"] = hd.moduleSize;
  out["modules"] = std::uint64_t(hd.modulesX) * hd.modulesZ;
  out["levels"] = hd.levels;
  out["baseline"] = s.baseline;
  return s;
}

// ------------------------------------------------------------- re-mesh

struct Case {
  const char* name;
  std::size_t modules;  ///< expected
  double x, z;
  bool jitterX, jitterZ;
};

/// Inside a square mid-module, on a module edge, on a module corner, round
/// the middle module corner of the database.
std::vector<Case> cases(const paging::World& w) {
  const pack::IndexHeader& hd = w.modules()->header();
  const double s = w.heights()->spacing(), edge = hd.moduleSize;
  const double kx = hd.modulesX / 2, kz = hd.modulesZ / 2, mid = (hd.moduleSquares / 2 + 0.5) * s;
  return {{"1 module", 1, kx * edge + mid, kz * edge + mid, true, true},
          {"2 modules", 2, kx * edge, kz * edge + mid, false, true},
          {"4 modules", 4, kx * edge, kz * edge, true, true}};
}

/// The baseline: the modules built as `sandtable build` builds them
/// (converters' buildModule: assembleModule with the culture's decals),
/// over the edited posts, then compressed for the pack.
class Builder {
 public:
  Builder(const Setup& s, const fs::path& work) : s_(s) {
    const pack::IndexHeader& hd = s.world->modules()->header();
    pack::PackLayout layout = pack::PackLayout::split(hd.levels);
    layout.encode = {.version = module::kNewestVersion, .heightStep = convert::kBuildHeightStep};
    pack::IndexHeader h;
    h.modulesX = hd.modulesX, h.modulesZ = hd.modulesZ, h.levels = hd.levels;
    h.moduleSquares = hd.moduleSquares, h.moduleSize = hd.moduleSize;
    fs::create_directories(work / "baseline");
    auto wr = pack::PackWriter::create((work / "baseline").string(), h, 9, layout);
    if (wr) writer_ = std::move(wr.value());
  }

  /// Builds one module; false when the pack writer refused it.
  bool build(const grid::HeightField& heights, paging::ModuleKey k) const {
    const pack::IndexHeader& hd = s_.world->modules()->header();
    const module::Module m = meshing::assembleModule(
        heights, hd.moduleSquares, int(hd.levels), k.kx, k.kz, s_.skirtMaterial,
        [&](int, const meshing::LevelLattice& lat, module::Level& out) {
          if (s_.culture) s_.culture->decalLevel(lat, out);
          else meshing::plainSkin(lat, s_.skirtMaterial, out);
          return true;
        });
    return writer_ && writer_->compress(m).ok();
  }

 private:
  const Setup& s_;
  std::unique_ptr<pack::PackWriter> writer_;
};

std::vector<std::pair<std::uint32_t, std::uint32_t>> squaresOf(const edits::HeightsChange& c) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  for (const auto& s : c.squares) out.emplace_back(s.i, s.j);
  return out;
}

struct CaseRuns {
  std::vector<double> cpu, wall, baseCpu, baseWall;
  double coldMs = 0;
  std::size_t modules = 0;
  std::uint64_t triangles0 = 0, refined = 0;
};

Status runCase(const Setup& s, const Builder& builder, const Case& c, int repeat, CaseRuns& runs) {
  const paging::World& w = *s.world;
  auto heights = std::make_shared<edits::EditedHeights>(w.heights());
  edits::EditedModules mods(w.modules(), w.heights(), heights);
  const paging::ModuleKey spare{0, 0};  // evicts the culture's cached partition between repeats
  for (int r = -1; r < repeat; ++r) {
    // A different crater each run (the same modules): centre moved by up to 1 m.
    const double dx = c.jitterX ? 0.5 * ((r + 5) % 5 - 2) : 0, dz = c.jitterZ ? 0.37 * ((r + 7) % 7 - 3) : 0;
    heights->reset();
    auto change = heights->apply(crater(c.x + dx, c.z + dz, edits::kCraterMedium, 1, 0));
    if (!change) return change.problems();
    const auto squares = squaresOf(change.value());
    const auto t0 = Clock::now();
    auto rep = mods.remesh(change->posts, squares);
    const double wall = seconds(t0);
    if (!rep) return rep.problems();
    if (r < 0) {  // cold: the base modules read and decoded
      runs.coldMs = 1e3 * wall;
      runs.modules = rep->modules.size();
      runs.triangles0 = rep->triangles.empty() ? 0 : rep->triangles[0];
      runs.refined = rep->refinedSquares;
      continue;
    }
    runs.cpu.push_back(1e3 * rep->seconds);
    runs.wall.push_back(1e3 * wall);
    builder.build(*heights, spare);  // not timed
    const double c0 = threadCpuSeconds();
    const auto b0 = Clock::now();
    for (const paging::ModuleKey& k : rep->modules) {
      if (!builder.build(*heights, k)) return Problem{"", 0, "bench edits: the baseline's pack writer refused a module"};
    }
    runs.baseWall.push_back(1e3 * seconds(b0));
    runs.baseCpu.push_back(1e3 * (threadCpuSeconds() - c0));
  }
  return {};
}

Result<nlohmann::json> remeshCases(const Setup& s, const fs::path& work, const EditsBenchOptions& o, const Notes& notes) {
  const Builder builder(s, work);
  nlohmann::json out = nlohmann::json::array();
  for (const Case& c : cases(*s.world)) {
    CaseRuns runs;
    if (Status st = runCase(s, builder, c, o.repeat, runs); !st) return st.problems();
    const double cpu = stats::median(runs.cpu), base = stats::median(runs.baseCpu);
    char line[200];
    std::snprintf(line, sizeof line, "re-mesh %s: %.2f ms CPU (%zu modules), build baseline %.2f ms (%.1fx)", c.name, cpu,
                  runs.modules, base, base / cpu);
    notes.say(line);
    out.push_back({{"case", c.name},
                   {"modules", runs.modules},
                   {"crater", {{"radius_m", edits::kCraterMedium.radius}, {"depth_m", edits::kCraterMedium.depth}}},
                   {"cold_ms", runs.coldMs},
                   {"cpu_ms", cpu},
                   {"wall_ms", stats::median(runs.wall)},
                   {"cpu_runs_ms", runs.cpu},
                   {"baseline_cpu_ms", base},
                   {"baseline_wall_ms", stats::median(runs.baseWall)},
                   {"baseline_over_remesh", base / cpu},
                   {"triangles_level0", runs.triangles0},
                   {"refined_squares", runs.refined}});
  }
  return out;
}

// ------------------------------------------------------------- journal

Status writeJournal(const paging::World& w, const std::string& path, std::uint64_t edits, std::uint64_t seed) {
  std::error_code ec;
  fs::remove(path, ec);
  journal::WriterOptions wo;
  wo.batchRecords = 8192;
  wo.batchDelay = std::chrono::hours(1);
  auto jw = journal::JournalWriter::open(path, wo);
  if (!jw) return jw.problems();
  for (std::uint64_t k = 0; k < edits; ++k) {
    const auto p = site(w, seed ^ 0x10, k);
    if (Status st = jw.value()->append(crater(p[0], p[1], edits::kCraterSmall, k + 1, 0.01 * double(k))); !st) return st;
  }
  return jw.value()->close();
}

/// Seconds of Editor::open replaying `path`.
Result<double> timeReplay(const Setup& s, const std::string& path, bool mesh, edits::EditorStats* stats) {
  edits::EditorOptions eo;
  eo.journal = path;
  eo.readOnly = true;
  eo.meshModules = mesh;
  eo.background = false;
  const auto t0 = Clock::now();
  auto ed = edits::Editor::open(s.world, eo);
  const double t = seconds(t0);
  if (!ed) return ed.problems();
  if (stats) *stats = ed.value()->stats();
  return t;
}

Result<nlohmann::json> journalReplay(const Setup& s, const fs::path& work, const EditsBenchOptions& o, const Notes& notes) {
  const std::string path = (work / "replay.journal").string();
  notes.say("writing a journal of " + std::to_string(o.journalEdits) + " small craters (not timed)");
  if (Status st = writeJournal(*s.world, path, o.journalEdits, o.seed); !st) return st.problems();
  const auto t0 = Clock::now();
  auto j = journal::readJournal(path);
  const double read = seconds(t0);
  if (!j) return j.problems();
  std::vector<double> runs;
  for (int r = 0; r < std::min(o.repeat, 3); ++r) {
    auto t = timeReplay(s, path, false, nullptr);
    if (!t) return t.problems();
    runs.push_back(t.value());
  }
  const double replay = stats::median(runs), per100k = replay * 1e5 / double(o.journalEdits);
  char line[200];
  std::snprintf(line, sizeof line, "journal: %llu edits replayed (heights) in %.3f s, %.3f s per 100,000",
                static_cast<unsigned long long>(o.journalEdits), replay, per100k);
  notes.say(line);
  nlohmann::json out = {{"edits", o.journalEdits},      {"crater", {{"radius_m", edits::kCraterSmall.radius}, {"depth_m", edits::kCraterSmall.depth}}},
                        {"file_bytes", fs::file_size(path)}, {"read_s", read},
                        {"replay_s", replay},           {"replay_runs_s", runs},
                        {"replay_per_100k_s", per100k}};
  if (o.journalMeshedEdits > 0) {
    const std::string meshed = (work / "replay-meshed.journal").string();
    if (Status st = writeJournal(*s.world, meshed, o.journalMeshedEdits, o.seed); !st) return st.problems();
    edits::EditorStats es;
    auto t = timeReplay(s, meshed, true, &es);
    if (!t) return t.problems();
    const double m100k = t.value() * 1e5 / double(o.journalMeshedEdits);
    std::snprintf(line, sizeof line, "journal: %llu edits replayed with modules re-meshed in %.3f s, %.1f s per 100,000",
                  static_cast<unsigned long long>(o.journalMeshedEdits), t.value(), m100k);
    notes.say(line);
    out["meshed"] = {{"edits", o.journalMeshedEdits},
                     {"replay_s", t.value()},
                     {"per_100k_s", m100k},
                     {"modules_remeshed", es.modulesRemeshed},
                     {"remesh_batches", es.remeshes},
                     {"remesh_cpu_s", es.remeshSeconds}};
  }
  return out;
}

// -------------------------------------------------------------- memory

std::uint64_t moduleBytes(const module::Module& m) {
  std::uint64_t n = m.objects.size() * sizeof(module::Object);
  for (const module::Level& l : m.levels) {
    n += l.vertices.size() * sizeof(module::Vertex) + l.indices.size() * 4 + l.groups.size() * sizeof(module::Group) +
         (l.maxHeight.size() + l.normals.size() + l.objectY.size()) * 4;
  }
  return n;
}

Result<nlohmann::json> memory(const Setup& s, const EditsBenchOptions& o, const Notes& notes) {
  const std::uint64_t rss0 = rssBytes();
  edits::EditorOptions eo;
  eo.background = false;
  auto ed = edits::Editor::open(s.world, eo);
  if (!ed) return ed.problems();
  for (std::uint32_t k = 0; k < o.memoryCraters; ++k) {
    const auto p = site(*s.world, o.seed ^ 0x20, k);
    auto a = ed.value()->apply(crater(p[0], p[1], edits::kCraterMedium, k + 1, double(k)));
    if (!a) return a.problems();
  }
  const std::uint64_t rss1 = rssBytes();
  const edits::EditorStats st = ed.value()->stats();
  const auto& mods = *ed.value()->modules();
  std::uint64_t moduleTotal = 0, remeshed = 0;
  module::Module m;
  for (std::uint32_t kz = 0; kz < mods.header().modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < mods.header().modulesX; ++kx) {
      if (mods.generation(kx, kz) == 0) continue;
      if (auto r = mods.read(kx, kz, m); !r) return r.problems();
      moduleTotal += moduleBytes(m);
      ++remeshed;
    }
  }
  const double per = 1000.0 / double(o.memoryCraters);
  const auto rssDelta = std::int64_t(rss1) - std::int64_t(rss0);
  char line[200];
  std::snprintf(line, sizeof line, "memory: %u medium craters hold %.1f MB of heights, %.1f MB of re-meshed modules; RSS +%.1f MB",
                o.memoryCraters, double(st.heights.bytes) / 1e6, double(moduleTotal) / 1e6, double(rssDelta) / 1e6);
  notes.say(line);
  return nlohmann::json{{"craters", o.memoryCraters},
                        {"heights_bytes", st.heights.bytes},
                        {"refined_squares", st.heights.refinedSquares},
                        {"remeshed_module_bytes", moduleTotal},
                        {"modules_remeshed", remeshed},
                        {"rss_delta_bytes", rssDelta},
                        {"per_1000",
                         {{"heights_bytes", double(st.heights.bytes) * per},
                          {"remeshed_module_bytes", double(moduleTotal) * per},
                          {"rss_delta_bytes", double(rssDelta) * per}}}};
}

// --------------------------------------------------------------- goals

nlohmann::json goal(double value, double limit, const char* unit) {
  return {{"value", value}, {"goal", limit}, {"unit", unit}, {"met", value <= limit}};
}

nlohmann::json goals(const nlohmann::json& j) {
  nlohmann::json g = nlohmann::json::object();
  for (const auto& c : j["remesh"]) {
    if (c["modules"] == 4) g["worker_ms_per_crater_4_modules"] = goal(c["cpu_ms"].get<double>(), 5, "ms");
  }
  g["journal_replay_per_100k"] = goal(j["journal"]["replay_per_100k_s"].get<double>(), 2, "s");
  g["drawn_frames_max"] = goal(j["latency"]["drawn_frames_60hz"]["max"].get<double>(), 2, "frames");
  if (j.contains("battle")) {
    const auto& b = j["battle"];
    g["battle_holes"] = goal(b["holes"].get<double>(), 0, "holes");
    g["battle_frames_over_budget"] = goal(b["frames_over_budget"].get<double>(), 0, "frames");
    g["battle_craters"] = {{"value", b["craters"]}, {"goal", 10000}, {"met", b["craters"].get<double>() >= 10000}};
  }
  return g;
}

Result<EditsBenchReport> runIn(const EditsBenchOptions& o, const Notes& notes, const fs::path& work) {
  nlohmann::json j = {{"repeat", o.repeat}, {"cpus", std::thread::hardware_concurrency()}};
  auto s = openSetup(o, work, notes, j);
  if (!s) return s.problems();
  auto remesh = remeshCases(s.value(), work, o, notes);
  if (!remesh) return remesh.problems();
  j["remesh"] = remesh.value();
  auto journal = journalReplay(s.value(), work, o, notes);
  if (!journal) return journal.problems();
  j["journal"] = journal.value();
  auto mem = memory(s.value(), o, notes);
  if (!mem) return mem.problems();
  j["memory"] = mem.value();
  if (Status st = runLive(s->world, o, notes, j); !st) return st.problems();
  j["goals"] = goals(j);
  EditsBenchReport rep;
  rep.json = std::move(j);
  return rep;
}

}  // namespace
}  // namespace editsbench

Result<EditsBenchReport> runEditsBench(const EditsBenchOptions& options, const Notes& notes) {
  if (Status st = editsbench::checkOptions(options); !st) return st.problems();
  namespace fs = std::filesystem;
  const fs::path work = fs::temp_directory_path() / ("sandtable-bench-edits-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::create_directories(work, ec);
  auto r = editsbench::runIn(options, notes, work);
  if (!options.keep) fs::remove_all(work, ec);
  return r;
}

}  // namespace sandtable::bench
