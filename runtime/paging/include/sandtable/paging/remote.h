#pragma once
// A database on a web server (issue 38 part B; docs/HTTP.md, "Databases
// on a web server"): `fly http://HOST/PATH/db` and the rest open it here.
//
// The server holds the database directory as `build` wrote it. The small
// files (manifest.json, modules.idx, materials.txt, icons.pack) are
// mirrored whole into a local cache directory, each checked against the
// manifest's size and CRC-32 (kept when the copy there already matches).
// modules.pack and grid.stg stay on the server and are read by range
// (net/http): each pack record checked by its own CRCs as from disk,
// fetched again once when they fail; each grid block by its table CRC, the
// table by the manifest's CRC (GridFile::openRemote). The database's
// directory is then the mirror (a journal beside it is local).
//
// Thread contract: call from one thread; what it returns keeps its own.
#include <memory>
#include <string>

#include "sandtable/base/result.h"
#include "sandtable/formats/database.h"
#include "sandtable/http/client.h"
#include "sandtable/paging/disk_cache.h"

namespace sandtable::paging {

struct RemoteOptions {
  http::ClientOptions client;
  /// Where the mirror goes; empty: remoteCacheDirectory(url).
  std::string cacheDirectory;
  /// modules.pack and grid.stg mirrored whole too (validate reads every
  /// byte).
  bool wholePack = false;
  /// The pack's records kept on disk beside the mirror (disk_cache.h);
  /// maxBytes 0: none. $SANDTABLE_PACK_CACHE_MB, when set, overrides it.
  DiskCacheOptions packCache;
  /// The grid's local copy (grid.h); $SANDTABLE_GRID_CACHE_MB, when set,
  /// overrides its bound.
  grid::RemoteGridOptions grid;
};

/// $SANDTABLE_CACHE, else $XDG_CACHE_HOME/sandtable, else
/// ~/.cache/sandtable, else /tmp/sandtable-cache; then one directory per
/// URL (its host and a hash of the whole URL).
std::string remoteCacheDirectory(const std::string& url);

/// Mirrors the database at `url` (trailing slashes ignored) and returns
/// the mirror's directory. Problems name the URL and file: unreachable, no
/// manifest, a file whose size or CRC differs from the manifest's.
Result<std::string> mirrorRemote(const std::string& url, const RemoteOptions& o = {});

/// Mirrors, then opens the database with modules.pack read over HTTP.
Result<Database> openRemoteDatabase(const std::string& url, const RemoteOptions& o = {});

/// Whether `pathOrUrl` names a database on a web server (http:// or https://).
bool isRemote(const std::string& pathOrUrl);

/// openRemoteDatabase for a URL, openDatabase for a directory.
Result<Database> openDatabaseAt(const std::string& pathOrUrl);

}  // namespace sandtable::paging
