#pragma once
// Child processes of the benchmarks that time other programs (bench build
// runs gdalwarp and, with --distributed, the sandtable CLI).
#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace sandtable::bench::detail {

/// Starts argv[0] (a path, no shell) with argv, stdin from /dev/null and
/// stdout and stderr to `log`. The child's pid, or -1 with `error` set to
/// posix_spawn's errno.
pid_t spawnLogged(const std::vector<std::string>& argv, const std::filesystem::path& log, int& error);

}  // namespace sandtable::bench::detail
