#pragma once
// What the Open-DIS tests (tests/opendis, docs/DIS.md §10) share: the
// scripts' folder, the build tree's node_modules, running node and
// failing, never skipping, without node or the package.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <unistd.h>

namespace sandtable::opendis_test {

namespace fs = std::filesystem;
using nlohmann::json;

inline const fs::path kScripts = SANDTABLE_OPENDIS_SCRIPTS;  // tests/opendis in the source tree
inline const fs::path kModules = SANDTABLE_OPENDIS_MODULES;  // node_modules in the build tree

inline std::string shellQuoted(const fs::path& p) {
  std::string q(1, '\'');  // appended, not "'" + ...: GCC 12's -Wrestrict misfires on that
  q += p.string();
  q += '\'';
  return q;
}

/// stdout of `command`, and whether it exited 0.
inline std::pair<std::string, bool> capture(const std::string& command) {
  std::string out;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return {out, false};
  std::array<char, 4096> buf{};
  while (std::size_t n = std::fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int status = pclose(pipe);
  return {out, status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == 0};
}

/// Fails the test (never skips) without node or the installed package.
inline ::testing::AssertionResult haveOpenDis() {
  if (!capture("command -v node >/dev/null 2>&1").second) {
    return ::testing::AssertionFailure() << "node is missing: run tools/setup.sh (docs/INSTALL.md)";
  }
  const fs::path manifest = kModules / "open-dis" / "package.json";
  std::ifstream in(manifest);
  if (!in) {
    return ::testing::AssertionFailure() << manifest << " is missing: the ctest fixture OpenDis.npmInstall "
                                         << "installs it (run ctest -R OpenDis)";
  }
  const json j = json::parse(in, nullptr, false);
  if (j.is_discarded() || j.value("version", "") != "1.3.6") {
    return ::testing::AssertionFailure() << manifest << " is not open-dis 1.3.6";
  }
  return ::testing::AssertionSuccess();
}

/// Runs a script of tests/opendis with the build tree's node_modules and
/// parses what it prints; empty (and the test failed) when it fails.
inline std::optional<json> node(const std::string& script, const std::string& args) {
  std::string command = "NODE_PATH=";
  command += shellQuoted(kModules);
  command += " node ";
  command += shellQuoted(kScripts / script);
  command += ' ';
  command += args;
  const auto [out, ok] = capture(command);
  if (!ok) {
    ADD_FAILURE() << "node " << script << " " << args << " failed; it printed:\n" << out;
    return std::nullopt;
  }
  json j = json::parse(out, nullptr, false);
  if (j.is_discarded()) {
    ADD_FAILURE() << "node " << script << " printed no JSON:\n" << out;
    return std::nullopt;
  }
  return j;
}

/// A fresh folder under the system's temporary one.
inline fs::path scratchDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("sandtable_opendis_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

}  // namespace sandtable::opendis_test
