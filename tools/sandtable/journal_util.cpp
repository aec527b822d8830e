#include "journal_util.h"

#include <cstdio>
#include <filesystem>

#include "commands.h"
#include "db_util.h"
#include "flags.h"
#include "sandtable/formats/edit_journal.h"

namespace sandtable::cli {

edits::EditorOptions editorOptions(bool meshModules, bool background) {
  edits::EditorOptions o;
  o.meshModules = meshModules;
  o.background = background;
  return o;
}

std::string journalPath(const std::string& databaseDir, const std::string& flag) {
  if (flag == "none") return {};
  if (!flag.empty()) return flag;
  return journal::defaultPath(databaseDir);
}

std::optional<EditedWorld> openEditedWorld(const std::string& cmd, const std::string& dir, const std::string& flag,
                                           bool append, edits::EditorOptions options) {
  EditedWorld out;
  out.base = openWorldOrReport(cmd, dir);
  if (!out.base) return std::nullopt;
  out.journal = journalPath(dir, flag);
  if (!flag.empty() && flag != "none" && !append && !std::filesystem::exists(out.journal)) {
    usageError(cmd, "--journal " + flag + ": no such file (give an existing journal, or none)");
    return std::nullopt;
  }
  if (append && !flag.empty() && flag != "none") {
    // Said before anything is applied, naming the flag (the writer would
    // fail later on its temp file's name).
    const std::filesystem::path parent = std::filesystem::path(out.journal).parent_path();
    if (!parent.empty() && !std::filesystem::is_directory(parent)) {
      usageError(cmd, "--journal " + flag + ": no directory " + parent.string() + " to write the journal in");
      return std::nullopt;
    }
  }
  // The database's own journal is read when present; a run appends to it
  // only when asked to.
  if (flag.empty() && !append && !std::filesystem::exists(out.journal)) out.journal.clear();
  options.journal = out.journal;
  options.readOnly = !append;
  auto ed = edits::Editor::open(out.base, options);
  if (!ed) {
    std::vector<Problem> problems = ed.problems();
    for (auto& p : problems) p.message = withFlags(p.message);
    reportProblems(cmd, problems);
    return std::nullopt;
  }
  out.editor = std::move(ed.value());
  for (const Problem& w : out.editor->warnings()) {
    std::fprintf(stderr, "sandtable %s: warning: %s @%llu: %s\n", cmd.c_str(), w.file.c_str(),
                 static_cast<unsigned long long>(w.offset), w.message.c_str());
  }
  return out;
}

}  // namespace sandtable::cli
