// The merge of a distributed build: every part checked, then streamed in
// task order into grid.stg and modules.pack; the accuracy sample, the side
// files and the manifest made by the one-machine build's own stages.
#include <chrono>
#include <filesystem>
#include <unistd.h>

#include "build_stages.h"
#include "distributed_internal.h"
#include "sandtable/converters/distributed.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/part.h"

namespace sandtable::convert {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// The sums the parts' reports carry into the module report.
Status addPartReport(const json& j, ModuleReport& r, double& resampleSeconds) {
  try {
    const json& levels = j.at("levels");
    std::vector<LevelTotals> totals;
    for (const json& l : levels) {
      totals.push_back({l.at(0).get<std::uint64_t>(), l.at(1).get<std::uint64_t>(), l.at(2).get<std::uint64_t>(),
                        l.at(3).get<std::uint64_t>(), l.at(4).get<std::uint64_t>(), l.at(5).get<std::uint64_t>()});
    }
    if (totals.size() != r.levels.size()) return Problem{"", 0, "the report's level count differs from the plan's"};
    addTotals(r, totals);
    ObjectTotals o;
    o.placed = j.at("objects").at("placed").get<std::uint64_t>();
    o.scatterRefused = j.at("objects").at("scatter_refused").get<std::uint64_t>();
    for (const json& c : j.at("objects").at("by_class")) {
      o.byClass[c.at(0).get<std::uint16_t>()] = c.at(1).get<std::uint64_t>();
    }
    addObjects(r.objects, o);
    const json& s = j.at("stage_cpu_seconds");
    StageSeconds st{s.at(0).get<double>(), s.at(1).get<double>(), s.at(2).get<double>(), s.at(3).get<double>(),
                    s.at(4).get<double>(), s.at(5).get<double>(), s.at(6).get<double>(), s.at(7).get<double>()};
    r.stages += st;
    r.modules += j.at("modules").get<std::uint64_t>();
    resampleSeconds += j.at("resample_seconds").get<double>();
  } catch (const json::exception& e) {
    return Problem{"", 0, std::string("its report lacks a field: ") + e.what()};
  }
  return {};
}

ModuleReport planLayout(const Plan& p, const detail::Frame& f, const ModuleOptions& mo) {
  ModuleReport r;
  r.moduleSquares = p.moduleSquares;
  r.moduleSize = p.moduleSquares * f.spacing;
  r.modulesX = p.modulesX, r.modulesZ = p.modulesZ;
  r.moduleVersion = mo.moduleVersion;
  r.heightStep = mo.moduleVersion >= module::kVersion2 ? mo.heightStep : 0.0;
  r.normals = mo.moduleVersion >= module::kVersion2 && mo.normals;
  r.levels.assign(std::size_t(mo.levels), {});
  return r;
}

/// Where the merge writes, and what it has summed so far.
struct MergeState {
  grid::GridWriter* grid = nullptr;
  pack::PackWriter* pack = nullptr;
  ModuleReport modules;
  double resampleSeconds = 0;
  json firstReport;
};

/// Copies one part's blocks and modules, in order, into the writers.
Status copyPart(const Plan& plan, std::uint32_t task, MergeState& m) {
  const std::string path = partPath(plan, task);
  auto reader = part::PartReader::open(path);
  if (!reader) return reader.problems();
  part::PartReader& in = *reader.value();
  auto fail = [&](const std::string& what) {
    return Status(Problem{path, 0, "merge: task " + std::to_string(task) + ": " + what});
  };
  const PlanTask& t = plan.tasks[task];
  std::vector<std::byte> block(grid::kBlockBytes);
  for (std::uint32_t bz = t.blockRow0; bz < t.blockRow0 + t.blockRows; ++bz) {
    for (std::uint32_t bx = 0; bx < plan.blocksX; ++bx) {
      auto e = in.nextBlock(block);
      if (!e) return e.problems();
      if (Status st = m.grid->writeEncodedBlock(bx, bz, block, e.value()); !st) return st;
    }
  }
  for (std::uint64_t k = 0; k < in.header().moduleCount(); ++k) {
    if (cancelRequested()) return fail("cancelled");
    auto rec = in.nextModule();
    if (!rec) return rec.problems();
    pack::PackWriter::Record r{rec->entry, std::move(rec->coarse), std::move(rec->fine)};
    if (r.entry.kz != t.moduleRow0 + k / plan.modulesX || r.entry.kx != k % plan.modulesX) {
      return fail("module " + std::to_string(k) + " is not the next module in row order");
    }
    if (Status st = m.pack->append(std::move(r)); !st) return fail(st.message());
  }
  const json report = json::parse(in.report(), nullptr, false);
  if (report.is_discarded()) return fail("its report is not JSON");
  if (Status st = addPartReport(report, m.modules, m.resampleSeconds); !st) return fail(st.message());
  if (task == 0) m.firstReport = report;
  return {};
}

/// The accuracy sample against the merged grid, read back in 64-row bands.
Result<SourceAccuracy> sampleAccuracy(const std::string& vrt, const detail::Frame& f, const std::string& gridPath) {
  detail::AccuracySampler sampler;
  if (Status st = sampler.prepare(vrt, f); !st) return st.problems();
  auto g = grid::GridFile::open(gridPath);
  if (!g) return g.problems();
  const std::uint32_t band = grid::kBlockPosts;
  std::vector<float> rows;
  for (std::uint32_t a = 0; a < f.postsZ; a += band) {
    const std::uint32_t e = std::min(f.postsZ, a + band), last = std::min(f.postsZ, e + 1);
    rows.resize(std::size_t(last - a) * f.postsX);
    for (std::uint32_t j = a; j < last; ++j) {
      for (std::uint32_t i = 0; i < f.postsX; ++i) rows[std::size_t(j - a) * f.postsX + i] = g.value()->elevation(i, j);
    }
    sampler.add(a, e, [&](std::uint32_t j) { return rows.data() + std::size_t(std::min(j, last - 1) - a) * f.postsX; });
  }
  return sampler.finish();
}

}  // namespace

Result<ElevationReport> mergeParts(const Plan& plan, const MergeOptions& mopt, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  ElevationOptions o = plan.options;
  if (!mopt.output.empty()) o.output = mopt.output;
  o.force = mopt.force;
  o.threads = mopt.threads;
  if (auto ok = detail::checkOptions(o); !ok) return ok.problems();
  // Every part first: nothing is written while one is missing or damaged.
  for (std::uint32_t t = 0; t < plan.tasks.size(); ++t) {
    if (progress) progress(double(t) / double(plan.tasks.size()) * 0.2, "checking parts");
    if (Status st = checkPart(plan, t); !st) {
      Problem p = st.problems().front();
      p.message = "merge: " + p.message;
      return p;
    }
  }
  // The tasks checked every source under the grid against its CRC; the
  // merge checks sizes and takes the plan's CRCs for the manifest.
  auto opened = detail::openPlanned(o, o.threads, {}, false);
  if (!opened) return opened.problems();
  detail::PlanFrame& pf = opened.value();
  const detail::Frame& f = pf.frame;
  if (Status st = detail::checkSources(plan, pf.sources, [](const detail::Source&) { return false; }, o.threads); !st) {
    return st.problems();
  }
  auto others = detail::fingerprintOthers(o);
  if (!others) return others.problems();
  if (Status st = detail::sameOtherInputs(plan, others.value()); !st) return st.problems();
  if (Status st = detail::sameFrame(plan, f); !st) return st.problems();
  detail::CultureSetup c;
  auto table = detail::loadMaterials(o);
  if (!table) return table.problems();
  c.table = std::move(table.value());
  if (Status st = detail::loadIcons(o, c); !st) return st.problems();

  detail::PartialDirectory partial(o.output + ".partial." + std::to_string(::getpid()));
  std::error_code ec;
  fs::create_directories(partial.path(), ec);
  if (ec) return Problem{partial.path(), 0, "merge: cannot create the work directory: " + ec.message()};
  const std::string vrt = partial.path() + "/mosaic.vrt";
  if (Status st = detail::buildMosaic(pf.sources, vrt); !st) return Problem{o.output, 0, st.message()};

  const std::string gridPath = partial.path() + "/" + manifest::kGridFileName;
  auto gw = grid::GridWriter::create(
      gridPath, grid::makeHeader(f.postsX, f.postsZ, f.spacing, f.originEasting, f.originNorthing));
  if (!gw) return gw.problems();
  ModuleOptions mo = detail::moduleOptions(o, c);
  MergeState m;
  m.modules = planLayout(plan, f, mo);
  auto pw = createPackWriter(partial.path(), m.modules, mo);
  if (!pw) return pw.problems();
  m.grid = gw.value().get(), m.pack = pw.value().get();
  for (std::uint32_t t = 0; t < plan.tasks.size(); ++t) {
    if (progress) progress(0.2 + 0.7 * double(t) / double(plan.tasks.size()), "merging parts");
    if (Status st = copyPart(plan, t, m); !st) return st.problems();
  }
  if (Status st = gw.value()->finish(); !st) return st.problems();
  if (Status st = pw.value()->finish(); !st) return Problem{o.output, 0, "merge: modules: " + st.message()};
  ModuleReport& r = m.modules;
  r.sizes = pw.value()->stats();
  r.packBytes = pw.value()->packBytes(), r.indexBytes = pw.value()->indexBytes();
  r.packCrc = pw.value()->packCrc(), r.indexCrc = pw.value()->indexCrc();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  if (progress) progress(0.95, "accuracy");
  auto accuracy = sampleAccuracy(vrt, f, gridPath);
  if (!accuracy) return Problem{o.output, 0, accuracy.problems().front().message};
  ElevationReport report;
  report.manifest = detail::makeManifest(o, f, gw.value()->header(), pf.sources);
  report.manifest.files.push_back({manifest::kGridFileName, gw.value()->header().fileBytes, gw.value()->fileCrc()});
  if (Status st = detail::writeModuleSideFiles(partial.path(), c, r, report); !st) return st.problems();
  const detail::BandCost cost = detail::bandCost(vrt, f, pf.kernel);
  const std::uint32_t bandRows = detail::planBandRows(o.memoryBudgetBytes, f, cost);
  const std::uint32_t bands = (f.postsZ + bandRows - 1) / bandRows;
  const detail::BuildFacts facts{pf.kernel, accuracy.value(), 0, 0, m.resampleSeconds, bandRows, bands, bands > 1,
                                 static_cast<std::uint64_t>(cost.fixed + cost.perRow * bandRows)};
  detail::ModuleJson mj;
  mj.culture = m.firstReport.at("culture");
  mj.icons = detail::iconsReportJson(o, c);
  mj.objects = detail::objectsReportJson(o, c.table, m.firstReport.at("object_warnings"), r);
  fs::remove(vrt, ec);
  detail::describeBuild(o, facts, r, mj, t0, report);
  if (Status st = detail::publishWithManifest(partial, o.output, report.manifest, "merge"); !st) {
    return st.problems();
  }
  if (progress) progress(1.0, "merged");
  return report;
}

}  // namespace sandtable::convert
