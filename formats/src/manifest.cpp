#include "sandtable/formats/manifest.h"

#include <cmath>
#include <cstdio>

#include "sandtable/formats/bytes.h"

namespace sandtable::manifest {
namespace {

using nlohmann::json;

json toJson(const Manifest& m) {
  json j;
  j["format"] = kFormat;
  j["version"] = kVersion;
  j["tool_version"] = m.toolVersion;
  j["created_utc"] = m.createdUtc;
  j["crs"] = {{"wkt", m.crsWkt}, {"name", m.crsName}, {"epsg", m.epsg}};
  j["grid"] = {{"origin_easting", m.originEasting}, {"origin_northing", m.originNorthing},
               {"spacing_m", m.spacing},           {"posts_x", m.postsX},
               {"posts_z", m.postsZ},              {"block_posts", m.blockPosts},
               {"min_elevation", m.minElevation},  {"max_elevation", m.maxElevation}};
  json corners = json::array();
  for (const auto& c : m.cornersLonLat) corners.push_back({c[0], c[1]});
  j["corners_lonlat"] = corners;  // NW, NE, SE, SW
  j["modules"] = {{"size_m", m.moduleSize}, {"levels", m.levels}};
  json files = json::array();
  for (const auto& f : m.files) {
    files.push_back({{"path", f.path}, {"bytes", f.bytes}, {"crc32", crcHex(f.crc)}});
  }
  j["files"] = files;
  json sources = json::array();
  for (const auto& s : m.sources) {
    sources.push_back({{"path", s.path}, {"bytes", s.bytes}, {"crc32", crcHex(s.crc)},
                       {"driver", s.driver}});
  }
  j["sources"] = sources;
  j["build"] = m.build;
  return j;
}

std::uint32_t checksumOf(const json& withoutChecksum) {
  const std::string text = withoutChecksum.dump();
  return crc32(std::as_bytes(std::span(text.data(), text.size())));
}

/// Typed field access that records a schema problem instead of throwing.
class Reader {
 public:
  Reader(std::string file, std::vector<Problem>& out) : file_(std::move(file)), out_(out) {}

  const json* node(const json& parent, const char* key, json::value_t type, const std::string& at) {
    auto it = parent.find(key);
    if (it == parent.end()) {
      fail(at + key + " is missing");
      return nullptr;
    }
    const bool numeric = type == json::value_t::number_float;
    const bool isUnsigned = type == json::value_t::number_unsigned;
    if ((numeric && !it->is_number()) || (isUnsigned && !it->is_number_unsigned()) ||
        (!numeric && !isUnsigned && it->type() != type)) {
      fail(at + key + " has the wrong type");
      return nullptr;
    }
    return &*it;
  }
  double num(const json& p, const char* k, const std::string& at) {
    const json* n = node(p, k, json::value_t::number_float, at);
    if (!n) return 0;
    const double v = n->get<double>();
    if (!std::isfinite(v)) fail(at + k + " is not finite");
    return v;
  }
  /// A number that must be an f32 value written as the equal double
  /// (§5.3), so that comparing it with the grid header's f32 is exact:
  /// rounding it to f32 would hide a difference.
  float f32(const json& p, const char* k, const std::string& at) {
    const double v = num(p, k, at);
    const auto f = static_cast<float>(v);
    if (std::isfinite(v) && static_cast<double>(f) != v) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%s%s %.17g is not an f32 value (the nearest is %.9g); it must be the grid "
                    "header's f32 written as the equal double", at.c_str(), k, v, double(f));
      fail(buf);
    }
    return f;
  }
  std::uint64_t uns(const json& p, const char* k, const std::string& at) {
    const json* n = node(p, k, json::value_t::number_unsigned, at);
    return n ? n->get<std::uint64_t>() : 0;
  }
  std::string str(const json& p, const char* k, const std::string& at) {
    const json* n = node(p, k, json::value_t::string, at);
    return n ? n->get<std::string>() : std::string();
  }
  std::uint32_t crc(const json& p, const char* k, const std::string& at) {
    const std::string s = str(p, k, at);
    const bool hex = s.size() == 10 && s.rfind("0x", 0) == 0 &&
                     s.find_first_not_of("0123456789abcdef", 2) == std::string::npos;
    if (!hex) {
      fail(at + k + " must be \"0x\" and 8 lowercase hex digits");
      return 0;
    }
    return static_cast<std::uint32_t>(std::stoul(s.substr(2), nullptr, 16));
  }
  std::uint32_t u32(const json& p, const char* k, const std::string& at) {
    const std::uint64_t v = uns(p, k, at);
    if (v > 0xffffffffull) fail(at + k + " is out of range");
    return static_cast<std::uint32_t>(v);
  }
  void fail(const std::string& msg) { out_.push_back({file_, 0, "manifest: " + msg}); }

 private:
  std::string file_;
  std::vector<Problem>& out_;
};

Manifest fromJson(const json& j, Reader& r) {
  Manifest m;
  m.toolVersion = r.str(j, "tool_version", "");
  m.createdUtc = r.str(j, "created_utc", "");
  if (const json* crs = r.node(j, "crs", json::value_t::object, "")) {
    m.crsWkt = r.str(*crs, "wkt", "crs.");
    m.crsName = r.str(*crs, "name", "crs.");
    if (const json* e = r.node(*crs, "epsg", json::value_t::number_unsigned, "crs.")) m.epsg = static_cast<int>(std::min<std::uint64_t>(e->get<std::uint64_t>(), 0x7fffffff));
    if (m.crsWkt.empty()) r.fail("crs.wkt is empty");
  }
  if (const json* g = r.node(j, "grid", json::value_t::object, "")) {
    m.originEasting = r.num(*g, "origin_easting", "grid.");
    m.originNorthing = r.num(*g, "origin_northing", "grid.");
    m.spacing = r.num(*g, "spacing_m", "grid.");
    m.postsX = r.u32(*g, "posts_x", "grid.");
    m.postsZ = r.u32(*g, "posts_z", "grid.");
    m.blockPosts = r.u32(*g, "block_posts", "grid.");
    m.minElevation = r.f32(*g, "min_elevation", "grid.");
    m.maxElevation = r.f32(*g, "max_elevation", "grid.");
    if (!(m.spacing > 0)) r.fail("grid.spacing_m must be positive");
  }
  if (const json* c = r.node(j, "corners_lonlat", json::value_t::array, "")) {
    if (c->size() != 4) r.fail("corners_lonlat must hold 4 [lon, lat] pairs");
    for (std::size_t k = 0; k < std::min<std::size_t>(4, c->size()); ++k) {
      const json& p = (*c)[k];
      if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) {
        r.fail("corners_lonlat[" + std::to_string(k) + "] must be [lon, lat]");
        continue;
      }
      m.cornersLonLat[k] = {p[0].get<double>(), p[1].get<double>()};
    }
  }
  if (const json* mod = r.node(j, "modules", json::value_t::object, "")) {
    m.moduleSize = r.num(*mod, "size_m", "modules.");
    m.levels = static_cast<int>(std::min<std::uint64_t>(r.uns(*mod, "levels", "modules."), 64));
  }
  if (const json* fs = r.node(j, "files", json::value_t::array, "")) {
    for (const json& f : *fs) {
      if (!f.is_object()) { r.fail("files[] entries must be objects"); continue; }
      FileEntry e{r.str(f, "path", "files[]."), r.uns(f, "bytes", "files[]."), r.crc(f, "crc32", "files[].")};
      if (e.path.empty() || e.path.find('/') != std::string::npos || e.path[0] == '.') {
        r.fail("files[].path \"" + e.path + "\" must be a plain file name in the database directory");
      }
      m.files.push_back(e);
    }
  }
  if (const json* ss = r.node(j, "sources", json::value_t::array, "")) {
    for (const json& s : *ss) {
      if (!s.is_object()) { r.fail("sources[] entries must be objects"); continue; }
      m.sources.push_back({r.str(s, "path", "sources[]."), r.uns(s, "bytes", "sources[]."),
                           r.crc(s, "crc32", "sources[]."), r.str(s, "driver", "sources[].")});
    }
  }
  if (const json* b = r.node(j, "build", json::value_t::object, "")) m.build = *b;
  return m;
}

}  // namespace

std::string encode(const Manifest& m) {
  json j = toJson(m);
  j["checksum"] = crcHex(checksumOf(j));
  return j.dump(2) + "\n";
}

Result<Manifest> decode(std::span<const std::byte> bytes, const std::string& file) {
  json j;
  try {
    j = json::parse(reinterpret_cast<const char*>(bytes.data()),
                    reinterpret_cast<const char*>(bytes.data()) + bytes.size());
  } catch (const json::parse_error& e) {
    return Problem{file, e.byte, std::string("manifest: not valid JSON: ") + e.what()};
  } catch (const json::exception& e) {
    // Syntactically valid but unrepresentable, e.g. a number beyond double range (1e400).
    return Problem{file, 0, std::string("manifest: not valid JSON: ") + e.what()};
  }
  if (!j.is_object()) return Problem{file, 0, "manifest: the top level must be a JSON object"};
  if (!j.contains("format") || !j["format"].is_string() || j["format"].get<std::string>() != kFormat) {
    return Problem{file, 0, std::string("manifest: \"format\" must be \"") + kFormat +
                                "\"; this is not a sandtable database"};
  }
  if (!j.contains("version") || !j["version"].is_number_unsigned()) {
    return Problem{file, 0, "manifest: \"version\" is missing or not a whole number"};
  }
  if (j["version"].get<std::uint64_t>() != kVersion) {
    return Problem{file, 0, "manifest: version " + std::to_string(j["version"].get<std::uint64_t>()) +
                                " is not supported (this reader knows " + std::to_string(kVersion) +
                                "); use a matching sandtable"};
  }
  if (!j.contains("checksum") || !j["checksum"].is_string()) {
    return Problem{file, 0, "manifest: \"checksum\" is missing"};
  }
  const std::string stored = j["checksum"].get<std::string>();
  j.erase("checksum");
  const std::string computed = crcHex(checksumOf(j));
  std::vector<Problem> problems;
  if (stored != computed) {
    problems.push_back({file, 0, "manifest: checksum mismatch (stored " + stored + ", computed " +
                                     computed + "): the manifest was edited or corrupted; rebuild "
                                     "the database rather than editing it"});
  }
  Reader r(file, problems);
  Manifest m;
  try {
    m = fromJson(j, r);
  } catch (const json::exception& e) {
    problems.push_back({file, 0, std::string("manifest: malformed: ") + e.what()});
  }
  if (!problems.empty()) return problems;
  return m;
}

Result<Manifest> readFromDirectory(const std::string& dir) {
  const std::string path = dir + "/" + kFileName;
  auto bytes = readSmallFile(path, kMaxBytes);
  if (!bytes) return Problem{path, 0, "manifest: " + bytes.message() + " (is this a sandtable database directory?)"};
  return decode(bytes.value(), path);
}

}  // namespace sandtable::manifest
