// sandtable sample: elevation and material at points, on the drawn triangles.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "db_util.h"
#include "journal_util.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/world/terrain.h"

namespace sandtable::cli {
namespace {

struct SampleArgs {
  std::string dir;
  std::vector<double> lonlat, xy;
  std::string points;
  std::string journal;
  bool json = false;
};

struct Point {
  double lon = 0, lat = 0, easting = 0, northing = 0;
  std::optional<world::TerrainSample> sample;
};

Result<std::vector<std::array<double, 2>>> readPoints(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Problem{path, 0, "sample: cannot open the points file"};
  std::vector<std::array<double, 2>> out;
  std::string line;
  std::uint64_t offset = 0;
  for (int n = 1; std::getline(in, line); ++n) {
    const std::uint64_t lineOffset = offset;
    offset += line.size() + 1;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ss(line);
    double lon, lat;
    if (!(ss >> lon)) continue;  // blank or comment line
    std::string rest;
    if (!(ss >> lat) || (ss >> rest) || !std::isfinite(lon) || !std::isfinite(lat)) {
      return Problem{path, lineOffset, "sample: line " + std::to_string(n) + ": expected \"lon lat\""};
    }
    out.push_back({lon, lat});
  }
  return out;
}

int runSample(const SampleArgs& a) {
  const int modes = !a.lonlat.empty() + !a.xy.empty() + !a.points.empty();
  if (modes != 1) return usageError("sample", "give exactly one of --lonlat LON LAT, --xy E N or --points FILE");
  // The ground as the journal left it (the database's own edits.journal
  // when there is one; --journal none: as built).
  auto ew = openEditedWorld("sample", a.dir, a.journal, /*append=*/false, editorOptions(false, false));
  if (!ew) return kUsage;
  auto geo = geodesy::Projection::create(ew->base->manifest().crsWkt);
  if (!geo) return usageError("sample", geo.error());
  world::Terrain terrain(ew->world()->heights());

  std::vector<Point> pts;
  if (!a.points.empty()) {
    auto list = readPoints(a.points);
    if (!list) return usageError("sample", list.error());
    for (const auto& p : list.value()) {
      Point q;
      q.lon = p[0];
      q.lat = p[1];
      pts.push_back(q);
    }
  } else if (!a.lonlat.empty()) {
    Point q;
    q.lon = a.lonlat[0];
    q.lat = a.lonlat[1];
    pts.push_back(q);
  } else {
    Point p;
    p.easting = a.xy[0];
    p.northing = a.xy[1];
    const auto ll = geo->toLonLat({p.easting, p.northing});
    if (!ll) return usageError("sample", "cannot transform --xy");
    p.lon = ll->lon, p.lat = ll->lat;
    pts.push_back(p);
  }
  int outside = 0;
  for (auto& p : pts) {
    if (a.xy.empty()) {
      const auto en = geo->toProjected({p.lon, p.lat});
      if (!en) {
        ++outside;
        continue;
      }
      p.easting = en->easting, p.northing = en->northing;
    }
    p.sample = terrain.sampleEN(p.easting, p.northing);
    if (!p.sample) {
      ++outside;
      std::fprintf(stderr, "sandtable sample: lon %.6f lat %.6f (E %.2f N %.2f) is outside the database\n", p.lon,
                   p.lat, p.easting, p.northing);
    }
  }
  if (a.json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const auto& p : pts) {
      nlohmann::json j = {{"lon", p.lon}, {"lat", p.lat}, {"easting", p.easting}, {"northing", p.northing}};
      j["elevation"] = p.sample ? nlohmann::json(p.sample->elevation) : nlohmann::json(nullptr);
      j["material"] = p.sample ? nlohmann::json(p.sample->material) : nlohmann::json(nullptr);
      arr.push_back(j);
    }
    std::printf("%s\n", (pts.size() == 1 && a.points.empty() ? arr[0] : arr).dump(2).c_str());
  } else {
    for (const auto& p : pts) {
      if (p.sample) std::printf("%.8f %.8f %.3f %u\n", p.lon, p.lat, p.sample->elevation, p.sample->material);
      else std::printf("%.8f %.8f nan -1\n", p.lon, p.lat);
    }
  }
  return outside == 0 ? kOk : kUsage;
}

}  // namespace

void registerSample(CLI::App& root, Commands& c) {
  auto a = std::make_shared<SampleArgs>();
  auto* sub = root.add_subcommand("sample", "Elevation and material at points (on the rendered triangles)");
  sub->footer(
      "Output: one \"lon lat elevation material\" line per point; points outside give \"nan -1\" and exit 2.\n"
      "Examples:\n  sandtable sample db --lonlat 13.30 42.30\n  sandtable sample db --points pts.txt --json");
  sub->add_option("DB", a->dir, "Database directory")->required();
  sub->add_option("--lonlat", a->lonlat, "LON LAT in WGS 84 degrees")->expected(2);
  sub->add_option("--xy", a->xy, "EASTING NORTHING in the database CRS")->expected(2);
  sub->add_option("--points", a->points, "File of \"lon lat\" lines ('#' starts a comment)");
  sub->add_option("--journal", a->journal,
                  "Terrain edits to sample over (default: DB/edits.journal when present; none: the ground as built)");
  sub->add_flag("--json", a->json, "Print JSON");
  c.add(sub, [a] { return runSample(*a); });
}

}  // namespace sandtable::cli
