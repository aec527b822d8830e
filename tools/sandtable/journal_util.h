#pragma once
// `--journal` as every command that reads the ground takes it (docs/
// DYNAMIC.md, "The journal"): "" means the database's own edits.journal when
// there is one, "none" the ground as built, anything else a journal file.
// The run's world is then the editor's edited world.
#include <memory>
#include <optional>
#include <string>

#include "sandtable/edits/editor.h"
#include "sandtable/paging/world.h"

namespace sandtable::cli {

/// Editor options: modules re-meshed or not (`sample` and `export --grid`
/// read posts only), the re-mesh in the background or in apply().
edits::EditorOptions editorOptions(bool meshModules, bool background);

/// The journal a flag names: "" for none.
std::string journalPath(const std::string& databaseDir, const std::string& flag);

struct EditedWorld {
  std::shared_ptr<const paging::World> base;
  std::unique_ptr<edits::Editor> editor;
  std::string journal;  ///< replayed (and appended to with `append`); "" for none
  const std::shared_ptr<const paging::World>& world() const { return editor->world(); }
};

/// Opens `dir` and replays its journal. `append`: the run's edits go to the
/// journal (created when missing; a "" flag then means the database's own);
/// else it is only read. Prints every problem and returns nullopt.
std::optional<EditedWorld> openEditedWorld(const std::string& cmd, const std::string& dir, const std::string& flag,
                                           bool append, edits::EditorOptions options = {});

}  // namespace sandtable::cli
