// A database on a web server (remote.h).
#include "sandtable/paging/remote.h"

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "sandtable/base/hash.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/formats/pack.h"
#include "sandtable/http/remote_range.h"

namespace sandtable::paging {

namespace fs = std::filesystem;

namespace {

std::string trimmed(std::string url) {
  while (!url.empty() && url.back() == '/') url.pop_back();
  return url;
}

std::uint64_t hashOf(const std::string& s) {
  std::uint64_t h = 0x5a17ab1eull;
  for (const unsigned char c : s) h = hash::mix(h ^ c);
  return h;
}

/// Whether the local copy at `path` is the manifest's file.
bool matches(const std::string& path, const manifest::FileEntry& f) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec) || fs::file_size(path, ec) != f.bytes) return false;
  const auto crc = crc32File(path);
  return crc && crc->crc == f.crc && crc->bytes == f.bytes;
}

/// A manifest path that stays inside the database directory.
bool safePath(const std::string& p) {
  if (p.empty() || p.front() == '/') return false;
  for (const auto& part : fs::path(p)) {
    if (part == "..") return false;
  }
  return true;
}

}  // namespace

std::string remoteCacheDirectory(const std::string& url) {
  std::string root;
  if (const char* c = std::getenv("SANDTABLE_CACHE"); c && *c) {
    root = c;
  } else if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) {
    root = std::string(x) + "/sandtable";
  } else if (const char* h = std::getenv("HOME"); h && *h) {
    root = std::string(h) + "/.cache/sandtable";
  } else {
    root = "/tmp/sandtable-cache";
  }
  const std::string u = trimmed(url);
  std::string host = u.substr(u.find("://") + 3);
  host = host.substr(0, host.find('/'));
  for (char& c : host) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-') c = '_';
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hashOf(u)));
  return root + "/" + host + "-" + hex;
}

namespace {

/// mirrorRemote through `client` (openRemoteDatabase then reads the pack
/// through the same one, on the same connections).
Result<std::string> mirrorWith(const http::Client& client, const std::string& url, const RemoteOptions& o) {
  const std::string base = trimmed(url);
  const std::string manifestUrl = base + "/" + manifest::kFileName;
  auto bytes = client.get(manifestUrl, 16u << 20);
  if (!bytes) return bytes.problems();
  auto m = manifest::decode(bytes.value(), manifestUrl);
  if (!m) return m.problems();
  const std::string dir = o.cacheDirectory.empty() ? remoteCacheDirectory(base) : o.cacheDirectory;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Problem{dir, 0, "remote database: cannot make the cache directory: " + ec.message()};
  for (const manifest::FileEntry& f : m->files) {
    if (!safePath(f.path)) return Problem{manifestUrl, 0, "remote database: the manifest lists '" + f.path + "', outside the database"};
    if ((f.path == pack::kPackFileName || f.path == manifest::kGridFileName) && !o.wholePack) continue;
    const std::string local = dir + "/" + f.path;
    if (matches(local, f)) continue;
    const std::string fileUrl = base + "/" + f.path;
    auto got = client.get(fileUrl, f.bytes);
    if (!got) return got.problems();
    if (got->size() != f.bytes || crc32(got.value()) != f.crc) {
      return Problem{fileUrl, 0, "remote database: " + std::to_string(got->size()) + " bytes with CRC " + crcHex(crc32(got.value())) +
                                     ", the manifest says " + std::to_string(f.bytes) + " with " + crcHex(f.crc) +
                                     ": the server's copy is damaged or from another build"};
    }
    fs::create_directories(fs::path(local).parent_path(), ec);
    if (Status w = writeFileAtomic(local, got.value()); !w) return w.problems();
  }
  // The manifest last: a mirror with a manifest is whole.
  if (Status w = writeFileAtomic(dir + "/" + manifest::kFileName, bytes.value()); !w) return w.problems();
  return dir;
}

}  // namespace

Result<std::string> mirrorRemote(const std::string& url, const RemoteOptions& o) {
  if (!http::isUrl(url)) return Problem{url, 0, "remote database: not an http:// or https:// URL"};
  auto client = http::Client::create(o.client);
  if (!client) return client.problems();
  return mirrorWith(*client.value(), url, o);
}

namespace {

/// The entry of `name` in the mirror's manifest (size and CRC).
Result<manifest::FileEntry> manifestEntry(const std::string& dir, const std::string& name) {
  auto m = manifest::readFromDirectory(dir);
  if (!m) return m.problems();
  for (const auto& f : m->files) {
    if (f.path == name) return f;
  }
  return Problem{dir + "/" + manifest::kFileName, 0, "remote database: the manifest does not list " + name};
}

/// The pack behind its on-disk cache (none when its bound is 0), named by
/// the manifest's CRC of the pack.
Result<std::shared_ptr<const RangeSource>> packCache(std::shared_ptr<const RangeSource> pack, const std::string& dir,
                                                     const RemoteOptions& o) {
  DiskCacheOptions c = o.packCache;
  if (const char* mb = std::getenv("SANDTABLE_PACK_CACHE_MB"); mb && *mb) {
    c.maxBytes = std::strtoull(mb, nullptr, 10) << 20;
  }
  if (c.maxBytes == 0) return pack;
  auto entry = manifestEntry(dir, pack::kPackFileName);
  if (!entry) return entry.problems();
  // Beside the mirror, not in it: the mirror holds the database's files only.
  auto cached = DiskCachedRange::open(std::move(pack), dir + ".records", pack::kPackFileName, entry->crc, c);
  if (!cached) return cached.problems();
  return std::shared_ptr<const RangeSource>(cached.value());
}

/// grid.stg read by block through a client of its own with no memory cache
/// (its blocks are kept in the local copy), into DIR.records/.
Result<std::shared_ptr<const grid::GridFile>> remoteGrid(const std::string& url, const std::string& dir,
                                                          const RemoteOptions& o) {
  auto entry = manifestEntry(dir, manifest::kGridFileName);
  if (!entry) return entry.problems();
  http::ClientOptions co = o.client;
  co.cacheBytes = 0;
  auto client = http::Client::create(co);
  if (!client) return client.problems();
  auto range = http::RemoteRange::open(client.value(), trimmed(url) + "/" + manifest::kGridFileName);
  if (!range) return range.problems();
  if (range.value()->size() != entry->bytes) {
    return Problem{range.value()->name(), 0,
                   "remote database: the server's file is " + std::to_string(range.value()->size()) +
                       " bytes, the manifest says " + std::to_string(entry->bytes) + ": it is damaged or from another build"};
  }
  grid::RemoteGridOptions g = o.grid;
  if (const char* mb = std::getenv("SANDTABLE_GRID_CACHE_MB"); mb && *mb) g.maxBytes = std::strtoull(mb, nullptr, 10) << 20;
  const std::string records = dir + ".records";
  std::error_code ec;
  fs::create_directories(records, ec);
  const std::string stem = cacheStem(manifest::kGridFileName, entry->bytes, entry->crc);
  removeOtherCaches(records, manifest::kGridFileName, stem);
  return grid::GridFile::openRemote(range.value(), records + "/" + stem + ".cache", entry->crc, g);
}

}  // namespace

Result<Database> openRemoteDatabase(const std::string& url, const RemoteOptions& o) {
  if (!http::isUrl(url)) return Problem{url, 0, "remote database: not an http:// or https:// URL"};
  auto client = http::Client::create(o.client);
  if (!client) return client.problems();
  auto dir = mirrorWith(*client.value(), url, o);
  if (!dir) return dir.problems();
  std::shared_ptr<const RangeSource> pack;
  if (!o.wholePack && fs::exists(dir.value() + "/" + pack::kIndexFileName)) {
    auto r = http::RemoteRange::open(client.value(), trimmed(url) + "/" + pack::kPackFileName);
    if (!r) return r.problems();
    pack = r.value();
    auto cached = packCache(pack, dir.value(), o);
    if (!cached) return cached.problems();
    pack = cached.value();
  }
  std::shared_ptr<const grid::GridFile> grid;
  if (!o.wholePack) {
    auto g = remoteGrid(url, dir.value(), o);
    if (!g) return g.problems();
    grid = g.value();
  }
  return openDatabase(dir.value(), pack, grid);
}

bool isRemote(const std::string& pathOrUrl) { return http::isUrl(pathOrUrl); }

Result<Database> openDatabaseAt(const std::string& pathOrUrl) {
  if (http::isUrl(pathOrUrl)) return openRemoteDatabase(pathOrUrl);
  return openDatabase(pathOrUrl);
}

}  // namespace sandtable::paging
