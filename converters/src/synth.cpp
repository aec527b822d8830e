// `sandtable synth` orchestration: lays out the square and its DTED cells,
// samples the terrain into DTED1/DTED2 cells (in parallel, one cell buffer
// per worker) and a GeoTIFF DEM (in bands), writes the culture GeoPackage
// and synth.json, all into a temp directory renamed into place at the end.
#include "sandtable/converters/synth.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <mutex>

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>
#include <nlohmann/json.hpp>
#include <ogr_srs_api.h>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/elevation.h"  // requestCancel / cancelRequested: one Ctrl-C flag for all
#include "synth_internal.h"
#include "sandtable/base/jobs.h"

namespace sandtable::convert {

namespace fs = std::filesystem;
using synth::Frame;
using synth::Vec2;
using synth::World;

namespace {

// ---------------------------------------------------------------- layout

/// One 1x1 degree DTED cell, named by its south-west corner.
struct Cell {
  int lon = 0, lat = 0;
  int level = 1;
};

int dtedRows(int level) { return level == 1 ? 1201 : 3601; }

/// DTED thins longitude posts towards the poles (MIL-PRF-89020B zones; the
/// same rule as GDAL's DTED driver, southern cells by their northern edge).
int lonThinning(int lat) {
  const int ref = lat < 0 ? -(lat + 1) : lat;
  if (ref >= 80) return 6;
  if (ref >= 75) return 4;
  if (ref >= 70) return 3;
  if (ref >= 50) return 2;
  return 1;
}

int dtedCols(const Cell& c) { return (dtedRows(c.level) - 1) / lonThinning(c.lat) + 1; }

/// "dted1/e013/n42.dt1": the standard DTED directory tree, lowercase.
std::string cellPath(const Cell& c) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "dted%d/%c%03d/%c%02d.dt%d", c.level, c.lon < 0 ? 'w' : 'e', std::abs(c.lon),
                c.lat < 0 ? 's' : 'n', std::abs(c.lat), c.level);
  return buf;
}

/// The square, the DTED cells covering it and the DEM grid.
struct Layout {
  Frame frame;
  double sizeM = 0;
  double west = 0, south = 0, east = 0, north = 0;
  int lonCell0 = 0, lonCell1 = 0, latCell0 = 0, latCell1 = 0;  ///< inclusive
  int demStep = 1;  ///< arc-seconds
  long long demCol0 = 0, demRow0 = 0;  ///< in steps from (0, 0); row 0 is the north edge
  int demWidth = 0, demHeight = 0;
};

/// The DEM is 1" unless that passes this many pixels a side; then it
/// coarsens in whole arc-seconds (1000 km: 3"), keeping it under a GB.
constexpr int kMaxDemSide = 16384;

Layout layout(const SynthOptions& o) {
  Layout l;
  l.frame = Frame(o.centerLon, o.centerLat);
  l.sizeM = o.sizeKm * 1000.0;
  const double half = 0.5 * l.sizeM;
  l.west = l.frame.lonOf(-half), l.east = l.frame.lonOf(half);
  l.south = l.frame.latOf(-half), l.north = l.frame.latOf(half);
  // Cells cover the square; a cell's edge posts belong to it, so a square
  // ending exactly on a whole degree needs no further cell.
  l.lonCell0 = static_cast<int>(std::floor(l.west));
  l.lonCell1 = static_cast<int>(std::ceil(l.east)) - 1;
  l.latCell0 = static_cast<int>(std::floor(l.south));
  l.latCell1 = static_cast<int>(std::ceil(l.north)) - 1;
  const double side = std::max(l.east - l.west, l.north - l.south) * 3600.0;
  l.demStep = std::max(1, static_cast<int>(std::ceil(side / kMaxDemSide)));
  const double perDeg = 3600.0 / l.demStep;
  // Pixel centres on whole multiples of the step (DTED2 posts at 1"),
  // covering the square.
  l.demCol0 = static_cast<long long>(std::floor(l.west * perDeg));
  const long long col1 = static_cast<long long>(std::ceil(l.east * perDeg));
  l.demRow0 = static_cast<long long>(std::ceil(l.north * perDeg));
  const long long row1 = static_cast<long long>(std::floor(l.south * perDeg));
  l.demWidth = static_cast<int>(col1 - l.demCol0 + 1);
  l.demHeight = static_cast<int>(l.demRow0 - row1 + 1);
  return l;
}

std::vector<Cell> cells(const Layout& l, int level) {
  std::vector<Cell> out;
  for (int lat = l.latCell0; lat <= l.latCell1; ++lat) {
    for (int lon = l.lonCell0; lon <= l.lonCell1; ++lon) out.push_back({lon, lat, level});
  }
  return out;
}

// ---------------------------------------------------------------- progress

/// Turns work units done (from any thread) into one overall fraction.
class Reporter {
 public:
  Reporter(const SynthProgress& cb, double total) : cb_(cb), total_(std::max(total, 1.0)) {}

  void advance(double units, const std::string& stage) {
    std::lock_guard lock(mutex_);
    done_ += units;
    emit(stage);
  }
  void reach(double units, const std::string& stage) {
    std::lock_guard lock(mutex_);
    done_ = std::max(done_, units);
    emit(stage);
  }

 private:
  void emit(const std::string& stage) {
    if (!cb_) return;
    const double f = std::min(1.0, done_ / total_);
    if (stage == stage_ && f < 1.0 && f - last_ < 0.002) return;
    last_ = f, stage_ = stage;
    cb_(f, stage);
  }

  const SynthProgress& cb_;
  double total_, done_ = 0, last_ = -1;
  std::string stage_;
  std::mutex mutex_;
};

/// Elevation range over everything written.
struct Range {
  double lo = std::numeric_limits<double>::max(), hi = -std::numeric_limits<double>::max();
  void add(double v) { lo = std::min(lo, v), hi = std::max(hi, v); }
  void add(const Range& o) { lo = std::min(lo, o.lo), hi = std::max(hi, o.hi); }
};

std::string gdalError(const std::string& what) {
  const char* msg = CPLGetLastErrorMsg();
  return what + (msg && *msg ? std::string(": ") + msg : std::string());
}

Problem cancelled(const fs::path& where) { return Problem{where.string(), 0, "synth: cancelled"}; }

std::string wgs84Wkt() {
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRSetWellKnownGeogCS(srs, "WGS84");
  char* wkt = nullptr;
  OSRExportToWkt(srs, &wkt);
  std::string s = wkt ? wkt : "";
  CPLFree(wkt);
  OSRRelease(srs);
  return s;
}

// ---------------------------------------------------------------- DTED

/// Samples one cell into buf (row 0 north, pixel-is-point posts) and writes
/// it through GDAL's DTED driver (CreateCopy from a MEM dataset).
Result<Range> writeDtedCell(const World& w, const Cell& c, const fs::path& file, std::vector<std::int16_t>& buf,
                            Reporter& rep) {
  const int rows = dtedRows(c.level), cols = dtedCols(c);
  const int thin = lonThinning(c.lat);
  buf.resize(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols));
  Range range;
  const synth::Terrain& t = *w.terrain;
  const std::string stage = "dted";
  for (int r = 0; r < rows; ++r) {
    // i / (rows - 1) rounds the same for DTED1 post i and DTED2 post 3i, so
    // shared posts sample the terrain at bit-identical coordinates.
    const double lat = (c.lat + 1) - static_cast<double>(r) / (rows - 1);
    for (int i = 0; i < cols; ++i) {
      const double lon = c.lon + static_cast<double>(i * thin) / (rows - 1);
      // Real DTED holds 0 over the sea.
      const double h = std::clamp(std::round(t.elevation(w.frame.toLocal(lon, lat))), 0.0, 32767.0);
      buf[static_cast<std::size_t>(r) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(i)] =
          static_cast<std::int16_t>(h);
      range.add(h);
    }
    if ((r & 63) == 63) {
      rep.advance(64.0 * cols, stage);
      if (cancelRequested()) return cancelled(file);
    }
  }
  rep.advance(static_cast<double>(rows % 64) * cols, stage);

  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", cols, rows, 1, GDT_Int16, nullptr);
  if (!mem) return Problem{file.string(), 0, gdalError("synth: dted: cannot create MEM dataset")};
  const double dx = static_cast<double>(thin) / (rows - 1), dy = 1.0 / (rows - 1);
  double gt[6] = {c.lon - 0.5 * dx, dx, 0, c.lat + 1 + 0.5 * dy, 0, -dy};
  GDALSetGeoTransform(mem, gt);
  GDALSetProjection(mem, wgs84Wkt().c_str());
  CPLErr err = GDALRasterIO(GDALGetRasterBand(mem, 1), GF_Write, 0, 0, cols, rows, buf.data(), cols, rows, GDT_Int16, 0, 0);
  GDALDatasetH out = nullptr;
  if (err == CE_None) {
    out = GDALCreateCopy(GDALGetDriverByName("DTED"), file.c_str(), mem, TRUE, nullptr, nullptr, nullptr);
  }
  const std::string why = gdalError("synth: dted: cannot write cell");
  GDALClose(mem);
  if (!out) return Problem{file.string(), 0, why};
  GDALClose(out);
  return range;
}

/// All cells of the requested levels, biggest first, `threads` at a time;
/// each worker keeps one cell buffer.
Result<Range> writeDted(const World& w, const std::vector<Cell>& all, const fs::path& root, int threads,
                        Reporter& rep) {
  for (const Cell& c : all) {
    std::error_code ec;
    fs::create_directories((root / cellPath(c)).parent_path(), ec);
    if (ec) return Problem{(root / cellPath(c)).parent_path().string(), 0, "synth: dted: " + ec.message()};
  }
  std::mutex mutex;
  Range range;
  std::vector<Problem> problems;
  jobs::Scratch<std::vector<std::int16_t>> buffers;
  jobs::parallelFor(all.size(), threads, [&](std::size_t k) {
    {
      std::lock_guard lock(mutex);
      if (!problems.empty()) return;
    }
    auto r = buffers.use([&](std::vector<std::int16_t>& buf) {
      return writeDtedCell(w, all[k], root / cellPath(all[k]), buf, rep);
    });
    std::lock_guard lock(mutex);
    if (r) range.add(r.value());
    else problems.insert(problems.end(), r.problems().begin(), r.problems().end());
  });
  if (!problems.empty()) return problems;
  return range;
}

// ---------------------------------------------------------------- GeoTIFF

/// dem.tif: Float32, geographic WGS 84, tiled, DEFLATE. Rows are sampled in
/// bands of one tile height, in parallel within a band.
Result<Range> writeDem(const World& w, const Layout& l, const fs::path& file, int threads, Reporter& rep) {
  const char* opts[] = {"TILED=YES", "BLOCKXSIZE=256", "BLOCKYSIZE=256", "COMPRESS=DEFLATE", "PREDICTOR=3",
                        "BIGTIFF=IF_SAFER", nullptr};
  GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), file.c_str(), l.demWidth, l.demHeight, 1, GDT_Float32,
                               const_cast<char**>(opts));
  if (!ds) return Problem{file.string(), 0, gdalError("synth: dem: cannot create")};
  const double step = l.demStep / 3600.0;
  double gt[6] = {(static_cast<double>(l.demCol0) - 0.5) * step, step, 0,
                  (static_cast<double>(l.demRow0) + 0.5) * step, 0, -step};
  GDALSetGeoTransform(ds, gt);
  GDALSetProjection(ds, wgs84Wkt().c_str());
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  GDALSetRasterUnitType(band, "m");
  GDALSetDescription(band, "elevation");

  constexpr int kBand = 256;
  const double perDeg = 3600.0 / l.demStep;
  std::vector<float> buf(static_cast<std::size_t>(l.demWidth) * kBand);
  std::vector<Range> ranges(kBand);  // one per row: no sharing between threads
  CPLErr err = CE_None;
  for (int r0 = 0; r0 < l.demHeight && err == CE_None; r0 += kBand) {
    const int n = std::min(kBand, l.demHeight - r0);
    synth::parallelFor(static_cast<std::size_t>(n), threads, [&](std::size_t b, std::size_t e) {
      for (std::size_t r = b; r < e; ++r) {
        Range& range = ranges[r];
        const double lat = static_cast<double>(l.demRow0 - r0 - static_cast<long long>(r)) / perDeg;
        float* row = buf.data() + r * static_cast<std::size_t>(l.demWidth);
        for (int i = 0; i < l.demWidth; ++i) {
          const double lon = static_cast<double>(l.demCol0 + i) / perDeg;
          const double h = w.terrain->elevation(w.frame.toLocal(lon, lat));
          row[i] = static_cast<float>(h);
          range.add(h);
        }
      }
    });
    err = GDALRasterIO(band, GF_Write, 0, r0, l.demWidth, n, buf.data(), l.demWidth, n, GDT_Float32, 0, 0);
    // Write this row of tiles out and drop it from the block cache: memory
    // stays at one band, not GDAL_CACHEMAX, however big the DEM.
    if (err == CE_None) err = GDALFlushRasterCache(band);
    rep.advance(static_cast<double>(n) * l.demWidth, "dem");
    if (cancelRequested()) {
      GDALClose(ds);
      return cancelled(file);
    }
  }
  const std::string why = gdalError("synth: dem: write failed");
  GDALClose(ds);  // flushes the last tiles
  if (err != CE_None) return Problem{file.string(), 0, why};
  Range all;
  for (const Range& r : ranges) all.add(r);
  return all;
}

// ---------------------------------------------------------------- summary

std::string toJson(const SynthSummary& s) {
  nlohmann::ordered_json j;
  j["generator"] = "sandtable synth";
  j["seed"] = s.seed;
  j["size_km"] = s.sizeKm;
  j["crs"] = "EPSG:4326";
  j["center"] = {{"lon", s.centerLon}, {"lat", s.centerLat}};
  j["bounds"] = {{"west", s.west}, {"south", s.south}, {"east", s.east}, {"north", s.north}};
  j["dted"] = {{"level1_cells", s.dted1Cells}, {"level2_cells", s.dted2Cells}};
  j["dem"] = {{"path", s.demWidth > 0 ? "dem.tif" : ""},
              {"width", s.demWidth},
              {"height", s.demHeight},
              {"pixel_arcsec", s.demArcSeconds},
              {"type", "Float32"}};
  j["culture"] = {{"roads", s.roads}, {"rivers", s.rivers}, {"lakes", s.lakes}, {"forest", s.forests},
                  {"buildings", s.buildings}};
  j["elevation_m"] = {{"min", s.minElevation}, {"max", s.maxElevation}};
  j["files"] = s.files;
  return j.dump(2) + "\n";
}

/// Removes the temp directory unless released.
struct TempDir {
  fs::path path;
  bool keep = false;
  ~TempDir() {
    if (keep || path.empty()) return;
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

fs::path targetPath(const std::string& dir) {
  fs::path p = fs::path(dir).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();  // "out/" -> "out"
  return p;
}

/// Expected work in terrain evaluations per stage, so the bar moves evenly.
struct Work {
  double world = 0, dted = 0, dem = 0, culture = 0;
  double total() const { return world + dted + dem + culture; }
};

Work workUnits(const Layout& l, const SynthOptions& o, const std::vector<Cell>& todo) {
  // The analysis grid's side, as synth::buildWorld sizes it (roughly).
  const double side = std::min(1601.0, (l.sizeM + 2 * std::max(2500.0, 0.15 * l.sizeM)) / 50.0);
  Work w;
  w.world = side * side * (o.culture ? 3.0 : 1.5);
  for (const Cell& c : todo) w.dted += static_cast<double>(dtedRows(c.level)) * dtedCols(c);
  w.dem = o.dem ? static_cast<double>(l.demWidth) * l.demHeight : 0.0;
  w.culture = o.culture ? side * side * 0.5 : 0.0;
  return w;
}

/// DTED cells, the DEM and the culture, into dir; fills in s.
Result<bool> writeProducts(const World& w, const Layout& l, const SynthOptions& o, const std::vector<Cell>& todo,
                           const fs::path& dir, int threads, Reporter& rep, SynthSummary& s) {
  Range range;
  if (!todo.empty()) {
    auto r = writeDted(w, todo, dir, threads, rep);
    if (!r) return r.problems();
    range.add(r.value());
    for (const Cell& c : todo) {
      (c.level == 1 ? s.dted1Cells : s.dted2Cells) += 1;
      s.files.push_back(cellPath(c));
    }
  }
  if (o.dem) {
    auto r = writeDem(w, l, dir / "dem.tif", threads, rep);
    if (!r) return r.problems();
    range.add(r.value());
    s.demWidth = l.demWidth, s.demHeight = l.demHeight, s.demArcSeconds = l.demStep;
    s.files.push_back("dem.tif");
  }
  if (o.culture) {
    rep.advance(0, "culture");
    auto r = synth::writeCulture(w, (dir / "culture.gpkg").string());
    if (!r) return r.problems();
    s.roads = r->roads, s.rivers = r->rivers, s.lakes = r->lakes, s.forests = r->forests;
    s.buildings = r->buildings;
    s.files.push_back("culture.gpkg");
  }
  if (range.lo <= range.hi) s.minElevation = range.lo, s.maxElevation = range.hi;
  return true;
}

/// Writes a small text file in one go.
Result<bool> writeText(const fs::path& file, const std::string& text) {
  FILE* f = std::fopen(file.c_str(), "wb");
  bool ok = f && std::fwrite(text.data(), 1, text.size(), f) == text.size();
  if (f && std::fclose(f) != 0) ok = false;
  if (!ok) return Problem{file.string(), 0, "synth: cannot write " + file.string()};
  return true;
}

/// Renames the finished temp directory to target. With force an existing
/// target is moved aside first (its name matches the temp pattern, so it is
/// ignored by git too), so a failed rename leaves the old data, not nothing.
Result<bool> moveIntoPlace(const fs::path& tmp, const fs::path& target, bool force) {
  std::error_code ec;
  if (!fs::exists(target, ec)) {
    fs::rename(tmp, target, ec);
    if (ec) return Problem{target.string(), 0, "synth: cannot move the output into place: " + ec.message()};
    return true;
  }
  if (!force) return Problem{target.string(), 0, "synth: " + target.string() + " appeared while writing"};
  const fs::path old = tmp.string() + ".old";
  fs::remove_all(old, ec);
  fs::rename(target, old, ec);
  if (ec) return Problem{target.string(), 0, "synth: cannot replace " + target.string() + ": " + ec.message()};
  fs::rename(tmp, target, ec);
  if (ec) {
    std::error_code ignored;
    fs::rename(old, target, ignored);
    return Problem{target.string(), 0, "synth: cannot move the output into place: " + ec.message()};
  }
  fs::remove_all(old, ec);
  return true;
}

/// Everything but the output directory. Problems name the option field
/// (file and message); the CLI shows its flag instead.
Status validateGeometry(const SynthOptions& o) {
  Status out;
  auto bad = [&](const std::string& field, const std::string& msg) { out.add(Problem{field, 0, msg}); };
  if (!std::isfinite(o.sizeKm) || o.sizeKm < 1.0 || o.sizeKm > 1000.0) {
    char got[32];
    std::snprintf(got, sizeof got, "%g", o.sizeKm);
    bad("SynthOptions::sizeKm", std::string("SynthOptions::sizeKm must be between 1 and 1000 (got ") + got + ")");
  }
  if (!std::isfinite(o.centerLon) || o.centerLon < -180.0 || o.centerLon > 180.0 || !std::isfinite(o.centerLat) ||
      o.centerLat < -80.0 || o.centerLat > 80.0) {
    bad("SynthOptions::centerLon, centerLat",
        "SynthOptions::centerLon, centerLat must have -180 <= LON <= 180 and -80 <= LAT <= 80");
  }
  if (o.threads < 0) bad("SynthOptions::threads", "SynthOptions::threads must be >= 0");
  if (out.ok()) {
    const Layout l = layout(o);
    if (l.west < -180.0 || l.east > 180.0 || l.south < -80.0 || l.north > 80.0) {
      bad("SynthOptions::centerLon, centerLat", "the square must lie within -180..180 longitude and -80..80 latitude");
    }
  }
  return out;
}

}  // namespace

Status validateSynthOptions(const SynthOptions& o) {
  Status out;
  if (o.outDir.empty() || targetPath(o.outDir).empty()) {
    out.add(Problem{"SynthOptions::outDir", 0, "an output directory (SynthOptions::outDir) is required"});
  }
  out.merge(validateGeometry(o));
  return out;
}

Result<SynthSummary> synthesize(const SynthOptions& o, const SynthProgress& progress) {
  if (Status valid = validateSynthOptions(o); !valid) return valid.problems();
  initGdal();
  const auto start = std::chrono::steady_clock::now();
  const int threads = jobs::threadCount(o.threads);
  const fs::path target = targetPath(o.outDir);
  std::error_code ec;
  if (fs::exists(target, ec) && !o.force) {
    return Problem{target.string(), 0, "synth: " + target.string() + " exists (use SynthOptions::force to replace it)"};
  }
  TempDir tmp{target.string() + ".partial." + std::to_string(::getpid())};
  if (target.has_parent_path()) fs::create_directories(target.parent_path(), ec);
  fs::remove_all(tmp.path, ec);
  if (!fs::create_directories(tmp.path, ec)) {
    return Problem{tmp.path.string(), 0, "synth: cannot create " + tmp.path.string() + ": " + ec.message()};
  }

  const Layout l = layout(o);
  std::vector<Cell> todo;
  if (o.dted2) todo = cells(l, 2);  // biggest first: better load balance
  if (o.dted1) {
    const auto c1 = cells(l, 1);
    todo.insert(todo.end(), c1.begin(), c1.end());
  }
  const Work work = workUnits(l, o, todo);
  Reporter rep(progress, work.total());

  rep.reach(0, "terrain model");
  const World w = synth::buildWorld(l.frame, l.sizeM, o.seed, threads, o.culture,
                                    [&](double f) { rep.reach(f * work.world, "terrain model"); });

  SynthSummary s;
  s.outDir = target.string();
  s.west = l.west, s.south = l.south, s.east = l.east, s.north = l.north;
  s.centerLon = o.centerLon, s.centerLat = o.centerLat, s.sizeKm = o.sizeKm, s.seed = o.seed;
  if (cancelRequested()) return cancelled(target);
  auto written = writeProducts(w, l, o, todo, tmp.path, threads, rep, s);
  if (cancelRequested()) return cancelled(target);  // one line, not one per worker
  if (!written) return written.problems();
  std::sort(s.files.begin(), s.files.end());
  for (const auto& f : s.files) s.bytes += fs::file_size(tmp.path / f, ec);
  s.json = toJson(s);

  if (auto ok = writeText(tmp.path / "synth.json", s.json); !ok) return ok.problems();
  if (auto ok = moveIntoPlace(tmp.path, target, o.force); !ok) return ok.problems();
  tmp.keep = true;
  rep.reach(std::numeric_limits<double>::max(), "done");
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return s;
}

// ---------------------------------------------------------------- SynthTerrain

struct SynthTerrain::Impl {
  World world;
};

SynthTerrain::SynthTerrain(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
SynthTerrain::~SynthTerrain() = default;

Result<std::unique_ptr<SynthTerrain>> SynthTerrain::create(const SynthOptions& o) {
  if (Status valid = validateGeometry(o); !valid) return valid.problems();
  const Layout l = layout(o);
  auto impl = std::make_unique<Impl>();
  impl->world = synth::buildWorld(l.frame, l.sizeM, o.seed, jobs::threadCount(o.threads), false, {});
  return std::unique_ptr<SynthTerrain>(new SynthTerrain(std::move(impl)));
}

double SynthTerrain::elevation(double lon, double lat) const {
  const World& w = impl_->world;
  return w.terrain->elevation(w.frame.toLocal(lon, lat));
}

}  // namespace sandtable::convert
