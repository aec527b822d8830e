#pragma once
// The database manifest (manifest.json), version 1: what the database is,
// where it lies, which files belong to it with their sizes and CRC-32s,
// which sources it came from, and how it was built. Its own "checksum" key
// is the CRC-32 of the canonical JSON text without that key, so a hand edit
// is detected. Layout and keys: docs/FORMAT.md, "manifest".
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"

namespace sandtable::manifest {

inline constexpr const char* kFormat = "sandtable-manifest";
inline constexpr int kVersion = 1;
inline constexpr const char* kFileName = "manifest.json";
inline constexpr const char* kGridFileName = "grid.stg";
inline constexpr std::uint64_t kMaxBytes = 16u << 20;

struct FileEntry {
  std::string path;  ///< relative to the database directory
  std::uint64_t bytes = 0;
  std::uint32_t crc = 0;
};

struct SourceEntry {
  std::string path;  ///< as given on the command line, resolved
  std::uint64_t bytes = 0;
  std::uint32_t crc = 0;
  std::string driver;  ///< GDAL driver short name
};

struct Manifest {
  std::string toolVersion;
  std::string createdUtc;
  std::string crsWkt;
  std::string crsName;
  int epsg = 0;  ///< 0 when the CRS has no EPSG code (e.g. Cassini)
  double originEasting = 0;   ///< north-west corner post
  double originNorthing = 0;
  double spacing = 0;
  std::uint32_t postsX = 0;
  std::uint32_t postsZ = 0;
  std::uint32_t blockPosts = 64;
  float minElevation = 0;
  float maxElevation = 0;
  /// lon/lat of the corner posts: NW, NE, SE, SW.
  std::array<std::array<double, 2>, 4> cornersLonLat{};
  double moduleSize = 1000.0;  ///< load-module edge in metres (seed: 1 km)
  int levels = 4;              ///< LoD levels per module (seed: 4)
  std::vector<FileEntry> files;
  std::vector<SourceEntry> sources;
  nlohmann::json build = nlohmann::json::object();  ///< parameters and report

  double eastEasting() const { return originEasting + spacing * (postsX - 1); }
  double southNorthing() const { return originNorthing - spacing * (postsZ - 1); }
};

/// JSON text, keys sorted, with the checksum key filled in.
std::string encode(const Manifest& m);
/// Parses and checks schema, version and checksum.
Result<Manifest> decode(std::span<const std::byte> bytes, const std::string& file);
/// Reads `dir`/manifest.json.
Result<Manifest> readFromDirectory(const std::string& dir);

}  // namespace sandtable::manifest
