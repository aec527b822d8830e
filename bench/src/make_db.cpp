// bench make-db: the standard paging benchmark database. Synth writes DTED2
// and culture for a square, then the ordinary build turns them into a grid
// and 1 km load modules with roads decaled on, exactly as `sandtable synth`
// followed by `sandtable build` would.
#include "sandtable/bench/make_db.h"

#include <array>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <optional>
#include <system_error>

#include "sandtable/base/jobs.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/manifest.h"

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

Result<nlohmann::json> repackBenchDatabase(const std::string& from, const std::string& to,
                                           const pack::PackLayout& layout, int threads, int zstdLevel, bool force,
                                           const Notes& notes) {
  auto fail = [](const std::string& msg) { return Result<nlohmann::json>(Problem{"", 0, "repack: " + msg}); };
  std::error_code ec;
  if (fs::exists(to) && !force) return fail(to + " exists; pass force to replace it");
  auto reader = pack::PackReader::open(from);
  if (!reader) return reader.problems();
  auto man = manifest::readFromDirectory(from);
  if (!man) return man.problems();
  fs::remove_all(to, ec);
  fs::create_directories(to, ec);
  if (ec) return fail("cannot create " + to + ": " + ec.message());
  for (const auto& e : fs::directory_iterator(from)) {
    const std::string name = e.path().filename().string();
    if (!e.is_regular_file() || name == pack::kPackFileName || name == pack::kIndexFileName ||
        name == manifest::kFileName) {
      continue;
    }
    fs::create_hard_link(e.path(), fs::path(to) / name, ec);
    if (ec) fs::copy_file(e.path(), fs::path(to) / name, fs::copy_options::overwrite_existing, ec);
    if (ec) return fail("cannot link or copy " + e.path().string() + ": " + ec.message());
  }
  const pack::PackReader& r = *reader.value();
  pack::IndexHeader h = r.header();
  h.version = pack::kVersion1;  // the writer sets version, coarse level and order from the layout
  auto writer = pack::PackWriter::create(to, h, zstdLevel, layout);
  if (!writer) return writer.problems();
  const std::size_t n = std::size_t(h.modulesX) * h.modulesZ;
  std::atomic<bool> stop{false};
  std::string error;
  std::size_t done = 0;
  jobs::orderedPipeline<std::optional<pack::PackWriter::Record>>(
      n, threads, 32 * std::size_t(jobs::threadCount(threads)),
      [&](std::size_t k) -> std::optional<pack::PackWriter::Record> {
        if (stop) return std::nullopt;
        auto m = r.read(std::uint32_t(k % h.modulesX), std::uint32_t(k / h.modulesX));
        if (!m) {
          error = m.error();  // the first failure stops the pipeline; the race on which is harmless
          stop = true;
          return std::nullopt;
        }
        auto rec = writer.value()->compress(m.value());
        if (!rec) {
          error = rec.error();
          stop = true;
          return std::nullopt;
        }
        return std::move(rec.value());
      },
      [&](std::size_t, std::optional<pack::PackWriter::Record>&& rec) {
        if (stop || !rec) return;
        if (Status a = writer.value()->append(std::move(*rec)); !a) {
          error = a.message();
          stop = true;
        }
        if (++done % 256 == 0) notes.report(double(done) / double(n), "repack");
      },
      &stop);
  if (stop) return fail(error);
  if (Status f = writer.value()->finish(); !f) return fail(f.message());
  manifest::Manifest m = man.value();
  for (manifest::FileEntry& f : m.files) {
    if (f.path == pack::kPackFileName) f = {f.path, writer.value()->packBytes(), writer.value()->packCrc()};
    if (f.path == pack::kIndexFileName) f = {f.path, writer.value()->indexBytes(), writer.value()->indexCrc()};
  }
  {
    std::ofstream out(fs::path(to) / manifest::kFileName, std::ios::binary | std::ios::trunc);
    out << manifest::encode(m);
    if (!out) return fail("cannot write the manifest of " + to);
  }
  const pack::SizeStats st = writer.value()->stats();
  return nlohmann::json{{"output", to},
                        {"from", from},
                        {"pack_version", layout.version},
                        {"coarse_level", layout.coarseLevel},
                        {"order", layout.order == pack::PackOrder::morton ? "morton" : "row-major"},
                        {"modules", st.count},
                        {"pack_bytes", writer.value()->packBytes()},
                        {"median_module_bytes", st.medianCompressed},
                        {"p95_module_bytes", st.p95Compressed}};
}

}  // namespace sandtable::bench
