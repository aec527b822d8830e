// One task of a distributed build: its rows resampled (with the halo the
// triangle fit and the normals need), its grid blocks and load modules
// built by the one-machine build's stages, written into its part.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <unistd.h>

#include "build_stages.h"
#include "distributed_internal.h"
#include "sandtable/converters/distributed.h"
#include "sandtable/formats/part.h"

namespace sandtable::convert {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json levelsJson(const ModuleReport& r) {
  json levels = json::array();
  for (const auto& l : r.levels) {
    levels.push_back({l.triangles, l.skinPolygons, l.decalPolygons, l.skirtTriangles, l.buildings,
                      l.buildingTriangles});
  }
  return levels;
}

json objectsJson(const ObjectTotals& t) {
  json byClass = json::array();
  for (const auto& [cls, n] : t.byClass) byClass.push_back({cls, n});
  return {{"placed", t.placed}, {"scatter_refused", t.scatterRefused}, {"by_class", byClass}};
}

json stagesJson(const StageSeconds& s) {
  return {s.terrain, s.partition, s.gather, s.arrangement, s.pieces, s.cut, s.compress, s.write};
}

/// Voids left after resampling in rows [j0, j1) of `rows` (first row `first`).
std::uint64_t voidsIn(const std::vector<float>& rows, std::uint32_t first, std::uint32_t j0, std::uint32_t j1,
                      std::uint32_t w) {
  std::uint64_t n = 0;
  for (std::size_t k = std::size_t(j0 - first) * w; k < std::size_t(j1 - first) * w; ++k) n += std::isnan(rows[k]);
  return n;
}

struct TaskWork {
  const Plan& plan;
  const PlanTask& task;
  ElevationOptions o;
  detail::PlanFrame pf;
  detail::CultureSetup culture;
  std::string scratch;
  double resampleSeconds = 0;
};

/// Resamples and fits the task's fill rows and writes their blocks into a
/// scratch grid of the whole database's size (sparse: only those blocks).
Result<std::shared_ptr<const grid::GridFile>> scratchGrid(TaskWork& w, int threads, const ProgressFn& progress) {
  const detail::Frame& f = w.pf.frame;
  const std::uint32_t B = grid::kBlockPosts;
  const std::uint32_t a = w.task.fillRow0 * B, e = std::min(f.postsZ, (w.task.fillRow0 + w.task.fillRows) * B);
  const std::uint32_t ea = a >= detail::kFitHalo ? a - detail::kFitHalo : 0;
  const std::uint32_t ee = std::min(f.postsZ, e + detail::kFitHalo);
  const std::string vrt = w.scratch + "/mosaic.vrt";
  auto at = [&](const Status& st) { return Problem{partPath(w.plan, w.task.index), 0, st.message()}; };
  if (Status st = detail::buildMosaic(w.pf.sources, vrt); !st) return at(st);
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<float> rows(std::size_t(ee - ea) * f.postsX);
  if (Status st = detail::resampleRows(vrt, f, w.pf.kernel.resample, ea, ee, threads, rows.data(), progress); !st) {
    return at(st);
  }
  if (w.pf.kernel.fit == "triangles") {
    if (Status st = detail::fitTriangles(vrt, f, ea, ee, threads, rows.data(), progress); !st) return at(st);
  }
  w.resampleSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::uint32_t ra = a > 0 ? a - 1 : 0, re = std::min(f.postsZ, e + 1);
  if (const std::uint64_t voids = voidsIn(rows, ea, ra, re, f.postsX); voids > 0) {
    return Problem{partPath(w.plan, w.task.index), 0,
                   "task " + std::to_string(w.task.index) + ": the sources leave " + std::to_string(voids) +
                       " void posts in rows " + std::to_string(ra) + ".." + std::to_string(re - 1) +
                       "; void fill looks at the whole grid, so build these sources on one machine "
                       "(sandtable build without --executor)"};
  }
  const grid::Header h = grid::makeHeader(f.postsX, f.postsZ, f.spacing, f.originEasting, f.originNorthing);
  const std::string path = w.scratch + "/" + manifest::kGridFileName;
  auto writer = grid::GridWriter::create(path, h);
  if (!writer) return writer.problems();
  const detail::GridRows g{rows.data(), nullptr, long(ea), f.postsX};
  if (Status st = detail::writeBlockRows(*writer.value(), f, g, w.task.fillRow0, w.task.fillRow0 + w.task.fillRows,
                                         threads, {});
      !st) {
    return at(st);
  }
  if (Status st = writer.value()->finish(); !st) return st.problems();
  return grid::GridFile::open(path);
}

Status addBlocks(const grid::GridFile& g, const PlanTask& t, part::PartWriter& out) {
  for (std::uint32_t bz = t.blockRow0; bz < t.blockRow0 + t.blockRows; ++bz) {
    for (std::uint32_t bx = 0; bx < g.header().blocksX; ++bx) {
      if (Status st = out.addBlock(g.blockEntry(bx, bz), g.blockBytes(bx, bz)); !st) return st;
    }
  }
  return {};
}

Result<ModuleReport> addModules(TaskWork& w, const grid::GridFile& g, int threads, part::PartWriter& out,
                                const ProgressFn& progress) {
  ModuleOptions mo = detail::moduleOptions(w.o, w.culture);
  mo.threads = threads;
  // The pack writer is made for its compress() only (the records go into
  // the part); it removes its empty files when it goes.
  auto compressor = createPackWriter(w.scratch, moduleLayout(g, mo), mo);
  if (!compressor) return compressor.problems();
  return buildModuleRows(
      g, *w.culture.culture, w.culture.table.defaultArea, mo, {w.task.moduleRow0, w.task.moduleRows},
      *compressor.value(),
      [&out](pack::PackWriter::Record&& r) { return out.addModule(r.entry, r.bytes, r.fineBytes); }, progress);
}

}  // namespace

Status checkPart(const Plan& plan, std::uint32_t task) {
  const std::string path = partPath(plan, task);
  std::error_code ec;
  if (!fs::exists(path, ec)) return Problem{path, 0, "task " + std::to_string(task) + " has no part yet"};
  auto reader = part::PartReader::open(path);
  if (!reader) return reader.problems();
  const part::Header& h = reader.value()->header();
  const PlanTask& t = plan.tasks.at(task);
  char crcs[80];
  std::snprintf(crcs, sizeof crcs, " (plan CRC-32 %08x; this plan's is %08x)", h.planCrc, plan.crc);
  if (h.planCrc != plan.crc) {
    return Problem{path, part::field::planCrc, "part of task " + std::to_string(task) + " was built from another plan" +
                                                   crcs + "; delete it, or build with the plan that made it"};
  }
  if (h.task != task || h.blockRow0 != t.blockRow0 || h.blockRows != t.blockRows || h.moduleRow0 != t.moduleRow0 ||
      h.moduleRows != t.moduleRows || h.blocksX != plan.blocksX || h.modulesX != plan.modulesX) {
    return Problem{path, part::field::task, "part of task " + std::to_string(task) + " holds task " +
                                                std::to_string(h.task) + "'s rows, not this task's"};
  }
  if (Status st = reader.value()->verify(); !st) {
    Problem p = st.problems().front();
    p.message = "task " + std::to_string(task) + ": " + p.message;
    return p;
  }
  return {};
}

Result<TaskReport> buildTask(const Plan& plan, std::uint32_t task, int threads, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  if (task >= plan.tasks.size()) {
    return Problem{"task", 0, "task " + std::to_string(task) + ": the plan has " + std::to_string(plan.tasks.size()) +
                                  " tasks, 0 to " + std::to_string(plan.tasks.size() - 1)};
  }
  TaskReport rep;
  rep.task = task;
  const std::string path = partPath(plan, task);
  if (checkPart(plan, task)) {
    rep.skipped = true;
    return rep;
  }
  TaskWork w{plan, plan.tasks[task], plan.options, {}, {}, {}};
  w.o.threads = threads;
  // Only the sources under this task's rows (and its halo) are read whole
  // for their CRCs; the others are checked by size, and by the tasks under them.
  auto opened = detail::openPlanned(w.o, threads, {}, false);
  if (!opened) return opened.problems();
  w.pf = std::move(opened.value());
  if (Status st = detail::sameFrame(plan, w.pf.frame); !st) return st.problems();
  const PlanTask& t0rows = plan.tasks[task];
  const std::uint32_t B = grid::kBlockPosts;
  const std::uint32_t j0 = t0rows.fillRow0 * B >= B ? t0rows.fillRow0 * B - B : 0;
  const std::uint32_t j1 = std::min(w.pf.frame.postsZ, (t0rows.fillRow0 + t0rows.fillRows + 1) * B);
  const std::array<double, 4> box = detail::rowsLonLat(w.pf.frame, j0, j1);
  const auto under = [&box](const detail::Source& s) {
    return s.lonLatBox[0] <= box[2] && s.lonLatBox[2] >= box[0] && s.lonLatBox[1] <= box[3] && s.lonLatBox[3] >= box[1];
  };
  if (Status st = detail::checkSources(plan, w.pf.sources, under, threads); !st) return st.problems();
  auto others = detail::fingerprintOthers(w.o);
  if (!others) return others.problems();
  if (Status st = detail::sameOtherInputs(plan, others.value()); !st) return st.problems();
  auto culture = detail::loadCulture(w.o, w.pf.frame, {});
  if (!culture) return culture.problems();
  w.culture = std::move(culture.value());

  std::error_code ec;
  fs::create_directories(plan.parts, ec);
  if (ec) return Problem{plan.parts, 0, "task: cannot create the parts directory: " + ec.message()};
  detail::PartialDirectory scratch(plan.parts + "/task-" + std::to_string(task) + ".work." + std::to_string(::getpid()));
  fs::create_directories(scratch.path(), ec);
  if (ec) return Problem{scratch.path(), 0, "task: cannot create the work directory: " + ec.message()};
  w.scratch = scratch.path();
  auto grid = scratchGrid(w, threads, progress);
  if (!grid) return grid.problems();

  const PlanTask& t = w.task;
  part::Header ph;
  ph.planCrc = plan.crc;
  ph.task = task;
  ph.blockRow0 = t.blockRow0, ph.blockRows = t.blockRows, ph.blocksX = plan.blocksX;
  ph.moduleRow0 = t.moduleRow0, ph.moduleRows = t.moduleRows, ph.modulesX = plan.modulesX;
  ph.levels = std::uint32_t(w.o.levels);
  auto out = part::PartWriter::create(path, ph);
  if (!out) return out.problems();
  if (Status st = addBlocks(*grid.value(), t, *out.value()); !st) return st.problems();
  auto modules = addModules(w, *grid.value(), threads, *out.value(), progress);
  if (!modules) return Problem{path, 0, modules.problems().front().message};
  rep.modules = modules->modules;
  rep.blocks = std::uint64_t(t.blockRows) * plan.blocksX;
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const json report = {{"task", task},
                       {"modules", rep.modules},
                       {"blocks", rep.blocks},
                       {"seconds", rep.seconds},
                       {"resample_seconds", w.resampleSeconds},
                       {"module_seconds", modules->seconds},
                       {"levels", levelsJson(modules.value())},
                       {"objects", objectsJson(modules->objects)},
                       {"stage_cpu_seconds", stagesJson(modules->stages)},
                       {"culture", detail::cultureReportJson(w.o, *w.culture.culture)},
                       {"object_warnings", detail::objectWarningsJson(w.culture)}};
  if (Status st = out.value()->finish(report.dump()); !st) return st.problems();
  rep.bytes = fs::file_size(path, ec);
  return rep;
}

}  // namespace sandtable::convert
