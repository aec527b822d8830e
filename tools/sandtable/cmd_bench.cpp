// sandtable bench: a group of benchmarks, one subcommand each. Only the
// leaves register runners, so `sandtable bench` alone is a usage error
// listing them. The benchmarks themselves are sandtable_bench (bench/).
#include "cmd_bench.h"

#include <algorithm>
#include <csignal>
#include <cstdio>

#include "sandtable/converters/elevation.h"

namespace sandtable::cli {
namespace {

void onSignal(int) { convert::requestCancel(); }

}  // namespace

std::string withFlags(std::string text, const FlagMap& flags) {
  // Longest field first, so that no field is replaced inside a longer one.
  FlagMap byLength = flags;
  std::stable_sort(byLength.begin(), byLength.end(),
                   [](const auto& x, const auto& y) { return x.first.size() > y.first.size(); });
  for (const auto& [field, flag] : byLength) {
    for (std::size_t at = text.find(field); at != std::string::npos; at = text.find(field, at + flag.size())) {
      text.replace(at, field.size(), flag);
    }
  }
  return text;
}

int reportBenchProblems(const std::string& cmd, const std::vector<Problem>& problems, const FlagMap& flags) {
  for (Problem p : problems) {
    p.message = withFlags(p.message, flags);
    if (p.file.empty()) usageError(cmd, p.message);
    else reportProblems(cmd, {p});
  }
  return kUsage;
}

bench::Notes stderrNotes(const std::string& prefix, bool quiet, const FlagMap& flags) {
  bench::Notes n;
  if (!quiet) {
    n.note = [prefix, flags](const std::string& line) {
      std::fprintf(stderr, "%s: %s\n", prefix.c_str(), withFlags(line, flags).c_str());
    };
  }
  return n;
}

void cancelOnSignals() {
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
}

void registerBench(CLI::App& root, Commands& c) {
  auto* bench = root.add_subcommand("bench", "Benchmarks: measure speed against a reference");
  bench->require_subcommand(1);
  registerBenchBuild(*bench, c);
  registerBenchModules(*bench, c);
  registerBenchRender(*bench, c);
  registerBenchPaging(*bench, c);
  registerBenchMakeDb(*bench, c);
  registerBenchSim(*bench, c);
  registerBenchDis(*bench, c);
  registerBenchEdits(*bench, c);
}

}  // namespace sandtable::cli
