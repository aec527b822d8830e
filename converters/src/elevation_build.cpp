// The elevation build: sources -> frame -> resample -> fill -> grid file ->
// manifest -> atomic publish of the database directory.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string_view>

#include "build_stages.h"
#include "elevation_internal.h"
#include "sandtable/base/jobs.h"
#include "sandtable/converters/culture.h"
#include "sandtable/converters/modules.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/formats/materials.h"
#include "sandtable/icons/icon_build.h"

namespace sandtable::convert {
namespace fs = std::filesystem;

namespace {
std::atomic<bool> gCancel{false};
}

void requestCancel() { gCancel.store(true); }
bool cancelRequested() { return gCancel.load(); }

KernelChoice chooseKernel(const std::string& request, const std::string& fit, double targetSpacing,
                          double nativeSpacing) {
  KernelChoice k;
  k.spacingRatio = nativeSpacing > 0 ? targetSpacing / nativeSpacing : 1.0;
  char ratio[160];
  std::snprintf(ratio, sizeof ratio, "target spacing %.2f m is %.2fx the sources' finest native spacing %.2f m",
                targetSpacing, k.spacingRatio, nativeSpacing);
  char limit[16];
  std::snprintf(limit, sizeof limit, "%gx", kAutoWeightedRatio);
  if (request != "auto") {
    k.resample = request;
    k.reason = "--resample " + request + " as requested (" + ratio + ")";
  } else if (k.spacingRatio >= kAutoWeightedRatio) {
    // The seed's average filters the source posts a coarser post stands for.
    k.resample = "weighted";
    k.reason = std::string("auto: ") + ratio + " (>= " + limit + ", clearly coarser): the seed's weighted average";
  } else {
    // Near native spacing an average flattens summits and fills valleys;
    // interpolation keeps them (issue 9: -52 m on summits with weighted).
    k.resample = "bilinear";
    k.reason = std::string("auto: ") + ratio + " (< " + limit + ", near native): bilinear, an interpolating kernel" +
               (fit == "triangles" ? ", with the triangle fit" : "");
  }
  k.fit = k.resample == "bilinear" ? fit : "posts";
  return k;
}

namespace detail {



/// Material indices written by an elevation-only build.
enum Material : std::uint8_t { kGround = 0, kWater = 1, kFilledVoid = 2 };


std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char s[32];
  std::strftime(s, sizeof s, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return s;
}

Result<bool> checkOptions(const ElevationOptions& o) {
  static const char* kKernels[] = {"auto", "weighted", "bilinear", "cubic", "average"};
  if (std::find(std::begin(kKernels), std::end(kKernels), o.resample) == std::end(kKernels)) {
    return Problem{"ElevationOptions::resample", 0, "build: unknown ElevationOptions::resample \"" + o.resample +
                                        "\"; use auto, weighted, bilinear, cubic or average"};
  }
  if (o.fit != "triangles" && o.fit != "posts") {
    return Problem{"ElevationOptions::fit", 0, "build: unknown ElevationOptions::fit \"" + o.fit + "\"; use triangles or posts"};
  }
  if (o.output.empty()) return Problem{"ElevationOptions::output", 0, "build: no output directory (ElevationOptions::output)"};
  std::error_code ec;
  if (fs::exists(o.output, ec) && !o.force) {
    return Problem{o.output, 0,
                   "build: the output already exists; choose another ElevationOptions::output or pass "
                   "ElevationOptions::force to replace it"};
  }
  const fs::path parent = fs::absolute(o.output).parent_path();
  if (!fs::is_directory(parent, ec)) {
    return Problem{o.output, 0, "build: the parent directory " + parent.string() + " does not exist"};
  }
  if (o.spacing < 0 || !std::isfinite(o.spacing)) {
    return Problem{"ElevationOptions::spacing", 0, "build: ElevationOptions::spacing must be positive"};
  }
  if (!(o.moduleSize > 0) || o.levels < 1 || o.levels > 8) {
    return Problem{"ElevationOptions::moduleSize", 0,
                   "build: ElevationOptions::moduleSize must be positive and ElevationOptions::levels 1..8"};
  }
  if (!o.modules && (!o.culture.empty() || !o.materials.empty() || !o.icons.empty() || !o.objects.empty())) {
    return Problem{"ElevationOptions::culture", 0,
                   "build: ElevationOptions::culture, ElevationOptions::materials, ElevationOptions::icons and "
                   "ElevationOptions::objects need load modules; drop ElevationOptions::modules = false"};
  }
  if (o.zstdLevel < 1 || o.zstdLevel > 22) {
    return Problem{"ElevationOptions::zstdLevel", 0, "build: ElevationOptions::zstdLevel must be 1..22"};
  }
  if (o.moduleVersion < 1 || o.moduleVersion > module::kNewestVersion || !(std::isfinite(o.heightStep) && o.heightStep >= 0)) {
    return Problem{"ElevationOptions::moduleVersion", 0,
                   "build: ElevationOptions::moduleVersion must be 1 to 4 and ElevationOptions::heightStep a "
                   "finite number >= 0"};
  }
  // OGR would say only that it cannot open a missing file; GDAL's virtual
  // paths (/vsizip/...) and connection strings (PG:...) are OGR's to judge.
  for (const auto& c : o.culture) {
    const bool plainPath = c.rfind("/vsi", 0) != 0 && c.find(':') == std::string::npos;
    if (plainPath && !fs::exists(c, ec)) {
      return Problem{c, 0, "culture: file not found; check the ElevationOptions::culture path"};
    }
  }
  if (!o.materials.empty() && !fs::exists(o.materials, ec)) {
    return Problem{o.materials, 0, "materials: file not found; check the ElevationOptions::materials path"};
  }
  if (!o.icons.empty() && !fs::exists(o.icons, ec)) {
    return Problem{o.icons, 0, "icons: file not found; check the ElevationOptions::icons path"};
  }
  for (const auto& f : o.objects) {
    if (!fs::exists(f, ec)) return Problem{f, 0, "objects: file not found; check the ElevationOptions::objects path"};
  }
  return true;
}


/// One block of the grid file. Posts beyond the grid's edge repeat the
/// edge posts, so every block is complete and plausible. Needs the rows of
/// the block and one more on each side (clamped to the grid). Normals by
/// grid::postNormal, the rule the dynamic-terrain overlay shares.
void fillBlock(const GridRows& g, const Frame& f, std::uint32_t bx, std::uint32_t bz, grid::BlockData& b) {
  const long W = long(f.postsX), H = long(f.postsZ);
  const auto at = [&g](std::uint32_t i, std::uint32_t j) { return g.row(long(j))[i]; };
  for (std::uint32_t lz = 0; lz < grid::kBlockPosts; ++lz) {
    const long j = std::min<long>(bz * grid::kBlockPosts + lz, H - 1);
    const float* mid = g.row(j);
    const std::uint8_t* was = g.classes(j);
    for (std::uint32_t lx = 0; lx < grid::kBlockPosts; ++lx) {
      const long i = std::min<long>(bx * grid::kBlockPosts + lx, W - 1);
      const std::size_t k = lz * grid::kBlockPosts + lx;
      const float h = mid[i];
      b.elevation[k] = h;
      const grid::PostNormal n = grid::postNormal(at, std::uint32_t(i), std::uint32_t(j), f.postsX, f.postsZ, f.spacing);
      b.normalX[k] = n[0];
      b.normalY[k] = n[1];
      b.normalZ[k] = n[2];
      const std::uint8_t c = was ? was[i] : std::uint8_t(detail::kValidPost);
      b.material[k] = c == detail::kSeaPost    ? kWater
                      : c == detail::kVoidPost ? kFilledVoid
                                               : (h <= 0.0f ? kWater : kGround);
    }
  }
}


/// Writes block rows [bz0, bz1) from `g`, in parallel.
Status writeBlockRows(grid::GridWriter& writer, const Frame& f, const GridRows& g, std::uint32_t bz0,
                      std::uint32_t bz1, int threads, const ProgressFn& progress) {
  const grid::Header& h = writer.header();
  const std::size_t n = std::size_t(bz1 - bz0) * h.blocksX;
  std::uint64_t done = 0;
  std::mutex mutex;
  std::string firstError;
  jobs::Scratch<grid::BlockData> blocks;
  jobs::parallelFor(n, threads, [&](std::size_t k) {
    if (cancelRequested()) return;
    const auto bx = static_cast<std::uint32_t>(k % h.blocksX), bz = bz0 + static_cast<std::uint32_t>(k / h.blocksX);
    const std::string err = blocks.use([&](grid::BlockData& block) {
      fillBlock(g, f, bx, bz, block);
      return writer.writeBlock(bx, bz, block).message();
    });
    std::lock_guard lock(mutex);
    if (!err.empty() && firstError.empty()) firstError = err;
    const std::uint64_t d = ++done;
    if (progress && (d % 64 == 0 || d == n)) {
      progress((double(bz0) * h.blocksX + double(d)) / double(h.blockCount()), "writing grid");
    }
  });
  if (cancelRequested()) return Problem{"", 0, "build: cancelled"};
  if (!firstError.empty()) return Problem{"", 0, firstError};
  return {};
}

Result<WrittenGrid> writeGrid(const std::string& path, const Frame& f, const std::vector<float>& g,
                              const std::vector<std::uint8_t>& cls, int threads, const ProgressFn& progress) {
  const grid::Header h = grid::makeHeader(f.postsX, f.postsZ, f.spacing, f.originEasting, f.originNorthing);
  auto writer = grid::GridWriter::create(path, h);
  if (!writer) return writer.problems();
  const GridRows rows{g.data(), cls.data(), 0, f.postsX};
  if (Status st = writeBlockRows(*writer.value(), f, rows, 0, h.blocksZ, threads, progress); !st) {
    return Problem{path, 0, st.message()};
  }
  if (Status st = writer.value()->finish(); !st) return st.problems();
  return WrittenGrid{writer.value()->header(), writer.value()->fileCrc()};
}

/// pwrite / pread of a whole range (they may move fewer bytes).
bool writeAt(int fd, const void* data, std::size_t n, std::uint64_t offset) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::pwrite(fd, p, n, off_t(offset));
    if (w <= 0) return false;
    p += w, n -= std::size_t(w), offset += std::uint64_t(w);
  }
  return true;
}
bool readAt(int fd, void* data, std::size_t n, std::uint64_t offset) {
  char* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::pread(fd, p, n, off_t(offset));
    if (r <= 0) return false;
    p += r, n -= std::size_t(r), offset += std::uint64_t(r);
  }
  return true;
}

/// A scratch file removed when it goes out of scope.
class ScratchFile {
 public:
  explicit ScratchFile(std::string path) : path_(std::move(path)) {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  }
  ~ScratchFile() {
    if (fd_ >= 0) ::close(fd_);
    ::unlink(path_.c_str());
  }
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;
  int fd() const { return fd_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

/// Rows per band: whole 64-row strips, as many as the budget allows, at
/// least one strip; the grid's height when it all fits.
std::uint32_t planBandRows(std::uint64_t budget, const Frame& f, const BandCost& c) {
  const double avail = double(budget) - c.fixed;
  std::uint64_t rows = avail > 0 && c.perRow > 0 ? static_cast<std::uint64_t>(avail / c.perRow) : 0;
  rows = std::max<std::uint64_t>(rows / kMinBandRows * kMinBandRows, kMinBandRows);
  return rows >= f.postsZ ? f.postsZ : static_cast<std::uint32_t>(rows);
}

/// Progress of band b of n: a stage's fraction within its band.
ProgressFn bandProgress(const ProgressFn& p, std::uint32_t b, std::uint32_t n) {
  if (!p) return {};
  return [p, b, n](double fr, const std::string& stage) { p((double(b) + fr) / double(n), stage); };
}

Status fsyncDirectory(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return Problem{dir, 0, "cannot open " + dir};
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) return Problem{dir, 0, "cannot fsync " + dir};
  return {};
}

/// Renames the finished directory into place, replacing an old one only
/// after the new one is complete. Problems name `output`.
Status publish(const std::string& partial, const std::string& output) {
  auto fail = [&](const std::string& msg) { return Status(Problem{output, 0, "build: " + msg}); };
  if (Status st = fsyncDirectory(partial); !st) return fail(st.message());
  std::error_code ec;
  std::string old;
  if (fs::exists(output, ec)) {
    old = output + ".old." + std::to_string(::getpid());
    fs::rename(output, old, ec);
    if (ec) return fail("cannot move the old " + output + " aside: " + ec.message());
  }
  fs::rename(partial, output, ec);
  if (ec) {
    std::error_code back;
    if (!old.empty()) fs::rename(old, output, back);  // put the old database back
    return fail("cannot rename " + partial + " to " + output + ": " + ec.message());
  }
  if (!old.empty()) fs::remove_all(old, ec);
  fsyncDirectory(fs::absolute(output).parent_path().string());
  return {};
}

manifest::Manifest makeManifest(const ElevationOptions& o, const Frame& f, const grid::Header& h,
                                const std::vector<detail::Source>& sources) {
  manifest::Manifest m;
  m.toolVersion = SANDTABLE_VERSION;
  m.createdUtc = utcNow();
  m.crsWkt = f.crs.wkt;
  m.crsName = f.crs.name;
  m.epsg = f.crs.epsg;
  m.originEasting = h.originEasting;
  m.originNorthing = h.originNorthing;
  m.spacing = h.spacing;
  m.postsX = h.postsX;
  m.postsZ = h.postsZ;
  m.blockPosts = h.blockPosts;
  m.minElevation = h.minElevation;
  m.maxElevation = h.maxElevation;
  m.cornersLonLat = f.cornersLonLat;
  m.moduleSize = o.moduleSize;
  m.levels = o.levels;
  for (const auto& s : sources) m.sources.push_back({s.path, s.bytes, s.crc, s.driver});
  return m;
}


/// The icon database: the definitions' icons and the built-in tree, or the
/// tree alone. Built before the grid, so a bad model fails fast.
Status loadIcons(const ElevationOptions& o, CultureSetup& c) {
  icons::Definitions none;
  auto defs = o.icons.empty() ? Result<icons::Definitions>(none) : icons::readDefinitions(o.icons);
  if (!defs) return defs.problems();
  auto pack = icons::buildPack(defs.value());
  if (!pack) return pack.problems();
  c.iconWarnings = pack.warnings();
  c.icons = std::move(pack.value());
  return {};
}

Result<materials::Table> loadMaterials(const ElevationOptions& o) {
  return o.materials.empty()
             ? materials::parse(std::as_bytes(std::span(std::string_view(detail::defaultMaterialsText()))),
                                "built-in materials")
             : materials::readFile(o.materials);
}

Result<CultureSetup> loadCulture(const ElevationOptions& o, const Frame& f, const ProgressFn& progress) {
  CultureSetup c;
  if (!o.modules) return c;
  auto table = loadMaterials(o);
  if (!table) return table.problems();
  c.table = std::move(table.value());
  CultureOptions co;
  co.sources = o.culture;
  co.progress = progress;
  CultureFrame frame{f.crs.wkt, f.originEasting, f.originNorthing, f.spacing * (f.postsX - 1),
                     f.spacing * (f.postsZ - 1)};
  auto culture = Culture::load(co, c.table, frame);
  if (!culture) return culture.problems();
  c.culture = culture.value();
  if (Status st = loadIcons(o, c); !st) return st.problems();
  auto plan = makeObjectPlan(o.objects, frame, c.table, c.culture.get(), c.icons);
  if (!plan) return plan.problems();
  c.objectWarnings = plan.warnings();
  c.objects = std::move(plan.value());
  return c;
}

ModuleOptions moduleOptions(const ElevationOptions& o, const CultureSetup& c) {
  ModuleOptions mo;
  mo.moduleSize = o.moduleSize;
  mo.levels = o.levels;
  mo.threads = o.threads;
  mo.zstdLevel = o.zstdLevel;
  mo.moduleVersion = o.moduleVersion;
  mo.heightStep = o.heightStep;
  mo.normals = o.moduleNormals;
  mo.objects = &c.objects;
  return mo;
}

Status writeModuleSideFiles(const std::string& dir, const CultureSetup& c, const ModuleReport& r,
                            ElevationReport& report) {
  const std::string text = materials::format(c.table);
  const auto bytes = std::as_bytes(std::span(text.data(), text.size()));
  if (Status st = writeFileAtomic(dir + "/" + materials::kFileName, bytes); !st) {
    return Problem{dir, 0, "build: " + st.message()};
  }
  auto iconBytes = iconpack::encode(c.icons);
  if (!iconBytes) return iconBytes.problems();
  if (Status st = writeFileAtomic(dir + "/" + iconpack::kFileName, iconBytes.value()); !st) {
    return Problem{dir, 0, "build: " + st.message()};
  }
  auto& files = report.manifest.files;
  files.push_back({pack::kPackFileName, r.packBytes, r.packCrc});
  files.push_back({pack::kIndexFileName, r.indexBytes, r.indexCrc});
  files.push_back({materials::kFileName, text.size(), crc32(bytes)});
  files.push_back({iconpack::kFileName, iconBytes->size(), crc32(iconBytes.value())});
  report.manifest.moduleSize = r.moduleSize;
  report.modules = r.modules;
  report.moduleSeconds = r.seconds;
  return {};
}

Result<ModuleReport> writeModules(const ElevationOptions& o, const std::string& gridPath, const std::string& dir,
                                  const CultureSetup& c, ElevationReport& report, const ProgressFn& progress) {
  auto grid = grid::GridFile::open(gridPath);
  if (!grid) return grid.problems();
  auto r = buildModules(dir, *grid.value(), *c.culture, c.table.defaultArea, moduleOptions(o, c), progress);
  if (!r) return r.problems();
  if (Status st = writeModuleSideFiles(dir, c, r.value(), report); !st) return st.problems();
  return r;
}

nlohmann::json iconsReportJson(const ElevationOptions& o, const CultureSetup& c) {
  nlohmann::json names = nlohmann::json::array(), warnings = nlohmann::json::array();
  for (const auto& i : c.icons.icons) names.push_back(i.name);
  for (const Problem& w : c.iconWarnings) warnings.push_back(w.str());
  return {{"definitions", o.icons.empty() ? std::string("built-in tree") : o.icons},
          {"count", c.icons.icons.size()},
          {"names", names},
          {"textures", c.icons.textures.size()},
          {"warnings", warnings}};
}

/// The name objects_by_class gives an Object::cls.
std::string objectClassName(const materials::Table& t, std::uint16_t cls) {
  if (cls == module::kObjectClassExplicit) return "explicit";
  if (cls >= module::kObjectClassPlace) {
    const std::size_t k = cls - module::kObjectClassPlace;
    return k < t.places.size() ? t.places[k].key + "=" + t.places[k].value : "place " + std::to_string(k);
  }
  const materials::Class* c = t.find(cls);
  return c ? c->name : "class " + std::to_string(cls);
}

nlohmann::json objectWarningsJson(const CultureSetup& c) {
  nlohmann::json warnings = nlohmann::json::array();
  for (const Problem& w : c.objectWarnings) warnings.push_back(w.str());
  return warnings;
}

nlohmann::json objectsReportJson(const ElevationOptions& o, const materials::Table& table,
                                 const nlohmann::json& warnings, const ModuleReport& r) {
  nlohmann::json byClass = nlohmann::json::object(), files = nlohmann::json::array();
  for (const auto& [cls, n] : r.objects.byClass) byClass[objectClassName(table, cls)] = n;
  for (const auto& f : o.objects) files.push_back(f);
  return {{"count", r.objects.placed},
          {"by_class", byClass},
          {"scatter_refused", r.objects.scatterRefused},
          {"points_files", files},
          {"warnings", warnings}};
}

nlohmann::json moduleReportJson(const ModuleReport& r) {
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& l : r.levels) {
    levels.push_back({{"triangles", l.triangles}, {"skin_polygons", l.skinPolygons},
                      {"decal_polygons", l.decalPolygons}, {"skirt_triangles", l.skirtTriangles},
                      {"buildings", l.buildings}, {"building_triangles", l.buildingTriangles}});
  }
  const auto& s = r.sizes;
  return {{"count", r.modules},
          {"modules_x", r.modulesX},
          {"modules_z", r.modulesZ},
          {"module_squares", r.moduleSquares},
          {"module_size_m", r.moduleSize},
          {"format_version", r.moduleVersion},
          {"height_step_m", r.heightStep},
          {"normals", r.normals},
          {"seconds", r.seconds},
          {"modules_per_second", double(r.modules) / std::max(r.seconds, 1e-9)},
          {"bytes", sizeStatsJson(s)},
          {"per_level", levels},
          {"stage_cpu_seconds", {{"terrain", r.stages.terrain}, {"culture_partition", r.stages.partition},
                                 {"culture_gather", r.stages.gather}, {"culture_arrangement", r.stages.arrangement},
                                 {"culture_pieces", r.stages.pieces}, {"culture_cut", r.stages.cut},
                                 {"compress", r.stages.compress}, {"write", r.stages.write}}}};
}

nlohmann::json accuracyJson(const SourceAccuracy& a) {
  return {{"source_posts", a.samples}, {"rmse_m", a.rmse}, {"max_abs_m", a.maxAbs}, {"mean_m", a.mean},
          {"worst_lonlat", a.worstLonLat}, {"worst_source_m", a.worstSource}, {"worst_error_m", a.worstError},
          {"sample", "every k-th source post along rows and columns (about 8192 over the grid), valid and inside it, "
                     "against the drawn triangles"}};
}

nlohmann::json cultureReportJson(const ElevationOptions& o, const Culture& c) {
  const CultureStats& st = c.stats();
  nlohmann::json classes = nlohmann::json::object();
  for (const auto& [name, k] : st.perClass) {
    classes[name] = {{"read", k.read},         {"dropped", k.dropped}, {"repaired", k.repaired},
                     {"defaulted", k.defaulted}, {"length_km", k.lengthKm}, {"area_km2", k.areaKm2}};
  }
  nlohmann::json reasons = nlohmann::json::object();
  for (const auto& [key, r] : st.reasons) {
    reasons[key] = {{"count", r.count}, {"action", r.action}, {"text", r.text}, {"sample", r.sample},
                    {"warning", r.warning}};
  }
  return {{"sources", o.culture},
          {"materials", o.materials.empty() ? std::string("built-in default") : o.materials},
          {"reasons", reasons},
          {"features_read", st.featuresRead},
          {"features_landed", st.featuresLanded},
          {"buildings", st.buildings},
          {"features_outside", st.featuresOutside},
          {"line_vertices_read", st.lineVerticesRead},
          {"line_vertices_kept", st.lineVerticesKept},
          {"lines_coarsened", st.coarsened},
          {"max_line_vertices", CultureOptions{}.maxLineVertices},
          {"warnings", st.warnings},
          {"load_seconds", st.seconds},
          {"messages", st.messages},
          {"classes", classes}};
}

void describeBuild(const ElevationOptions& o, const BuildFacts& b, const std::optional<ModuleReport>& modules,
                   const ModuleJson& mj, std::chrono::steady_clock::time_point t0, ElevationReport& report) {
  report.posts = std::uint64_t(report.manifest.postsX) * report.manifest.postsZ;
  report.voidsFilled = b.voidsFilled;
  report.seaPosts = b.seaPosts;
  report.kernel = b.kernel;
  report.accuracy = b.accuracy;
  report.resampleSeconds = b.resampleSeconds;
  report.bandRows = b.bandRows;
  report.bands = b.bands;
  report.banded = b.banded;
  report.bandBytes = b.bandBytes;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  report.postsPerSecond = double(report.posts) / std::max(report.seconds, 1e-9);
  const KernelChoice& kernel = b.kernel;
  report.manifest.build = {
      {"crs_request", o.crs},        {"resample", kernel.resample}, {"fit", kernel.fit},
      {"resample_request", o.resample}, {"resample_reason", kernel.reason},
      {"spacing_ratio", kernel.spacingRatio},
      {"spacing_request_m", o.spacing}, {"voids_filled", report.voidsFilled},
      {"sea_posts", report.seaPosts}, {"sea_from_voids", o.seaFromVoids},
      {"posts", report.posts},       {"seconds", report.seconds},
      {"resample_seconds", b.resampleSeconds}, {"posts_per_second", report.postsPerSecond},
      {"memory", {{"budget_bytes", o.memoryBudgetBytes}, {"band_rows", b.bandRows}, {"bands", b.bands},
                  {"banded", b.banded}, {"band_bytes_estimate", report.bandBytes}}},
      {"void_fill", "GDALFillNodata within 64 posts; beyond, the same on 16x coarser grids, interpolated back"},
      {"accuracy", accuracyJson(b.accuracy)},
      {"materials", {{"0", "ground"}, {"1", "water (elevation <= 0 m, or sea from voids)"}, {"2", "filled void"}}}};
  if (o.seaFromVoids) {
    char rule[200];
    std::snprintf(rule, sizeof rule,
                  "void components reached from the grid's edge through voids and posts <= 0 m, whose shore posts "
                  "have a median elevation within %g m of 0, are sea: 0 m, material 1",
                  kSeaShoreMedianM);
    report.manifest.build["sea_rule"] = rule;
  }
  if (o.extent) report.manifest.build["extent_lonlat"] = *o.extent;
  if (modules) {
    report.manifest.build["modules"] = moduleReportJson(*modules);
    report.manifest.build["culture"] = mj.culture;
    report.manifest.build["icons"] = mj.icons;
    report.manifest.build["objects"] = mj.objects;
  }
}

Status publishWithManifest(PartialDirectory& partial, const std::string& output, const manifest::Manifest& m,
                           const std::string& stage) {
  const std::string text = manifest::encode(m);
  if (Status st = writeFileAtomic(partial.path() + "/" + manifest::kFileName,
                                  std::as_bytes(std::span(text.data(), text.size())));
      !st) {
    return Problem{output, 0, stage + ": " + st.message()};
  }
  if (cancelRequested()) return Problem{output, 0, stage + ": cancelled"};
  if (Status st = publish(partial.path(), output); !st) return st;
  partial.published();
  return {};
}

}  // namespace detail

Result<ElevationReport> buildElevation(const ElevationOptions& o, const ProgressFn& progress) {
  using namespace detail;
  const auto t0 = std::chrono::steady_clock::now();
  if (auto ok = checkOptions(o); !ok) return ok.problems();
  auto paths = expandSources(o.sources);
  if (!paths) return paths.problems();
  auto sources = detail::openSources(paths.value(), o.threads, progress);
  if (!sources) return sources.problems();
  auto frame = detail::planFrame(o, sources.value());
  if (!frame) return frame.problems();
  const Frame& f = frame.value();
  if (o.onEstimate) o.onEstimate(estimateBuild(o, f.postsX, f.postsZ, f.spacing));
  auto culture = loadCulture(o, f, progress);  // before resampling: bad culture fails fast
  if (!culture) return culture.problems();

  PartialDirectory partial(o.output + ".partial." + std::to_string(::getpid()));
  std::error_code ec;
  fs::create_directories(partial.path(), ec);
  if (ec) return Problem{partial.path(), 0, "build: cannot create the work directory: " + ec.message()};

  const std::string vrt = partial.path() + "/mosaic.vrt";
  // The stages' problems carry only a message; the build names its output.
  auto atOutput = [&](const auto& st) { return Problem{o.output, 0, st.message()}; };
  if (Status st = detail::buildMosaic(sources.value(), vrt); !st) return atOutput(st);
  const KernelChoice kernel = chooseKernel(o.resample, o.fit, f.spacing, detail::nativeSpacingMetres(sources.value()));
  const bool triangles = kernel.fit == "triangles";
  const detail::BandCost cost = detail::bandCost(vrt, f, kernel);
  const std::uint32_t bandRows = planBandRows(o.memoryBudgetBytes, f, cost);
  const std::uint32_t bands = (f.postsZ + bandRows - 1) / bandRows;
  const std::size_t W = f.postsX;
  const std::string gridPath = partial.path() + "/" + manifest::kGridFileName;
  const auto tr = std::chrono::steady_clock::now();
  auto since = [](auto t) { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count(); };
  double resampleSeconds = 0;
  std::vector<float> g;  // the whole grid, when it is held at once
  std::optional<WrittenGrid> written;
  std::uint64_t seaPosts = 0, voidsFilled = 0;
  SourceAccuracy accuracy;
  bool banded = bands > 1;
  if (banded) {
    // Pass 1: resample (and fit) band by band into a scratch file of raw
    // posts; the fit's halo rows are resampled again by the next band.
    ScratchFile raw(partial.path() + "/resampled.f32");
    if (raw.fd() < 0) return Problem{o.output, 0, "build: cannot create " + raw.path()};
    std::vector<float> buf;
    std::uint64_t voids = 0;
    for (std::uint32_t b = 0; b < bands; ++b) {
      const std::uint32_t a = b * bandRows, e = std::min(f.postsZ, a + bandRows);
      const std::uint32_t ea = triangles ? (a >= detail::kFitHalo ? a - detail::kFitHalo : 0) : a;
      const std::uint32_t ee = triangles ? std::min(f.postsZ, e + detail::kFitHalo) : e;
      buf.resize(std::size_t(ee - ea) * W);
      const ProgressFn bp = bandProgress(progress, b, bands);
      if (Status st = detail::resampleRows(vrt, f, kernel.resample, ea, ee, o.threads, buf.data(), bp); !st) {
        return atOutput(st);
      }
      if (triangles) {
        if (Status st = detail::fitTriangles(vrt, f, ea, ee, o.threads, buf.data(), bp); !st) return atOutput(st);
      }
      const float* rows = buf.data() + std::size_t(a - ea) * W;
      const std::size_t n = std::size_t(e - a) * W;
      voids += static_cast<std::uint64_t>(std::count_if(rows, rows + n, [](float v) { return std::isnan(v); }));
      if (!writeAt(raw.fd(), rows, n * sizeof(float), std::uint64_t(a) * W * sizeof(float))) {
        return Problem{o.output, 0, "build: cannot write " + raw.path()};
      }
    }
    resampleSeconds = since(tr);
    if (voids > 0) {
      // Sea and void fill look at the whole grid: hold it after all.
      banded = false;
      g.resize(W * f.postsZ);
      if (!readAt(raw.fd(), g.data(), g.size() * sizeof(float), 0)) {
        return Problem{o.output, 0, "build: cannot read " + raw.path()};
      }
    } else {
      // Pass 2: each band with a row more on each side (the normals), into
      // its block rows and the accuracy sample.
      const grid::Header h = grid::makeHeader(f.postsX, f.postsZ, f.spacing, f.originEasting, f.originNorthing);
      auto writer = grid::GridWriter::create(gridPath, h);
      if (!writer) return writer.problems();
      detail::AccuracySampler sampler;
      if (Status st = sampler.prepare(vrt, f); !st) return atOutput(st);
      for (std::uint32_t b = 0; b < bands; ++b) {
        const std::uint32_t a = b * bandRows, e = std::min(f.postsZ, a + bandRows);
        const std::uint32_t ra = a > 0 ? a - 1 : 0, re = std::min(f.postsZ, e + 1);
        buf.resize(std::size_t(re - ra) * W);
        if (!readAt(raw.fd(), buf.data(), buf.size() * sizeof(float), std::uint64_t(ra) * W * sizeof(float))) {
          return Problem{o.output, 0, "build: cannot read " + raw.path()};
        }
        const GridRows rows{buf.data(), nullptr, long(ra), W};
        const std::uint32_t bz0 = a / grid::kBlockPosts, bz1 = (e + grid::kBlockPosts - 1) / grid::kBlockPosts;
        if (Status st = writeBlockRows(*writer.value(), f, rows, bz0, bz1, o.threads, progress); !st) {
          return Problem{gridPath, 0, st.message()};
        }
        sampler.add(a, e, [&](std::uint32_t j) { return rows.row(long(j)); });
      }
      if (Status st = writer.value()->finish(); !st) return st.problems();
      written = WrittenGrid{writer.value()->header(), writer.value()->fileCrc()};
      accuracy = sampler.finish();
    }
  } else {
    g.assign(W * f.postsZ, NAN);
    if (Status st = detail::resampleRows(vrt, f, kernel.resample, 0, f.postsZ, o.threads, g.data(), progress); !st) {
      return atOutput(st);
    }
    if (triangles) {
      if (Status st = detail::fitTriangles(vrt, f, 0, f.postsZ, o.threads, g.data(), progress); !st) {
        return atOutput(st);
      }
    }
    resampleSeconds = since(tr);
  }
  if (!written) {
    std::vector<std::uint8_t> cls(g.size());  // detail::PostClass per post
    jobs::parallelRanges(g.size(), o.threads, std::size_t(1) << 16, [&](std::size_t b, std::size_t e) {
      for (std::size_t k = b; k < e; ++k) cls[k] = std::isnan(g[k]) ? detail::kVoidPost : detail::kValidPost;
    });
    seaPosts = o.seaFromVoids ? detail::markSea(f, g, cls) : 0;
    auto voids = detail::fillVoids(f, g, progress);
    if (!voids) return voids.problems();
    voidsFilled = voids.value();
    const auto measured = detail::measureAccuracy(vrt, f, g);
    if (!measured) return atOutput(measured);
    accuracy = measured.value();
    auto w = writeGrid(gridPath, f, g, cls, o.threads, progress);
    if (!w) return w.problems();
    written = w.value();
    g = {};
  }
  fs::remove(vrt, ec);
  const WrittenGrid& header = *written;

  ElevationReport report;
  report.manifest = makeManifest(o, f, header.header, sources.value());
  // The CRC of what was written, from the writer's block CRCs: re-reading
  // the file would only check the page cache.
  report.manifest.files.push_back({manifest::kGridFileName, header.header.fileBytes, header.crc});
  std::optional<ModuleReport> modules;
  if (o.modules) {
    auto built = writeModules(o, gridPath, partial.path(), culture.value(), report, progress);
    if (!built) return built.problems();
    modules = built.value();
  }
  BuildFacts facts{kernel, accuracy, voidsFilled, seaPosts, resampleSeconds, bandRows, bands, banded,
                   static_cast<std::uint64_t>(cost.fixed + cost.perRow * bandRows)};
  ModuleJson moduleJson;
  if (modules) {
    moduleJson.culture = cultureReportJson(o, *culture.value().culture);
    moduleJson.icons = iconsReportJson(o, culture.value());
    moduleJson.objects = objectsReportJson(o, culture.value().table, objectWarningsJson(culture.value()), *modules);
  }
  describeBuild(o, facts, modules, moduleJson, t0, report);

  if (Status st = publishWithManifest(partial, o.output, report.manifest, "build"); !st) return st.problems();
  return report;
}

}  // namespace sandtable::convert
