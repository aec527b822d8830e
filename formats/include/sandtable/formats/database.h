#pragma once
// A database directory: manifest.json plus the files it lists.
#include <memory>
#include <string>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/manifest.h"

namespace sandtable {

/// An opened database: the checked manifest and the mapped grid.
struct Database {
  std::string directory;
  manifest::Manifest manifest;
  std::shared_ptr<const grid::GridFile> grid;
};

/// Opens a database: reads the manifest (schema and checksum) and maps the
/// grid (header checks only). Cheap; does not read the elevation data.
Result<Database> openDatabase(const std::string& directory);

/// Checks everything: manifest schema and checksum, every listed file's
/// size and CRC-32, files present but not listed, grid contents, and that
/// the grid header and manifest agree. Empty when the database is sound.
std::vector<Problem> validateDatabase(const std::string& directory);

}  // namespace sandtable
