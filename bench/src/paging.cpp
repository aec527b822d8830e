// bench paging: real-time flights over a database, one per speed and mode,
// each from a cold cache. The predictive pager is measured against demand
// paging (no prediction), the seed's scheme and the NPSStealth mmap mode in
// the same run, modes interleaved so that drift on a shared machine hits
// them alike. Definitions (hole, degraded frame, mmap holes) and the
// measured figures: docs/PAGER.md §11.
#include "sandtable/bench/paging.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <thread>

#include "paging_plot.h"
#include "sandtable/base/stats.h"
#include "sandtable/formats/database.h"
#include "sandtable/paging/pager.h"
#include "sandtable/paging/remote.h"

namespace sandtable::bench {
namespace {

namespace fs = std::filesystem;
using paging::PagerMode;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

constexpr double kTickHz = 60.0;

// ------------------------------------------------------------------ path

/// A flight path in world metres that never comes back to a module it left:
/// a polyline whose X (or a circle whose angle) only increases.
class FlightPath {
 public:
  struct Point {
    double x = 0, z = 0, dx = 1, dz = 0;  ///< position and unit direction
  };

  static FlightPath polyline(std::vector<std::array<double, 2>> v) {
    FlightPath p;
    p.vertices_ = std::move(v);
    p.cumulative_.push_back(0);
    for (std::size_t i = 1; i < p.vertices_.size(); ++i) {
      const double d = std::hypot(p.vertices_[i][0] - p.vertices_[i - 1][0], p.vertices_[i][1] - p.vertices_[i - 1][1]);
      p.cumulative_.push_back(p.cumulative_.back() + d);
    }
    p.length_ = p.cumulative_.back();
    return p;
  }

  static FlightPath circle(double cx, double cz, double r, double length) {
    FlightPath p;
    p.circle_ = true;
    p.cx_ = cx;
    p.cz_ = cz;
    p.r_ = r;
    p.length_ = length;
    return p;
  }

  double length() const { return length_; }

  Point at(double s) const {
    s = std::clamp(s, 0.0, length_);
    if (circle_) {
      const double a = s / r_;
      return {cx_ + r_ * std::cos(a), cz_ + r_ * std::sin(a), -std::sin(a), std::cos(a)};
    }
    const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), s);
    const std::size_t i = std::min<std::size_t>(std::max<std::ptrdiff_t>(1, it - cumulative_.begin()),
                                                vertices_.size() - 1);
    const auto& a = vertices_[i - 1];
    const auto& b = vertices_[i];
    const double seg = cumulative_[i] - cumulative_[i - 1];
    const double f = seg > 0 ? (s - cumulative_[i - 1]) / seg : 0;
    return {a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), (b[0] - a[0]) / seg, (b[1] - a[1]) / seg};
  }

 private:
  bool circle_ = false;
  std::vector<std::array<double, 2>> vertices_;
  std::vector<double> cumulative_;
  double cx_ = 0, cz_ = 0, r_ = 1, length_ = 0;
};

/// The path inside [m, w - m] x [m, d - m]: straight along the diagonal,
/// a zigzag of 45-degree legs eastwards, one lap of the largest circle
/// short of its start module, or rows back and forth along X `rowGap`
/// apart.
Result<FlightPath> makePath(const std::string& kind, double w, double d, double m, double edge, double rowGap) {
  const double uw = w - 2 * m, ud = d - 2 * m;
  if (uw < 4 * edge || ud < 4 * edge) {
    char msg[400];
    std::snprintf(msg, sizeof msg,
                  "the database is %.0f x %.0f km, too small to fly at this view distance without leaving it "
                  "(a margin of %.1f km is kept on every side); build a larger one with `sandtable bench make-db "
                  "--size-km N` or lower PagingBenchOptions::viewDistance",
                  w / 1000, d / 1000, m / 1000);
    return Problem{"bench paging", 0, msg};
  }
  if (kind == "straight") return FlightPath::polyline({{m, m}, {w - m, d - m}});
  if (kind == "rows") {
    // Rows one active area apart: a row's window never reaches the modules
    // of the row before, so the path still never comes back to a module.
    std::vector<std::array<double, 2>> v;
    bool east = true;
    for (double z = m; z <= d - m; z += rowGap) {
      v.push_back({east ? m : w - m, z});
      v.push_back({east ? w - m : m, z});
      east = !east;
    }
    return FlightPath::polyline(std::move(v));
  }
  if (kind == "zigzag") {
    const double amp = std::min(ud, 50000.0);  // leg's Z extent
    const double z0 = d / 2 - amp / 2;
    std::vector<std::array<double, 2>> v{{m, z0}};
    bool up = false;
    while (v.back()[0] + amp <= w - m) {
      v.push_back({v.back()[0] + amp, up ? z0 : z0 + amp});
      up = !up;
    }
    if (v.size() < 2) return Problem{"bench paging", 0, "the database is too narrow for a zigzag; use PagingBenchOptions::path straight"};
    return FlightPath::polyline(std::move(v));
  }
  const double r = std::min(uw, ud) / 2;
  // Stop two modules short of the start so the lap never re-enters it.
  return FlightPath::circle(w / 2, d / 2, r, 2 * std::numbers::pi * r - 2 * edge);
}

// --------------------------------------------------------- speed profile

/// Constant speed, or (ramp) a geometric ramp from the first to the last
/// speed, so that every octave of speed gets the same time.
struct Profile {
  double v0 = 0, v1 = 0, duration = 0;  ///< m/s, m/s, s
  double speed(double t) const {
    if (v1 == v0 || duration <= 0) return v0;
    return v0 * std::pow(v1 / v0, std::clamp(t / duration, 0.0, 1.0));
  }
  double distance(double t) const {
    if (v1 == v0 || duration <= 0) return v0 * t;
    const double k = std::log(v1 / v0) / duration;
    return v0 * (std::exp(k * t) - 1) / k;
  }
};

Profile makeProfile(double v0, double v1, double wantSeconds, double length) {
  Profile p{v0, v1, wantSeconds};
  if (p.distance(wantSeconds) <= length) return p;
  if (v0 == v1) return {v0, v1, length / v0};
  // The ramp's duration T with distance(T) = length: v0 T (r - 1) / ln r.
  const double r = v1 / v0;
  return {v0, v1, length * std::log(r) / (v0 * (r - 1))};
}

// --------------------------------------------------------------- system

/// Drops every file of the database from the page cache. Pages mapped by
/// this process stay, so callers close the database first.
std::uint64_t dropCache(const std::string& dir) {
  std::uint64_t bytes = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const int fd = ::open(e.path().c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) continue;
    ::fdatasync(fd);
    ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
    bytes += e.file_size();
    ::close(fd);
  }
  return bytes;
}

/// Fraction of the database's pages in the page cache (mincore on a fresh
/// mapping): checks that dropCache worked.
double cachedFraction(const std::string& dir) {
  std::uint64_t pages = 0, resident = 0;
  const long page = ::sysconf(_SC_PAGESIZE);
  std::vector<unsigned char> vec;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file() || e.file_size() == 0) continue;
    const int fd = ::open(e.path().c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) continue;
    const std::size_t size = e.file_size();
    void* p = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, fd, 0);
    ::close(fd);
    if (p == MAP_FAILED) continue;
    vec.resize((size + page - 1) / page);
    if (::mincore(p, size, vec.data()) == 0) {
      pages += vec.size();
      for (unsigned char c : vec) resident += c & 1u;
    }
    ::munmap(p, size);
  }
  return pages ? double(resident) / double(pages) : 0;
}

/// A field of /proc/self/status in kB (VmRSS, VmHWM).
double statusMb(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string key = std::string(field) + ":";
  while (std::getline(in, line)) {
    if (line.rfind(key, 0) == 0) return std::stod(line.substr(key.size())) / 1024.0;
  }
  return 0;
}

/// Bytes this process caused to be read from storage (/proc/self/io).
std::uint64_t diskReadBytes() {
  std::ifstream in("/proc/self/io");
  std::string k;
  std::uint64_t v = 0;
  while (in >> k >> v) {
    if (k == "read_bytes:") return v;
  }
  return 0;
}

/// Resets VmHWM so each flight reports its own peak (Linux >= 4.0).
void resetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
}

// ----------------------------------------------------------------- holes

/// mmap mode has no modules: a needed module is a hole when any page of the
/// grid blocks under it is not in the page cache (a render would take a
/// major fault), checked with mincore on the database's own mapping.
class GridResidency {
 public:
  explicit GridResidency(const grid::GridFile& g, double moduleSize) : grid_(g) {
    postsPerModule_ = moduleSize / g.spacing();
  }

  bool resident(std::uint32_t kx, std::uint32_t kz) {
    const grid::Header& h = grid_.header();
    const double i0 = kx * postsPerModule_, j0 = kz * postsPerModule_;
    const auto bx0 = std::uint32_t(i0 / grid::kBlockPosts);
    const auto bz0 = std::uint32_t(j0 / grid::kBlockPosts);
    const auto bx1 = std::min<std::uint32_t>(h.blocksX - 1, std::uint32_t((i0 + postsPerModule_) / grid::kBlockPosts));
    const auto bz1 = std::min<std::uint32_t>(h.blocksZ - 1, std::uint32_t((j0 + postsPerModule_) / grid::kBlockPosts));
    for (std::uint32_t bz = bz0; bz <= bz1; ++bz) {
      for (std::uint32_t bx = bx0; bx <= bx1; ++bx) {
        if (!blockResident(bx, bz)) return false;
      }
    }
    return true;
  }

 private:
  bool blockResident(std::uint32_t bx, std::uint32_t bz) {
    const std::span<const std::byte> b = grid_.blockBytes(bx, bz);
    const auto page = std::uintptr_t(grid::kPageBytes);
    const auto start = reinterpret_cast<std::uintptr_t>(b.data()) & ~(page - 1);
    const auto end = reinterpret_cast<std::uintptr_t>(b.data() + b.size());
    vec_.resize((end - start + page - 1) / page);
    if (::mincore(reinterpret_cast<void*>(start), end - start, vec_.data()) != 0) return false;
    return std::all_of(vec_.begin(), vec_.end(), [](unsigned char c) { return (c & 1u) != 0; });
  }

  const grid::GridFile& grid_;
  double postsPerModule_ = 32;
  std::vector<unsigned char> vec_;
};

// ---------------------------------------------------------------- flight

/// Counts of one speed bin of one flight.
struct Bin {
  double speedKmh = 0;
  double seconds = 0;
  std::uint64_t frames = 0, holeFrames = 0, degradedFrames = 0, lookups = 0, holes = 0, degraded = 0;
};

struct FlightResult {
  std::vector<Bin> bins;  ///< one per speed (one for a constant-speed flight)
  double seconds = 0, initialFillSeconds = 0, cachedAfterDrop = 0;
  std::uint64_t lateTicks = 0;
  std::uint32_t maxLead = 0;      ///< most lead strips on one side, sampled at 10 Hz
  double maxEstimateMs = 0;       ///< highest latency estimate, sampled at 10 Hz
  paging::PagerMetrics before, after;
  std::uint64_t diskBytes = 0;
  double rssMb = 0, peakRssMb = 0;
};

/// A mode flown: a pager mode, and for "seed" the seed's scheme without
/// what goes beyond it (predictive with no lead strips, no work stealing).
struct ModeSpec {
  std::string name;
  PagerMode mode = PagerMode::predictive;
  bool lead = true;
};

struct Flight {
  ModeSpec mode;
  std::vector<double> speedsKmh;  ///< bins; one for a constant speed
  double seconds = 0;
};

paging::PagerOptions pagerOptions(const PagingBenchOptions& a, const ModeSpec& mode, const Notes& notes) {
  paging::PagerOptions o;
  o.mode = mode.mode;
  o.viewDistance = a.viewDistance;
  o.loaderThreads = a.loaders;
  o.maxLeadStrips = a.maxLeadStrips;
  o.lookAheadScale = mode.lead ? a.lookAhead : 0;
  o.workStealing = mode.lead;  // "seed": the seed's four independent loaders
  o.memoryBudgetBytes = std::uint64_t(a.budgetMb * 1024 * 1024);
  o.coarseFirst = a.coarseFirst;
  o.readaheadHints = a.readahead;
  o.log = [&notes](const std::string& m) { notes.say("pager: " + m); };
  return o;
}

class FlightRunner {
 public:
  FlightRunner(const PagingBenchOptions& a, const Database& db, const paging::Pager& pager) : pager_(pager) {
    const pack::IndexHeader& h = db.modules->header();
    edge_ = h.moduleSize;
    mx_ = h.modulesX;
    mz_ = h.modulesZ;
    levels_ = h.levels;
    need_.viewDistance = a.viewDistance;
    need_.halfAngleDeg = a.halfAngle;
    need_.pullback = db.grid->spacing();
    if (pager.options().mode == PagerMode::mmap) grid_.emplace(*db.grid, edge_);
  }

  /// Counts the holes and degraded modules of one frame at the eye.
  void frame(const FlightPath::Point& p, Bin& bin) {
    need_.eyeX = p.x;
    need_.eyeZ = p.z;
    need_.headingDeg = std::atan2(p.dx, -p.dz) * 180 / std::numbers::pi;
    paging::neededModules(need_, edge_, mx_, mz_, levels_, needed_);
    std::uint64_t holes = 0, degraded = 0;
    for (const paging::NeededModule& n : needed_) {
      if (grid_) {
        holes += grid_->resident(n.kx, n.kz) ? 0 : 1;
        continue;
      }
      const paging::ResidentRef r = pager_.resident(n.kx, n.kz, n.level);
      if (!r) ++holes;
      else if (r.finestLevel() > n.level) ++degraded;
    }
    ++bin.frames;
    bin.lookups += needed_.size();
    bin.holes += holes;
    bin.degraded += degraded;
    bin.holeFrames += holes ? 1 : 0;
    bin.degradedFrames += degraded ? 1 : 0;
  }

  /// Holes of a frame, without counting it (the running start).
  std::uint64_t holesAt(const FlightPath::Point& p) {
    Bin b;
    frame(p, b);
    return b.holes;
  }

 private:
  const paging::Pager& pager_;
  double edge_ = 1000;
  std::uint32_t mx_ = 0, mz_ = 0, levels_ = 1;
  paging::NeedParams need_;
  std::vector<paging::NeededModule> needed_;
  std::optional<GridResidency> grid_;
};

/// The viewer is put at the start, already moving at the first speed, and
/// the pager is given until it has the first view (and, predictive, the
/// whole window with its lead strips): a running start, so the flight
/// measures sustained paging, not the cold start of an empty area.
double runningStart(paging::Pager& pager, FlightRunner& runner, const FlightPath::Point& p0, double v) {
  const auto t0 = Clock::now();
  const double deadline = 60;
  for (;;) {
    pager.update(p0.x, p0.z, p0.dx * v, p0.dz * v, 0.0);
    const bool idle = pager.waitIdle(0.05);
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    if ((idle && runner.holesAt(p0) == 0) || s > deadline) return s;
    // mmap mode is idle at once: give its prefetcher the cores.
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

void sample(const paging::Pager& pager, FlightResult& out) {
  const paging::PagerMetrics m = pager.metrics();
  out.maxLead = std::max(out.maxLead, *std::max_element(m.leadStrips.begin(), m.leadStrips.end()));
  out.maxEstimateMs = std::max(out.maxEstimateMs, m.latencyEstimateSeconds * 1000);
}

Result<FlightResult> fly(const PagingBenchOptions& a, const Flight& f, const FlightPath& path, const Notes& notes) {
  FlightResult out;
  if (!a.warm && !paging::isRemote(a.database)) {  // a URL: the server's cache is the server's
    dropCache(a.database);
    out.cachedAfterDrop = cachedFraction(a.database);
  }
  auto dbr = paging::openDatabaseAt(a.database);
  if (!dbr) return dbr.problems();
  const Database db = std::move(dbr.value());
  auto pr = paging::Pager::open(db, pagerOptions(a, f.mode, notes));
  if (!pr) return pr.problems();
  paging::Pager& pager = *pr.value();
  FlightRunner runner(a, db, pager);

  const double v0 = f.speedsKmh.front() / 3.6, v1 = f.speedsKmh.back() / 3.6;
  const Profile prof = makeProfile(v0, v1, f.seconds, path.length());
  out.initialFillSeconds = runningStart(pager, runner, path.at(0), v0);
  pager.resetLatency();
  resetPeakRss();
  out.before = pager.metrics();
  const std::uint64_t disk0 = diskReadBytes();

  for (double s : f.speedsKmh) out.bins.push_back(Bin{s});
  const auto start = Clock::now();
  for (std::uint64_t k = 0;; ++k) {
    const auto due = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(double(k) / kTickHz));
    std::this_thread::sleep_until(due);
    const auto now = Clock::now();
    // The viewer is where real time puts it: a late tick skips ahead rather
    // than giving the loaders extra time.
    const double t = std::chrono::duration<double>(now - start).count();
    if (t > prof.duration) break;
    if (now - due > std::chrono::duration<double>(1 / kTickHz)) ++out.lateTicks;
    const double v = prof.speed(t);
    const FlightPath::Point p = path.at(prof.distance(t));
    pager.update(p.x, p.z, p.dx * v, p.dz * v, t);
    std::size_t b = 0;
    while (b + 1 < out.bins.size() && v * 3.6 >= out.bins[b + 1].speedKmh * (1 - 1e-9)) ++b;
    runner.frame(p, out.bins[b]);
    out.bins[b].seconds += 1 / kTickHz;
    if (k % 6 == 0) sample(pager, out);
  }
  out.seconds = prof.duration;
  out.after = pager.metrics();
  out.diskBytes = diskReadBytes() - disk0;
  out.rssMb = statusMb("VmRSS");
  out.peakRssMb = statusMb("VmHWM");
  pager.stop();
  return out;
}

// ---------------------------------------------------------------- stages

/// Where a load's time goes, one module at a time on this thread, from a
/// cold cache: pread of the record, unpack (CRCs + zstd), module::decode,
/// and the copy into reused storage that publishing does. Modules are taken
/// along the path, as a flight meets them.
json stageBreakdown(const PagingBenchOptions& a, const FlightPath& path, std::size_t want) {
  if (paging::isRemote(a.database)) return json::object();  // preads of a local pack
  if (!a.warm) dropCache(a.database);
  auto dbr = openDatabase(a.database);
  if (!dbr || !dbr->modules) return json::object();
  const pack::PackReader& pk = *dbr->modules;
  const pack::IndexHeader& h = pk.header();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> keys;
  for (double s = 0; s < path.length() && keys.size() < want; s += h.moduleSize / 2) {
    const FlightPath::Point p = path.at(s);
    const auto kx = std::uint32_t(p.x / h.moduleSize), kz = std::uint32_t(p.z / h.moduleSize);
    if (kx < h.modulesX && kz < h.modulesZ && (keys.empty() || keys.back() != std::make_pair(kx, kz))) {
      keys.emplace_back(kx, kz);
    }
  }
  double readNs = 0, unpackNs = 0, decodeNs = 0, copyNs = 0;
  std::uint64_t n = 0, compressed = 0, raw = 0;
  std::vector<std::byte> record;
  module::Module reuse;
  auto since = [](Clock::time_point t) { return double(std::chrono::nanoseconds(Clock::now() - t).count()); };
  // A v2 pack: both records of each module, one pread each (their times add up).
  const bool split = h.version >= pack::kVersion2 && h.coarseLevel > 0;
  std::uint64_t coarseCompressed = 0;
  module::Module part;
  for (const auto& [kx, kz] : keys) {
    const pack::Entry e = pk.entry(kx, kz);
    if (e.compressedBytes == 0) continue;
    bool ok = true;
    reuse.levels.resize(h.levels);
    for (const pack::Part which : {pack::Part::coarse, pack::Part::fine}) {
      if (which == pack::Part::fine && !split) break;
      const pack::Extent x = which == pack::Part::fine ? e.fine : e.coarse();
      record.resize(x.compressedBytes);
      auto t = Clock::now();
      if (::pread(pk.packFd(), record.data(), record.size(), off_t(x.offset)) != ssize_t(record.size())) {
        ok = false;
        break;
      }
      readNs += since(t);
      t = Clock::now();
      auto bytes = pk.unpack(kx, kz, record, which);
      unpackNs += since(t);
      if (!bytes) {
        ok = false;
        break;
      }
      t = Clock::now();
      auto m = module::decode(bytes.value(), pk.packPath());
      decodeNs += since(t);
      if (!m) {
        ok = false;
        break;
      }
      t = Clock::now();
      const std::size_t first = which == pack::Part::fine || !split ? 0 : h.coarseLevel;
      for (std::size_t l = 0; l < m->levels.size() && first + l < reuse.levels.size(); ++l) {
        module::Level& dst = reuse.levels[first + l];
        dst.vertices.assign(m->levels[l].vertices.begin(), m->levels[l].vertices.end());
        dst.indices.assign(m->levels[l].indices.begin(), m->levels[l].indices.end());
        dst.groups.assign(m->levels[l].groups.begin(), m->levels[l].groups.end());
        dst.maxHeight.assign(m->levels[l].maxHeight.begin(), m->levels[l].maxHeight.end());
      }
      copyNs += since(t);
    }
    if (!ok) continue;
    ++n;
    compressed += e.storedBytes();
    coarseCompressed += e.compressedBytes;
    raw += e.storedRawBytes();
  }
  if (n == 0) return json::object();
  const double dn = double(n), total = (readNs + unpackNs + decodeNs + copyNs) / dn;
  return {{"modules", n},
          {"cold_cache", !a.warm},
          {"pack_version", h.version},
          {"coarse_level", h.coarseLevel},
          {"compressed_kb_mean", double(compressed) / dn / 1024},
          {"coarse_record_kb_mean", double(coarseCompressed) / dn / 1024},
          {"raw_kb_mean", double(raw) / dn / 1024},
          {"pread_us", readNs / dn / 1000},
          {"unpack_us", unpackNs / dn / 1000},
          {"decode_us", decodeNs / dn / 1000},
          {"copy_us", copyNs / dn / 1000},
          {"total_us", total / 1000},
          {"modules_per_s_one_core", 1e9 / total}};
}

// --------------------------------------------------------------- results

json binJson(const Bin& b, const FlightResult& r, double share) {
  const paging::PagerMetrics& m0 = r.before;
  const paging::PagerMetrics& m1 = r.after;
  const double s = std::max(1e-9, r.seconds * share);
  const bool mmap = m1.mode == PagerMode::mmap;
  // Per-bin rates share the flight's totals by time (exact for one bin).
  const double modules = mmap ? double(m1.prefetchBlocks - m0.prefetchBlocks) : double(m1.loaded - m0.loaded);
  return {{"speed_kmh", b.speedKmh},
          {"seconds_flown", b.seconds},
          {"frames", b.frames},
          {"hole_frames", b.holeFrames},
          {"degraded_frames", b.degradedFrames},
          {"lookups", b.lookups},
          {"hole_lookups", b.holes},
          {"degraded_lookups", b.degraded},
          {"latency_ms", {{"p50", m1.latency.p50Ms}, {"p99", m1.latency.p99Ms}, {"max", m1.latency.maxMs},
                          {"count", m1.latency.count}}},
          {mmap ? "blocks_per_s" : "modules_per_s", modules * share / s},
          {"mb_per_s", double(m1.bytesRead - m0.bytesRead) * share / s / 1e6},
          {"disk_mb_per_s", double(r.diskBytes) * share / s / 1e6},
          {"rss_mb", r.rssMb},
          {"peak_rss_mb", r.peakRssMb},
          {"pool_mb", double(m1.poolBytes) / 1e6},
          {"late_ticks", r.lateTicks},
          {"initial_fill_s", r.initialFillSeconds},
          {"cached_after_drop", r.cachedAfterDrop},
          {"cancelled", (m1.cancelledQueued - m0.cancelledQueued) + (m1.cancelledInFlight - m0.cancelledInFlight)},
          {"max_queue_length", m1.maxQueueLength},
          {"lead_strips_max", r.maxLead},
          {"latency_estimate_max_ms", r.maxEstimateMs},
          {"loader_read_s", m1.readSeconds - m0.readSeconds},
          {"loader_publish_s", m1.publishSeconds - m0.publishSeconds},
          {"placeholders", m1.placeholders - m0.placeholders},
          {"stolen", m1.stolen - m0.stolen}};
}

/// The median over repeats of every numeric field, the runs kept.
json medianOf(const std::vector<json>& runs) {
  json out = runs.front();
  for (auto& [k, v] : out.items()) {
    if (v.is_number()) {
      std::vector<double> xs;
      for (const json& r : runs) xs.push_back(r[k].get<double>());
      v = stats::median(xs);
    } else if (v.is_object()) {
      for (auto& [k2, v2] : v.items()) {
        std::vector<double> xs;
        for (const json& r : runs) xs.push_back(r[k][k2].get<double>());
        v2 = stats::median(xs);
      }
    }
  }
  // A speed has zero holes only when every repeat had none.
  std::uint64_t worst = 0;
  for (const json& r : runs) worst = std::max(worst, r["hole_frames"].get<std::uint64_t>());
  out["hole_frames_worst"] = worst;
  out["runs"] = runs;
  return out;
}

/// The highest speed at which the median repeat had holes in under 1 % of
/// its frames: a finite comparison when a baseline is never hole-free.
double maxUnderOnePercent(const json& speeds) {
  double best = 0;
  for (const json& s : speeds) {
    const double frames = s["frames"].get<double>();
    if (frames > 0 && s["hole_frames"].get<double>() < 0.01 * frames) best = std::max(best, s["speed_kmh"].get<double>());
  }
  return best;
}

double maxZeroHoles(const json& speeds) {
  double best = 0;
  for (const json& s : speeds) {
    if (s["hole_frames_worst"].get<std::uint64_t>() == 0 && s["frames"].get<double>() > 0) {
      best = std::max(best, s["speed_kmh"].get<double>());
    }
  }
  return best;
}

/// predictive / baseline for both speed criteria; a baseline that met a
/// criterion at no speed gives a string, not a number.
json ratios(const json& modes) {
  json r = json::object();
  if (!modes.contains("predictive")) return r;
  for (const char* metric : {"max_speed_zero_holes_kmh", "max_speed_under_1pct_hole_frames_kmh"}) {
    const double p = modes["predictive"][metric].get<double>();
    for (const char* base : {"seed", "demand", "mmap"}) {
      if (!modes.contains(base)) continue;
      const double b = modes[base][metric].get<double>();
      const std::string key = std::string(metric) + " predictive/" + base;
      if (b > 0) {
        r[key] = p / b;
      } else {
        const double lowest = modes[base]["speeds"].front()["speed_kmh"].get<double>();
        char msg[200];
        std::snprintf(msg, sizeof msg, "> %.0f (%s met it at none of the speeds flown, down to %.0f km/h)",
                      p / lowest, base, lowest);
        r[key] = msg;
      }
    }
  }
  return r;
}

// -------------------------------------------------------------------- run

std::optional<ModeSpec> modeOf(const std::string& s) {
  if (s == "predictive") return ModeSpec{s, PagerMode::predictive, true};
  if (s == "seed") return ModeSpec{s, PagerMode::predictive, false};
  if (s == "demand") return ModeSpec{s, PagerMode::demand, true};
  if (s == "mmap") return ModeSpec{s, PagerMode::mmap, true};
  return std::nullopt;
}

/// "" or what is wrong; sorts and deduplicates the speeds.
std::string checkOptions(PagingBenchOptions& a, const Database& db) {
  if (!db.modules) return a.database + " has no load modules; build one with `sandtable bench make-db`";
  if (a.speedsKmh.empty()) return "PagingBenchOptions::speedsKmh needs at least one speed";
  for (double s : a.speedsKmh) {
    if (!(s > 0) || !std::isfinite(s)) return "PagingBenchOptions::speedsKmh: every speed must be > 0 km/h";
  }
  std::sort(a.speedsKmh.begin(), a.speedsKmh.end());
  a.speedsKmh.erase(std::unique(a.speedsKmh.begin(), a.speedsKmh.end()), a.speedsKmh.end());
  for (const std::string& m : a.modes) {
    if (!modeOf(m)) return "PagingBenchOptions::modes: unknown mode '" + m + "' (predictive, seed, demand, mmap)";
  }
  for (const std::string& plot : a.plots) {
    const std::string ext = fs::path(plot).extension().string();
    if (ext != ".png" && ext != ".svg") {
      return "PagingBenchOptions::plots " + plot + ": the file must end in .png or .svg";
    }
  }
  return "";
}

std::vector<Flight> flightsOf(const PagingBenchOptions& a) {
  std::vector<Flight> flights;
  for (const std::string& m : a.modes) {
    if (a.ramp) flights.push_back({*modeOf(m), a.speedsKmh, a.seconds * double(a.speedsKmh.size())});
    else for (double s : a.speedsKmh) flights.push_back({*modeOf(m), {s}, a.seconds});
  }
  return flights;
}

/// runs[mode][speed] = one json per repeat
using Runs = std::map<std::string, std::map<double, std::vector<json>>>;

std::string binNote(std::size_t done, std::size_t total, const Flight& f, const Bin& b, const FlightResult& r) {
  char line[300];
  std::snprintf(line, sizeof line, "[%zu/%zu] %-10s %8.0f km/h  %5.2f s  %4llu/%llu hole frames, %llu degraded%s",
                done, total, f.mode.name.c_str(), b.speedKmh, b.seconds,
                static_cast<unsigned long long>(b.holeFrames), static_cast<unsigned long long>(b.frames),
                static_cast<unsigned long long>(b.degradedFrames),
                r.cachedAfterDrop > 0.01 ? "  (warning: cache not dropped)" : "");
  return line;
}

Result<Runs> flyAll(const PagingBenchOptions& a, const std::vector<Flight>& flights, const FlightPath& path,
                    const Notes& notes) {
  Runs runs;
  const std::size_t total = flights.size() * std::size_t(a.repeat);
  std::size_t done = 0;
  for (int rep = 0; rep < a.repeat; ++rep) {
    // Speeds outer, modes inner: the modes of one speed run back to back.
    std::vector<std::size_t> order(flights.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
      return flights[x].speedsKmh.front() < flights[y].speedsKmh.front();
    });
    for (std::size_t i : order) {
      const Flight& f = flights[i];
      auto r = fly(a, f, path, notes);
      if (!r) return r.problems();
      ++done;
      for (const Bin& b : r->bins) {
        const double share = r->seconds > 0 ? b.seconds / r->seconds : 0;
        runs[f.mode.name][b.speedKmh].push_back(binJson(b, r.value(), std::min(1.0, share)));
        notes.say(binNote(done, total, f, b, r.value()));
      }
    }
  }
  return runs;
}

json modesJson(const Runs& runs) {
  json modes = json::object();
  for (const auto& [mode, bySpeed] : runs) {
    json speeds = json::array();
    for (const auto& [speed, rs] : bySpeed) speeds.push_back(medianOf(rs));
    modes[mode] = {{"speeds", speeds},
                   {"max_speed_zero_holes_kmh", maxZeroHoles(speeds)},
                   {"max_speed_under_1pct_hole_frames_kmh", maxUnderOnePercent(speeds)}};
  }
  return modes;
}

json reportJson(const PagingBenchOptions& a, const pack::IndexHeader& h, const FlightPath& path, const json& modes) {
  json j = {{"database", a.database},
            {"modules", {{"x", h.modulesX}, {"z", h.modulesZ}, {"edge_m", h.moduleSize}, {"levels", h.levels}}},
            {"view_distance_m", a.viewDistance},
            {"half_angle_deg", a.halfAngle},
            {"path", a.path},
            {"path_length_km", path.length() / 1000},
            {"ramp", a.ramp},
            {"repeat", a.repeat},
            {"seconds_per_speed", a.seconds},
            {"tick_hz", kTickHz},
            {"cold_cache", !a.warm},
            {"loaders", a.loaders},
            {"max_lead_strips", a.maxLeadStrips},
            {"look_ahead_scale", a.lookAhead},
            {"coarse_first", a.coarseFirst},
            {"readahead", a.readahead},
            {"pack_version", h.version},
            {"pack_coarse_level", h.coarseLevel},
            {"pack_order", h.version >= pack::kVersion2 ? (h.order == pack::PackOrder::morton ? "morton" : "row-major")
                                                         : "append (v1)"},
            {"cpus", std::thread::hardware_concurrency()},
            {"modes", modes}};
  j["ratios"] = ratios(modes);
  return j;
}

std::string writePlots(const PagingBenchOptions& a, const json& modes) {
  for (const std::string& plot : a.plots) {
    char title[160];
    std::snprintf(title, sizeof title, "bench paging: %s path, vd %.0f km, %s", a.path.c_str(), a.viewDistance / 1000,
                  a.warm ? "warm" : "cold cache");
    if (const std::string err = writePlot(plot, modes, title); !err.empty()) return err;
  }
  return "";
}

}  // namespace

Result<PagingBenchReport> runPagingBench(const PagingBenchOptions& options, const Notes& notes) {
  PagingBenchOptions a = options;
  pack::IndexHeader h;
  {
    auto db = paging::openDatabaseAt(a.database);  // a URL too (paging/remote.h)
    if (!db) return db.problems();
    if (const std::string err = checkOptions(a, db.value()); !err.empty()) return Problem{"", 0, err};
    h = db->modules->header();
  }  // closed: a mapped grid would keep its pages in the cache
  const double w = h.modulesX * h.moduleSize, d = h.modulesZ * h.moduleSize;
  const double margin = a.viewDistance + (a.maxLeadStrips + 2) * h.moduleSize;
  // Rows: the active area's side (2R + 1 modules, R = ceil((vd + h) / e),
  // docs/PAGER.md section 1) plus one module.
  const double rowGap = (2 * std::ceil((a.viewDistance + 100) / h.moduleSize) + 2) * h.moduleSize;
  auto path = makePath(a.path, w, d, margin, h.moduleSize, rowGap);
  if (!path) return path.problems();

  const json stages = stageBreakdown(a, path.value(), 400);
  auto runs = flyAll(a, flightsOf(a), path.value(), notes);
  if (!runs) return runs.problems();
  const json modes = modesJson(runs.value());
  PagingBenchReport report;
  for (const auto& [mode, m] : modes.items()) {
    report.maxSpeedZeroHolesKmh[mode] = m["max_speed_zero_holes_kmh"].get<double>();
  }
  report.json = reportJson(a, h, path.value(), modes);
  report.json["stages"] = stages;
  if (const std::string err = writePlots(a, modes); !err.empty()) {
    return Problem{"", 0, "PagingBenchOptions::plots: " + err};
  }
  return report;
}

}  // namespace sandtable::bench
