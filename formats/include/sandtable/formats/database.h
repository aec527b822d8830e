#pragma once
// A database directory: manifest.json plus the files it lists.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/base/range_source.h"
#include "sandtable/formats/grid.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/formats/materials.h"
#include "sandtable/formats/pack.h"

namespace sandtable {

/// An opened database: the checked manifest, the mapped grid and, when the
/// manifest lists them, the load modules and the material table.
struct Database {
  std::string directory;
  manifest::Manifest manifest;
  std::shared_ptr<const grid::GridFile> grid;
  /// modules.idx + modules.pack (index header, table CRC and pack header
  /// checked; no module read); null when the manifest lists no modules.
  std::shared_ptr<const pack::PackReader> modules;
  /// materials.txt, parsed; empty when the manifest does not list it.
  std::optional<materials::Table> materials;
  /// icons.pack, decoded; empty when the manifest does not list it
  /// (databases built before issue 12).
  std::optional<iconpack::Pack> icons;
};

/// Opens a database: reads the manifest (schema and checksum), maps the
/// grid (header checks only), opens the pack index and reads the material
/// table when listed, and checks that grid, pack index and manifest agree.
/// Cheap; reads neither the elevation data nor any module.
/// With `remotePack` (a database on a web server, mirrored but for its
/// pack: paging/remote.h), modules.pack is read by range through it and
/// only modules.idx comes from `directory`. With `remoteGrid` (opened by
/// GridFile::openRemote), that is the grid and `directory` need not hold
/// grid.stg.
Result<Database> openDatabase(const std::string& directory, std::shared_ptr<const RangeSource> remotePack = {},
                              std::shared_ptr<const grid::GridFile> remoteGrid = {});
/// How many times openDatabase has been called in this process (one
/// atomic, every call counted, failed ones too): the test that `sim` and
/// `fly --scenario` open their database once reads it.
std::uint64_t databaseOpens();

/// Checks everything: manifest schema and checksum, every listed file's
/// size and CRC-32, files present but not listed, grid contents, and that
/// the grid header and manifest agree. With load modules also: the pack
/// (validatePack), the pack index against manifest and grid, materials.txt, icons.pack (decoded),
/// and every module's geometry and its edges against its neighbours
/// (module_check.h; docs/VALIDATE.md), at most a few problems of
/// each kind per module. The edit journal beside the database
/// (journal::defaultPath), which the manifest does not list, is read when
/// present: its problems are the database's, a torn tail is a warning on
/// the result. Ok when the database is sound.
/// `work` reports progress by stage ("checking files", "checking grid",
/// "checking pack", "checking modules") and may cancel: the problems found
/// so far are returned, the last one kCancelledMessage.
Status validateDatabase(const std::string& directory, const Work& work = {});

}  // namespace sandtable
