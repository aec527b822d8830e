#pragma once
// The stages of the one-machine build (elevation_build.cpp) that a
// distributed build's plan, tasks and merge (distributed_*.cpp) call too:
// one implementation of each, so the two builds write the same bytes.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include <nlohmann/json.hpp>

#include "elevation_internal.h"
#include "sandtable/converters/culture.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/converters/modules.h"
#include "sandtable/converters/objects.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/formats/materials.h"

namespace sandtable::convert::detail {

/// Removes the partial directory unless the build was published.
class PartialDirectory {
 public:
  explicit PartialDirectory(std::string path) : path_(std::move(path)) {}
  ~PartialDirectory() {
    if (!published_) {
      std::error_code ec;
      std::filesystem::remove_all(path_, ec);
    }
  }
  PartialDirectory(const PartialDirectory&) = delete;
  PartialDirectory& operator=(const PartialDirectory&) = delete;
  const std::string& path() const { return path_; }
  void published() { published_ = true; }

 private:
  std::string path_;
  bool published_ = false;
};

/// Grid rows held in memory: row `first` at `data`, and their classes
/// (null: every post valid).
struct GridRows {
  const float* data = nullptr;
  const std::uint8_t* cls = nullptr;
  long first = 0;
  std::size_t w = 0;
  const float* row(long j) const { return data + std::size_t(j - first) * w; }
  const std::uint8_t* classes(long j) const { return cls ? cls + std::size_t(j - first) * w : nullptr; }
};

/// The written grid's header and the CRC-32 of the whole file.
struct WrittenGrid {
  grid::Header header;
  std::uint32_t crc = 0;
};

/// The material table, culture and icons of a build with modules (empty
/// without).
struct CultureSetup {
  materials::Table table;
  std::shared_ptr<const Culture> culture;
  iconpack::Pack icons;
  Warnings iconWarnings;
  ObjectPlan objects;
  Warnings objectWarnings;
};

/// What the elevation stage chose and measured, for the manifest.
struct BuildFacts {
  KernelChoice kernel;
  SourceAccuracy accuracy;
  std::uint64_t voidsFilled = 0, seaPosts = 0;
  double resampleSeconds = 0;
  std::uint32_t bandRows = 0, bands = 0;
  bool banded = false;
  std::uint64_t bandBytes = 0;
};

/// The manifest's culture, icons and objects objects.
struct ModuleJson {
  nlohmann::json culture, icons, objects;
};

std::string utcNow();
Result<bool> checkOptions(const ElevationOptions& o);
/// One block of the grid file from rows held in memory (the rows of the
/// block and one more on each side, clamped to the grid).
void fillBlock(const GridRows& g, const Frame& f, std::uint32_t bx, std::uint32_t bz, grid::BlockData& b);
/// Writes block rows [bz0, bz1) from `g`, in parallel.
Status writeBlockRows(grid::GridWriter& writer, const Frame& f, const GridRows& g, std::uint32_t bz0,
                      std::uint32_t bz1, int threads, const ProgressFn& progress);
/// Rows per band under a memory budget (whole 64-row strips).
std::uint32_t planBandRows(std::uint64_t budget, const Frame& f, const BandCost& c);
Status fsyncDirectory(const std::string& dir);
/// Renames the finished directory into place (replacing an old one only
/// after the new one is complete).
Status publish(const std::string& partial, const std::string& output);
/// Writes the manifest into the partial directory and publishes it as
/// `output` (problems name `output`, messages start with `stage`).
Status publishWithManifest(PartialDirectory& partial, const std::string& output, const manifest::Manifest& m,
                           const std::string& stage);
manifest::Manifest makeManifest(const ElevationOptions& o, const Frame& f, const grid::Header& h,
                                const std::vector<Source>& sources);
/// The material table: ElevationOptions::materials, or the built-in one.
Result<materials::Table> loadMaterials(const ElevationOptions& o);
Status loadIcons(const ElevationOptions& o, CultureSetup& c);
Result<CultureSetup> loadCulture(const ElevationOptions& o, const Frame& f, const ProgressFn& progress);
ModuleOptions moduleOptions(const ElevationOptions& o, const CultureSetup& c);
/// materials.txt and icons.pack, and the module files' entries and counts
/// in the report's manifest.
Status writeModuleSideFiles(const std::string& dir, const CultureSetup& c, const ModuleReport& r,
                            ElevationReport& report);
nlohmann::json iconsReportJson(const ElevationOptions& o, const CultureSetup& c);
nlohmann::json objectWarningsJson(const CultureSetup& c);
nlohmann::json objectsReportJson(const ElevationOptions& o, const materials::Table& table,
                                 const nlohmann::json& warnings, const ModuleReport& r);
nlohmann::json cultureReportJson(const ElevationOptions& o, const Culture& c);
/// Fills the report's counts and its manifest's build object.
void describeBuild(const ElevationOptions& o, const BuildFacts& b, const std::optional<ModuleReport>& modules,
                   const ModuleJson& mj, std::chrono::steady_clock::time_point t0, ElevationReport& report);

}  // namespace sandtable::convert::detail
