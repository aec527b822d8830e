// sandtable validate: every check the formats know, with file and offset,
// and the georeference (converters: it needs PROJ).
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "progress.h"
#include "sandtable/converters/validate.h"
#include "sandtable/paging/remote.h"

namespace sandtable::cli {
namespace {

// Ctrl-C (or SIGTERM) stops the check at the next grid block row, pack
// record batch or module row; validate writes nothing, so nothing is left.
std::atomic<bool> gCancel{false};
void onSignal(int) { gCancel.store(true); }

int runValidate(const std::string& given, bool json) {
  std::string dir = given;
  if (http::isUrl(given)) {
    // Every file fetched whole into the local mirror (each checked against
    // the manifest on the way), then the mirror checked as any database.
    paging::RemoteOptions o;
    o.wholePack = true;
    auto mirror = paging::mirrorRemote(given, o);
    if (!mirror) {
      reportProblems("validate", mirror.problems());
      return int(kProblems);
    }
    dir = mirror.value();
  }
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    return usageError("validate", dir + " is not a directory");
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  Progress progress(json);
  Work work;
  work.progress = [&](double f, const std::string& stage) { progress.update(f, stage); };
  work.cancel = &gCancel;
  const Status checked = convert::validateDatabaseWithCrs(dir, work);
  const std::vector<Problem>& problems = checked.problems();
  progress.done();
  if (!problems.empty() && problems.back().message == kCancelledMessage) {
    return usageError("validate", "cancelled; " + dir + " was not fully checked (" +
                                      std::to_string(problems.size() - 1) + " problem(s) found before that)");
  }
  if (json) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& p : problems) list.push_back({{"file", p.file}, {"offset", p.offset}, {"message", p.message}});
    std::printf("%s\n", nlohmann::json{{"database", dir}, {"ok", problems.empty()}, {"problems", list}}.dump(2).c_str());
  } else if (problems.empty()) {
    std::printf("%s: ok\n", dir.c_str());
  } else {
    for (const auto& p : problems) std::printf("%s\n", p.str().c_str());
    std::printf("%s: %zu problem(s)\n", dir.c_str(), problems.size());
  }
  return problems.empty() ? int(kOk) : int(kProblems);
}

}  // namespace

void registerValidate(CLI::App& root, Commands& c) {
  auto dir = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto* sub = root.add_subcommand("validate", "Check a database byte by byte; exit 1 if anything is wrong");
  sub->footer(
      "Checks: manifest schema and checksum, CRS and lon/lat corners, every file's size and CRC-32, grid\n"
      "header, reserved bytes, block table, every block's CRC-32, edge padding, NaN/inf, unit normals,\n"
      "plausible elevations, header/manifest agreement; the pack, and every load module's geometry and\n"
      "texture coordinates (docs/VALIDATE.md). Progress goes to stderr; Ctrl-C stops (exit 2).\n"
      "Example:\n  sandtable validate db --json");
  sub->add_option("DB", *dir, "Database directory")->required();
  sub->add_flag("--json", *json, "Print JSON");
  c.add(sub, [dir, json] { return runValidate(*dir, *json); });
}

}  // namespace sandtable::cli
