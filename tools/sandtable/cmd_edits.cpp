// sandtable edits apply|list|bake: terrain edits from the command line
// (docs/DYNAMIC.md, "Command line").
#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <numbers>
#include <sstream>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "db_util.h"
#include "flags.h"
#include "journal_util.h"
#include "progress.h"
#include "sandtable/edits/bake.h"
#include "sandtable/edits/editor.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/geodesy/geodesy.h"

namespace sandtable::cli {
namespace {

struct ApplyArgs {
  std::string dir, journal;
  std::string kind;  ///< the subcommand's name
  std::vector<double> lonlat, xy;
  std::string line, polygon;
  bool projected = false;
  double radius = 0, depth = 0, width = 0, height = 0, slope = 0.5;
  std::uint64_t object = 0;
  std::vector<std::uint32_t> module;
  std::string icon;                  ///< add-object, switch-object: a name in icons.pack
  std::uint16_t iconIndex = 0;       ///< `icon` resolved by runApply
  double headingDeg = 0, scale = 1;  ///< add-object, scale-object
  bool json = false;
};

/// "A B, C D, ..." into pairs; a message naming the flag when malformed.
Result<std::vector<std::array<double, 2>>> parsePairs(const std::string& text, const std::string& flag) {
  std::vector<std::array<double, 2>> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::istringstream one(item);
    double a = 0, b = 0;
    std::string rest;
    if (!(one >> a >> b) || (one >> rest) || !std::isfinite(a) || !std::isfinite(b)) {
      return Problem{"", 0, flag + ": \"" + item + "\" is not two numbers; write \"A B, A B, ...\""};
    }
    out.push_back({a, b});
  }
  return out;
}

/// Lon/lat (or easting/northing with `projected`) into the database frame.
struct ToFrame {
  std::optional<geodesy::Projection> geo;
  double originE = 0, originN = 0;
  Result<std::array<double, 2>> operator()(std::array<double, 2> p, bool projected) const {
    double e = p[0], n = p[1];
    if (!projected) {
      const auto en = geo->toProjected({p[0], p[1]});
      if (!en) return Problem{"", 0, "cannot transform lon " + std::to_string(p[0]) + " lat " + std::to_string(p[1])};
      e = en->easting, n = en->northing;
    }
    return std::array<double, 2>{e - originE, originN - n};
  }
};

Result<edit::Edit> editFrom(const ApplyArgs& a, const ToFrame& toFrame) {
  edit::Edit e;
  const auto points = [&](std::vector<std::array<double, 2>> in, bool projected) -> Status {
    for (const auto& p : in) {
      auto f = toFrame(p, projected);
      if (!f) return f.problems();
      e.points.push_back(f.value());
    }
    return {};
  };
  const auto onePoint = [&]() -> Status {
    if (a.lonlat.empty() == a.xy.empty()) return Problem{"", 0, a.kind + ": give exactly one of --lonlat LON LAT or --xy E N"};
    const bool xy = !a.xy.empty();
    const auto& p = xy ? a.xy : a.lonlat;
    return points({{p[0], p[1]}}, xy);
  };
  const auto inModule = [&]() -> Status {
    if (a.module.size() != 2) return Problem{"", 0, a.kind + ": give --module KX KZ, the object's load module"};
    e.object = a.object;
    e.moduleX = a.module[0], e.moduleZ = a.module[1];
    return {};
  };
  if (a.kind == "crater") {
    e.kind = edit::Kind::crater;
    if (Status st = onePoint(); !st) return st.problems();
    e.radius = a.radius, e.depth = a.depth;
  } else if (a.kind == "add-object") {
    e.kind = edit::Kind::addObject;
    if (Status st = onePoint(); !st) return st.problems();
    e.icon = a.iconIndex, e.heading = a.headingDeg * std::numbers::pi / 180.0, e.scale = a.scale;
  } else if (a.kind == "switch-object" || a.kind == "scale-object") {
    e.kind = a.kind == "switch-object" ? edit::Kind::switchObject : edit::Kind::scaleObject;
    if (Status st = inModule(); !st) return st.problems();
    e.icon = a.iconIndex, e.scale = a.scale;
  } else if (a.kind == "berm" || a.kind == "ditch") {
    e.kind = a.kind == "berm" ? edit::Kind::berm : edit::Kind::ditch;
    auto pts = parsePairs(a.line, "--line");
    if (!pts) return pts.problems();
    if (Status st = points(pts.value(), a.projected); !st) return st.problems();
    e.width = a.width, e.height = a.kind == "berm" ? a.height : (a.depth > 0 ? a.depth : a.height);
    e.sideSlope = a.slope;
  } else if (a.kind == "flatten") {
    e.kind = edit::Kind::flatten;
    auto pts = parsePairs(a.polygon, "--polygon");
    if (!pts) return pts.problems();
    if (Status st = points(pts.value(), a.projected); !st) return st.problems();
    e.height = a.height, e.sideSlope = a.slope;
  } else {
    e.kind = edit::Kind::removeObject;
    if (Status st = inModule(); !st) return st.problems();
  }
  return e;
}

nlohmann::json editJson(const edit::Edit& e) {
  nlohmann::json j = {{"id", e.id}, {"origin", e.origin}, {"time_s", e.time}, {"kind", edit::kindName(e.kind)}};
  nlohmann::json pts = nlohmann::json::array();
  for (const auto& p : e.points) pts.push_back({p[0], p[1]});
  if (!e.points.empty()) j["points_xz"] = pts;
  switch (e.kind) {
    case edit::Kind::crater: j["radius_m"] = e.radius, j["depth_m"] = e.depth; break;
    case edit::Kind::berm: j["width_m"] = e.width, j["height_m"] = e.height, j["side_slope"] = e.sideSlope; break;
    case edit::Kind::ditch: j["width_m"] = e.width, j["depth_m"] = e.height, j["side_slope"] = e.sideSlope; break;
    case edit::Kind::flatten: j["height_m"] = e.height, j["side_slope"] = e.sideSlope; break;
    default:
      j["module"] = {e.moduleX, e.moduleZ};
      j["object"] = e.object;
      j["icon"] = e.icon;
      j["scale"] = e.scale;
  }
  return j;
}

/// `name`'s index in the database's icons.pack; a message naming --icon
/// and the icons there are when it is not one.
Result<std::uint16_t> iconIndex(const paging::World& w, const std::string& name) {
  std::string names;
  if (const auto& pack = w.icons()) {
    for (std::size_t k = 0; k < pack->icons.size(); ++k) {
      if (pack->icons[k].name == name) return std::uint16_t(k);
      names += (names.empty() ? "" : ", ") + pack->icons[k].name;
    }
  }
  return Problem{"", 0, "--icon " + name + ": no such icon in the database's icons.pack" +
                            (names.empty() ? std::string(" (it has none; build with --icons)") : " (it has " + names + ")")};
}

int runApply(ApplyArgs& a) {
  const std::string cmd = "edits apply";
  auto ew = openEditedWorld(cmd, a.dir, a.journal, /*append=*/true, editorOptions(true, false));
  if (!ew) return kUsage;
  if (!a.icon.empty()) {
    auto k = iconIndex(*ew->base, a.icon);
    if (!k) return usageError(cmd, k.problems().front().message);
    a.iconIndex = k.value();
  }
  ToFrame toFrame;
  const auto& man = ew->base->manifest();
  toFrame.originE = man.originEasting, toFrame.originN = man.originNorthing;
  auto geo = geodesy::Projection::create(man.crsWkt);
  if (!geo) return usageError(cmd, geo.error());
  toFrame.geo.emplace(std::move(geo.value()));
  auto made = editFrom(a, toFrame);
  if (!made) return usageError(cmd, withFlags(made.problems().front().message));
  edit::Edit e = made.value();
  edits::Editor& ed = *ew->editor;
  e.id = ed.nextId(0);
  // After every edit already there, so the journal's order is the key order.
  for (const edit::Edit& x : ed.edits()) e.time = std::max(e.time, x.time);
  auto applied = ed.apply(e);
  if (!applied) {
    std::vector<Problem> problems = applied.problems();
    for (auto& p : problems) p.message = withFlags(p.message);
    return reportProblems(cmd, problems);
  }
  ed.wait();
  if (Status st = ed.flush(); !st) return reportProblems(cmd, st.problems());
  const edits::EditorStats st = ed.stats();
  if (st.remeshFailures) return usageError(cmd, "re-meshing failed: " + st.lastRemeshError);
  const edits::HeightsChange& c = applied.value().heights;
  const std::uint64_t posts = c.posts.empty() ? 0 : std::uint64_t(c.posts.i1 - c.posts.i0) * (c.posts.j1 - c.posts.j0);
  if (a.json) {
    nlohmann::json j = editJson(e);
    j["journal"] = ew->journal;
    j["edits_in_journal"] = ed.edits().size();
    j["posts_changed_box"] = posts;
    j["refined_squares"] = c.squares.size();
    j["modules_remeshed"] = st.modulesRemeshed;
    j["remesh_s"] = st.remeshSeconds;
    std::printf("%s\n", j.dump(2).c_str());
  } else if (!edit::changesHeights(e.kind)) {
    std::printf("applied %s %llu: its module's objects follow in a new generation\n",
                std::string(edit::kindName(e.kind)).c_str(), static_cast<unsigned long long>(e.id));
    std::printf("journal %s now holds %zu edits\n", ew->journal.c_str(), ed.edits().size());
  } else {
    std::printf("applied %s %llu: %zu refined squares, %llu posts in the changed box, %llu modules re-meshed (%.1f ms)\n",
                std::string(edit::kindName(e.kind)).c_str(), static_cast<unsigned long long>(e.id), c.squares.size(),
                static_cast<unsigned long long>(posts), static_cast<unsigned long long>(st.modulesRemeshed),
                st.remeshSeconds * 1e3);
    std::printf("journal %s now holds %zu edits\n", ew->journal.c_str(), ed.edits().size());
  }
  return kOk;
}

struct ListArgs {
  std::string journal;
  bool json = false;
};

int runList(const ListArgs& a) {
  auto j = journal::readJournal(a.journal);
  if (!j) return reportProblems("edits list", j.problems());
  for (const Problem& w : j.value().warnings) {
    std::fprintf(stderr, "sandtable edits list: warning: %s @%llu: %s\n", w.file.c_str(),
                 static_cast<unsigned long long>(w.offset), w.message.c_str());
  }
  const auto& edits = j.value().edits;
  if (a.json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const edit::Edit& e : edits) arr.push_back(editJson(e));
    const nlohmann::json out = {{"journal", a.journal}, {"edits", arr}, {"bytes", j.value().validBytes},
                                {"torn_tail_cut", !j.value().warnings.empty()}};
    std::printf("%s\n", out.dump(2).c_str());
    return kOk;
  }
  std::printf("%-8s %-10s %-10s %-14s %s\n", "id", "origin", "time_s", "kind", "where (database frame x z, m) and size");
  for (const edit::Edit& e : edits) {
    std::string where;
    if (!e.points.empty()) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "%.2f %.2f", e.points[0][0], e.points[0][1]);
      where = buf;
      if (e.points.size() > 1) where += " (+" + std::to_string(e.points.size() - 1) + " points)";
    }
    char size[96] = "";
    if (e.kind == edit::Kind::crater) std::snprintf(size, sizeof size, "  r %.2f d %.2f", e.radius, e.depth);
    else if (edit::changesHeights(e.kind)) std::snprintf(size, sizeof size, "  w %.2f h %.2f", e.width, e.height);
    std::printf("%-8llu %-10u %-10.3f %-14s %s%s\n", static_cast<unsigned long long>(e.id), e.origin, e.time,
                std::string(edit::kindName(e.kind)).c_str(), where.c_str(), size);
  }
  std::printf("%zu edits\n", edits.size());
  return kOk;
}

struct BakeArgs {
  std::string dir, journal, output;
  bool replace = false, json = false;
};

std::atomic<bool> gBakeCancel{false};
volatile std::sig_atomic_t gBakeSignal = 0;
void onBakeSignal(int sig) {
  gBakeSignal = sig;
  gBakeCancel.store(true);
  std::signal(sig, SIG_DFL);
}

int runBake(const BakeArgs& a) {
  const std::string cmd = "edits bake";
  auto base = openWorldOrReport(cmd, a.dir);
  if (!base) return kUsage;
  auto j = journal::readJournal(a.journal);
  if (!j) return reportProblems(cmd, j.problems());
  std::signal(SIGINT, onBakeSignal);
  std::signal(SIGTERM, onBakeSignal);
  Progress progress(a.json);
  Work work;
  work.progress = [&](double f, const std::string& stage) { progress.update(f, stage); };
  work.cancel = &gBakeCancel;
  auto r = edits::bake(*base, j.value().edits, a.output, a.replace, work);
  progress.done();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (!r && gBakeSignal != 0) {
    std::fprintf(stderr, "sandtable %s: cancelled by signal %d; nothing was written to %s\n", cmd.c_str(),
                 int(gBakeSignal), a.output.c_str());
    return 128 + gBakeSignal;
  }
  if (!r) return reportProblems(cmd, r.problems());
  const edits::BakeReport& b = r.value();
  if (a.json) {
    const nlohmann::json out = {{"database", a.dir},    {"journal", a.journal},
                                {"output", b.output},   {"edits", b.edits},
                                {"modules", b.modules}, {"modules_remeshed", b.modulesRemeshed},
                                {"grid_bytes", b.gridBytes}, {"pack_bytes", b.packBytes},
                                {"seconds", b.seconds}};
    std::printf("%s\n", out.dump(2).c_str());
  } else {
    std::printf("baked %llu edits into %s (%llu module rebuilds, %.2f s); check it with `sandtable validate %s`\n",
                static_cast<unsigned long long>(b.edits), b.output.c_str(),
                static_cast<unsigned long long>(b.modulesRemeshed), b.seconds, b.output.c_str());
  }
  return kOk;
}

void addApply(CLI::App& edits, Commands& c) {
  auto* apply = edits.add_subcommand("apply", "Apply one terrain edit to a database's journal");
  apply->require_subcommand(1);
  apply->footer(
      "Examples:\n"
      "  sandtable edits apply db --journal battle.journal crater --lonlat 7.42 43.74 --radius 3 --depth 1.2\n"
      "  sandtable edits apply db berm --line \"11.57 49.96, 11.58 49.96\" --width 2 --height 1.5\n"
      "  sandtable edits apply db flatten --polygon \"E N, E N, E N\" --projected --height 412\n"
      "The journal is DB/edits.journal unless --journal FILE; every edit is appended to it.");
  // DB and --journal go before the kind (`edits apply DB --journal J
  // crater ...`) or after it (`edits apply crater DB ...`).
  auto common = std::make_shared<ApplyArgs>();
  apply->add_option("DB", common->dir, "Database directory");
  apply->add_option("--journal", common->journal, "Journal to append to (default: DB/edits.journal)");
  apply->add_flag("--json", common->json, "Print JSON");
  // `positionals` come before the optional DB (remove-object's ID).
  const auto sub = [&](const char* name, const char* what,
                       const std::function<void(CLI::App&, ApplyArgs&)>& positionals = {}) {
    auto a = std::make_shared<ApplyArgs>();
    a->kind = name;
    auto* s = apply->add_subcommand(name, what);
    if (positionals) positionals(*s, *a);
    s->add_option("DB", a->dir, "Database directory (or give it before the kind)");
    s->add_option("--journal", a->journal, "Journal to append to (default: DB/edits.journal)");
    s->add_flag("--json", a->json, "Print JSON");
    c.add(s, [a, common] {
      if (a->dir.empty()) a->dir = common->dir;
      if (a->journal.empty()) a->journal = common->journal;
      a->json = a->json || common->json;
      if (a->dir.empty()) {
        return usageError("edits apply " + a->kind,
                          "the database is missing: give DB before the kind (`edits apply DB " + a->kind +
                              " ...`) or after it");
      }
      return runApply(*a);
    });
    return std::pair{s, a};
  };
  {
    auto [s, a] = sub("crater", "A crater: a bowl and its rim (docs/DYNAMIC.md)");
    s->add_option("--lonlat", a->lonlat, "Centre, LON LAT (WGS 84 degrees)")->expected(2);
    s->add_option("--xy", a->xy, "Centre, EASTING NORTHING in the database CRS")->expected(2);
    s->add_option("--radius", a->radius, "Rim crest radius, metres")->required();
    s->add_option("--depth", a->depth, "Depth at the centre below the ground before, metres")->required();
  }
  for (const char* name : {"berm", "ditch"}) {
    auto [s, a] = sub(name, std::string(name) == std::string("berm") ? "A berm along a line" : "A ditch along a line");
    s->add_option("--line", a->line, "\"LON LAT, LON LAT, ...\" (or E N with --projected)")->required();
    s->add_flag("--projected", a->projected, "--line is in the database CRS");
    s->add_option("--width", a->width, "Crest (berm) or floor (ditch) width, metres")->required();
    s->add_option("--height", a->height, "Height (berm) or depth (ditch), metres");
    s->add_option("--depth", a->depth, "Depth of a ditch, metres (same as --height)");
    s->add_option("--slope", a->slope, "Side slope, rise over run (default 0.5)");
  }
  {
    auto [s, a] = sub("flatten", "Flatten a polygon to a height");
    s->add_option("--polygon", a->polygon, "\"LON LAT, LON LAT, LON LAT, ...\" (or E N with --projected)")->required();
    s->add_flag("--projected", a->projected, "--polygon is in the database CRS");
    s->add_option("--height", a->height, "Height, metres above the datum")->required();
    s->add_option("--slope", a->slope, "Side slope of the cut or fill around it (default 0.5)");
  }
  const auto objectId = [](CLI::App& app, ApplyArgs& args) {
    app.add_option("ID", args.object, "The object's id in its module (export --objects lists them)")->required();
  };
  {
    auto [s, a] = sub("add-object", "Place a static object (an icon of icons.pack)");
    s->add_option("--icon", a->icon, "Icon name in the database's icons.pack")->required();
    s->add_option("--lonlat", a->lonlat, "Where, LON LAT (WGS 84 degrees)")->expected(2);
    s->add_option("--xy", a->xy, "Where, EASTING NORTHING in the database CRS")->expected(2);
    s->add_option("--heading", a->headingDeg, "Degrees clockwise from grid north (default 0)");
    s->add_option("--scale", a->scale, "Uniform scale (default 1)");
  }
  {
    auto [s, a] = sub("switch-object", "Show another icon for a static object (the seed's model switching)", objectId);
    s->add_option("--module", a->module, "KX KZ: the object's load module")->expected(2)->required();
    s->add_option("--icon", a->icon, "Icon name in the database's icons.pack")->required();
  }
  {
    auto [s, a] = sub("scale-object", "Scale a static object (the seed's scaling)", objectId);
    s->add_option("--module", a->module, "KX KZ: the object's load module")->expected(2)->required();
    s->add_option("--scale", a->scale, "Uniform scale")->required();
  }
  {
    auto [s, a] = sub("remove-object", "Remove a static object", objectId);
    s->add_option("--module", a->module, "KX KZ: the object's load module")->expected(2)->required();
  }
}

}  // namespace

void registerEdits(CLI::App& root, Commands& c) {
  auto* edits = root.add_subcommand("edits", "Dynamic terrain: apply, list and bake terrain edits (craters, berms, ditches)");
  edits->require_subcommand(1);
  addApply(*edits, c);
  {
    auto a = std::make_shared<ListArgs>();
    auto* s = edits->add_subcommand("list", "List a journal's edits");
    s->add_option("JOURNAL", a->journal, "Journal file")->required();
    s->add_flag("--json", a->json, "Print JSON");
    c.add(s, [a] { return runList(*a); });
  }
  {
    auto a = std::make_shared<BakeArgs>();
    auto* s = edits->add_subcommand("bake", "Write a new database with a journal's edits built in");
    s->add_option("DB", a->dir, "Database directory")->required();
    s->add_option("JOURNAL", a->journal, "Journal file")->required();
    s->add_option("-o,--output", a->output, "New database directory")->required();
    s->add_flag("--replace", a->replace, "Replace the output if it exists (atomically)");
    s->add_flag("--json", a->json, "Print JSON");
    c.add(s, [a] { return runBake(*a); });
  }
}

}  // namespace sandtable::cli
