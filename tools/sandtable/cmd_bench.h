#pragma once
// The `bench` subcommands: argument parsing and printing over the
// benchmarks of sandtable_bench (bench/include/sandtable/bench/). Each
// cmd_bench_*.cpp registers one; this header holds what they share.
#include <string>
#include <utility>
#include <vector>

#include "commands.h"
#include "sandtable/bench/notes.h"

namespace sandtable::cli {

/// A benchmark's option fields ("PagingBenchOptions::speedsKmh") and the
/// flags that set them ("--speeds"), for rewriting library messages.
using FlagMap = std::vector<std::pair<std::string, std::string>>;

/// `text` with every field of `flags` replaced by its flag.
std::string withFlags(std::string text, const FlagMap& flags);

/// Prints a benchmark's problems under `cmd`, fields as flags: one without
/// a file as a usage error (its message alone), the others as
/// "file @offset: message". Returns kUsage.
int reportBenchProblems(const std::string& cmd, const std::vector<Problem>& problems, const FlagMap& flags);

/// Notes as "PREFIX: line" on stderr, fields as flags; nothing when quiet.
bench::Notes stderrNotes(const std::string& prefix, bool quiet, const FlagMap& flags);

/// Sets convert::requestCancel on SIGINT and SIGTERM.
void cancelOnSignals();

void registerBenchBuild(CLI::App& bench, Commands& c);
void registerBenchModules(CLI::App& bench, Commands& c);
void registerBenchRender(CLI::App& bench, Commands& c);
void registerBenchPaging(CLI::App& bench, Commands& c);
void registerBenchMakeDb(CLI::App& bench, Commands& c);
void registerBenchSim(CLI::App& bench, Commands& c);
void registerBenchDis(CLI::App& bench, Commands& c);
void registerBenchEdits(CLI::App& bench, Commands& c);

}  // namespace sandtable::cli
