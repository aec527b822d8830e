// sandtable bench paging: real-time flights over a database, one per speed
// and mode, each from a cold cache. The predictive pager is measured
// against demand paging (no prediction) and the NPSStealth mmap mode in the
// same run, modes interleaved so that drift on a shared machine hits all
// three alike. Definitions (hole, degraded frame, mmap holes) and the
// measured figures: docs/PAGER.md §11.
#include "bench_paging.h"

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
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "db_util.h"
#include "sandtable/render/hud.h"
#include "sandtable/render/image.h"
#include "sandtable/paging/pager.h"

namespace sandtable::cli {
namespace {

namespace fs = std::filesystem;
using runtime::PagerMode;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

constexpr double kTickHz = 60.0;

struct Args {
  std::string db;
  double viewDistance = 10000;
  std::vector<double> speedsKmh = {2000, 5000, 10000, 20000, 50000, 100000, 200000, 300000};
  bool ramp = false;
  std::string path = "straight";
  bool json = false;
  std::vector<std::string> plots;
  double seconds = 8;
  int repeat = 3;
  std::vector<std::string> modes = {"predictive", "seed", "demand", "mmap"};
  std::uint32_t loaders = 4;
  std::uint32_t maxLeadStrips = 16;
  double lookAhead = 2;
  double halfAngle = 35;
  double budgetMb = 2048;
  bool warm = false;
};

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
/// a zigzag of 45-degree legs eastwards, or one lap of the largest circle
/// short of its start module.
Result<FlightPath> makePath(const std::string& kind, double w, double d, double m, double edge) {
  const double uw = w - 2 * m, ud = d - 2 * m;
  if (uw < 4 * edge || ud < 4 * edge) {
    char msg[400];
    std::snprintf(msg, sizeof msg,
                  "the database is %.0f x %.0f km, too small to fly at this view distance without leaving it "
                  "(a margin of %.1f km is kept on every side); build a larger one with `sandtable bench make-db "
                  "--size-km N` or lower --view-distance",
                  w / 1000, d / 1000, m / 1000);
    return Problem{"bench paging", 0, msg};
  }
  if (kind == "straight") return FlightPath::polyline({{m, m}, {w - m, d - m}});
  if (kind == "zigzag") {
    const double amp = std::min(ud, 50000.0);  // leg's Z extent
    const double z0 = d / 2 - amp / 2;
    std::vector<std::array<double, 2>> v{{m, z0}};
    bool up = false;
    while (v.back()[0] + amp <= w - m) {
      v.push_back({v.back()[0] + amp, up ? z0 : z0 + amp});
      up = !up;
    }
    if (v.size() < 2) return Problem{"bench paging", 0, "the database is too narrow for a zigzag; use --path straight"};
    return FlightPath::polyline(std::move(v));
  }
  const double r = std::min(uw, ud) / 2;
  // Stop two modules short of the start so the lap never re-enters it.
  return FlightPath::circle(w / 2, d / 2, r, 2 * std::numbers::pi * r - 2 * edge);
}

// --------------------------------------------------------- speed profile

/// Constant speed, or (--ramp) a geometric ramp from the first to the last
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

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
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
  runtime::PagerMetrics before, after;
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

runtime::PagerOptions pagerOptions(const Args& a, const ModeSpec& mode) {
  runtime::PagerOptions o;
  o.mode = mode.mode;
  o.viewDistance = a.viewDistance;
  o.loaderThreads = a.loaders;
  o.maxLeadStrips = a.maxLeadStrips;
  o.lookAheadScale = mode.lead ? a.lookAhead : 0;
  o.workStealing = mode.lead;  // "seed": the seed's four independent loaders
  o.memoryBudgetBytes = std::uint64_t(a.budgetMb * 1024 * 1024);
  o.log = [](const std::string& m) { std::fprintf(stderr, "bench paging: pager: %s\n", m.c_str()); };
  return o;
}

class FlightRunner {
 public:
  FlightRunner(const Args& a, const Database& db, const runtime::Pager& pager) : pager_(pager) {
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
    runtime::neededModules(need_, edge_, mx_, mz_, levels_, needed_);
    std::uint64_t holes = 0, degraded = 0;
    for (const runtime::NeededModule& n : needed_) {
      if (grid_) {
        holes += grid_->resident(n.kx, n.kz) ? 0 : 1;
        continue;
      }
      const runtime::ResidentRef r = pager_.resident(n.kx, n.kz, n.level);
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
  const runtime::Pager& pager_;
  double edge_ = 1000;
  std::uint32_t mx_ = 0, mz_ = 0, levels_ = 1;
  runtime::NeedParams need_;
  std::vector<runtime::NeededModule> needed_;
  std::optional<GridResidency> grid_;
};

/// The viewer is put at the start, already moving at the first speed, and
/// the pager is given until it has the first view (and, predictive, the
/// whole window with its lead strips): a running start, so the flight
/// measures sustained paging, not the cold start of an empty area.
double runningStart(runtime::Pager& pager, FlightRunner& runner, const FlightPath::Point& p0, double v) {
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

void sample(const runtime::Pager& pager, FlightResult& out) {
  const runtime::PagerMetrics m = pager.metrics();
  out.maxLead = std::max(out.maxLead, *std::max_element(m.leadStrips.begin(), m.leadStrips.end()));
  out.maxEstimateMs = std::max(out.maxEstimateMs, m.latencyEstimateSeconds * 1000);
}

Result<FlightResult> fly(const Args& a, const Flight& f, const FlightPath& path) {
  FlightResult out;
  if (!a.warm) {
    dropCache(a.db);
    out.cachedAfterDrop = cachedFraction(a.db);
  }
  auto dbr = openDatabase(a.db);
  if (!dbr) return dbr.problems();
  const Database db = std::move(dbr.value());
  auto pr = runtime::Pager::open(db, pagerOptions(a, f.mode));
  if (!pr) return pr.problems();
  runtime::Pager& pager = *pr.value();
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
json stageBreakdown(const Args& a, const FlightPath& path, std::size_t want) {
  if (!a.warm) dropCache(a.db);
  auto dbr = openDatabase(a.db);
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
  for (const auto& [kx, kz] : keys) {
    const pack::Entry e = pk.entry(kx, kz);
    if (e.compressedBytes == 0) continue;
    record.resize(e.compressedBytes);
    auto t = Clock::now();
    if (::pread(pk.packFd(), record.data(), record.size(), off_t(e.offset)) != ssize_t(record.size())) continue;
    readNs += since(t);
    t = Clock::now();
    auto bytes = pk.unpack(kx, kz, record);
    unpackNs += since(t);
    if (!bytes) continue;
    t = Clock::now();
    auto m = module::decode(bytes.value(), pk.packPath());
    decodeNs += since(t);
    if (!m) continue;
    t = Clock::now();
    reuse.levels.resize(m->levels.size());
    for (std::size_t l = 0; l < m->levels.size(); ++l) {
      reuse.levels[l].vertices.assign(m->levels[l].vertices.begin(), m->levels[l].vertices.end());
      reuse.levels[l].indices.assign(m->levels[l].indices.begin(), m->levels[l].indices.end());
      reuse.levels[l].groups.assign(m->levels[l].groups.begin(), m->levels[l].groups.end());
      reuse.levels[l].maxHeight.assign(m->levels[l].maxHeight.begin(), m->levels[l].maxHeight.end());
    }
    copyNs += since(t);
    ++n;
    compressed += e.compressedBytes;
    raw += e.rawBytes;
  }
  if (n == 0) return json::object();
  const double dn = double(n), total = (readNs + unpackNs + decodeNs + copyNs) / dn;
  return {{"modules", n},
          {"cold_cache", !a.warm},
          {"compressed_kb_mean", double(compressed) / dn / 1024},
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
  const runtime::PagerMetrics& m0 = r.before;
  const runtime::PagerMetrics& m1 = r.after;
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
      v = median(xs);
    } else if (v.is_object()) {
      for (auto& [k2, v2] : v.items()) {
        std::vector<double> xs;
        for (const json& r : runs) xs.push_back(r[k][k2].get<double>());
        v2 = median(xs);
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

// ------------------------------------------------------------------ plot

struct Series {
  std::string label;
  std::vector<std::array<double, 2>> points;  ///< speed km/h, % of frames
  runtime::Rgb color;
  bool dashed = false;
};

std::string speedLabel(double v) {
  char b[32];
  if (v >= 1e6) std::snprintf(b, sizeof b, "%gM", v / 1e6);
  else if (v >= 1000) std::snprintf(b, sizeof b, "%gk", v / 1000);
  else std::snprintf(b, sizeof b, "%g", v);
  return b;
}

std::vector<Series> plotSeries(const json& modes) {
  const std::map<std::string, runtime::Rgb> colors = {
      {"predictive", {0, 114, 178}}, {"demand", {213, 94, 0}}, {"mmap", {0, 158, 115}}, {"seed", {204, 121, 167}}};
  std::vector<Series> out;
  for (const auto& [mode, m] : modes.items()) {
    for (const char* what : {"hole_frames", "degraded_frames"}) {
      if (mode == "mmap" && std::string(what) == "degraded_frames") continue;  // one level: never degraded
      const bool holes = std::string(what) == "hole_frames";
      std::string label = mode + (holes ? " holes" : " degraded");
      if (holes) {
        const double z = m["max_speed_zero_holes_kmh"].get<double>();
        label += z > 0 ? ", 0 to " + speedLabel(z) : ", never 0";
      }
      Series s{label, {}, colors.at(mode), !holes};
      for (const json& p : m["speeds"]) {
        const double frames = p["frames"].get<double>();
        if (frames > 0) s.points.push_back({p["speed_kmh"].get<double>(), 100 * p[what].get<double>() / frames});
      }
      out.push_back(std::move(s));
    }
  }
  // Predictive last, so that its line at 0 % is drawn over the others.
  std::stable_partition(out.begin(), out.end(), [](const Series& s) { return s.label.rfind("predictive", 0) != 0; });
  return out;
}

/// Plot frame: log X (speed), linear Y (0..100 % of frames).
struct Axes {
  int w = 1120, h = 560, left = 80, right = 440, top = 70, bottom = 60;
  double x0 = 1000, x1 = 1e6;
  double px(double speed) const {
    return left + (std::log10(speed) - std::log10(x0)) / (std::log10(x1) - std::log10(x0)) * (w - left - right);
  }
  double py(double pct) const { return top + (1 - pct / 100) * (h - top - bottom); }
};

Axes axesFor(const std::vector<Series>& series) {
  Axes ax;
  double lo = 1e12, hi = 0;
  for (const Series& s : series) {
    for (const auto& p : s.points) lo = std::min(lo, p[0]), hi = std::max(hi, p[0]);
  }
  if (hi <= 0) lo = 1000, hi = 1e6;
  ax.x0 = std::pow(10, std::floor(std::log10(lo)));
  ax.x1 = std::pow(10, std::ceil(std::log10(hi) - 1e-9));
  if (ax.x1 <= ax.x0) ax.x1 = ax.x0 * 10;
  return ax;
}

std::string svgPlot(const std::vector<Series>& series, const std::string& title) {
  const Axes ax = axesFor(series);
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << ax.w << "' height='" << ax.h
    << "' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n";
  o << "<text x='" << ax.left << "' y='28' font-size='15'>" << title << "</text>\n";
  const double xr = ax.w - ax.right, yb = ax.h - ax.bottom;
  for (int pct = 0; pct <= 100; pct += 20) {
    o << "<line x1='" << ax.left << "' y1='" << ax.py(pct) << "' x2='" << xr << "' y2='" << ax.py(pct)
      << "' stroke='#ddd'/>\n<text x='" << ax.left - 8 << "' y='" << ax.py(pct) + 4 << "' text-anchor='end'>" << pct
      << "%</text>\n";
  }
  for (double v = ax.x0; v <= ax.x1 * 1.0001; v *= 10) {
    for (int m = 1; m < 10 && v * m <= ax.x1 * 1.0001; ++m) {
      const double x = ax.px(v * m);
      o << "<line x1='" << x << "' y1='" << ax.top << "' x2='" << x << "' y2='" << yb << "' stroke='"
        << (m == 1 ? "#bbb" : "#eee") << "'/>\n";
      if (m == 1 || m == 2 || m == 5) {
        o << "<text x='" << x << "' y='" << yb + 18 << "' text-anchor='middle'>" << speedLabel(v * m) << "</text>\n";
      }
    }
  }
  o << "<rect x='" << ax.left << "' y='" << ax.top << "' width='" << xr - ax.left << "' height='" << yb - ax.top
    << "' fill='none' stroke='black'/>\n";
  o << "<text x='" << (ax.left + xr) / 2 << "' y='" << ax.h - 18 << "' text-anchor='middle'>speed, km/h (log)</text>\n";
  o << "<text transform='translate(20," << (ax.top + yb) / 2
    << ") rotate(-90)' text-anchor='middle'>frames with a hole / degraded, % of frames</text>\n";
  int ly = ax.top + 10;
  for (const Series& s : series) {
    char rgb[16];
    std::snprintf(rgb, sizeof rgb, "#%02x%02x%02x", s.color.r, s.color.g, s.color.b);
    const std::string dash = s.dashed ? " stroke-dasharray='6,4'" : "";
    o << "<polyline fill='none' stroke='" << rgb << "' stroke-width='2'" << dash << " points='";
    for (const auto& p : s.points) o << ax.px(p[0]) << "," << ax.py(p[1]) << " ";
    o << "'/>\n";
    for (const auto& p : s.points) {
      o << "<circle cx='" << ax.px(p[0]) << "' cy='" << ax.py(p[1]) << "' r='3' fill='" << rgb << "'/>\n";
    }
    o << "<line x1='" << xr + 15 << "' y1='" << ly << "' x2='" << xr + 45 << "' y2='" << ly << "' stroke='" << rgb
      << "' stroke-width='2'" << dash << "/>\n<text x='" << xr + 52 << "' y='" << ly + 4 << "'>" << s.label
      << "</text>\n";
    ly += 20;
  }
  o << "</svg>\n";
  return o.str();
}

void dot(runtime::Image& img, int x, int y, runtime::Rgb c) {
  if (x < 0 || y < 0 || x >= int(img.width) || y >= int(img.height)) return;
  const std::size_t k = (std::size_t(y) * img.width + std::size_t(x)) * 4;
  img.rgba[k] = c.r, img.rgba[k + 1] = c.g, img.rgba[k + 2] = c.b, img.rgba[k + 3] = 255;
}

/// A line two pixels wide; `dashed` leaves gaps every 6 pixels.
void line(runtime::Image& img, double x0, double y0, double x1, double y1, runtime::Rgb c, bool dashed = false) {
  const double len = std::max(1.0, std::hypot(x1 - x0, y1 - y0));
  for (double t = 0; t <= len; t += 0.5) {
    if (dashed && int(t) % 10 >= 6) continue;
    const double x = x0 + (x1 - x0) * t / len, y = y0 + (y1 - y0) * t / len;
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) dot(img, int(x) + dx, int(y) + dy, c);
  }
}

std::string pngPlot(const std::string& file, const std::vector<Series>& series, const std::string& title) {
  const Axes ax = axesFor(series);
  runtime::Image img{std::uint32_t(ax.w), std::uint32_t(ax.h), {}};
  img.rgba.assign(std::size_t(ax.w) * ax.h * 4, 255);
  const runtime::Rgb grey{200, 200, 200}, black{0, 0, 0};
  const double xr = ax.w - ax.right, yb = ax.h - ax.bottom;
  for (int pct = 0; pct <= 100; pct += 20) {
    line(img, ax.left, ax.py(pct), xr, ax.py(pct), grey);
    const std::string t = std::to_string(pct) + "%";
    runtime::drawText(img, ax.left - 8 - runtime::textWidth(t, 2), int(ax.py(pct)) - 7, t, 2, black);
  }
  for (double v = ax.x0; v <= ax.x1 * 1.0001; v *= 10) {
    line(img, ax.px(v), ax.top, ax.px(v), yb, grey);
    const std::string t = speedLabel(v);
    runtime::drawText(img, int(ax.px(v)) - runtime::textWidth(t, 2) / 2, int(yb) + 8, t, 2, black);
  }
  line(img, ax.left, ax.top, xr, ax.top, black);
  line(img, ax.left, yb, xr, yb, black);
  line(img, ax.left, ax.top, ax.left, yb, black);
  line(img, xr, ax.top, xr, yb, black);
  runtime::drawText(img, ax.left, 14, title, 2, black);
  runtime::drawText(img, int(ax.left + xr) / 2 - 100, ax.h - 28, "SPEED KM/H (LOG)", 2, black);
  runtime::drawText(img, ax.left - 60, ax.top - 32, "% OF FRAMES", 2, black);
  int ly = ax.top + 10;
  for (const Series& s : series) {
    for (std::size_t i = 1; i < s.points.size(); ++i) {
      line(img, ax.px(s.points[i - 1][0]), ax.py(s.points[i - 1][1]), ax.px(s.points[i][0]), ax.py(s.points[i][1]),
           s.color, s.dashed);
    }
    for (const auto& p : s.points) {
      for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx) dot(img, int(ax.px(p[0])) + dx, int(ax.py(p[1])) + dy, s.color);
    }
    line(img, xr + 10, ly, xr + 40, ly, s.color, s.dashed);
    runtime::drawText(img, int(xr) + 46, ly - 6, s.label, 2, black);
    ly += 22;
  }
  return runtime::writePng(file, img).error();
}

std::string writePlot(const std::string& file, const json& modes, const std::string& title) {
  const std::vector<Series> series = plotSeries(modes);
  const std::string ext = fs::path(file).extension().string();
  if (ext == ".png") return pngPlot(file, series, title);
  std::ofstream out(file);
  out << svgPlot(series, title);
  return out ? "" : "cannot write " + file;
}

// ----------------------------------------------------------------- report

void printHuman(const json& j) {
  std::printf("bench paging: %s, %s path, view distance %.0f m, %s, median of %d\n",
              j["database"].get<std::string>().c_str(), j["path"].get<std::string>().c_str(),
              j["view_distance_m"].get<double>(), j["cold_cache"].get<bool>() ? "cold cache" : "warm cache",
              j["repeat"].get<int>());
  std::printf("%-10s %9s %6s %6s %7s %7s %8s %8s %8s %8s %7s %7s %6s\n", "mode", "km/h", "sec", "frames", "holes",
              "degr.", "p50 ms", "p99 ms", "max ms", "mod/s", "MB/s", "RSS MB", "lead");
  for (const std::string mode : {"predictive", "seed", "demand", "mmap"}) {
    if (!j["modes"].contains(mode)) continue;
    const json& m = j["modes"][mode];
    for (const json& s : m["speeds"]) {
      const double rate = s.contains("modules_per_s") ? s["modules_per_s"].get<double>() : s["blocks_per_s"].get<double>();
      std::printf("%-10s %9.0f %6.2f %6.0f %7.0f %7.0f %8.1f %8.1f %8.1f %8.0f %7.1f %7.0f %6.0f\n", mode.c_str(),
                  s["speed_kmh"].get<double>(), s["seconds_flown"].get<double>(), s["frames"].get<double>(),
                  s["hole_frames"].get<double>(), s["degraded_frames"].get<double>(), s["latency_ms"]["p50"].get<double>(),
                  s["latency_ms"]["p99"].get<double>(), s["latency_ms"]["max"].get<double>(), rate,
                  s[mode == "mmap" ? "disk_mb_per_s" : "mb_per_s"].get<double>(), s["peak_rss_mb"].get<double>(),
                  s["lead_strips_max"].get<double>());
    }
    std::printf("%-10s highest speed with zero hole frames (every repeat): %.0f km/h; under 1%% of frames: %.0f km/h\n",
                mode.c_str(), m["max_speed_zero_holes_kmh"].get<double>(),
                m["max_speed_under_1pct_hole_frames_kmh"].get<double>());
  }
  for (const auto& [k, v] : j["ratios"].items()) {
    if (v.is_number()) std::printf("ratio %s: %.1f\n", k.c_str(), v.get<double>());
    else std::printf("ratio %s: %s\n", k.c_str(), v.get<std::string>().c_str());
  }
  if (const json& st = j["stages"]; !st.empty()) {
    std::printf("one load, one core, %s (%llu modules along the path, %.1f kB compressed, %.1f kB raw): pread %.0f us,"
                " unpack (CRC + zstd) %.0f us, decode %.0f us, copy %.0f us = %.0f us, %.0f modules/s\n",
                st["cold_cache"].get<bool>() ? "cold cache" : "warm", static_cast<unsigned long long>(st["modules"].get<std::uint64_t>()),
                st["compressed_kb_mean"].get<double>(), st["raw_kb_mean"].get<double>(), st["pread_us"].get<double>(),
                st["unpack_us"].get<double>(), st["decode_us"].get<double>(), st["copy_us"].get<double>(),
                st["total_us"].get<double>(), st["modules_per_s_one_core"].get<double>());
  }
  std::printf("(mmap: mod/s is grid blocks prefetched per second, MB/s is disk reads; holes are needed modules whose\n"
              " grid pages are not in the page cache; mmap has one level, so never a degraded frame)\n");
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

std::string checkArgs(Args& a, const Database& db) {
  if (!db.modules) return a.db + " has no load modules; build one with `sandtable bench make-db`";
  if (a.speedsKmh.empty()) return "--speeds needs at least one speed";
  for (double s : a.speedsKmh) {
    if (!(s > 0) || !std::isfinite(s)) return "--speeds: every speed must be > 0 km/h";
  }
  std::sort(a.speedsKmh.begin(), a.speedsKmh.end());
  a.speedsKmh.erase(std::unique(a.speedsKmh.begin(), a.speedsKmh.end()), a.speedsKmh.end());
  for (const std::string& m : a.modes) {
    if (!modeOf(m)) return "--modes: unknown mode '" + m + "' (predictive, seed, demand, mmap)";
  }
  for (const std::string& plot : a.plots) {
    const std::string ext = fs::path(plot).extension().string();
    if (ext != ".png" && ext != ".svg") return "--plot " + plot + ": the file must end in .png or .svg";
  }
  return "";
}

int runBench(Args& a) {
  auto db = openOrReport("bench paging", a.db);
  if (!db) return kUsage;
  if (const std::string err = checkArgs(a, *db); !err.empty()) return usageError("bench paging", err);
  const pack::IndexHeader h = db->modules->header();
  const double w = h.modulesX * h.moduleSize, d = h.modulesZ * h.moduleSize;
  const double margin = a.viewDistance + (a.maxLeadStrips + 2) * h.moduleSize;
  auto path = makePath(a.path, w, d, margin, h.moduleSize);
  if (!path) return usageError("bench paging", path.error());
  db.reset();  // a mapped grid would keep its pages in the cache

  const json stages = stageBreakdown(a, path.value(), 400);
  std::vector<Flight> flights;
  for (const std::string& m : a.modes) {
    if (a.ramp) flights.push_back({*modeOf(m), a.speedsKmh, a.seconds * double(a.speedsKmh.size())});
    else for (double s : a.speedsKmh) flights.push_back({*modeOf(m), {s}, a.seconds});
  }
  // runs[mode][speed] = one json per repeat
  std::map<std::string, std::map<double, std::vector<json>>> runs;
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
      auto r = fly(a, f, path.value());
      if (!r) {
        reportProblems("bench paging", r.problems());
        return kUsage;
      }
      ++done;
      for (const Bin& b : r->bins) {
        const double share = r->seconds > 0 ? b.seconds / r->seconds : 0;
        runs[f.mode.name][b.speedKmh].push_back(binJson(b, r.value(), std::min(1.0, share)));
        {
          std::fprintf(stderr, "bench paging: [%zu/%zu] %-10s %8.0f km/h  %5.2f s  %4llu/%llu hole frames, %llu degraded%s\n",
                       done, total, f.mode.name.c_str(), b.speedKmh, b.seconds,
                       static_cast<unsigned long long>(b.holeFrames), static_cast<unsigned long long>(b.frames),
                       static_cast<unsigned long long>(b.degradedFrames),
                       r->cachedAfterDrop > 0.01 ? "  (warning: cache not dropped)" : "");
        }
      }
    }
  }
  json modes = json::object();
  for (auto& [mode, bySpeed] : runs) {
    json speeds = json::array();
    for (auto& [speed, rs] : bySpeed) speeds.push_back(medianOf(rs));
    modes[mode] = {{"speeds", speeds},
                   {"max_speed_zero_holes_kmh", maxZeroHoles(speeds)},
                   {"max_speed_under_1pct_hole_frames_kmh", maxUnderOnePercent(speeds)}};
  }
  json j = {{"database", a.db},
            {"modules", {{"x", h.modulesX}, {"z", h.modulesZ}, {"edge_m", h.moduleSize}, {"levels", h.levels}}},
            {"view_distance_m", a.viewDistance},
            {"half_angle_deg", a.halfAngle},
            {"path", a.path},
            {"path_length_km", path->length() / 1000},
            {"ramp", a.ramp},
            {"repeat", a.repeat},
            {"seconds_per_speed", a.seconds},
            {"tick_hz", kTickHz},
            {"cold_cache", !a.warm},
            {"loaders", a.loaders},
            {"max_lead_strips", a.maxLeadStrips},
            {"look_ahead_scale", a.lookAhead},
            {"cpus", std::thread::hardware_concurrency()},
            {"modes", modes}};
  j["ratios"] = ratios(modes);
  j["stages"] = stages;
  for (const std::string& plot : a.plots) {
    char title[160];
    std::snprintf(title, sizeof title, "bench paging: %s path, vd %.0f km, %s", a.path.c_str(), a.viewDistance / 1000,
                  a.warm ? "warm" : "cold cache");
    if (const std::string err = writePlot(plot, modes, title); !err.empty()) {
      return usageError("bench paging", "--plot: " + err);
    }
  }
  if (a.json) std::printf("%s\n", j.dump(2).c_str());
  else printHuman(j);
  return kOk;
}

}  // namespace

void registerBenchPaging(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto* sub = bench.add_subcommand("paging", "Fly in real time at a list of speeds: predictive pager vs demand vs mmap");
  sub->footer(
      "Example:\n  sandtable bench paging out/bench-db --view-distance 10000 --speeds 2000,20000,200000 --plot paging.svg\n"
      "Each speed and mode is one real-time flight at 60 Hz from a cold cache (posix_fadvise DONTNEED on every\n"
      "database file) along a path that never revisits a module. Every tick counts the modules under the view\n"
      "triangle that are not resident (holes) or only coarser than needed (degraded). See docs/PAGER.md.");
  sub->add_option("DB", a->db, "Database directory (with load modules)")->required();
  sub->add_option("--view-distance", a->viewDistance, "View distance, metres")
      ->default_val(10000)
      ->check(CLI::Range(100.0, 100000.0));
  sub->add_option("--speeds", a->speedsKmh, "Speeds in km/h, comma separated")
      ->delimiter(',')
      ->default_str("2000,5000,10000,20000,50000,100000,200000,300000");
  sub->add_flag("--ramp", a->ramp, "One flight per mode with the speed rising geometrically through the list");
  sub->add_option("--path", a->path, "Flight path")->default_val("straight")->check(CLI::IsMember({"straight", "zigzag", "circle"}));
  sub->add_option("--seconds", a->seconds, "Seconds per speed (capped by what the path allows)")
      ->default_val(8)
      ->check(CLI::Range(0.5, 600.0));
  sub->add_option("--repeat", a->repeat, "Flights per speed and mode (median reported)")->default_val(3)->check(CLI::Range(1, 50));
  sub->add_option("--modes", a->modes,
                  "Modes, comma separated: predictive, seed (the seed's strips, no lead), demand, mmap")
      ->delimiter(',')
      ->default_str("predictive,seed,demand,mmap");
  sub->add_option("--loaders", a->loaders, "Loader threads (1..4)")->default_val(4)->check(CLI::Range(1, 4));
  sub->add_option("--max-lead-strips", a->maxLeadStrips, "Most strips loaded ahead on one axis (0..16)")
      ->default_val(16)
      ->check(CLI::Range(0, 16));
  sub->add_option("--look-ahead", a->lookAhead, "Lead time as a multiple of the loaders' latency estimate")
      ->default_val(2)
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--half-angle", a->halfAngle, "Half the view triangle's ground angle, degrees")
      ->default_val(35)
      ->check(CLI::Range(1.0, 89.0));
  sub->add_option("--budget-mb", a->budgetMb, "Pager memory budget, MiB")->default_val(2048)->check(CLI::PositiveNumber);
  sub->add_flag("--warm", a->warm, "Keep the page cache (skip the cold-cache drop)");
  sub->add_flag("--json", a->json, "Print one JSON object");
  sub->add_option("--plot", a->plots, "Write holes and degraded frames against speed, FILE.png or FILE.svg (repeatable)")
      ->take_all()
      ->allow_extra_args(false);
  c.add(sub, [a] { return runBench(*a); });
}

}  // namespace sandtable::cli
