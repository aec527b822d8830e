#pragma once
// Helpers shared by the commands that read a database.
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "commands.h"
#include "sandtable/formats/database.h"
#include "sandtable/paging/remote.h"
#include "sandtable/paging/world.h"

namespace sandtable::cli {

/// Opens a database (a directory, or an http(s):// URL: paging/remote.h)
/// or prints every problem and returns nullopt.
inline std::optional<Database> openOrReport(const std::string& cmd, const std::string& dir) {
  auto db = paging::openDatabaseAt(dir);
  if (!db) {
    reportProblems(cmd, db.problems());
    std::fprintf(stderr, "sandtable %s: hint: run `sandtable validate %s` for a full report\n", cmd.c_str(), dir.c_str());
    return std::nullopt;
  }
  return std::move(db.value());
}

/// Opens a database as the run's one World (paging/world.h), or prints
/// every problem as openOrReport does and returns null.
inline std::shared_ptr<const paging::World> openWorldOrReport(const std::string& cmd, const std::string& dir) {
  auto db = openOrReport(cmd, dir);
  if (!db) return nullptr;
  return std::make_shared<const paging::World>(std::move(*db));
}

}  // namespace sandtable::cli
