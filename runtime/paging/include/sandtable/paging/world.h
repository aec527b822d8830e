#pragma once
// The database opened once (issue 34 item 4), shared by the viewer and the
// simulator: the manifest, the terrain's posts as a HeightField, the load
// modules as a ModuleSource, the material table and the icons. `sim` and
// `fly --scenario` open one World and hand it to everything that reads the
// database (the pager, the scene's ground clamp, the map, the simulator's
// SimWorld), so no reader opens the directory again and a dynamic-terrain
// overlay put in here (another HeightField and ModuleSource) reaches every
// reader at once.
//
// It lives in paging because ModuleSource does; world (below) has the
// queries on the posts, paging the modules.
//
// Thread contract: immutable after construction; every member is const and
// may be called from any thread. What it hands out keeps its own contract
// (HeightField and ModuleSource: any thread; the GridFile and PackReader:
// immutable).
#include <memory>
#include <optional>
#include <string>

#include "sandtable/base/result.h"
#include "sandtable/formats/database.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/paging/module_source.h"

namespace sandtable::paging {

class World {
 public:
  /// Opens a database directory, or an http(s):// URL (remote.h: the small
  /// files mirrored, modules.pack read by range); the one open of the run.
  static Result<std::shared_ptr<const World>> open(const std::string& directory);
  /// Over a database already open: the grid file's posts, the pack (when
  /// there is one) as a PackSource.
  explicit World(Database db);
  /// With other posts or another module source (dynamic terrain, tests).
  /// `heights` must have the grid's layout; `modules` null means none
  /// (and must have the pack's layout when the database has one).
  World(Database db, std::shared_ptr<const grid::HeightField> heights, std::shared_ptr<const ModuleSource> modules);

  const Database& database() const { return db_; }
  const std::string& directory() const { return db_.directory; }
  const manifest::Manifest& manifest() const { return db_.manifest; }
  /// The terrain's posts: every run-time reader reads these.
  const std::shared_ptr<const grid::HeightField>& heights() const { return heights_; }
  /// The grid file itself, for what is about the file (the pager's mmap
  /// mode and prefetcher, its placeholders' block table).
  const std::shared_ptr<const grid::GridFile>& gridFile() const { return db_.grid; }
  /// Where load modules come from; null when the database has none.
  const std::shared_ptr<const ModuleSource>& modules() const { return modules_; }
  const std::optional<materials::Table>& materials() const { return db_.materials; }
  const std::optional<iconpack::Pack>& icons() const { return db_.icons; }

 private:
  Database db_;
  std::shared_ptr<const grid::HeightField> heights_;
  std::shared_ptr<const ModuleSource> modules_;
};

}  // namespace sandtable::paging
