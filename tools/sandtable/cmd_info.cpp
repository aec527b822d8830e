// sandtable info: what a database holds and where it lies.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "culture_report.h"
#include "db_util.h"
#include "icon_report.h"

namespace sandtable::cli {
namespace {

// The manifest's `build` object is informational (FORMAT.md §5.5): another
// build, an older or newer sandtable, or a hand edit may leave out any key or
// give it another type. Every read of it below is checked; what cannot be
// read prints as "?".
const nlohmann::json& field(const nlohmann::json& j, const char* key) {
  static const nlohmann::json kAbsent;
  if (!j.is_object()) return kAbsent;
  const auto it = j.find(key);
  return it == j.end() ? kAbsent : *it;
}

std::string count(const nlohmann::json& j, const char* key) {
  const auto& v = field(j, key);
  if (v.is_number_unsigned()) return std::to_string(v.get<std::uint64_t>());
  if (v.is_number_integer()) return std::to_string(v.get<std::int64_t>());
  char buf[64];
  if (v.is_number_float() && std::isfinite(v.get<double>())) {
    std::snprintf(buf, sizeof buf, "%.0f", v.get<double>());
    return buf;
  }
  return "?";
}

std::string real(const nlohmann::json& j, const char* key, int decimals, double scale = 1.0) {
  const auto& v = field(j, key);
  if (!v.is_number()) return "?";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v.get<double>() * scale);
  return buf;
}

std::string text(const nlohmann::json& j, const char* key) {
  const auto& v = field(j, key);
  return v.is_string() ? v.get<std::string>() : "?";
}

nlohmann::json infoJson(const Database& db) {
  const auto& m = db.manifest;
  double lonMin = 1e9, lonMax = -1e9, latMin = 1e9, latMax = -1e9;
  for (const auto& c : m.cornersLonLat) {
    lonMin = std::min(lonMin, c[0]), lonMax = std::max(lonMax, c[0]);
    latMin = std::min(latMin, c[1]), latMax = std::max(latMax, c[1]);
  }
  nlohmann::json files = nlohmann::json::array();
  for (const auto& f : m.files) files.push_back({{"path", f.path}, {"bytes", f.bytes}});
  nlohmann::json sources = nlohmann::json::array();
  for (const auto& s : m.sources) sources.push_back({{"path", s.path}, {"bytes", s.bytes}, {"driver", s.driver}});
  nlohmann::json j = {{"database", db.directory},
          {"crs_wkt", m.crsWkt},
          {"crs_name", m.crsName},
          {"epsg", m.epsg},
          {"origin_easting", m.originEasting},
          {"origin_northing", m.originNorthing},
          {"east_easting", m.eastEasting()},
          {"south_northing", m.southNorthing()},
          {"width_m", m.eastEasting() - m.originEasting},
          {"height_m", m.originNorthing - m.southNorthing()},
          {"corners_lonlat", {{"nw", m.cornersLonLat[0]}, {"ne", m.cornersLonLat[1]},
                              {"se", m.cornersLonLat[2]}, {"sw", m.cornersLonLat[3]}}},
          {"lon_min", lonMin}, {"lon_max", lonMax}, {"lat_min", latMin}, {"lat_max", latMax},
          {"spacing_m", m.spacing},
          {"posts_x", m.postsX},
          {"posts_z", m.postsZ},
          {"posts", std::uint64_t(m.postsX) * m.postsZ},
          {"block_posts", m.blockPosts},
          {"module_size_m", m.moduleSize},
          {"levels", m.levels},
          {"min_elevation", m.minElevation},
          {"max_elevation", m.maxElevation},
          {"files", files},
          {"sources", sources},
          {"tool_version", m.toolVersion},
          {"created_utc", m.createdUtc},
          {"build", m.build}};
  // Void counts as the build recorded them; null when it did not.
  for (const char* key : {"voids_filled", "sea_posts"}) {
    const auto v = m.build.is_object() ? m.build.find(key) : m.build.end();
    j[key] = v != m.build.end() && v->is_number_unsigned() ? *v : nlohmann::json();
  }
  // Culture and module statistics are recorded by the build; null for a grid-only database.
  j["modules"] = field(m.build, "modules");
  j["culture"] = field(m.build, "culture");
  // The icons of icons.pack; null for a database built before icons.
  j["icons"] = db.icons ? iconsJson(*db.icons) : nlohmann::json();
  // Static objects as the build placed them; 0 and {} before objects.
  const auto& objects = field(m.build, "objects");
  j["objects"] = objects.is_object() ? objects.value("count", std::uint64_t(0)) : std::uint64_t(0);
  j["objects_by_class"] = objects.is_object() && objects.contains("by_class") ? objects["by_class"]
                                                                               : nlohmann::json::object();
  return j;
}

void printModules(const nlohmann::json& m) {
  const auto& b = field(m, "bytes");
  std::printf("modules    %s = %s x %s of %s m (%s squares), built in %s s (%s modules/s)\n", count(m, "count").c_str(),
              count(m, "modules_x").c_str(), count(m, "modules_z").c_str(), real(m, "module_size_m", 2).c_str(),
              count(m, "module_squares").c_str(), real(m, "seconds", 2).c_str(),
              real(m, "modules_per_second", 0).c_str());
  std::printf("  bytes    min %s, median %s, p95 %s, max %s, mean %s compressed; %s MB packed of %s MB raw\n",
              count(b, "min").c_str(), count(b, "median").c_str(), count(b, "p95").c_str(), count(b, "max").c_str(),
              real(b, "mean", 0).c_str(), real(b, "compressed_total", 1, 1e-6).c_str(),
              real(b, "raw_total", 1, 1e-6).c_str());
  const auto& levels = field(m, "per_level");
  if (!levels.is_array()) return;
  int level = 0;
  for (const auto& l : levels) {
    std::printf("  level %d  %s triangles, %s skin polygons, %s decal polygons, %s skirt triangles\n", level++,
                count(l, "triangles").c_str(), count(l, "skin_polygons").c_str(), count(l, "decal_polygons").c_str(),
                count(l, "skirt_triangles").c_str());
  }
}

void printCulture(const nlohmann::json& c) {
  std::printf("culture    %s features read, %s warnings, materials: %s\n", count(c, "features_read").c_str(),
              count(c, "warnings").c_str(), text(c, "materials").c_str());
  printCultureReasons(c, "  ");
  const auto& classes = field(c, "classes");
  if (!classes.is_object()) return;
  std::printf("  %-16s %8s %8s %8s %9s %10s %10s\n", "class", "read", "dropped", "repaired", "defaulted", "km",
              "km2");
  for (const auto& [name, k] : classes.items()) {
    std::printf("  %-16s %8s %8s %8s %9s %10s %10s\n", name.c_str(), count(k, "read").c_str(),
                count(k, "dropped").c_str(), count(k, "repaired").c_str(), count(k, "defaulted").c_str(),
                real(k, "length_km", 2).c_str(), real(k, "area_km2", 3).c_str());
  }
}

void printIconLines(const nlohmann::json& icons) {
  for (const auto& i : icons) {
    std::string levels;
    for (const auto& l : i["levels"]) {
      levels += (levels.empty() ? "" : ", ") + std::to_string(l["triangles"].get<std::uint64_t>()) + " to " +
                std::to_string(std::lround(l["range_m"].get<double>())) + " m";
    }
    std::printf("icon       %s: %s\n", i["name"].get<std::string>().c_str(), levels.c_str());
  }
}

void printHuman(const nlohmann::json& j) {
  std::printf("database   %s\n", j["database"].get<std::string>().c_str());
  std::printf("crs        %s (EPSG %d)\n", j["crs_name"].get<std::string>().c_str(), j["epsg"].get<int>());
  std::printf("extent     E %.2f .. %.2f, N %.2f .. %.2f (%.2f x %.2f km)\n", j["origin_easting"].get<double>(),
              j["east_easting"].get<double>(), j["south_northing"].get<double>(), j["origin_northing"].get<double>(),
              j["width_m"].get<double>() / 1000, j["height_m"].get<double>() / 1000);
  std::printf("lon/lat    %.6f .. %.6f E, %.6f .. %.6f N\n", j["lon_min"].get<double>(), j["lon_max"].get<double>(),
              j["lat_min"].get<double>(), j["lat_max"].get<double>());
  for (const char* c : {"nw", "ne", "se", "sw"}) {
    std::printf("  %s corner  lon %.6f lat %.6f\n", c, j["corners_lonlat"][c][0].get<double>(),
                j["corners_lonlat"][c][1].get<double>());
  }
  std::printf("posts      %u x %u = %llu at %.3f m\n", j["posts_x"].get<unsigned>(), j["posts_z"].get<unsigned>(),
              static_cast<unsigned long long>(j["posts"].get<std::uint64_t>()), j["spacing_m"].get<double>());
  std::printf("elevation  %.2f .. %.2f m\n", j["min_elevation"].get<double>(), j["max_elevation"].get<double>());
  std::printf("lod        %.0f m modules, %d levels\n", j["module_size_m"].get<double>(), j["levels"].get<int>());
  for (const auto& f : j["files"]) {
    std::printf("file       %s  %.1f MiB\n", f["path"].get<std::string>().c_str(),
                double(f["bytes"].get<std::uint64_t>()) / 1048576.0);
  }
  for (const auto& s : j["sources"]) {
    std::printf("source     %s (%s)\n", s["path"].get<std::string>().c_str(), s["driver"].get<std::string>().c_str());
  }
  const auto& b = j["build"];
  std::printf("built      %s by sandtable %s, resample %s, %s voids filled, %s sea posts from voids, %s s\n",
              j["created_utc"].get<std::string>().c_str(), j["tool_version"].get<std::string>().c_str(),
              text(b, "resample").c_str(), count(b, "voids_filled").c_str(), count(b, "sea_posts").c_str(),
              real(b, "seconds", 2).c_str());
  if (const auto& a = field(b, "accuracy"); a.is_object()) {
    std::printf("accuracy   RMSE %s m, max |error| %s m against %s source posts\n", real(a, "rmse_m", 2).c_str(),
                real(a, "max_abs_m", 2).c_str(), count(a, "source_posts").c_str());
  }
  if (!j["modules"].is_null()) printModules(j["modules"]);
  if (!j["culture"].is_null()) printCulture(j["culture"]);
  if (!j["icons"].is_null()) printIconLines(j["icons"]);
  std::string classes;
  for (const auto& [name, n] : j["objects_by_class"].items()) {
    classes += (classes.empty() ? ": " : ", ") + std::to_string(n.get<std::uint64_t>()) + " " + name;
  }
  std::printf("objects    %llu%s\n", static_cast<unsigned long long>(j["objects"].get<std::uint64_t>()), classes.c_str());
}

}  // namespace

void registerInfo(CLI::App& root, Commands& c) {
  auto dir = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto* sub = root.add_subcommand("info", "Show a database's extent, posts, elevations, files and provenance");
  sub->footer("Example:\n  sandtable info db --json");
  sub->add_option("DB", *dir, "Database directory")->required();
  sub->add_flag("--json", *json, "Print JSON");
  c.add(sub, [dir, json] {
    auto db = openOrReport("info", *dir);
    if (!db) return int(kUsage);
    const auto j = infoJson(*db);
    if (*json) std::printf("%s\n", j.dump(2).c_str());
    else printHuman(j);
    return int(kOk);
  });
}

}  // namespace sandtable::cli
