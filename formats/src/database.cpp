#include "sandtable/formats/database.h"

#include <optional>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/formats/module_check.h"

namespace sandtable {
namespace {

namespace fs = std::filesystem;

void checkAgreement(const manifest::Manifest& m, const grid::Header& h, const std::string& file,
                    std::vector<Problem>& out) {
  auto differ = [&](const char* what, double a, double b, std::uint64_t off) {
    if (a != b) {
      // Every digit: values that must agree exactly may differ in the last bit.
      char buf[200];
      std::snprintf(buf, sizeof buf, "database: grid header and manifest disagree on %s (header %.17g, manifest %.17g)",
                    what, b, a);
      out.push_back({file, off, buf});
    }
  };
  differ("posts_x", m.postsX, h.postsX, grid::field::postsX);
  differ("posts_z", m.postsZ, h.postsZ, grid::field::postsZ);
  differ("block_posts", m.blockPosts, h.blockPosts, grid::field::blockPosts);
  differ("spacing_m", m.spacing, h.spacing, grid::field::spacing);
  differ("origin_easting", m.originEasting, h.originEasting, grid::field::originEasting);
  differ("origin_northing", m.originNorthing, h.originNorthing, grid::field::originNorthing);
  differ("min_elevation", m.minElevation, h.minElevation, grid::field::minElevation);
  differ("max_elevation", m.maxElevation, h.maxElevation, grid::field::maxElevation);
}

void checkFiles(const std::string& dir, const manifest::Manifest& m, const Work& work, std::vector<Problem>& out) {
  bool hasGrid = false;
  std::uint64_t total = 0, done = 0;
  for (const auto& f : m.files) total += f.bytes;
  for (const auto& f : m.files) {
    work.report(total ? double(done) / double(total) : 0.0, "checking files");
    if (work.cancelled()) return;
    done += f.bytes;
    const std::string path = dir + "/" + f.path;
    hasGrid = hasGrid || f.path == manifest::kGridFileName;
    const auto read = crc32File(path);
    if (!read) {
      out.push_back({path, 0, "database: listed in the manifest but cannot be read"});
      continue;
    }
    const auto [crc, bytes] = read.value();
    if (bytes != f.bytes) {
      out.push_back({path, std::min(bytes, f.bytes),
                     "database: file is " + std::to_string(bytes) + " bytes, the manifest says " +
                         std::to_string(f.bytes) + (bytes < f.bytes ? " (truncated)" : "")});
    } else if (crc != f.crc) {
      out.push_back({path, 0, "database: file checksum " + crcHex(crc) +
                                  " does not match the manifest's " + crcHex(f.crc) +
                                  ": the file was modified or corrupted"});
    }
  }
  work.report(1.0, "checking files");
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    // The edit journal lies beside the database unlisted: it grows while
    // the database is in use, so no manifest CRC could cover it.
    const bool listed = name == manifest::kFileName || name == journal::kFileName ||
                        std::any_of(m.files.begin(), m.files.end(), [&](const auto& f) { return f.path == name; });
    if (!listed) out.push_back({e.path().string(), 0, "database: file is not listed in the manifest"});
  }
  if (!hasGrid) {
    out.push_back({dir + "/" + manifest::kFileName, 0,
                   std::string("database: the manifest does not list ") + manifest::kGridFileName});
  }
}

bool lists(const manifest::Manifest& m, const char* name) {
  return std::any_of(m.files.begin(), m.files.end(), [&](const auto& f) { return f.path == name; });
}

/// The pack index against the manifest and the grid: same levels and module
/// edge, and a module layout that covers the grid (modulesX = ceil((postsX -
/// 1) / moduleSquares)). Returns false when the layout cannot be used to
/// locate modules in the grid.
bool checkPackAgreement(const manifest::Manifest& m, const grid::Header* g, const pack::IndexHeader& h,
                        const std::string& indexPath, std::vector<Problem>& out) {
  auto differ = [&](const char* what, const std::string& index, const std::string& other, const char* source,
                    std::uint64_t off) {
    out.push_back({indexPath, off, std::string("database: pack index and ") + source + " disagree on " + what +
                                       " (index " + index + ", " + source + " " + other + ")"});
  };
  if (std::int64_t(h.levels) != m.levels) {
    differ("levels", std::to_string(h.levels), std::to_string(m.levels), "manifest", pack::indexField::levels);
  }
  if (h.moduleSize != m.moduleSize) {
    differ("module_size_m", std::to_string(h.moduleSize), std::to_string(m.moduleSize), "manifest",
           pack::indexField::moduleSize);
  }
  if (!g) return false;
  bool usable = h.moduleSquares > 0;
  const double edge = double(h.moduleSquares) * g->spacing;
  if (!(std::fabs(edge - h.moduleSize) <= 1e-9 * std::max(edge, 1.0))) {
    differ("the module edge", std::to_string(h.moduleSize) + " m",
           std::to_string(h.moduleSquares) + " squares x " + std::to_string(g->spacing) + " m", "grid",
           pack::indexField::moduleSize);
  }
  if (usable) {
    const std::uint64_t wantX = (std::uint64_t(g->postsX) - 2) / h.moduleSquares + 1;
    const std::uint64_t wantZ = (std::uint64_t(g->postsZ) - 2) / h.moduleSquares + 1;
    if (h.modulesX != wantX || h.modulesZ != wantZ) {
      differ("the module count", std::to_string(h.modulesX) + " x " + std::to_string(h.modulesZ),
             std::to_string(wantX) + " x " + std::to_string(wantZ) + " modules of " +
                 std::to_string(h.moduleSquares) + " squares over " + std::to_string(g->postsX) + " x " +
                 std::to_string(g->postsZ) + " posts",
             "grid", pack::indexField::modulesX);
      usable = false;
    }
  }
  return usable;
}

bool sameObject(const module::Object& a, const module::Object& b) {
  return a.icon == b.icon && a.cls == b.cls && a.x == b.x && a.z == b.z && a.heading == b.heading &&
         a.scale == b.scale && a.radius == b.radius && a.height == b.height;
}

/// Each record of a v2 pack carries the module's whole objects list (the
/// pager shows a module's coarse record first, the reader keeps the fine
/// record's list): the two must be the same.
Status compareObjects(const pack::PackReader& r, std::uint32_t kx, std::uint32_t kz,
                      const std::vector<module::Object>& coarse, const std::vector<module::Object>& fine) {
  std::size_t k = 0;
  while (k < coarse.size() && k < fine.size() && sameObject(coarse[k], fine[k])) ++k;
  if (k == coarse.size() && k == fine.size()) return {};
  // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "(" + std::string.
  std::string message = "module (";
  message += std::to_string(kx);
  message += ',';
  message += std::to_string(kz);
  message += "): its coarse record holds " + std::to_string(coarse.size()) + " objects and its fine record " +
             std::to_string(fine.size()) + ", different from object " + std::to_string(k) +
             " on; both must carry the same list (rebuild the database)";
  return Problem{r.packPath(), r.entry(kx, kz).fine.offset, message};
}

/// Load modules: the pack's own checks, the material table, then every
/// module's geometry and its edges against its west and north neighbours,
/// row by row (only the previous row's edges are kept).
void checkModules(const std::string& dir, const manifest::Manifest& m, const grid::GridFile* g,
                  std::optional<std::uint32_t> iconCount, const Work& work, std::vector<Problem>& out) {
  const bool idx = lists(m, pack::kIndexFileName), pk = lists(m, pack::kPackFileName);
  const std::string manifestPath = dir + "/" + manifest::kFileName;
  if (!idx && !pk) return;
  if (idx != pk) {
    out.push_back({manifestPath, 0, std::string("database: the manifest lists ") +
                                        (idx ? pack::kIndexFileName : pack::kPackFileName) + " but not " +
                                        (idx ? pack::kPackFileName : pack::kIndexFileName)});
    return;
  }
  std::vector<Problem> found = pack::validatePack(dir, work).problems();
  if (work.cancelled()) {
    out.insert(out.end(), found.begin(), found.end());
    return;
  }
  const bool packSound = found.empty();
  std::optional<materials::Table> table;
  if (lists(m, materials::kFileName)) {
    auto t = materials::readFile(dir + "/" + materials::kFileName);
    if (t) table = std::move(t.value());
    else found.insert(found.end(), t.problems().begin(), t.problems().end());
  } else {
    found.push_back({manifestPath, 0, std::string("database: the manifest lists load modules but not ") +
                                          materials::kFileName + ", the table their material ids refer to"});
  }
  auto reader = pack::PackReader::open(dir);
  if (!reader) {
    if (packSound) found.insert(found.end(), reader.problems().begin(), reader.problems().end());
  } else if (checkPackAgreement(m, g ? &g->header() : nullptr, reader.value()->header(),
                                reader.value()->indexPath(), found) && g) {
    const pack::PackReader& r = *reader.value();
    const pack::IndexHeader& h = r.header();
    module::CheckOptions o;
    o.materials = table ? &*table : nullptr;
    o.iconCount = iconCount;
    const module::ModuleChecker checker(*g, h, r.packPath(), o);
    std::vector<module::ModuleEdges> above(h.modulesX), row(h.modulesX);
    std::vector<bool> haveAbove(h.modulesX, false), haveRow(h.modulesX, false);
    auto append = [&](const Status& st) { found.insert(found.end(), st.problems().begin(), st.problems().end()); };
    for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
      work.report(double(kz) / h.modulesZ, "checking modules");
      if (work.cancelled()) {
        found.push_back({r.packPath(), 0, kCancelledMessage});
        break;
      }
      for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
        haveRow[kx] = false;
        module::Module mod;
        std::vector<module::Object> coarseObjects;
        Status read = r.readCoarseInto(kx, kz, mod);
        if (read) {
          coarseObjects = mod.objects;
          read = r.readFineInto(kx, kz, mod);
        }
        if (!read) {
          if (packSound) append(read);
          continue;
        }
        append(compareObjects(r, kx, kz, coarseObjects, mod.objects));
        append(checker.check(mod, r.entry(kx, kz).offset, &row[kx]));
        haveRow[kx] = true;
        if (kx > 0 && haveRow[kx - 1]) append(checker.neighbours(row[kx - 1], row[kx]));
        if (kz > 0 && haveAbove[kx]) append(checker.neighbours(above[kx], row[kx]));
      }
      std::swap(above, row);
      std::swap(haveAbove, haveRow);
    }
    if (!work.cancelled()) work.report(1.0, "checking modules");
  }
  // One order whatever the pack's record order: by file, then offset; the
  // problems of one module keep the order they were found in. A cancelled
  // check keeps its last word last.
  const bool cancelled = !found.empty() && found.back().message == kCancelledMessage;
  if (cancelled) found.pop_back();
  std::stable_sort(found.begin(), found.end(), [](const Problem& a, const Problem& b) {
    return a.file != b.file ? a.file < b.file : a.offset < b.offset;
  });
  out.insert(out.end(), found.begin(), found.end());
  if (cancelled) out.push_back({dir + "/" + pack::kPackFileName, 0, kCancelledMessage});
}

}  // namespace

namespace {
std::atomic<std::uint64_t> gDatabaseOpens{0};

/// modules.idx from `directory` (size capped by the manifest's check of
/// the index header) and the pack through `pack`.
Result<std::shared_ptr<const pack::PackReader>> openRemotePack(const std::string& directory,
                                                              std::shared_ptr<const RangeSource> pack) {
  const std::string path = directory + "/" + pack::kIndexFileName;
  auto bytes = readSmallFile(path, std::uint64_t(1) << 32);
  if (!bytes) return bytes.problems();
  return pack::PackReader::openRemote(std::move(bytes.value()), path, std::move(pack));
}
}  // namespace

std::uint64_t databaseOpens() { return gDatabaseOpens.load(std::memory_order_relaxed); }

Result<Database> openDatabase(const std::string& directory, std::shared_ptr<const RangeSource> remotePack,
                              std::shared_ptr<const grid::GridFile> remoteGrid) {
  gDatabaseOpens.fetch_add(1, std::memory_order_relaxed);
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) {
    return Problem{directory, 0, "database: not a directory (give the path that `sandtable build -o` wrote)"};
  }
  auto m = manifest::readFromDirectory(directory);
  if (!m) return m.problems();
  auto g = remoteGrid ? Result<std::shared_ptr<const grid::GridFile>>(std::move(remoteGrid))
                     : grid::GridFile::open(directory + "/" + manifest::kGridFileName);
  if (!g) return g.problems();
  Database db{directory, std::move(m.value()), g.value(), nullptr, std::nullopt, std::nullopt};
  std::vector<Problem> problems;
  checkAgreement(db.manifest, db.grid->header(), db.grid->path(), problems);
  if (lists(db.manifest, pack::kIndexFileName) || lists(db.manifest, pack::kPackFileName)) {
    auto r = remotePack ? openRemotePack(directory, std::move(remotePack)) : pack::PackReader::open(directory);
    if (!r) return r.problems();
    checkPackAgreement(db.manifest, &db.grid->header(), r.value()->header(), r.value()->indexPath(), problems);
    db.modules = r.value();
  }
  if (lists(db.manifest, materials::kFileName)) {
    auto t = materials::readFile(directory + "/" + materials::kFileName);
    if (!t) return t.problems();
    db.materials = std::move(t.value());
  }
  if (lists(db.manifest, iconpack::kFileName)) {
    auto icons = iconpack::readFile(directory + "/" + iconpack::kFileName);
    if (!icons) return icons.problems();
    db.icons = std::move(icons.value());
  }
  if (!problems.empty()) return problems;
  return db;
}

Status validateDatabase(const std::string& directory, const Work& work) {
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) {
    return Problem{directory, 0, "database: not a directory"};
  }
  auto m = manifest::readFromDirectory(directory);
  if (!m) return m.problems();
  std::vector<Problem> out;
  // Once cancelled, the report ends with one kCancelledMessage.
  auto stopped = [&](const std::string& file) {
    if (!work.cancelled()) return false;
    if (out.empty() || out.back().message != kCancelledMessage) out.push_back({file, 0, kCancelledMessage});
    return true;
  };
  checkFiles(directory, m.value(), work, out);
  if (stopped(directory + "/" + manifest::kFileName)) return out;
  const std::string gridPath = directory + "/" + manifest::kGridFileName;
  const Status gridStatus = grid::validateGrid(gridPath, work);
  out.insert(out.end(), gridStatus.problems().begin(), gridStatus.problems().end());
  if (stopped(gridPath)) return out;
  auto g = grid::GridFile::open(gridPath);
  if (g) checkAgreement(m.value(), g.value()->header(), gridPath, out);
  // icons.pack before the modules: their icon indices are checked against it.
  std::optional<std::uint32_t> iconCount;
  std::vector<Problem> iconProblems;
  if (lists(m.value(), iconpack::kFileName)) {
    const auto icons = iconpack::readFile(directory + "/" + iconpack::kFileName);
    if (icons) iconCount = std::uint32_t(icons->icons.size());
    iconProblems = icons.problems();
  }
  checkModules(directory, m.value(), g ? g.value().get() : nullptr, iconCount, work, out);
  if (stopped(directory + "/" + pack::kPackFileName)) return out;
  out.insert(out.end(), iconProblems.begin(), iconProblems.end());  // after the modules', as before
  // The journal beside the database, when there is one: damage is a
  // problem, a torn tail (what a crash leaves, cut when it is next opened)
  // a warning.
  Warnings warnings;
  if (const std::string path = journal::defaultPath(directory); fs::exists(path, ec)) {
    const auto j = journal::readJournal(path);
    out.insert(out.end(), j.problems().begin(), j.problems().end());
    if (j) warnings = j->warnings;
  }
  Status result(std::move(out));
  result.addWarnings(warnings);
  return result;
}

}  // namespace sandtable
