// sandtable script: seed Figure 71 scripts from the command line: convert a
// Table 7 path file into a script, or check and print one.
#include <cstdio>
#include <span>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "db_util.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/sim/script.h"
#include "sandtable/world/path.h"

namespace sandtable::cli {
namespace {

struct ScriptArgs {
  std::string db, path, check, output;
  std::uint32_t entity = 1, type = 1;
  double speedKmh = 0;
  bool json = false;
};

int fromPath(const ScriptArgs& a) {
  auto db = openOrReport("script", a.db);
  if (!db) return kUsage;
  auto geo = geodesy::Projection::create(db->manifest.crsWkt);
  if (!geo) return reportProblems("script", geo.problems());
  world::PathOptions po;
  if (a.speedKmh > 0) po.defaultSpeedKmh = a.speedKmh;
  const geodesy::Projection& g = geo.value();
  po.toProjected = [&](double lon, double lat, double& e, double& n) -> std::string {
    const auto en = g.toProjected({lon, lat});
    if (!en) return "cannot be projected into " + db->manifest.crsName;
    e = en->easting, n = en->northing;
    return {};
  };
  auto path = world::readPathFile(a.path, po);
  if (!path) return reportProblems("script", path.problems());
  const auto& h = db->grid->header();
  auto lines = sim::scriptFromPath(path.value(), a.entity, a.type, h.originEasting, h.originNorthing);
  if (!lines) return reportProblems("script", lines.problems());
  const std::string text = sim::formatScript(lines.value());
  if (a.output.empty()) {
    std::fputs(text.c_str(), stdout);
  } else if (Status st = writeFileAtomic(a.output, std::as_bytes(std::span(text.data(), text.size()))); !st) {
    return reportProblems("script", st.problems());
  }
  if (a.json) {
    std::printf("%s\n", nlohmann::json{{"lines", lines->size()}, {"duration_s", path->durationS()},
                                       {"output", a.output}}
                            .dump()
                            .c_str());
  } else if (!a.output.empty()) {
    std::printf("%s: %zu lines over %.1f s\n", a.output.c_str(), lines->size(), path->durationS());
  }
  return kOk;
}

int check(const ScriptArgs& a) {
  auto lines = sim::readScriptFile(a.check);
  if (!lines) return reportProblems("script", lines.problems());
  const auto entities = sim::scriptEntities(lines.value());
  const double end = lines->empty() ? 0.0 : lines->back().timeS;
  if (a.json) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& e : entities) list.push_back({{"entity", e.entity}, {"type", e.type}, {"first_s", e.firstTimeS}});
    std::printf("%s\n", nlohmann::json{{"script", a.check}, {"lines", lines->size()}, {"end_s", end},
                                       {"entities", list}}
                            .dump(1)
                            .c_str());
  } else {
    std::printf("%s: %zu lines, %zu entities, %.1f s\n", a.check.c_str(), lines->size(), entities.size(), end);
    for (const auto& e : entities) std::printf("  entity %u type %u from %.1f s\n", e.entity, e.type, e.firstTimeS);
  }
  return kOk;
}

int runScript(const ScriptArgs& a) {
  if (!a.check.empty()) return check(a);
  if (a.db.empty() || a.path.empty()) {
    return usageError("script", "give DB --from-path PATH (a path into a script) or --check SCRIPT");
  }
  return fromPath(a);
}

}  // namespace

void registerScript(CLI::App& root, Commands& c) {
  auto a = std::make_shared<ScriptArgs>();
  auto* sub = root.add_subcommand("script", "Seed Figure 71 scripts: make one from a Table 7 path file, or check one");
  sub->footer(
      "A path file (docs/PATH.md: waypoints with some times and some leg speeds) becomes one script line per\n"
      "leg at its start time, direction and mean speed, and a last line at rest (docs/SCRIPTS.md §4).\n"
      "Examples:\n"
      "  sandtable script db --from-path samples/demo.path --entity 7 --type 2 -o tank7.script\n"
      "  sandtable script --check samples/demo.script");
  sub->add_option("DB", a->db, "Database directory (its CRS places lon/lat waypoints)");
  sub->add_option("--from-path", a->path, "Path file to convert");
  sub->add_option("--entity", a->entity, "Entity_Number of the lines (default 1)");
  sub->add_option("--type", a->type, "Entity_Type of the lines (default 1)");
  sub->add_option("--speed", a->speedKmh, "Leg speed where the path gives neither a speed nor a time, km/h");
  sub->add_option("-o,--output", a->output, "Write the script here (default: stdout)");
  sub->add_option("--check", a->check, "Read a script and print its entities");
  sub->add_flag("--json", a->json, "Print JSON");
  c.add(sub, [a] { return runScript(*a); });
}

}  // namespace sandtable::cli
