// sandtable info: what a database holds and where it lies.
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "db_util.h"

namespace sandtable::cli {
namespace {

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
  j["modules"] = m.build.contains("modules") ? m.build["modules"] : nlohmann::json();
  j["culture"] = m.build.contains("culture") ? m.build["culture"] : nlohmann::json();
  return j;
}

void printModules(const nlohmann::json& m) {
  const auto& b = m["bytes"];
  std::printf("modules    %llu = %u x %u of %.2f m (%u squares), built in %.2f s (%.0f modules/s)\n",
              static_cast<unsigned long long>(m["count"].get<std::uint64_t>()), m["modules_x"].get<unsigned>(),
              m["modules_z"].get<unsigned>(), m["module_size_m"].get<double>(), m["module_squares"].get<unsigned>(),
              m["seconds"].get<double>(), m["modules_per_second"].get<double>());
  std::printf("  bytes    min %u, median %u, p95 %u, max %u, mean %.0f compressed; %.1f MB packed of %.1f MB raw\n",
              b["min"].get<unsigned>(), b["median"].get<unsigned>(), b["p95"].get<unsigned>(),
              b["max"].get<unsigned>(), b["mean"].get<double>(),
              double(b["compressed_total"].get<std::uint64_t>()) / 1e6, double(b["raw_total"].get<std::uint64_t>()) / 1e6);
  int level = 0;
  for (const auto& l : m["per_level"]) {
    std::printf("  level %d  %llu triangles, %llu skin polygons, %llu decal polygons, %llu skirt triangles\n", level++,
                static_cast<unsigned long long>(l["triangles"].get<std::uint64_t>()),
                static_cast<unsigned long long>(l["skin_polygons"].get<std::uint64_t>()),
                static_cast<unsigned long long>(l["decal_polygons"].get<std::uint64_t>()),
                static_cast<unsigned long long>(l["skirt_triangles"].get<std::uint64_t>()));
  }
}

void printCulture(const nlohmann::json& c) {
  std::printf("culture    %llu features read, %llu warnings, materials: %s\n",
              static_cast<unsigned long long>(c["features_read"].get<std::uint64_t>()),
              static_cast<unsigned long long>(c["warnings"].get<std::uint64_t>()),
              c["materials"].get<std::string>().c_str());
  std::printf("  %-16s %8s %8s %8s %9s %10s %10s\n", "class", "read", "dropped", "repaired", "defaulted", "km",
              "km2");
  for (const auto& [name, k] : c["classes"].items()) {
    std::printf("  %-16s %8llu %8llu %8llu %9llu %10.2f %10.3f\n", name.c_str(),
                static_cast<unsigned long long>(k["read"].get<std::uint64_t>()),
                static_cast<unsigned long long>(k["dropped"].get<std::uint64_t>()),
                static_cast<unsigned long long>(k["repaired"].get<std::uint64_t>()),
                static_cast<unsigned long long>(k["defaulted"].get<std::uint64_t>()), k["length_km"].get<double>(),
                k["area_km2"].get<double>());
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
  std::printf("built      %s by sandtable %s, resample %s, %llu voids filled, %llu sea posts from voids, %.2f s\n",
              j["created_utc"].get<std::string>().c_str(), j["tool_version"].get<std::string>().c_str(),
              b.value("resample", std::string("?")).c_str(),
              static_cast<unsigned long long>(b.value("voids_filled", std::uint64_t{0})),
              static_cast<unsigned long long>(b.value("sea_posts", std::uint64_t{0})), b.value("seconds", 0.0));
  if (const auto a = b.find("accuracy"); a != b.end() && a->is_object()) {
    std::printf("accuracy   RMSE %.2f m, max |error| %.2f m against %llu source posts\n", a->value("rmse_m", 0.0),
                a->value("max_abs_m", 0.0), static_cast<unsigned long long>(a->value("source_posts", std::uint64_t{0})));
  }
  if (!j["modules"].is_null()) printModules(j["modules"]);
  if (!j["culture"].is_null()) printCulture(j["culture"]);
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
