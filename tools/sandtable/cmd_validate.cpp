// sandtable validate: every check the formats know, with file and offset.
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "sandtable/formats/database.h"

namespace sandtable::cli {

void registerValidate(CLI::App& root, Commands& c) {
  auto dir = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto* sub = root.add_subcommand("validate", "Check a database byte by byte; exit 1 if anything is wrong");
  sub->footer(
      "Checks: manifest schema and checksum, every file's size and CRC-32, grid header, block table,\n"
      "every block's CRC-32, NaN/inf, unit normals, plausible elevations, header/manifest agreement.\n"
      "Example:\n  sandtable validate db --json");
  sub->add_option("DB", *dir, "Database directory")->required();
  sub->add_flag("--json", *json, "Print JSON");
  c.add(sub, [dir, json] {
    std::error_code ec;
    if (!std::filesystem::is_directory(*dir, ec)) {
      return usageError("validate", *dir + " is not a directory");
    }
    const auto problems = validateDatabase(*dir);
    if (*json) {
      nlohmann::json list = nlohmann::json::array();
      for (const auto& p : problems) list.push_back({{"file", p.file}, {"offset", p.offset}, {"message", p.message}});
      std::printf("%s\n", nlohmann::json{{"database", *dir}, {"ok", problems.empty()}, {"problems", list}}.dump(2).c_str());
    } else if (problems.empty()) {
      std::printf("%s: ok\n", dir->c_str());
    } else {
      for (const auto& p : problems) std::printf("%s\n", p.str().c_str());
      std::printf("%s: %zu problem(s)\n", dir->c_str(), problems.size());
    }
    return problems.empty() ? int(kOk) : int(kProblems);
  });
}

}  // namespace sandtable::cli
