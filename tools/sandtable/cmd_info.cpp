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
  return {{"database", db.directory},
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
  std::printf("modules    %.0f m, %d levels\n", j["module_size_m"].get<double>(), j["levels"].get<int>());
  for (const auto& f : j["files"]) {
    std::printf("file       %s  %.1f MiB\n", f["path"].get<std::string>().c_str(),
                double(f["bytes"].get<std::uint64_t>()) / 1048576.0);
  }
  for (const auto& s : j["sources"]) {
    std::printf("source     %s (%s)\n", s["path"].get<std::string>().c_str(), s["driver"].get<std::string>().c_str());
  }
  const auto& b = j["build"];
  std::printf("built      %s by sandtable %s, resample %s, %llu voids filled, %.2f s\n",
              j["created_utc"].get<std::string>().c_str(), j["tool_version"].get<std::string>().c_str(),
              b.value("resample", std::string("?")).c_str(),
              static_cast<unsigned long long>(b.value("voids_filled", std::uint64_t{0})), b.value("seconds", 0.0));
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
