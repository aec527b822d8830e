#include "sandtable/edits/bake.h"

#include <stdio.h>  // renameat2, RENAME_EXCHANGE
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>

#include "sandtable/base/jobs.h"
#include "sandtable/edits/editor.h"
#include "sandtable/edits/heights.h"
#include "sandtable/edits/modules.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/formats/pack.h"

namespace sandtable::edits {

namespace fs = std::filesystem;

namespace {

/// The edited posts without their refined squares: what a grid file and
/// modules meshed on its posts can hold.
class PostsOnly final : public grid::HeightField {
 public:
  explicit PostsOnly(std::shared_ptr<const grid::HeightField> f) : f_(std::move(f)) {}
  const grid::PostLayout& layout() const override { return f_->layout(); }
  float elevation(std::uint32_t i, std::uint32_t j) const override { return f_->elevation(i, j); }
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const override { return f_->normal(i, j); }
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const override { return f_->material(i, j); }
  std::pair<float, float> elevationBounds() const override { return f_->elevationBounds(); }
  std::uint64_t generation() const override { return f_->generation(); }
  std::uint64_t regionGeneration(const grid::PostRect& r) const override { return f_->regionGeneration(r); }

 private:
  std::shared_ptr<const grid::HeightField> f_;
};

/// Removes a staging directory unless released (an error or a cancel
/// leaves nothing behind).
class Staging {
 public:
  explicit Staging(std::string path) : path_(std::move(path)) {}
  ~Staging() {
    if (!path_.empty()) {
      std::error_code ec;
      fs::remove_all(path_, ec);
    }
  }
  const std::string& path() const { return path_; }
  void release() { path_.clear(); }

 private:
  std::string path_;
};

Status fsyncPath(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Problem{path, 0, "bake: cannot open " + path + " to sync it: " + std::strerror(errno)};
  const int r = ::fsync(fd);
  ::close(fd);
  if (r != 0) return Problem{path, 0, "bake: cannot sync " + path + ": " + std::strerror(errno)};
  return {};
}

Status linkOrCopy(const std::string& from, const std::string& to) {
  std::error_code ec;
  fs::create_hard_link(from, to, ec);
  if (!ec) return {};
  fs::copy_file(from, to, ec);
  if (ec) return Problem{from, 0, "bake: cannot copy " + from + " to " + to + ": " + ec.message()};
  return {};
}

/// Every block of the grid from `field`'s posts; posts past the grid's edge
/// repeat the edge posts, as the build writes them.
Status writeGrid(const std::string& path, const grid::GridFile& was, const grid::HeightField& field, const Work& work,
                 std::uint32_t& crc, std::uint64_t& bytes) {
  const grid::Header& old = was.header();
  const grid::Header h = grid::makeHeader(old.postsX, old.postsZ, old.spacing, old.originEasting, old.originNorthing);
  auto writer = grid::GridWriter::create(path, h);
  if (!writer) return writer.problems();
  std::atomic<bool> failed{false};
  std::string error;
  std::mutex errorMutex;
  jobs::parallelFor(h.blockCount(), 0, [&](std::size_t k) {
    if (failed || work.cancelled()) return;
    const auto bx = std::uint32_t(k % h.blocksX), bz = std::uint32_t(k / h.blocksX);
    auto b = std::make_unique<grid::BlockData>();
    for (std::uint32_t lz = 0; lz < grid::kBlockPosts; ++lz) {
      const std::uint32_t j = std::min(bz * grid::kBlockPosts + lz, h.postsZ - 1);
      for (std::uint32_t lx = 0; lx < grid::kBlockPosts; ++lx) {
        const std::uint32_t i = std::min(bx * grid::kBlockPosts + lx, h.postsX - 1);
        const std::size_t p = std::size_t(lz) * grid::kBlockPosts + lx;
        const auto n = field.normal(i, j);
        b->elevation[p] = field.elevation(i, j);
        b->normalX[p] = grid::toSnorm(n[0]);
        b->normalY[p] = grid::toSnorm(n[1]);
        b->normalZ[p] = grid::toSnorm(n[2]);
        b->material[p] = field.material(i, j);
      }
    }
    if (Status st = writer.value()->writeBlock(bx, bz, *b); !st) {
      std::lock_guard lock(errorMutex);
      if (!failed.exchange(true)) error = st.message();
    }
  });
  if (failed) return Problem{path, 0, "bake: " + error};
  if (work.cancelled()) return Problem{path, 0, "bake: cancelled; nothing was written"};
  if (Status st = writer.value()->finish(); !st) return st.problems();
  crc = writer.value()->fileCrc();
  bytes = writer.value()->header().fileBytes;
  return {};
}

}  // namespace

Result<BakeReport> bake(const paging::World& base, const std::vector<edit::Edit>& edits, const std::string& output,
                        bool replace, const Work& work) {
  const auto t0 = std::chrono::steady_clock::now();
  BakeReport report;
  const fs::path target = fs::absolute(output).lexically_normal();
  const fs::path out = target.filename().empty() ? target.parent_path() : target;
  report.output = out.string();
  if (fs::exists(out) && !replace) {
    return Problem{out.string(), 0, "bake: " + out.string() + " exists; choose another -o or remove it first"};
  }
  if (fs::absolute(base.directory()).lexically_normal() == out) {
    return Problem{out.string(), 0, "bake: the output is the database itself; give another -o"};
  }
  if (!base.gridFile()) return Problem{base.directory(), 0, "bake: the database has no grid file"};

  // The edits in key order, over the base's posts.
  std::vector<edit::Edit> sorted = edits;
  std::stable_sort(sorted.begin(), sorted.end(), [](const edit::Edit& a, const edit::Edit& b) { return keyOf(a) < keyOf(b); });
  auto heights = std::make_shared<EditedHeights>(base.heights());
  auto posts = std::make_shared<PostsOnly>(heights);
  std::unique_ptr<EditedModules> modules;
  if (base.modules()) {
    modules = std::make_unique<EditedModules>(base.modules(), base.heights(), posts, remeshOptionsFor(base));
  }
  for (const edit::Edit& e : sorted) {
    if (work.cancelled()) return Problem{out.string(), 0, "bake: cancelled; nothing was written"};
    const std::string what = "bake: edit " + std::to_string(e.id) + " (" + std::string(edit::kindName(e.kind)) + "): ";
    if (edit::changesHeights(e.kind)) {
      auto c = heights->apply(e);
      if (!c) return Problem{out.string(), 0, what + c.error()};
      if (modules && !c.value().posts.empty()) {
        auto r = modules->remesh(c.value().posts, {});
        if (!r) return Problem{out.string(), 0, what + r.error()};
        report.modulesRemeshed += r.value().modules.size();
      }
    } else if (modules) {
      if (Status st = modules->editObject(e); !st) return Problem{out.string(), 0, what + st.message()};
    } else {
      return Problem{out.string(), 0, what + "the database has no load modules to hold objects"};
    }
    ++report.edits;
    work.report(double(report.edits) / double(sorted.size()) * 0.3, "edits");
  }

  auto man = manifest::readFromDirectory(base.directory());
  if (!man) return man.problems();
  Staging staging(out.string() + ".bake." + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(staging.path(), ec);
  if (!fs::create_directories(staging.path(), ec)) {
    return Problem{staging.path(), 0, "bake: cannot create " + staging.path() + ": " + ec.message()};
  }
  for (const auto& f : man->files) {
    if (f.path == manifest::kGridFileName || f.path == pack::kPackFileName || f.path == pack::kIndexFileName) continue;
    if (Status st = linkOrCopy(base.directory() + "/" + f.path, staging.path() + "/" + f.path); !st) {
      return st.problems();
    }
  }
  manifest::Manifest m = man.value();
  std::uint32_t gridCrc = 0;
  if (Status st = writeGrid(staging.path() + "/" + manifest::kGridFileName, *base.gridFile(), *posts, work, gridCrc,
                            report.gridBytes);
      !st) {
    return st.problems();
  }
  work.report(0.6, "grid");
  for (auto& f : m.files) {
    if (f.path == manifest::kGridFileName) f.bytes = report.gridBytes, f.crc = gridCrc;
  }
  const auto [lo, hi] = posts->elevationBounds();
  m.minElevation = std::min(m.minElevation, lo);
  m.maxElevation = std::max(m.maxElevation, hi);

  if (base.modules() && modules) {
    const pack::IndexHeader header = base.modules()->header();
    pack::PackLayout layout = pack::PackLayout::split(header.levels);
    double step = module::kDefaultHeightStep;
    if (m.build.contains("modules") && m.build["modules"].contains("height_step_m")) {
      step = m.build["modules"]["height_step_m"].get<double>();
    }
    layout.encode = {.version = module::kNewestVersion, .heightStep = step};
    auto writer = pack::PackWriter::create(staging.path(), header, 9, layout);
    if (!writer) return writer.problems();
    module::Module mod;
    for (std::uint32_t kz = 0; kz < header.modulesZ; ++kz) {
      for (std::uint32_t kx = 0; kx < header.modulesX; ++kx) {
        if (work.cancelled()) return Problem{out.string(), 0, "bake: cancelled; nothing was written"};
        if (auto r = modules->read(kx, kz, mod); !r) return r.problems();
        mod.scattering = {double(kx) * header.moduleSize, double(kz) * header.moduleSize, header.moduleSize,
                          header.moduleSize, {}};
        if (Status st = writer.value()->add(mod); !st) return Problem{out.string(), 0, "bake: " + st.message()};
        ++report.modules;
      }
      work.report(0.6 + 0.4 * double(kz + 1) / double(header.modulesZ), "modules");
    }
    if (Status st = writer.value()->finish(); !st) return Problem{out.string(), 0, "bake: " + st.message()};
    report.packBytes = writer.value()->packBytes();
    for (auto& f : m.files) {
      if (f.path == pack::kPackFileName) f.bytes = writer.value()->packBytes(), f.crc = writer.value()->packCrc();
      if (f.path == pack::kIndexFileName) f.bytes = writer.value()->indexBytes(), f.crc = writer.value()->indexCrc();
    }
    if (m.build.contains("modules") && m.build["modules"].is_object()) {
      m.build["modules"]["format_version"] = module::kNewestVersion;
    }
  }
  m.build["baked"] = {{"edits", report.edits}, {"modules_remeshed", report.modulesRemeshed}};
  const std::string text = manifest::encode(m);
  if (Status st = writeFileAtomic(staging.path() + "/" + manifest::kFileName,
                                  std::as_bytes(std::span(text.data(), text.size())));
      !st) {
    return st.problems();
  }
  if (Status st = fsyncPath(staging.path()); !st) return st.problems();
  if (fs::exists(out)) {
    // Swap in one step, then drop what was there.
    if (::renameat2(AT_FDCWD, staging.path().c_str(), AT_FDCWD, out.c_str(), RENAME_EXCHANGE) != 0) {
      return Problem{out.string(), 0, std::string("bake: cannot swap the baked database into place: ") + std::strerror(errno)};
    }
  } else if (::rename(staging.path().c_str(), out.c_str()) != 0) {
    return Problem{out.string(), 0, std::string("bake: cannot move the baked database into place: ") + std::strerror(errno)};
  } else {
    staging.release();
  }
  static_cast<void>(fsyncPath(out.parent_path().string()));
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace sandtable::edits
