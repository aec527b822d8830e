#pragma once
// Helpers shared by the commands that read a database.
#include <cstdio>
#include <optional>
#include <string>

#include "commands.h"
#include "sandtable/formats/database.h"

namespace sandtable::cli {

/// Opens a database or prints every problem and returns nullopt.
inline std::optional<Database> openOrReport(const std::string& cmd, const std::string& dir) {
  auto db = openDatabase(dir);
  if (!db) {
    reportProblems(cmd, db.problems());
    std::fprintf(stderr, "sandtable %s: hint: run `sandtable validate %s` for a full report\n", cmd.c_str(), dir.c_str());
    return std::nullopt;
  }
  return std::move(db.value());
}

}  // namespace sandtable::cli
