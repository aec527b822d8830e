// bench make-db: the standard paging benchmark database. Synth writes DTED2
// and culture for a square, then the ordinary build turns them into a grid
// and 1 km load modules with roads decaled on, exactly as `sandtable synth`
// followed by `sandtable build` would.
#include "sandtable/bench/make_db.h"

#include <array>
#include <filesystem>
#include <system_error>

#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"

namespace sandtable::bench {
namespace {

namespace fs = std::filesystem;

/// The stage's problems as messages of their own ("synth: file @offset: ...").
std::vector<Problem> failed(const std::vector<Problem>& problems, const char* what) {
  std::vector<Problem> out;
  for (const Problem& p : problems) out.push_back({"", 0, std::string(what) + ": " + p.str()});
  return out;
}

/// Synth inputs in a sibling directory, so a failed build leaves the
/// output untouched and the inputs can be reused (keepInputs).
Result<convert::SynthSummary> synthesizeInputs(const MakeDbOptions& a, const fs::path& dir, const Notes& notes) {
  convert::SynthOptions so;
  so.outDir = dir.string();
  so.sizeKm = a.sizeKm;
  so.seed = a.seed;
  so.threads = a.threads;
  so.force = true;
  // The build reads DTED2 and culture only; the rest would cost time and disk.
  so.dted1 = false;
  so.dem = false;
  if (Status valid = convert::validateSynthOptions(so); !valid) return valid.problems();
  return convert::synthesize(so, [&](double f, const std::string& stage) { notes.report(f, "synth " + stage); });
}

Result<convert::ElevationReport> buildDb(const MakeDbOptions& a, const convert::SynthSummary& s, const fs::path& in,
                                         const Notes& notes) {
  convert::ElevationOptions o;
  o.sources = {(in / "dted2").string()};
  o.culture = {(in / "culture.gpkg").string()};
  o.output = a.output;
  o.spacing = a.spacing;
  o.extent = std::array<double, 4>{s.west, s.south, s.east, s.north};
  o.moduleSize = a.moduleSize;
  o.levels = a.levels;
  o.threads = a.threads;
  o.zstdLevel = a.zstdLevel;
  o.force = a.force;
  return convert::buildElevation(o, [&](double f, const std::string& stage) { notes.report(f, stage); });
}

}  // namespace

Result<MakeDbReport> makeBenchDatabase(const MakeDbOptions& a, const Notes& notes) {
  if (fs::exists(a.output) && !a.force) {
    return Problem{"", 0, a.output + " exists; pass MakeDbOptions::force to replace it or choose another "
                                      "MakeDbOptions::output"};
  }
  const fs::path in = fs::path(a.output).string() + ".synth";
  notes.say("synthesizing a " + std::to_string(int(a.sizeKm)) + " km square (DTED2 + culture) in " + in.string());
  auto s = synthesizeInputs(a, in, notes);
  if (!s) return failed(s.problems(), "synth");
  notes.say("synth done in " + std::to_string(s->seconds) + " s; building " + a.output);
  auto r = buildDb(a, s.value(), in, notes);
  std::error_code ec;
  if (!a.keepInputs) fs::remove_all(in, ec);
  if (!r) return failed(r.problems(), "build");
  MakeDbReport rep;
  rep.posts = r->posts;
  rep.modules = r->modules;
  rep.synthSeconds = s->seconds;
  rep.buildSeconds = r->seconds;
  rep.moduleStageSeconds = r->moduleSeconds;
  rep.roads = s->roads;
  rep.json = {{"output", a.output},
              {"size_km", a.sizeKm},
              {"spacing_m", a.spacing},
              {"module_size_m", a.moduleSize},
              {"levels", a.levels},
              {"posts", r->posts},
              {"modules", r->modules},
              {"synth_s", s->seconds},
              {"build_s", r->seconds},
              {"module_stage_s", r->moduleSeconds},
              {"module_bytes", r->manifest.build["modules"]["bytes"]},
              {"roads", s->roads}};
  return rep;
}

}  // namespace sandtable::bench
