#include "sandtable/formats/database.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "sandtable/formats/bytes.h"

namespace sandtable {
namespace {

namespace fs = std::filesystem;

void checkAgreement(const manifest::Manifest& m, const grid::Header& h, const std::string& file,
                    std::vector<Problem>& out) {
  auto differ = [&](const char* what, double a, double b, std::uint64_t off) {
    if (a != b) {
      out.push_back({file, off, std::string("database: grid header and manifest disagree on ") +
                                    what + " (header " + std::to_string(b) + ", manifest " +
                                    std::to_string(a) + ")"});
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

void checkFiles(const std::string& dir, const manifest::Manifest& m, std::vector<Problem>& out) {
  bool hasGrid = false;
  for (const auto& f : m.files) {
    const std::string path = dir + "/" + f.path;
    hasGrid = hasGrid || f.path == manifest::kGridFileName;
    std::uint32_t crc = 0;
    std::uint64_t bytes = 0;
    if (!crc32File(path, crc, bytes)) {
      out.push_back({path, 0, "database: listed in the manifest but cannot be read"});
      continue;
    }
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
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    const bool listed = name == manifest::kFileName ||
                        std::any_of(m.files.begin(), m.files.end(), [&](const auto& f) { return f.path == name; });
    if (!listed) out.push_back({e.path().string(), 0, "database: file is not listed in the manifest"});
  }
  if (!hasGrid) {
    out.push_back({dir + "/" + manifest::kFileName, 0,
                   std::string("database: the manifest does not list ") + manifest::kGridFileName});
  }
}

}  // namespace

Result<Database> openDatabase(const std::string& directory) {
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) {
    return Problem{directory, 0, "database: not a directory (give the path that `sandtable build -o` wrote)"};
  }
  auto m = manifest::readFromDirectory(directory);
  if (!m) return m.problems();
  auto g = grid::GridFile::open(directory + "/" + manifest::kGridFileName);
  if (!g) return g.problems();
  Database db{directory, std::move(m.value()), g.value()};
  std::vector<Problem> problems;
  checkAgreement(db.manifest, db.grid->header(), db.grid->path(), problems);
  if (!problems.empty()) return problems;
  return db;
}

std::vector<Problem> validateDatabase(const std::string& directory) {
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) {
    return {{directory, 0, "database: not a directory"}};
  }
  auto m = manifest::readFromDirectory(directory);
  if (!m) return m.problems();
  std::vector<Problem> out;
  checkFiles(directory, m.value(), out);
  const std::string gridPath = directory + "/" + manifest::kGridFileName;
  auto gridProblems = grid::validateGrid(gridPath);
  out.insert(out.end(), gridProblems.begin(), gridProblems.end());
  if (auto g = grid::GridFile::open(gridPath)) {
    checkAgreement(m.value(), g.value()->header(), gridPath, out);
  }
  return out;
}

}  // namespace sandtable
