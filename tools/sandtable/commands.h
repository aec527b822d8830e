#pragma once
// Subcommand registry for the `sandtable` CLI. Each cmd_*.cpp adds its
// subcommand and a runner; main() parses and calls the chosen runner.
#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::cli {

/// Exit codes shared by every subcommand.
enum Exit : int { kOk = 0, kProblems = 1, kUsage = 2 };

using Runner = std::function<int()>;

struct Commands {
  std::vector<std::pair<CLI::App*, Runner>> list;
  void add(CLI::App* app, Runner run) { list.emplace_back(app, std::move(run)); }
};

void registerSynth(CLI::App& root, Commands& c);
void registerBuild(CLI::App& root, Commands& c);
void registerInfo(CLI::App& root, Commands& c);
void registerValidate(CLI::App& root, Commands& c);
void registerSample(CLI::App& root, Commands& c);
void registerFly(CLI::App& root, Commands& c);
void registerBench(CLI::App& root, Commands& c);
void registerExport(CLI::App& root, Commands& c);
void registerUpgrade(CLI::App& root, Commands& c);
void registerIcons(CLI::App& root, Commands& c);
void registerSim(CLI::App& root, Commands& c);
void registerScript(CLI::App& root, Commands& c);
void registerDis(CLI::App& root, Commands& c);
void registerEdits(CLI::App& root, Commands& c);

/// Prints "sandtable CMD: error: MSG" to stderr and returns kUsage. When the
/// command was given --json, main also prints every error of the run as one
/// JSON object on stdout: {"command", "ok": false, "exit_code", "error" (the
/// first message), "errors": [{"message"[, "file", "offset"]}]}.
int usageError(const std::string& cmd, const std::string& msg);
/// The same for problems: one stderr line each ("file @offset: message"),
/// with file, offset and message kept apart in the JSON. Returns kUsage.
int reportProblems(const std::string& cmd, const std::vector<Problem>& problems);

}  // namespace sandtable::cli
