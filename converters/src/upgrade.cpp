// The database upgrade (modules.h): records re-encoded as asked, and
// `sandtable upgrade`.
#include <fcntl.h>
#include <stdio.h>  // renameat2, RENAME_EXCHANGE
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "sandtable/converters/modules.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/formats/materials.h"

namespace sandtable::convert {

namespace fs = std::filesystem;

// ---------------------------------------------------------------- upgrade

namespace {

Status fsyncPath(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Problem{path, 0, "upgrade: cannot open " + path + " to fsync it"};
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) return Problem{path, 0, "upgrade: cannot fsync " + path};
  return {};
}

/// Hard link, or a copy where the file system will not link.
Status linkOrCopy(const std::string& from, const std::string& to) {
  if (::link(from.c_str(), to.c_str()) == 0) return {};
  std::error_code ec;
  fs::copy_file(from, to, ec);
  if (ec) return Problem{from, 0, "upgrade: cannot link or copy " + from + " to " + to + ": " + ec.message()};
  return fsyncPath(to);
}

/// Removes the staging directory unless it was swapped into place.
class Staging {
 public:
  explicit Staging(std::string path) : path_(std::move(path)) {}
  ~Staging() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace

Result<UpgradeReport> upgradeDatabase(const std::string& dir, const UpgradeOptions& o, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(std::isfinite(o.heightStep) && o.heightStep >= 0)) {
    return Problem{dir, 0, "upgrade: the height step must be a finite number >= 0 (0 keeps exact heights)"};
  }
  auto man = manifest::readFromDirectory(dir);
  if (!man) return man.problems();
  auto reader = pack::PackReader::open(dir);
  if (!reader) return reader.problems();
  const pack::PackReader& in = *reader.value();
  const pack::IndexHeader header = in.header();
  UpgradeReport report;
  report.modules = std::uint64_t(header.modulesX) * header.modulesZ;
  {
    auto first = in.readRaw(0, 0);
    if (!first) return first.problems();
    report.fromVersion = module::encodedVersion(first.value());
    if (report.fromVersion == module::kNewestVersion) {
      report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      return report;  // already the newest version: nothing to do
    }
    if (report.fromVersion < module::kVersion || report.fromVersion > module::kNewestVersion) {
      return Problem{in.packPath(), 0, "upgrade: module (0,0) is not a version 1 to " +
                                           std::to_string(module::kNewestVersion) + " load module"};
    }
  }
  const fs::path target = fs::absolute(dir).lexically_normal();
  const fs::path base = target.filename().empty() ? target.parent_path() : target;
  Staging staging(base.string() + ".upgrade." + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(staging.path(), ec);
  if (!fs::create_directory(staging.path(), ec)) {
    return Problem{staging.path(), 0, "upgrade: cannot create " + staging.path() + ": " + ec.message()};
  }
  // Everything but the modules and the manifest carries over unchanged.
  for (const auto& f : man->files) {
    if (f.path == pack::kPackFileName || f.path == pack::kIndexFileName) continue;
    if (Status st = linkOrCopy(base.string() + "/" + f.path, staging.path() + "/" + f.path); !st) return st.problems();
  }
  // The upgraded pack is version 2 as well: coarse records first (docs/FORMAT.md §10).
  pack::PackLayout layout = pack::PackLayout::split(header.levels);
  layout.encode = {.version = module::kNewestVersion, .heightStep = o.heightStep};
  auto writer = pack::PackWriter::create(staging.path(), header, o.zstdLevel, layout);
  if (!writer) return writer.problems();
  module::Module m;
  std::uint64_t done = 0;
  // Row-major reads; the writer puts the records in the layout's order.
  for (std::uint32_t kz = 0; kz < header.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < header.modulesX; ++kx) {
      if (cancelRequested()) return Problem{dir, 0, "upgrade: cancelled; the database is unchanged"};
      if (Status st = in.readInto(kx, kz, m); !st) return st.problems();
      // A version 5 module's objects become version 6's explicit objects,
      // quantised over the module's square (docs/FORMAT.md §9.11); both
      // records get the same square, so they decode the same list.
      m.scattering = {double(kx) * header.moduleSize, double(kz) * header.moduleSize, header.moduleSize,
                      header.moduleSize, {}};
      auto rec = writer.value()->compress(m);
      if (!rec) return Problem{dir, 0, "upgrade: " + rec.problems().front().message};
      if (Status st = writer.value()->append(std::move(rec.value())); !st) {
        return Problem{dir, 0, "upgrade: " + st.message()};
      }
      if (progress && (++done % 256 == 0)) progress(double(done) / double(report.modules), "modules");
    }
  }
  if (Status st = writer.value()->finish(); !st) return Problem{dir, 0, "upgrade: " + st.message()};
  report.packBytesAfter = writer.value()->packBytes();
  manifest::Manifest out = man.value();
  for (auto& f : out.files) {
    if (f.path == pack::kPackFileName) {
      report.packBytesBefore = f.bytes;
      f.bytes = writer.value()->packBytes(), f.crc = writer.value()->packCrc();
    } else if (f.path == pack::kIndexFileName) {
      f.bytes = writer.value()->indexBytes(), f.crc = writer.value()->indexCrc();
    }
  }
  if (out.build.contains("modules") && out.build["modules"].is_object()) {
    out.build["modules"]["format_version"] = module::kNewestVersion;
    out.build["modules"]["height_step_m"] = o.heightStep;
    out.build["modules"]["upgraded_from_version"] = report.fromVersion;
    out.build["modules"]["bytes"] = sizeStatsJson(writer.value()->stats());  // the new records' sizes
  }
  const std::string text = manifest::encode(out);
  if (Status st = writeFileAtomic(staging.path() + "/" + manifest::kFileName,
                                  std::as_bytes(std::span(text.data(), text.size())));
      !st) {
    return st.problems();
  }
  if (Status st = fsyncPath(staging.path()); !st) return st.problems();
  // One atomic swap: before it the old database is in place, after it the
  // new one; the staging name then holds the old one, which goes.
  if (::renameat2(AT_FDCWD, staging.path().c_str(), AT_FDCWD, base.c_str(), RENAME_EXCHANGE) != 0) {
    return Problem{base.string(), 0,
                   std::string("upgrade: cannot swap the upgraded database into place (renameat2 RENAME_EXCHANGE: ") +
                       std::strerror(errno) + "); the database is unchanged"};
  }
  fsyncPath(base.parent_path().string());
  report.upgraded = true;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (progress) progress(1.0, "modules");
  return report;
}

}  // namespace sandtable::convert
