#pragma once
// `sandtable bench paging`: real-time flights over a database at a list of
// speeds, each from a cold cache, with the predictive pager against demand
// paging and the NPSStealth mmap mode in the same run (docs/PAGER.md §11).
// `sandtable bench make-db`: the standard benchmark database from synth.
#include "commands.h"

namespace sandtable::cli {

/// Adds `paging` under the `bench` group.
void registerBenchPaging(CLI::App& bench, Commands& c);
/// Adds `make-db` under the `bench` group (bench_make_db.cpp).
void registerBenchMakeDb(CLI::App& bench, Commands& c);

}  // namespace sandtable::cli
