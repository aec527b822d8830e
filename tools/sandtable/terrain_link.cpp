#include "terrain_link.h"

#include <cstdio>

namespace sandtable::cli {

std::unique_ptr<sim::TerrainEditing> linkTerrain(sim::Simulation& s, edits::Editor& editor, DisLink* link,
                                                 const std::vector<edit::Edit>& preplaced) {
  sim::TerrainEditHooks hooks;
  if (link && link->gateway) {
    sim_dis::Gateway* g = link->gateway.get();
    hooks.publish = [g](const edit::Edit& e) { return g->publishEdit(e); };
    hooks.received = [g] { return g->takeReceivedEdits(); };
  }
  auto t = std::make_unique<sim::TerrainEditing>(s, editor, std::move(hooks));
  for (const edit::Edit& e : preplaced) t->applyLocal(e);
  return t;
}

std::string terrainSummary(const sim::TerrainEditing& t, const edits::Editor& editor, const std::string& journal) {
  const sim::TerrainEditCounters& c = t.counters();
  const edits::EditorStats st = editor.stats();
  char line[512];
  std::snprintf(line, sizeof line,
                "terrain edits: %llu applied this run (%llu made here, %llu received, %llu duplicates, %llu refused), "
                "%zu in all (%llu craters); %llu trees felled; %llu module rebuilds (%.1f ms); %s\n",
                static_cast<unsigned long long>(c.applied), static_cast<unsigned long long>(c.local),
                static_cast<unsigned long long>(c.received), static_cast<unsigned long long>(c.duplicates),
                static_cast<unsigned long long>(c.failed), editor.edits().size(),
                static_cast<unsigned long long>(st.byKind[std::size_t(edit::Kind::crater)]),
                static_cast<unsigned long long>(c.objectsFelled), static_cast<unsigned long long>(st.modulesRemeshed),
                st.remeshSeconds * 1e3,
                !journal.empty()  ? ("journal " + journal).c_str()
                : c.applied == 0 ? "nothing new to journal"
                                 : "not journaled (give --journal FILE to keep them)");
  std::string out = line;
  if (!c.lastError.empty()) out += "  last refused: " + c.lastError + "\n";
  return out;
}

nlohmann::json terrainJson(const sim::TerrainEditing& t, const edits::Editor& editor, const std::string& journal) {
  const sim::TerrainEditCounters& c = t.counters();
  const edits::EditorStats st = editor.stats();
  nlohmann::json kinds = nlohmann::json::object();
  for (std::uint8_t k = 1; k <= edit::kMaxKind; ++k) {
    if (st.byKind[k]) kinds[std::string(edit::kindName(edit::Kind(k)))] = st.byKind[k];
  }
  char hash[17];
  std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(editor.heights()->contentHash()));
  return {{"applied", c.applied},
          {"local", c.local},
          {"received", c.received},
          {"duplicates", c.duplicates},
          {"rebuilds", st.rebuilds},
          {"refused", c.failed},
          {"last_refused", c.lastError},
          {"objects_felled", c.objectsFelled},
          {"edits", editor.edits().size()},
          {"by_kind", kinds},
          {"modules_remeshed", st.modulesRemeshed},
          {"remesh_s", st.remeshSeconds},
          {"heights_bytes", st.heights.bytes},
          {"refined_squares", st.heights.refinedSquares},
          {"content_hash", hash},
          {"journal", journal}};
}

std::string terrainPanelLine(const edits::Editor& editor) {
  const edits::EditorStats st = editor.stats();
  char line[128];
  std::snprintf(line, sizeof line, "EDITS %zu  CRATERS %llu  MODULES %llu", editor.edits().size(),
                static_cast<unsigned long long>(st.byKind[std::size_t(edit::Kind::crater)]),
                static_cast<unsigned long long>(st.modulesRemeshed));
  return line;
}

}  // namespace sandtable::cli
