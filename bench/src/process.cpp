// spawnLogged (process.h).
#include "process.h"

#include <fcntl.h>
#include <spawn.h>

extern char** environ;

namespace sandtable::bench::detail {

pid_t spawnLogged(const std::vector<std::string>& argv, const std::filesystem::path& log, int& error) {
  std::vector<char*> av;
  for (const auto& s : argv) av.push_back(const_cast<char*>(s.c_str()));
  av.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = 0;
  error = ::posix_spawn(&pid, av[0], &fa, nullptr, av.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return error == 0 ? pid : -1;
}

}  // namespace sandtable::bench::detail
