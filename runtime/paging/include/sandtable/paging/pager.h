#pragma once
// Predictive paging of load modules (seed chapter V.H, Figures 28-31), with
// a demand-paging baseline and the NPSStealth memory-mapped mode. Design,
// threads, memory-ordering contract and formulas: docs/PAGER.md.
//
// Terms. A load module (kx, kz) covers world X in [kx, kx + 1) * edge and Z
// in [kz, kz + 1) * edge (edge = pack::IndexHeader::moduleSize; X east, Z
// south of the database's north-west corner post). The *centre module* is
// the module the viewer is paged around. The *active area* is the square of
// 2R + 1 modules centred on it, R = ceil((viewDistance + hysteresis) / edge):
// the seed's "two times the view distance plus two load modules", rounded
// to whole modules and made odd so that the circle of radius viewDistance
// round the eye stays inside wherever the eye is in the bounding box. The
// *bounding box* is the centre module grown by the hysteresis on every side
// (Figure 30); only leaving it moves the centre, so going back and forth
// across a module edge inside the margin pages nothing. The *window* is the
// active area plus the lead strips ahead of the viewer (prediction), clipped
// to the database: exactly the modules that should be resident.
//
// Threads (predictive mode). update() runs on the main thread: it moves the
// window and hands each changed strip to the loader thread of its direction
// (north, east, south, west; seed: four loader processes), which reads the
// new strip in and frees the strip on the opposite side (Figure 31). A jump
// refills the whole window, nearest modules first, spread over all loaders.
// Any number of reader threads (render, simulation) call resident() at any
// time: it takes no lock and never waits. Modules come from a ModuleSource
// (module_source.h; the pack is PackSource); a module whose generation
// there moves on is reloaded while the older one stays readable.
//
// Thread safety of Pager: update() and stop() from one thread (the main
// thread) only; resident(), metrics(), waitIdle() and the const accessors
// from any thread. A ResidentRef must be released (destroyed) before its
// thread calls waitIdle() or stop(), and should be held no longer than one
// frame: a loader that wants to reuse its slot waits for it. StripPlanner
// and the free functions are plain values/pure functions.
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "sandtable/formats/database.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/pack.h"
#include "sandtable/base/result.h"
#include "sandtable/paging/module_source.h"

namespace sandtable::paging {

class World;

// ------------------------------------------------------------ strip logic

/// Cardinal directions; north is -Z. Also the index of each loader thread.
enum class Direction : std::uint8_t { north = 0, east = 1, south = 2, west = 3 };
inline constexpr std::size_t kDirections = 4;
/// "north", "east", "south", "west".
const char* directionName(Direction d);

/// Half-open rectangle of module indices [x0, x1) x [z0, z1); may lie
/// partly or wholly outside the database until clipped.
struct ModuleRect {
  std::int64_t x0 = 0, z0 = 0, x1 = 0, z1 = 0;
  bool empty() const { return x1 <= x0 || z1 <= z0; }
  std::int64_t width() const { return empty() ? 0 : x1 - x0; }
  std::int64_t height() const { return empty() ? 0 : z1 - z0; }
  std::int64_t count() const { return width() * height(); }
  bool contains(std::int64_t kx, std::int64_t kz) const {
    return kx >= x0 && kx < x1 && kz >= z0 && kz < z1;
  }
  ModuleRect intersect(const ModuleRect& o) const;
  /// Clipped to a database of modulesX x modulesZ modules.
  ModuleRect clipped(std::uint32_t modulesX, std::uint32_t modulesZ) const;
  bool operator==(const ModuleRect&) const = default;
};

/// A rectangle in world metres, [x0, x1] x [z0, z1].
struct MetreBox {
  double x0 = 0, z0 = 0, x1 = 0, z1 = 0;
  bool contains(double x, double z) const { return x >= x0 && x <= x1 && z >= z0 && z <= z1; }
};

/// What the strip logic needs to know about the database and the view.
struct PagingGeometry {
  double moduleSize = 1000;         ///< edge of a load module, metres
  std::uint32_t modulesX = 0;       ///< modules across the database
  std::uint32_t modulesZ = 0;
  double viewDistance = 6000;       ///< metres, now (StripPlanner::setViewDistance)
  /// The most viewDistance may grow to; the residency ring is sized for it.
  /// 0: viewDistance.
  double maxViewDistance = 0;
  double hysteresis = 100;          ///< bounding-box margin, metres (seed: 100 m)
  std::uint32_t maxLeadStrips = 3;  ///< most strips loaded ahead on one axis

  /// R: modules on each side of the centre module, ceil((vd + h) / edge).
  std::int64_t radius() const;
  /// Side of the active area in modules, 2R + 1.
  std::int64_t side() const { return 2 * radius() + 1; }
  /// R and the side at maxViewDistance.
  std::int64_t maxRadius() const;
  std::int64_t maxSide() const { return 2 * maxRadius() + 1; }
  /// Slots of the residency ring along X and Z: the widest window
  /// (side + maxLeadStrips of lead on one side + as many guard strips on
  /// the other), but no more than the database.
  std::uint32_t ringX() const;
  std::uint32_t ringZ() const;
};

/// One loader's work for one update: modules to read (nearest first) and
/// modules to free (the strip on the opposite side).
struct StripJob {
  std::vector<ModuleKey> load;
  std::vector<ModuleKey> free;
  bool signalled() const { return !load.empty() || !free.empty(); }
};

/// The result of one StripPlanner::update.
struct PlanStep {
  bool changed = false;  ///< the window changed: some job is signalled
  bool refill = false;   ///< a jump: the window is refilled, jobs dealt round robin
  bool crossed = false;  ///< the viewer left the bounding box
  ModuleRect before;     ///< window before (clipped)
  ModuleRect after;      ///< window after (clipped)
  /// Indexed by Direction. On a strip move, load holds the new modules
  /// beyond the old window on that side and free the old modules beyond the
  /// new window on the opposite side. On a refill every module of the new
  /// window that was not in the old one is dealt round robin, nearest first.
  std::array<StripJob, kDirections> jobs;
};

/// The seed's bounding-box strip logic plus speed-scaled lead strips, as a
/// pure state machine (no threads, no I/O). Steady-state updates allocate
/// nothing (the job vectors keep their capacity).
///
/// Lead strips: on each axis the side the viewer moves towards gets
/// n = min(maxLeadStrips, ceil(speed * leadSeconds / edge)) extra strips.
/// They grow as soon as the speed asks for more (in the current direction
/// of travel), but shrink or switch sides only when the viewer leaves the
/// bounding box, so speed jitter and back-and-forth motion inside the
/// margin never page.
class StripPlanner {
 public:
  explicit StripPlanner(const PagingGeometry& g);

  /// Advances to the eye at (eyeX, eyeZ) moving at (vx, vz) m/s, with the
  /// loaders' lead time. The first call (and any jump that keeps less than
  /// half of the window) is a refill.
  ///
  /// `guardSeconds` (the time to the next update) adds a guard on every
  /// side: g = min(maxLeadStrips, ceil((speed * guardSeconds - hysteresis) /
  /// edge)) strips, 0 below the hysteresis. The window moves only at
  /// updates, and within one the eye may turn anywhere, so the view must be
  /// resident up to one update's travel beyond the active area on every
  /// side, not only ahead. A side's extent is the larger of its lead and
  /// the guard; the guard follows the lead's rule (exact at a box crossing,
  /// only growing inside the box).
  const PlanStep& update(double eyeX, double eyeZ, double vx, double vz, double leadSeconds,
                         double guardSeconds = 0);

  /// Grows or shrinks the active area from the next update on; clamped to
  /// (0, maxViewDistance]. The next update() loads the new ring nearest
  /// first (or frees the outer one) like any other window change.
  void setViewDistance(double metres);

  const PagingGeometry& geometry() const { return geometry_; }
  bool started() const { return started_; }
  std::int64_t centreX() const { return cx_; }
  std::int64_t centreZ() const { return cz_; }
  /// Lead strips on each side, indexed by Direction.
  const std::array<std::uint32_t, kDirections>& lead() const { return lead_; }
  /// Guard strips on every side (update()'s guardSeconds).
  std::uint32_t guard() const { return guard_; }
  /// The window, clipped to the database.
  const ModuleRect& window() const { return window_; }
  /// The active area (no lead), clipped.
  ModuleRect activeArea() const;
  /// The bounding box of the centre module, metres.
  MetreBox boundingBox() const;

 private:
  PagingGeometry geometry_;
  bool started_ = false;
  std::int64_t cx_ = 0, cz_ = 0;
  std::array<std::uint32_t, kDirections> lead_{};
  std::uint32_t guard_ = 0;
  ModuleRect window_;
  PlanStep step_;
};

// -------------------------------------------------------------- needed set

/// What a view needs: seed Figure 76's view triangle and Table 8's range
/// bins.
struct NeedParams {
  double eyeX = 0, eyeZ = 0;    ///< world metres
  double headingDeg = 0;        ///< clockwise from north (-Z)
  double halfAngleDeg = 30;     ///< half the horizontal ground angle, (0, 89]
  double viewDistance = 6000;   ///< metres
  double pullback = 0;          ///< apex pulled back this far (one post spacing)
  /// Outer edge of the range bin of each level, finest first (seed Table 8:
  /// 1500, 3000, 4500, 6000). Empty: equal bins, level l out to
  /// viewDistance * (l + 1) / levels.
  std::vector<double> ringEdges;
};

/// One module the view needs, and the finest level it needs.
struct NeededModule {
  std::uint32_t kx = 0, kz = 0;
  std::uint32_t level = 0;  ///< 0 = finest
  double distance = 0;      ///< metres from the eye to the module's nearest point
};

/// Level for a distance: the first range bin that reaches it (coarsest
/// beyond the last bin).
std::uint32_t levelForDistance(double distance, double viewDistance, std::uint32_t levels,
                               std::span<const double> ringEdges = {});

/// The modules under the view triangle (no growth) whose nearest point is
/// within viewDistance (the triangle's far corners reach beyond the fog),
/// each with the level of the range bin of that nearest point, row by row
/// north to south. `out` is cleared and reused.
void neededModules(const NeedParams& p, double moduleSize, std::uint32_t modulesX,
                   std::uint32_t modulesZ, std::uint32_t levels, std::vector<NeededModule>& out);
std::vector<NeededModule> neededModules(const NeedParams& p, double moduleSize,
                                        std::uint32_t modulesX, std::uint32_t modulesZ,
                                        std::uint32_t levels);

// ------------------------------------------------------------------ pager

struct ResidentModule;

enum class PagerMode {
  predictive,  ///< four directional loaders, lead strips, the seed's scheme
  demand,      ///< baseline: a module is read when resident() misses it
  mmap,        ///< NPSStealth: a prefetch thread touches the mapped grid
};
const char* modeName(PagerMode m);

struct PagerOptions {
  PagerMode mode = PagerMode::predictive;
  double viewDistance = 6000;  ///< metres, at open (Pager::setViewDistance changes it)
  /// The most Pager::setViewDistance may grow to (the ring of slots is sized
  /// for it); 0: viewDistance, fixed.
  double maxViewDistance = 0;
  double hysteresis = 100;     ///< bounding-box margin, metres (0 <= h < edge / 2)
  /// Pool of decoded modules; reads that would exceed it are refused.
  std::uint64_t memoryBudgetBytes = 1ull << 30;
  /// Loader threads, 1..4. Predictive: loader d % n serves direction d.
  /// Demand: faults are spread over them.
  std::uint32_t loaderThreads = 4;
  /// Lead time = lookAheadScale * the loaders' latency estimate; 0 turns
  /// the lead strips off (predictive) or the leading edge (mmap).
  double lookAheadScale = 2.0;
  std::uint32_t maxLeadStrips = 3;
  /// Predictive: a loader with nothing of its own to do takes the nearest
  /// pending module of the busiest loader, so a fast viewer's leading strips
  /// are read by every loader rather than by one (beyond the seed).
  bool workStealing = true;
  /// Predictive and demand, with a source that splits modules (pack v2,
  /// ModuleSource::coarseLevel() > 0): a load reads and publishes only the
  /// coarse levels, and the fine levels follow as a separate, lower
  /// priority job: a loader takes every pending coarse load, nearest first,
  /// before any fine one (docs/PAGER.md, section 5). false: one read of the
  /// whole module, as for a v1 pack.
  bool coarseFirst = true;
  /// Before a loader starts on the loads it has just taken from its queue
  /// (a strip), it tells the source which records it will read
  /// (ModuleSource::willNeed: posix_fadvise WILLNEED for the pack), coarse
  /// and fine, so the disk works ahead of the reads.
  bool readaheadHints = true;
  /// Latency estimate before the first measurement, seconds.
  double initialLatencySeconds = 0.05;
  /// Reserve every slot at open for the largest module of the pack (as far
  /// as the budget allows), so steady state never grows the pool.
  bool preallocate = true;
  /// Added to every module read (a slow disk or NFS, for tests and benchmarks).
  double simulatedReadSeconds = 0;
  /// Module edge for mmap mode when there is no pack, metres.
  double mmapModuleSize = 1000;
  /// mmap mode: sleep while the viewer covers this fraction of a grid
  /// block, clamped to [minSleepSeconds, maxSleepSeconds].
  double prefetchSleepBlocks = 0.25;
  double minSleepSeconds = 0.005;
  double maxSleepSeconds = 0.25;
  /// Where problems are logged (once per module or kind); null: stderr.
  std::function<void(const std::string&)> log;
  /// Called on a loader thread after a module's coarse level is published
  /// (tests, tracing): loader index, module, placeholder. Keep it quick.
  std::function<void(std::uint32_t, ModuleKey, bool)> onResident;
  /// The worker phase of a load (docs/PAGER.md, section 4): called on a
  /// loader thread, holding the slot, once level `level` of `m` is written
  /// and before it is published, coarsest level first (every coarser level
  /// is written; finer ones are not). It may (re)make m.prepared[level];
  /// with level 0 every level is written, so it may also add to the
  /// coarser levels' prepared data what needs them all, in members that a
  /// reader holding a ResidentRef with finestLevel() > 0 does not read.
  /// The viewer installs the renderer's CPU meshing here (render's
  /// moduleLevelPreparer), so the render thread only copies to the GPU.
  /// It delays the level's publication by its own time. Null: nothing is
  /// prepared and ResidentModule::prepared stays empty.
  std::function<void(ResidentModule& m, std::uint32_t level)> prepareLevel;
};

/// What PagerOptions::prepareLevel derives from a level on the loader
/// thread: plain CPU data (the renderer's vertex arrays, say) of a type the
/// hook's owner defines. Paging never looks inside; it keeps one per level
/// of each slot, reused (with its capacity) from load to load.
struct LevelExtra {
  virtual ~LevelExtra() = default;
};

/// A module as readers see it: the decoded levels, finest first. Only the
/// levels from ResidentRef::finestLevel() on are valid for a reference.
struct ResidentModule {
  std::uint32_t kx = 0, kz = 0;
  bool placeholder = false;  ///< a coarse stand-in from the grid (missing, corrupt, or no budget)
  std::uint64_t generation = 0;  ///< the source's generation of these levels (ModuleSource)
  std::vector<module::Level> levels;
  /// Static objects (module version 5): each resident level's objectY has
  /// one elevation per object; none on a placeholder. Not counted in the
  /// memory budget (a few tens of bytes each).
  std::vector<module::Object> objects;
  /// Per level, what PagerOptions::prepareLevel made of it (sized like
  /// `levels` with a hook, else empty; null until the hook makes one).
  /// Valid for the same levels as `levels`. Not counted in the budget.
  std::vector<std::unique_ptr<LevelExtra>> prepared;
};

/// A read guard on one resident module: while it lives, the module's
/// storage is not reused. Move-only; empty when the module was not
/// resident. Taking and releasing one is wait-free.
class ResidentRef {
 public:
  ResidentRef() = default;
  ~ResidentRef() { release(); }
  ResidentRef(ResidentRef&& o) noexcept { *this = std::move(o); }
  ResidentRef& operator=(ResidentRef&& o) noexcept;
  ResidentRef(const ResidentRef&) = delete;
  ResidentRef& operator=(const ResidentRef&) = delete;

  explicit operator bool() const { return readers_ != nullptr; }
  const ResidentModule& module() const { return *module_; }
  /// The level chosen: max(wanted level, finest resident level).
  std::uint32_t levelIndex() const { return level_; }
  /// Finest level resident when the guard was taken.
  std::uint32_t finestLevel() const { return finest_; }
  /// The chosen level is coarser than the one asked for.
  bool coarser() const { return coarser_; }
  bool placeholder() const { return module_->placeholder; }
  /// Changes each time the slot receives a module, or a newer generation
  /// of its module (cache key for GPU data).
  std::uint64_t generation() const { return generation_; }
  const module::Level& level() const { return module_->levels[level_]; }
  /// Any level from finestLevel() to the coarsest (asserted).
  const module::Level& level(std::uint32_t l) const;
  void release();

 private:
  friend class Pager;
  std::atomic<std::uint32_t>* readers_ = nullptr;
  const ResidentModule* module_ = nullptr;
  std::uint32_t level_ = 0, finest_ = 0;
  bool coarser_ = false;
  std::uint64_t generation_ = 0;
};

/// Latency from request to resident (coarse level published).
struct LatencyStats {
  std::uint64_t count = 0;
  double meanMs = 0, p50Ms = 0, p90Ms = 0, p99Ms = 0, maxMs = 0;  ///< p: bucket upper edges
};

/// The pager's event counters since open. T is std::uint64_t in
/// PagerMetrics and std::atomic<std::uint64_t> inside the pager, so the
/// list is written once and a snapshot is one loop over fields().
template <typename T>
struct PagerCountersOf {
  T updates{};
  T boxCrossings{};  ///< the viewer left the bounding box
  T refills{};       ///< jumps (and the first update)
  T requested{};     ///< loads queued (or demand faults taken)
  T loaded{};        ///< real modules published
  T freed{};         ///< modules freed: opposite strips, or slots reused for new ones
  T duplicates{};    ///< requests for a module already resident (and of its source's generation)
  T cancelledQueued{};    ///< left the window before the read began
  T cancelledInFlight{};  ///< left the window during the read
  T placeholders{};       ///< placeholder publications
  T missingModules{};     ///< distinct modules with no record
  T corruptModules{};     ///< distinct modules that failed to read or decode
  T budgetRefusals{};     ///< modules not resident (placeholder) for the budget
  T budgetTrimmedLevels{};///< fine levels left out for the budget
  T reclaimedBytes{};     ///< storage given back by empty slots under budget pressure
  T bytesRead{};     ///< bytes read from the module source (compressed, for the pack)
  T readerWaits{};   ///< loader waited for readers to leave a slot
  T queueOverflows{};
  T residentQueries{};
  T residentMisses{};  ///< queries for a database module not resident
  T demandFaults{};
  T stolen{};  ///< modules loaded by a loader other than their direction's
  T reloaded{};  ///< resident modules replaced by a newer generation from the source
  T fineLoaded{};   ///< coarse-first: fine records read and published after the coarse ones
  T fineFailed{};   ///< coarse-first: fine records that failed to read (the coarse levels stay)
  T readaheadHints{};  ///< willNeed calls made (one per strip taken from a queue)
  // mmap mode
  T prefetchPasses{};
  T prefetchBlocks{};
  T prefetchPages{};
  T prefetchMajorFaults{};  ///< faults taken by the prefetch thread
  T prefetchMinorFaults{};

  /// Every counter above, in order (pager.cpp static_asserts that none is
  /// left out).
  auto fields() {
    return std::tie(updates, boxCrossings, refills, requested, loaded, freed, duplicates, cancelledQueued,
                    cancelledInFlight, placeholders, missingModules, corruptModules, budgetRefusals,
                    budgetTrimmedLevels, reclaimedBytes, bytesRead, readerWaits, queueOverflows, residentQueries,
                    residentMisses, demandFaults, stolen, reloaded, fineLoaded, fineFailed, readaheadHints, prefetchPasses, prefetchBlocks, prefetchPages,
                    prefetchMajorFaults, prefetchMinorFaults);
  }
  auto fields() const { return const_cast<PagerCountersOf&>(*this).fields(); }
};
using PagerCounters = PagerCountersOf<std::uint64_t>;

/// Counters since open and the pager's state now. Taken without stopping
/// anything: a snapshot of independent counters, each exact, not mutually
/// consistent.
struct PagerMetrics : PagerCounters {
  PagerMode mode = PagerMode::predictive;
  std::array<std::uint64_t, kDirections> stripSignals{};  ///< strip moves per direction
  std::array<std::uint64_t, kDirections> loadsByLoader{}; ///< modules published per loader
  std::array<std::uint32_t, 4> queueLength{};  ///< per loader, now (queued + pending)
  std::uint32_t maxQueueLength = 0;            ///< largest seen
  LatencyStats latency;       ///< every publication (mmap mode: prefetch passes)
  LatencyStats stripLatency;  ///< strips and demand faults only (refills left out)
  std::uint32_t slots = 0;
  std::uint32_t windowModules = 0;  ///< modules in the window now
  std::uint32_t residentInWindow = 0;
  std::uint32_t holesInWindow = 0;  ///< window modules not resident now (0 in mmap mode)
  std::uint64_t poolBytes = 0;      ///< capacity of every slot's vectors
  std::uint64_t poolBudgetBytes = 0;
  double latencyEstimateSeconds = 0;  ///< running estimate (mean + 4 deviations)
  double leadSeconds = 0;
  std::array<std::uint32_t, kDirections> leadStrips{};
  double elapsedSeconds = 0;
  double modulesPerSecond = 0;
  /// Loader time summed over loaders: in the source's read (for the pack:
  /// pread, CRC, zstd, decode) and in copying into the slot and publishing.
  double readSeconds = 0;
  double publishSeconds = 0;
  double lastPassSeconds = 0;  ///< mmap mode
  double lastSleepSeconds = 0;
};

class Pager {
 public:
  /// Opens a pager on a grid and (except in mmap mode) a module source,
  /// and starts its threads. Fails ("pager options: ..." / "pager: ...") on
  /// bad options, no source, or when the slots' placeholder storage alone
  /// exceeds the budget. Placeholders use material 0.
  static Result<std::unique_ptr<Pager>> open(std::shared_ptr<const grid::GridFile> grid,
                                             std::shared_ptr<const ModuleSource> source,
                                             const PagerOptions& options);
  /// The pack as the source (PackSource).
  static Result<std::unique_ptr<Pager>> open(std::shared_ptr<const grid::GridFile> grid,
                                             std::shared_ptr<const pack::PackReader> pack,
                                             const PagerOptions& options);
  /// No modules: mmap mode only.
  static Result<std::unique_ptr<Pager>> open(std::shared_ptr<const grid::GridFile> grid, std::nullptr_t,
                                             const PagerOptions& options);
  /// The database's pack, placeholders in its default area material.
  static Result<std::unique_ptr<Pager>> open(const Database& db, const PagerOptions& options);
  /// The world's module source (world.h), placeholders in its default
  /// area material: opens nothing.
  static Result<std::unique_ptr<Pager>> open(const World& world, const PagerOptions& options);
  static Result<std::unique_ptr<Pager>> open(const std::string& directory,
                                             const PagerOptions& options);
  ~Pager();
  Pager(const Pager&) = delete;
  Pager& operator=(const Pager&) = delete;

  /// The main thread, every tick: the eye (world metres), its velocity
  /// (m/s) and the time (seconds, any origin). Never blocks; allocates
  /// nothing in steady state.
  void update(double eyeX, double eyeZ, double velocityX, double velocityZ, double timeNow);
  /// Lock-free, wait-free read of module (kx, kz) at `wantLevel` or the
  /// finest coarser level resident. Empty when not resident (or outside the
  /// database). In demand mode a miss inside the window also requests the
  /// module (a page fault that does not wait).
  ResidentRef resident(std::uint32_t kx, std::uint32_t kz, std::uint32_t wantLevel = 0) const;
  PagerMetrics metrics() const;
  /// Empties both latency histograms (a benchmark's warm-up is left out of
  /// its percentiles). Any thread; a publication racing with it may land
  /// on either side.
  void resetLatency();
  /// Waits until every queued load and fault is done; false on timeout.
  bool waitIdle(double timeoutSeconds) const;
  /// Stops and joins the threads; queued loads are dropped. Idempotent.
  void stop();

  const PagerOptions& options() const;
  const PagingGeometry& geometry() const;
  /// Levels per module (1 in mmap mode without a pack).
  std::uint32_t levels() const;
  /// The window as the loaders see it now (clipped).
  ModuleRect window() const;
  /// Main thread (as update()): the view distance the window follows from
  /// the next update() on, clamped to (0, PagerOptions::maxViewDistance].
  /// Returns the distance taken.
  double setViewDistance(double metres);
  double viewDistance() const;
  /// Distance from (eyeX, eyeZ) to the nearest module of the current
  /// window, within viewDistance(), that is not resident; viewDistance()
  /// when every one is. Drawing no further than this shows no hole, so a
  /// viewer that grows its view distance grows the drawn one with it.
  /// Any thread; reads the slot words only.
  double residentDistance(double eyeX, double eyeZ) const;

  struct Impl;

 private:
  static Result<std::unique_ptr<Pager>> openWith(std::shared_ptr<const grid::GridFile> grid,
                                                 std::shared_ptr<const ModuleSource> source,
                                                 const PagerOptions& options,
                                                 std::uint16_t placeholderMaterial);
  explicit Pager(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sandtable::paging
