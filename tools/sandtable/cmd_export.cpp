// sandtable export: load modules as OBJ + MTL or glTF 2.0 for other tools,
// and the elevation grid as a GeoTIFF (--grid).
#include <atomic>
#include <cctype>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <tuple>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "db_util.h"
#include "journal_util.h"
#include "progress.h"
#include "sandtable/converters/grid_export.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/formats/mesh_export.h"
#include "sandtable/formats/object_export.h"

namespace sandtable::cli {
namespace {

namespace fs = std::filesystem;

struct ExportArgs {
  std::string dir;
  std::string journal;  ///< terrain edits over the posts and modules (journal_util.h)
  std::vector<std::uint32_t> from, to;
  std::vector<double> lonlat, xy;  ///< a point whose module is the north-west one
  std::uint32_t level = 0;
  std::string format;
  std::string output;
  std::string objects = "auto";  ///< auto, instanced, flatten, none
  std::uint32_t iconLevel = 0;
  std::string icon;              ///< export this icon alone
  bool noSkirts = false;
  bool grid = false;  ///< the elevation grid as a GeoTIFF instead of modules
  bool json = false;
};

/// What a written export holds besides the terrain.
struct Written {
  mesh_export::GltfExtras more;
  std::string objectMode = "none";
  std::uint64_t objects = 0;
};

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string moduleName(std::uint32_t kx, std::uint32_t kz) {
  return "(" + std::to_string(kx) + "," + std::to_string(kz) + ")";
}

Status writeText(const std::string& path, const std::string& text) {
  return writeFileAtomic(path, std::as_bytes(std::span(text.data(), text.size())));
}

/// A point given by --lonlat or --xy, and the module that holds it.
struct Point {
  double lon = 0, lat = 0, easting = 0, northing = 0;
  std::uint32_t kx = 0, kz = 0;
};

/// The module under --lonlat / --xy: module (kx, kz) covers eastings
/// origin + [kx, kx + 1) * edge and northings origin - [kz, kz + 1) * edge;
/// a point on the grid's east or south edge belongs to the last module.
std::string locate(const ExportArgs& a, const Database& db, Point& p) {
  const auto& m = db.manifest;
  auto geo = geodesy::Projection::create(m.crsWkt);
  if (!geo) return geo.error();
  const char* opt = a.lonlat.empty() ? "--xy" : "--lonlat";
  if (!a.lonlat.empty()) {
    p.lon = a.lonlat[0], p.lat = a.lonlat[1];
    const auto en = geo->toProjected({p.lon, p.lat});
    if (en) p.easting = en->easting, p.northing = en->northing;
    else {
      return "--lonlat " + std::to_string(p.lon) + " " + std::to_string(p.lat) + " cannot be projected into " +
             m.crsName;
    }
  } else {
    p.easting = a.xy[0], p.northing = a.xy[1];
    const auto ll = geo->toLonLat({p.easting, p.northing});
    p.lon = ll ? ll->lon : NAN;
    p.lat = ll ? ll->lat : NAN;
  }
  const pack::IndexHeader& h = db.modules->header();
  const double edge = double(h.moduleSquares) * db.grid->spacing();
  const double dx = p.easting - m.originEasting, dz = m.originNorthing - p.northing;
  if (!(dx >= 0 && p.easting <= m.eastEasting() && dz >= 0 && p.northing >= m.southNorthing())) {
    char buf[256];
    std::snprintf(buf, sizeof buf, " (E %.2f N %.2f in %s) is outside the database: it covers E %.2f .. %.2f, "
                  "N %.2f .. %.2f", p.easting, p.northing, m.crsName.c_str(), m.originEasting, m.eastEasting(),
                  m.southNorthing(), m.originNorthing);
    return std::string(opt) + buf;
  }
  p.kx = std::min(std::uint32_t(dx / edge), h.modulesX - 1);
  p.kz = std::min(std::uint32_t(dz / edge), h.modulesZ - 1);
  return {};
}

/// The output format: --format, else the output's extension (.glb selects
/// binary glTF); "" after reporting a usage error.
std::string outputFormat(const ExportArgs& a, bool& glb) {
  const std::string ext = lower(fs::path(a.output).extension().string());
  const std::string byExt = ext == ".obj" ? "obj" : (ext == ".gltf" || ext == ".glb") ? "gltf" : "";
  const std::string format = a.format.empty() ? byExt : a.format;
  if (format.empty()) {
    usageError("export", "give --format obj|gltf (the output " + a.output + " ends in none of .obj, .gltf, .glb)");
    return {};
  }
  if (!byExt.empty() && byExt != format) {
    usageError("export", "--format " + format + " but the output " + a.output + " is a " + ext + " file");
    return {};
  }
  glb = format == "gltf" && ext == ".glb";
  return format;
}

/// Writes `mesh` (and `more`) as `format`; the files written are added to `files`.
Status writeMesh(const ExportArgs& a, const std::string& format, bool glb, const mesh_export::Mesh& mesh,
                 const nlohmann::json& info, const std::vector<std::string>& header,
                 const mesh_export::GltfExtras& more, std::vector<std::string>& files) {
  files = {a.output};
  if (format == "obj") {
    fs::path mtl = fs::path(a.output).replace_extension(".mtl");
    files.push_back(mtl.string());
    Status saved = writeText(mtl.string(), mesh_export::toMtl(mesh));
    if (saved) saved = writeText(a.output, mesh_export::toObj(mesh, mtl.filename().string(), header));
    return saved;
  }
  if (glb) return writeFileAtomic(a.output, mesh_export::toGlb(mesh, {{"sandtable", info}}, more));
  return writeText(a.output, mesh_export::toGltf(mesh, {{"sandtable", info}}, more));
}

/// The --json summary both exports start from.
nlohmann::json summary(const nlohmann::json& info, const std::vector<std::string>& files, const std::string& format,
                       bool glb, const mesh_export::Mesh& mesh) {
  nlohmann::json j = info;
  j["files"] = files;
  j["format"] = glb ? "glb" : format;
  j["vertices"] = mesh.positions.size();
  j["triangles"] = mesh.triangles();
  return j;
}

/// `export DB --icon NAME`: one icon of icons.pack alone, in its body frame.
int exportIcon(const ExportArgs& a, const Database& db, const std::string& format, bool glb) {
  if (!db.icons) {
    return usageError("export", a.dir + " has no icons.pack (built before icons); rebuild it to export icons");
  }
  const auto& icons = db.icons->icons;
  std::size_t index = icons.size();
  std::string names;
  for (std::size_t i = 0; i < icons.size(); ++i) {
    if (icons[i].name == a.icon) index = i;
    names += (i ? ", " : "") + icons[i].name;
  }
  if (index == icons.size()) return usageError("export", "--icon " + a.icon + " is not in icons.pack; it has " + names);
  const auto& icon = icons[index];
  if (a.iconLevel >= icon.ranges.size()) {
    return usageError("export", "--icon-level " + std::to_string(a.iconLevel) + " is out of range: " + a.icon +
                                    " has " + std::to_string(icon.ranges.size()) + " levels, 0 (full) to " +
                                    std::to_string(icon.ranges.size() - 1));
  }
  mesh_export::GltfExtras more;
  std::vector<std::int32_t> map;
  const mesh_export::Mesh mesh = mesh_export::iconMesh(*db.icons, index, a.iconLevel, more.textures, map);
  const nlohmann::json info = {{"database", a.dir},
                               {"icon", a.icon},
                               {"icon_level", a.iconLevel},
                               {"frame", "metres; the icon's body frame: X right, Y up, Z back (its front is -Z); "
                                         "origin at its base"}};
  std::vector<std::string> files;
  const std::vector<std::string> header = {"sandtable export of icon " + a.icon + " of " + a.dir + ", level " +
                                           std::to_string(a.iconLevel), info["frame"].get<std::string>()};
  if (Status st = writeMesh(a, format, glb, mesh, info, header, more, files); !st) {
    return usageError("export", st.message());
  }
  if (a.json) {
    nlohmann::json j = summary(info, files, format, glb, mesh);
    j["textures"] = more.textures.size();
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("wrote %s: icon %s at level %u, %zu vertices, %zu triangles, %zu materials, %zu textures\n",
                a.output.c_str(), a.icon.c_str(), a.iconLevel, mesh.positions.size(), mesh.triangles(),
                mesh.parts.size(), more.textures.size());
  }
  return kOk;
}

/// The objects mode: --objects, where "auto" is instanced for glTF and
/// flattened for OBJ; "" after reporting a usage error.
std::string objectMode(const ExportArgs& a, const std::string& format, const Database& db) {
  std::string mode = a.objects;
  if (mode == "auto") mode = !db.icons ? "none" : format == "obj" ? "flatten" : "instanced";
  if (mode == "instanced" && format == "obj") {
    usageError("export", "--objects instanced needs glTF (EXT_mesh_gpu_instancing); use --objects flatten for OBJ");
    return {};
  }
  if (mode != "none" && !db.icons) {
    usageError("export", "--objects " + mode + ": " + a.dir +
                             " has no icons.pack (built before icons); rebuild it, or give --objects none");
    return {};
  }
  return mode;
}

// ---------------------------------------------------------------- --grid

std::atomic<bool> gGridCancel{false};
volatile std::sig_atomic_t gGridSignal = 0;

/// Stops the grid export, which then removes its temporary file; a second
/// signal ends the process at once (as `build` does).
void onGridSignal(int sig) {
  gGridSignal = sig;
  gGridCancel.store(true);
  std::signal(sig, SIG_DFL);
}

/// Below this many posts the file is written in well under a second: no
/// progress lines.
constexpr std::uint64_t kGridProgressPosts = std::uint64_t(1) << 22;

/// `export DB --grid -o FILE.tif`: `field` (the database's grid, or the
/// same posts edited) as a GeoTIFF in the manifest's CRS.
int exportGrid(const ExportArgs& a, const Database& db, const grid::HeightField& field) {
  const std::string ext = lower(fs::path(a.output).extension().string());
  if (ext != ".tif" && ext != ".tiff") {
    return usageError("export", "--grid writes a GeoTIFF; give an output ending in .tif or .tiff (not " + a.output +
                                    ")");
  }
  const auto& man = db.manifest;
  const std::uint64_t posts = std::uint64_t(field.postsX()) * field.postsZ();
  std::signal(SIGINT, onGridSignal);
  std::signal(SIGTERM, onGridSignal);
  Progress progress(a.json || posts < kGridProgressPosts);
  Work work;
  work.progress = [&](double f, const std::string& stage) { progress.update(f, stage); };
  work.cancel = &gGridCancel;
  auto written = convert::exportGridGeoTiff(field, man.crsWkt, a.output, work);
  progress.done();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (!written && gGridSignal != 0) {
    std::fprintf(stderr, "sandtable export: cancelled by signal %d; nothing was written to %s\n", int(gGridSignal),
                 a.output.c_str());
    return 128 + gGridSignal;  // the shell's convention for a process ended by a signal
  }
  if (!written) return reportProblems("export", written.problems());
  const convert::GridExportReport& r = written.value();
  if (a.json) {
    const nlohmann::json j = {{"database", a.dir},
                              {"path", r.path},
                              {"format", "GTiff"},
                              {"data_type", "Float32"},
                              {"size", {r.postsX, r.postsZ}},
                              {"posts", r.posts},
                              {"bytes", r.bytes},
                              {"spacing_m", field.spacing()},
                              {"area_or_point", "Point"},
                              {"origin_easting", field.originEasting()},
                              {"origin_northing", field.originNorthing()},
                              {"crs_name", man.crsName},
                              {"epsg", man.epsg}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("wrote %s: %u x %u posts at %g m in %s, Float32, %llu bytes\n", r.path.c_str(), r.postsX, r.postsZ,
                field.spacing(), man.crsName.c_str(), static_cast<unsigned long long>(r.bytes));
  }
  return kOk;
}

/// Module (kx, kz) from the edited world when there is one, else the pack.
Result<module::Module> readModule(const Database& db, const std::optional<EditedWorld>& edited, std::uint32_t kx,
                                  std::uint32_t kz) {
  if (!edited) return db.modules->read(kx, kz);
  module::Module m;
  if (auto r = edited->world()->modules()->read(kx, kz, m); !r) return r.problems();
  return m;
}

int runExport(ExportArgs& a) {
  if (a.grid) {
    // The posts as the journal left them (the database's own edits.journal
    // when there is one; --journal none: as built).
    auto ew = openEditedWorld("export", a.dir, a.journal, /*append=*/false, editorOptions(false, false));
    if (!ew) return kUsage;
    return exportGrid(a, ew->base->database(), *ew->world()->heights());
  }
  const int sources = int(!a.from.empty()) + int(!a.lonlat.empty()) + int(!a.xy.empty()) + int(!a.icon.empty());
  if (sources != 1) {
    return usageError("export", "give exactly one of --module KX KZ, --lonlat LON LAT, --xy E N or --icon NAME");
  }
  bool glb = false;
  const std::string format = outputFormat(a, glb);
  if (format.empty()) return kUsage;

  auto db = openOrReport("export", a.dir);
  if (!db) return kUsage;
  if (!a.icon.empty()) return exportIcon(a, *db, format, glb);
  const std::string mode = objectMode(a, format, *db);
  if (mode.empty()) return kUsage;
  if (!db->modules) {
    return usageError("export", a.dir + " has no load modules (built with --no-modules?); rebuild it with modules");
  }
  // The modules as the journal left them, re-meshed (the database's own
  // edits.journal when there is one; --journal none: as built).
  std::optional<EditedWorld> edited;
  if (!journalPath(a.dir, a.journal).empty()) {
    edited = openEditedWorld("export", a.dir, a.journal, /*append=*/false, editorOptions(true, false));
    if (!edited) return kUsage;
  }
  const pack::IndexHeader& h = db->modules->header();
  std::optional<Point> point;
  if (a.from.empty()) {
    point.emplace();
    if (std::string e = locate(a, *db, *point); !e.empty()) return usageError("export", e);
    a.from = {point->kx, point->kz};
  }
  const std::uint32_t kx0 = a.from[0], kz0 = a.from[1];
  const std::uint32_t kx1 = a.to.empty() ? kx0 : a.to[0], kz1 = a.to.empty() ? kz0 : a.to[1];
  for (const auto& [kx, kz, opt] : {std::tuple{kx0, kz0, "--module"}, std::tuple{kx1, kz1, "--to"}}) {
    if (kx >= h.modulesX || kz >= h.modulesZ) {
      return usageError("export", std::string(opt) + " " + moduleName(kx, kz) + " is outside the database: it has " +
                                      std::to_string(h.modulesX) + " x " + std::to_string(h.modulesZ) +
                                      " modules, KX 0.." + std::to_string(h.modulesX - 1) + " and KZ 0.." +
                                      std::to_string(h.modulesZ - 1));
    }
  }
  if (kx1 < kx0 || kz1 < kz0) {
    return usageError("export", "--to " + moduleName(kx1, kz1) + " lies west or north of --module " +
                                    moduleName(kx0, kz0) + "; give the north-west module first");
  }
  if (a.level >= h.levels) {
    return usageError("export", "level " + std::to_string(a.level) + " is out of range: the database has " +
                                    std::to_string(h.levels) + " levels, 0 (finest) to " +
                                    std::to_string(h.levels - 1));
  }

  mesh_export::Options o;
  o.level = a.level;
  o.skirts = !a.noSkirts;
  o.materials = db->materials ? &*db->materials : nullptr;
  mesh_export::MeshBuilder builder(o);
  std::optional<mesh_export::ObjectCollector> objects;
  if (mode != "none") objects.emplace(*db->icons, a.level, a.iconLevel);
  const double edge = double(h.moduleSquares) * db->grid->spacing();
  for (std::uint32_t kz = kz0; kz <= kz1; ++kz) {
    for (std::uint32_t kx = kx0; kx <= kx1; ++kx) {
      Result<module::Module> m = readModule(*db, edited, kx, kz);
      if (!m) {
        reportProblems("export", m.problems());
        std::fprintf(stderr, "sandtable export: hint: run `sandtable validate %s` for a full report\n", a.dir.c_str());
        return kUsage;
      }
      const double x = double(kx - kx0) * edge, z = double(kz - kz0) * edge;
      if (Status st = builder.add(m.value(), x, z); !st) return usageError("export", st.message());
      if (objects) {
        if (Status st = objects->add(m.value(), x, z); !st) return usageError("export", st.message());
      }
    }
  }
  mesh_export::Mesh mesh = builder.finish();
  Written extra;
  if (objects) {
    extra.objectMode = mode;
    extra.objects = objects->objects();
    if (mode == "instanced") extra.more = objects->instanced();
    else objects->flattenInto(mesh, extra.more.textures);
  }
  if (mesh.triangles() == 0) return usageError("export", "nothing to export: the modules have no triangles at that level");

  const auto& man = db->manifest;
  const double easting = man.originEasting + double(kx0) * edge;
  const double northing = man.originNorthing - double(kz0) * edge;
  const std::uint64_t modules = std::uint64_t(kx1 - kx0 + 1) * (kz1 - kz0 + 1);
  nlohmann::json info = {
      {"database", a.dir},
      {"modules", {{"from", {kx0, kz0}}, {"to", {kx1, kz1}}, {"count", modules}}},
      {"level", a.level},
      {"skirts", !a.noSkirts},
      {"frame", "metres; X east, Y up (elevation above the vertical datum), Z south (north is -Z); "
                "origin at the north-west corner of module " + moduleName(kx0, kz0)},
      {"origin_easting", easting},
      {"origin_northing", northing},
      {"crs_name", man.crsName},
      {"epsg", man.epsg},
      {"objects", {{"mode", extra.objectMode}, {"count", extra.objects}, {"icon_level", a.iconLevel}}}};
  if (point) {
    info["point"] = {{"lon", point->lon}, {"lat", point->lat}, {"easting", point->easting},
                     {"northing", point->northing}};
  }

  const std::vector<std::string> header = {
      "sandtable export of " + a.dir + ": modules " + moduleName(kx0, kz0) + " to " + moduleName(kx1, kz1) +
          ", level " + std::to_string(a.level) + (a.noSkirts ? ", no skirts" : ", skirts in group \"skirt\"") +
          ", objects " + extra.objectMode,
      info["frame"].get<std::string>(),
      "origin: easting " + std::to_string(easting) + ", northing " + std::to_string(northing) + " in " +
          man.crsName + (man.epsg ? " (EPSG:" + std::to_string(man.epsg) + ")" : std::string())};
  std::vector<std::string> written;
  if (Status saved = writeMesh(a, format, glb, mesh, info, header, extra.more, written); !saved) {
    return usageError("export", saved.message());
  }

  if (a.json) {
    nlohmann::json j = summary(info, written, format, glb, mesh);
    nlohmann::json parts = nlohmann::json::array();
    for (const auto& p : mesh.parts) parts.push_back({{"name", p.name}, {"triangles", p.indices.size() / 3}});
    j["materials"] = parts;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("wrote %s%s: %llu module(s) at level %u, %zu vertices, %zu triangles, %zu materials, "
                "%llu objects (%s)\n",
                a.output.c_str(), written.size() > 1 ? (" + " + written[1]).c_str() : "",
                static_cast<unsigned long long>(modules), a.level, mesh.positions.size(), mesh.triangles(),
                mesh.parts.size(), static_cast<unsigned long long>(extra.objects), extra.objectMode.c_str());
  }
  return kOk;
}

}  // namespace

void registerExport(CLI::App& root, Commands& c) {
  auto a = std::make_shared<ExportArgs>();
  auto* sub = root.add_subcommand(
      "export", "Write load modules as OBJ + MTL or glTF 2.0 (.gltf/.glb), or the elevation grid as a GeoTIFF");
  sub->footer(
      "Frame: metres, X east, Y up, Z south (north is -Z), origin at the NW corner of --module;\n"
      "one material per class (named from materials.txt), skirts as material \"skirt\".\n"
      "The module may be named by a point in it: --lonlat LON LAT (WGS 84) or --xy E N (database CRS).\n"
      "Examples:\n  sandtable export db --module 3 4 -o m34.obj\n"
      "  sandtable export db --lonlat 7.42 43.74 -o monaco.glb\n"
      "  sandtable export db --module 0 0 --to 2 1 --level 1 --format gltf -o area.glb\n"
      "  sandtable export db --module 3 4 --objects flatten -o m34-trees.obj\n"
      "  sandtable export db --icon tree -o tree.glb\n"
      "  sandtable export db --grid -o ground.tif      (the elevation grid as a GeoTIFF, docs/EXPORT.md)");
  sub->add_option("DB", a->dir, "Database directory")->required();
  auto* module = sub->add_option("--module", a->from, "Module column and row (north-west module of the range)")
                     ->expected(2);
  auto* lonlat = sub->add_option("--lonlat", a->lonlat, "The module holding LON LAT (WGS 84 degrees)")
                     ->expected(2)->excludes(module);
  sub->add_option("--xy", a->xy, "The module holding EASTING NORTHING (database CRS)")
      ->expected(2)->excludes(module)->excludes(lonlat);
  sub->add_option("--to", a->to, "South-east module of the range (default: --module)")->expected(2);
  sub->add_option("--level", a->level, "Level of detail, 0 = finest")->default_val(0);
  sub->add_option("--format", a->format, "obj or gltf (default: from the output's extension; .glb is binary glTF)")
      ->check(CLI::IsMember({"obj", "gltf"}));
  sub->add_option("-o,--output", a->output, "Output file (.obj writes a .mtl beside it)")->required();
  sub->add_flag("--no-skirts", a->noSkirts, "Leave the skirts out");
  sub->add_option("--objects", a->objects,
                  "Static objects: instanced (glTF EXT_mesh_gpu_instancing), flatten (moved into the mesh), none; "
                  "auto: instanced for glTF, flatten for OBJ")
      ->default_val("auto")
      ->check(CLI::IsMember({"auto", "instanced", "flatten", "none"}));
  sub->add_option("--icon-level", a->iconLevel, "Icons' level of detail, 0 = full")->default_val(0);
  auto* icon = sub->add_option("--icon", a->icon, "Export this icon of icons.pack alone, in its own frame")
                   ->excludes(module)->excludes(lonlat);
  auto* grid = sub->add_flag("--grid", a->grid,
                             "Write the elevation grid as a Float32 GeoTIFF (-o FILE.tif) in the database's CRS, "
                             "one pixel per post, instead of modules");
  // The module and icon modes' options mean nothing to the grid.
  for (const char* name : {"--module", "--to", "--level", "--format", "--no-skirts", "--objects", "--icon-level"}) {
    grid->excludes(sub->get_option(name));
  }
  grid->excludes(lonlat)->excludes(icon);
  grid->excludes(sub->get_option("--xy"));
  sub->add_option("--journal", a->journal,
                  "Terrain edits: the grid's posts and the modules re-meshed as the journal leaves them "
                  "(default: DB/edits.journal when present; none: as built)");
  sub->add_flag("--json", a->json, "Print a JSON summary");
  c.add(sub, [a] {
    ExportArgs args = *a;  // runExport fills in --module from a point
    return runExport(args);
  });
}

}  // namespace sandtable::cli
