// sandtable bench: a group of benchmarks, one subcommand each. Only the
// leaves register runners, so `sandtable bench` alone is a usage error
// listing them. `bench paging` and `bench render` will join `build` here.
#include "bench_build.h"
#include "bench_modules.h"
#include "bench_render.h"
#include "bench_paging.h"
#include "commands.h"

namespace sandtable::cli {

void registerBench(CLI::App& root, Commands& c) {
  auto* bench = root.add_subcommand("bench", "Benchmarks: measure speed against a reference");
  bench->require_subcommand(1);
  registerBenchBuild(*bench, c);
  registerBenchModules(*bench, c);
  registerBenchRender(*bench, c);
  registerBenchPaging(*bench, c);
  registerBenchMakeDb(*bench, c);
}

}  // namespace sandtable::cli
