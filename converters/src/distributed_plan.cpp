// The plan of a distributed build: the options, the inputs' CRCs, the
// frame and the task tiling, as one deterministic JSON file.
#include <cpl_vsi.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "build_stages.h"
#include "distributed_internal.h"
#include "sandtable/converters/distributed.h"
#include "sandtable/base/jobs.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/formats/part.h"
#include "sandtable/meshing/lattice.h"

namespace sandtable::convert {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kFormat = "sandtable-build-plan";
constexpr int kPlanVersion = 1;

json optionsJson(const ElevationOptions& o) {
  json j = {{"sources", o.sources},
            {"output", o.output},
            {"crs", o.crs},
            {"spacing", o.spacing},
            {"resample", o.resample},
            {"fit", o.fit},
            {"module_size", o.moduleSize},
            {"levels", o.levels},
            {"culture", o.culture},
            {"materials", o.materials},
            {"icons", o.icons},
            {"objects", o.objects},
            {"zstd_level", o.zstdLevel},
            {"module_version", o.moduleVersion},
            {"height_step", o.heightStep},
            {"module_normals", o.moduleNormals},
            {"max_scale_error", o.maxScaleError},
            {"sea_from_voids", o.seaFromVoids},
            {"memory_budget_bytes", o.memoryBudgetBytes}};
  j["extent"] = o.extent ? json(*o.extent) : json(nullptr);
  return j;
}

ElevationOptions optionsFrom(const json& j) {
  ElevationOptions o;
  o.sources = j.at("sources").get<std::vector<std::string>>();
  o.output = j.at("output").get<std::string>();
  o.crs = j.at("crs").get<std::string>();
  o.spacing = j.at("spacing").get<double>();
  o.resample = j.at("resample").get<std::string>();
  o.fit = j.at("fit").get<std::string>();
  if (!j.at("extent").is_null()) o.extent = j.at("extent").get<std::array<double, 4>>();
  o.moduleSize = j.at("module_size").get<double>();
  o.levels = j.at("levels").get<int>();
  o.culture = j.at("culture").get<std::vector<std::string>>();
  o.materials = j.at("materials").get<std::string>();
  o.icons = j.at("icons").get<std::string>();
  o.objects = j.at("objects").get<std::vector<std::string>>();
  o.zstdLevel = j.at("zstd_level").get<int>();
  o.moduleVersion = j.at("module_version").get<std::uint32_t>();
  o.heightStep = j.at("height_step").get<double>();
  o.moduleNormals = j.at("module_normals").get<bool>();
  o.maxScaleError = j.at("max_scale_error").get<double>();
  o.seaFromVoids = j.at("sea_from_voids").get<bool>();
  o.memoryBudgetBytes = j.at("memory_budget_bytes").get<std::uint64_t>();
  return o;
}

/// Splits module rows into `n` tasks as evenly as whole rows allow, and
/// gives each the block rows whose first post row falls in its posts.
std::vector<PlanTask> tileTasks(const Plan& p, std::uint32_t n) {
  std::vector<PlanTask> tasks;
  const std::uint32_t S = p.moduleSquares, B = grid::kBlockPosts;
  for (std::uint32_t i = 0; i < n; ++i) {
    PlanTask t;
    t.index = i;
    t.moduleRow0 = std::uint32_t(std::uint64_t(i) * p.modulesZ / n);
    const std::uint32_t row1 = std::uint32_t(std::uint64_t(i + 1) * p.modulesZ / n);
    t.moduleRows = row1 - t.moduleRow0;
    const bool last = i + 1 == n;
    const std::uint64_t post0 = std::uint64_t(t.moduleRow0) * S, post1 = last ? p.postsZ : std::uint64_t(row1) * S;
    t.blockRow0 = std::uint32_t((post0 + B - 1) / B);
    const std::uint32_t blockEnd = last ? p.blocksZ : std::uint32_t((post1 + B - 1) / B);
    t.blockRows = blockEnd - t.blockRow0;
    // The modules read the posts of their rows and the block table entries
    // of every block those posts touch; two posts more on each side keep
    // that true of any rule that looks one post past a module's edge.
    const std::uint64_t lo = post0 >= 2 ? post0 - 2 : 0;
    const std::uint64_t hi = std::min<std::uint64_t>(std::uint64_t(row1) * S + 2, p.postsZ - 1);
    const std::uint32_t fill0 = std::min(t.blockRow0, std::uint32_t(lo / B));
    const std::uint32_t fill1 = std::max(blockEnd, std::uint32_t(hi / B) + 1);
    t.fillRow0 = fill0;
    t.fillRows = std::min(fill1, p.blocksZ) - fill0;
    tasks.push_back(t);
  }
  return tasks;
}

json planJson(const Plan& p) {
  json inputs = json::array(), tasks = json::array();
  for (const auto& in : p.inputs) {
    inputs.push_back({{"path", in.path}, {"kind", in.kind}, {"bytes", in.bytes}, {"crc32", in.crc}});
  }
  for (const auto& t : p.tasks) {
    tasks.push_back({{"index", t.index},
                     {"module_rows", {t.moduleRow0, t.moduleRows}},
                     {"block_rows", {t.blockRow0, t.blockRows}},
                     {"fill_block_rows", {t.fillRow0, t.fillRows}}});
  }
  return {{"format", kFormat},
          {"version", kPlanVersion},
          {"tool_version", SANDTABLE_VERSION},
          {"directory", p.directory},
          {"parts", p.parts},
          {"options", optionsJson(p.options)},
          {"inputs", inputs},
          {"grid", {{"posts_x", p.postsX}, {"posts_z", p.postsZ}, {"blocks_x", p.blocksX}, {"blocks_z", p.blocksZ}}},
          {"modules", {{"modules_x", p.modulesX}, {"modules_z", p.modulesZ}, {"module_squares", p.moduleSquares}}},
          {"tasks", tasks}};
}

Status checkTiling(const Plan& p, const std::string& path) {
  std::uint32_t moduleRow = 0, blockRow = 0;
  for (std::size_t i = 0; i < p.tasks.size(); ++i) {
    const PlanTask& t = p.tasks[i];
    if (t.index != i || t.moduleRow0 != moduleRow || t.blockRow0 != blockRow || t.fillRow0 > t.blockRow0 ||
        t.fillRow0 + t.fillRows < t.blockRow0 + t.blockRows || t.fillRow0 + t.fillRows > p.blocksZ) {
      return Problem{path, 0, "plan: task " + std::to_string(i) + " does not continue the rows before it"};
    }
    moduleRow += t.moduleRows, blockRow += t.blockRows;
  }
  if (p.tasks.empty() || moduleRow != p.modulesZ || blockRow != p.blocksZ) {
    return Problem{path, 0, "plan: the tasks do not cover every module row and block row"};
  }
  return {};
}

}  // namespace

namespace detail {

Result<PlanInput> fingerprint(const std::string& path, const std::string& kind) {
  auto crc = crcThroughGdal(path, kind);
  if (!crc) return crc.problems();
  return PlanInput{path, kind, crc->bytes, crc->crc};
}

Result<std::vector<PlanInput>> fingerprintOthers(const ElevationOptions& o) {
  std::vector<PlanInput> out;
  auto add = [&](const std::string& path, const char* kind) -> Status {
    auto in = fingerprint(path, kind);
    if (!in) return in.problems();
    out.push_back(in.value());
    return {};
  };
  for (const auto& c : o.culture) {
    if (Status st = add(c, "culture"); !st) return st.problems();
  }
  if (!o.materials.empty()) {
    if (Status st = add(o.materials, "materials"); !st) return st.problems();
  }
  if (!o.icons.empty()) {
    if (Status st = add(o.icons, "icons"); !st) return st.problems();
  }
  for (const auto& f : o.objects) {
    if (Status st = add(f, "objects"); !st) return st.problems();
  }
  return out;
}

std::vector<PlanInput> elevationInputs(const std::vector<Source>& sources) {
  std::vector<PlanInput> out;
  for (const auto& s : sources) out.push_back({s.path, "elevation", s.bytes, s.crc});
  return out;
}

Status sameOtherInputs(const Plan& p, const std::vector<PlanInput>& now) {
  std::vector<PlanInput> planned;
  for (const auto& in : p.inputs) {
    if (in.kind != "elevation") planned.push_back(in);
  }
  const std::string fix = "; the inputs changed since the plan was written: write a new plan (--plan) and build again";
  if (planned.size() != now.size()) {
    return Problem{p.directory, 0, "plan: " + std::to_string(now.size()) + " culture, materials, icons and objects inputs, the plan has " +
                                       std::to_string(planned.size()) + fix};
  }
  for (std::size_t k = 0; k < now.size(); ++k) {
    const PlanInput &a = planned[k], &b = now[k];
    if (a.path != b.path || a.bytes != b.bytes || a.crc != b.crc) {
      char s[160];
      std::snprintf(s, sizeof s, "planned %llu bytes, CRC-32 %08x; now %llu bytes, CRC-32 %08x",
                    static_cast<unsigned long long>(a.bytes), a.crc, static_cast<unsigned long long>(b.bytes), b.crc);
      return Problem{b.path, 0, "plan: " + b.kind + " input " + b.path + " " + s + fix};
    }
  }
  return {};
}

Result<PlanFrame> openPlanned(const ElevationOptions& o, int threads, const ProgressFn& progress, bool checksums) {
  auto paths = expandSources(o.sources);
  if (!paths) return paths.problems();
  auto sources = openSources(paths.value(), threads, progress, checksums);
  if (!sources) return sources.problems();
  auto frame = planFrame(o, sources.value());
  if (!frame) return frame.problems();
  PlanFrame pf{std::move(sources.value()), frame.value(), {}};
  pf.kernel = chooseKernel(o.resample, o.fit, pf.frame.spacing, nativeSpacingMetres(pf.sources));
  return pf;
}

Status checkSources(const Plan& p, std::vector<Source>& sources, const std::function<bool(const Source&)>& checksum,
                    int threads) {
  std::vector<const PlanInput*> planned;
  for (const auto& in : p.inputs) {
    if (in.kind == "elevation") planned.push_back(&in);
  }
  const std::string fix = "; the inputs changed since the plan was written: write a new plan (--plan) and build again";
  if (planned.size() != sources.size()) {
    return Problem{p.directory, 0, "plan: " + std::to_string(sources.size()) + " elevation inputs, the plan has " +
                                       std::to_string(planned.size()) + fix};
  }
  std::vector<std::string> problems(sources.size());
  jobs::parallelFor(sources.size(), threads, [&](std::size_t k) {
    const PlanInput& a = *planned[k];
    Source& s = sources[k];
    std::uint32_t crc = a.crc;
    if (a.path == s.path && a.bytes == s.bytes && checksum(s)) {
      const auto now = crcThroughGdal(s.path, "source");
      crc = now ? now->crc : ~a.crc;
    }
    if (a.path != s.path || a.bytes != s.bytes || crc != a.crc) {
      char d[160];
      std::snprintf(d, sizeof d, "planned %llu bytes, CRC-32 %08x; now %llu bytes%s", static_cast<unsigned long long>(a.bytes),
                    a.crc, static_cast<unsigned long long>(s.bytes), crc != a.crc ? ", another CRC-32" : "");
      problems[k] = "plan: elevation input " + s.path + " " + d + fix;
    }
    s.crc = a.crc;
  });
  for (std::size_t k = 0; k < problems.size(); ++k) {
    if (!problems[k].empty()) return Problem{sources[k].path, 0, problems[k]};
  }
  return {};
}

std::array<double, 4> rowsLonLat(const Frame& f, std::uint32_t j0, std::uint32_t j1) {
  std::array<double, 4> box{INFINITY, INFINITY, -INFINITY, -INFINITY};
  const auto projection = geodesy::Projection::create(f.crs.wkt);
  if (!projection) return {-180, -90, 180, 90};  // cannot tell: every source is under the rows
  const double e0 = f.originEasting, e1 = f.originEasting + (f.postsX - 1) * f.spacing;
  const double n0 = f.originNorthing - j0 * f.spacing, n1 = f.originNorthing - (std::max(j1, j0 + 1) - 1) * f.spacing;
  for (int k = 0; k <= 16; ++k) {
    const double t = k / 16.0;
    for (const auto& [e, n] : {std::pair{e0 + t * (e1 - e0), n0}, std::pair{e0 + t * (e1 - e0), n1},
                              std::pair{e0, n0 + t * (n1 - n0)}, std::pair{e1, n0 + t * (n1 - n0)}}) {
      const auto ll = projection->toLonLat({e, n});
      if (!ll) return {-180, -90, 180, 90};
      box = {std::min(box[0], ll->lon), std::min(box[1], ll->lat), std::max(box[2], ll->lon), std::max(box[3], ll->lat)};
    }
  }
  // The kernels read source posts up to about a grid square beyond a post;
  // 0.05 degrees (5 km) is far more than any spacing a build takes.
  constexpr double kMarginDeg = 0.05;
  return {box[0] - kMarginDeg, box[1] - kMarginDeg, box[2] + kMarginDeg, box[3] + kMarginDeg};
}

Status sameFrame(const Plan& p, const Frame& f) {
  if (f.postsX != p.postsX || f.postsZ != p.postsZ) {
    return Problem{p.directory, 0, "plan: the frame is " + std::to_string(f.postsX) + " x " + std::to_string(f.postsZ) +
                                       " posts here, " + std::to_string(p.postsX) + " x " + std::to_string(p.postsZ) +
                                       " in the plan (another GDAL or PROJ?)"};
  }
  return {};
}

}  // namespace detail

Result<Plan> makePlan(const PlanOptions& po, const ProgressFn& progress) {
  const ElevationOptions& o = po.build;
  if (auto ok = detail::checkOptions(o); !ok) return ok.problems();
  if (!o.modules) {
    return Problem{"ElevationOptions::modules", 0,
                   "plan: a distributed build makes load modules; build a grid-only database on one machine"};
  }
  auto opened = detail::openPlanned(o, o.threads, progress);
  if (!opened) return opened.problems();
  const detail::PlanFrame& pf = opened.value();
  if (pf.kernel.resample != "weighted" && pf.kernel.resample != "bilinear") {
    return Problem{"ElevationOptions::resample", 0,
                   "plan: --resample " + pf.kernel.resample +
                       " runs GDALWarp, whose last bits depend on the rows it is given, so tasks could not "
                       "reproduce the one-machine grid; use weighted, bilinear or auto"};
  }
  Plan p;
  p.options = o;
  p.options.force = false;
  p.directory = fs::current_path().string();
  p.parts = fs::absolute(po.parts.empty() ? o.output + ".parts" : po.parts).lexically_normal().string();
  p.inputs = detail::elevationInputs(pf.sources);
  auto others = detail::fingerprintOthers(o);
  if (!others) return others.problems();
  p.inputs.insert(p.inputs.end(), others->begin(), others->end());
  const grid::Header h = grid::makeHeader(pf.frame.postsX, pf.frame.postsZ, pf.frame.spacing, 0, 0);
  p.postsX = h.postsX, p.postsZ = h.postsZ, p.blocksX = h.blocksX, p.blocksZ = h.blocksZ;
  p.moduleSquares = meshing::moduleSquares(o.moduleSize, pf.frame.spacing, o.levels);
  p.modulesX = (p.postsX - 2) / p.moduleSquares + 1;
  p.modulesZ = (p.postsZ - 2) / p.moduleSquares + 1;
  const std::uint32_t wanted =
      po.tasks > 0 ? po.tasks : (p.modulesZ + kDefaultTaskModuleRows - 1) / kDefaultTaskModuleRows;
  p.tasks = tileTasks(p, std::clamp<std::uint32_t>(wanted, 1, p.modulesZ));
  p.text = planJson(p).dump(2) + "\n";
  p.crc = crc32(std::as_bytes(std::span(p.text.data(), p.text.size())));
  return p;
}

Status writePlan(const Plan& plan, const std::string& path) {
  return writeFileAtomic(path, std::as_bytes(std::span(plan.text.data(), plan.text.size())));
}

Result<Plan> readPlan(const std::string& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return Problem{path, 0, "plan: cannot read the plan file: " + ec.message()};
  if (size > (64u << 20)) return Problem{path, 0, "plan: over 64 MiB; not a plan file"};
  std::string text(size, '\0');
  if (FILE* f = std::fopen(path.c_str(), "rb")) {
    const std::size_t n = std::fread(text.data(), 1, text.size(), f);
    std::fclose(f);
    if (n != text.size()) return Problem{path, 0, "plan: short read"};
  } else {
    return Problem{path, 0, "plan: cannot open the plan file"};
  }
  const json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return Problem{path, 0, "plan: not JSON"};
  if (j.value("format", "") != kFormat) return Problem{path, 0, "plan: not a sandtable build plan (format)"};
  if (j.value("version", 0) != kPlanVersion) {
    return Problem{path, 0, "plan: version " + std::to_string(j.value("version", 0)) + "; this sandtable reads 1"};
  }
  Plan p;
  try {
    p.options = optionsFrom(j.at("options"));
    p.directory = j.at("directory").get<std::string>();
    p.parts = j.at("parts").get<std::string>();
    for (const auto& in : j.at("inputs")) {
      p.inputs.push_back({in.at("path").get<std::string>(), in.at("kind").get<std::string>(),
                          in.at("bytes").get<std::uint64_t>(), in.at("crc32").get<std::uint32_t>()});
    }
    const json& g = j.at("grid");
    p.postsX = g.at("posts_x").get<std::uint32_t>(), p.postsZ = g.at("posts_z").get<std::uint32_t>();
    p.blocksX = g.at("blocks_x").get<std::uint32_t>(), p.blocksZ = g.at("blocks_z").get<std::uint32_t>();
    const json& m = j.at("modules");
    p.modulesX = m.at("modules_x").get<std::uint32_t>(), p.modulesZ = m.at("modules_z").get<std::uint32_t>();
    p.moduleSquares = m.at("module_squares").get<std::uint32_t>();
    for (const auto& t : j.at("tasks")) {
      PlanTask pt;
      pt.index = t.at("index").get<std::uint32_t>();
      pt.moduleRow0 = t.at("module_rows").at(0).get<std::uint32_t>();
      pt.moduleRows = t.at("module_rows").at(1).get<std::uint32_t>();
      pt.blockRow0 = t.at("block_rows").at(0).get<std::uint32_t>();
      pt.blockRows = t.at("block_rows").at(1).get<std::uint32_t>();
      pt.fillRow0 = t.at("fill_block_rows").at(0).get<std::uint32_t>();
      pt.fillRows = t.at("fill_block_rows").at(1).get<std::uint32_t>();
      p.tasks.push_back(pt);
    }
  } catch (const json::exception& e) {
    return Problem{path, 0, std::string("plan: a field is missing or of the wrong type: ") + e.what()};
  }
  if (Status st = checkTiling(p, path); !st) return st.problems();
  p.text = std::move(text);
  p.crc = crc32(std::as_bytes(std::span(p.text.data(), p.text.size())));
  return p;
}

std::string partPath(const Plan& plan, std::uint32_t task) {
  char name[32];
  std::snprintf(name, sizeof name, "part-%05u.stp", task);
  return plan.parts + "/" + name;
}

}  // namespace sandtable::convert
