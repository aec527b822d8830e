// The database opened once (world.h).
#include "sandtable/paging/world.h"

#include "sandtable/paging/remote.h"
#include "sandtable/paging/retrying_source.h"

namespace sandtable::paging {
Result<std::shared_ptr<const World>> World::open(const std::string& directory) {
  auto db = openDatabaseAt(directory);  // a URL: mirrored, the pack read over HTTP (remote.h)
  if (!db) return db.problems();
  return std::make_shared<const World>(std::move(db.value()));
}

World::World(Database db) : db_(std::move(db)) {
  heights_ = grid::heightField(db_.grid);
  modules_ = packSourceOf(db_.modules);  // retried when read over HTTP
}

World::World(Database db, std::shared_ptr<const grid::HeightField> heights, std::shared_ptr<const ModuleSource> modules)
    : db_(std::move(db)), heights_(std::move(heights)), modules_(std::move(modules)) {}

}  // namespace sandtable::paging
