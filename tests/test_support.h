#pragma once
// Shared helpers for the integration tests: temp directories, the CLI,
// and the real data in ../shared/data.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/render/image.h"
#include "sandtable/testing/require.h"

namespace sandtable::test {

/// ../shared/data relative to the repository root.
inline std::string dataDir() { return std::string(SANDTABLE_SOURCE_DIR) + "/../shared/data"; }
inline std::string data(const std::string& rel) { return dataDir() + "/" + rel; }
inline bool haveData() { return std::filesystem::is_directory(dataDir() + "/elevation"); }

/// The real data, or a skip (a failure under SANDTABLE_REQUIRE_ALL=1).
#define SANDTABLE_REQUIRE_DATA() \
  SANDTABLE_REQUIRE(::sandtable::test::haveData(), "../shared/data at " << ::sandtable::test::dataDir())

/// A fresh directory under the system temp dir, removed at scope exit.
class TempDir {
 public:
  explicit TempDir(const std::string& tag = "st");
  ~TempDir();
  const std::string& path() const { return path_; }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

struct CommandResult {
  int exitCode = -1;
  std::string out;  ///< stdout
  std::string err;  ///< stderr
};

/// Runs the sandtable CLI with arguments (shell-quoted here).
CommandResult runCli(const std::vector<std::string>& args);

/// Whole file as bytes in a string; "" if unreadable.
std::string slurpFile(const std::string& path);
/// Replaces a file's contents.
void spit(const std::string& path, const std::string& bytes);

/// Rewrites DB/manifest.json after `edit` changes its JSON, with the
/// checksum resealed (FORMAT.md §5.2), so only the edit itself is wrong.
void resealManifest(const std::string& db, const std::function<void(nlohmann::json&)>& edit);
/// Brings every files[] size and CRC in DB/manifest.json up to date.
void resealFiles(const std::string& db);

/// A PNG's red, green and blue read through GDAL (alpha 255); an empty
/// image when it does not read.
render::Image readPng(const std::string& path);

/// Every file (recursively) under `dir` matching the extensions.
std::vector<std::string> filesUnder(const std::string& dir, const std::vector<std::string>& exts);

}  // namespace sandtable::test
