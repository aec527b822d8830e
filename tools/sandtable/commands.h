#pragma once
// Subcommand registry for the `sandtable` CLI. Each cmd_*.cpp adds its
// subcommand and a runner; main() parses and calls the chosen runner.
#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <utility>
#include <vector>

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

/// Prints "sandtable CMD: error: MSG" to stderr and returns kUsage.
int usageError(const std::string& cmd, const std::string& msg);

}  // namespace sandtable::cli
