// The `sandtable` CLI: a thin dispatcher over the subcommands.
#include <cstdio>
#include <cstring>
#include <exception>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "flags.h"

namespace sandtable::cli {
namespace {

/// The errors of this run, for the JSON error object of --json (commands.h).
nlohmann::json& errorList() {
  static nlohmann::json errors = nlohmann::json::array();
  return errors;
}

void printError(const std::string& cmd, const std::string& text) {
  std::fprintf(stderr, "sandtable%s%s: error: %s\n", cmd.empty() ? "" : " ", cmd.c_str(), withFlags(text).c_str());
}

/// The deepest subcommand that was parsed ("bench render"), or null.
CLI::App* parsedLeaf(CLI::App& app) {
  CLI::App* leaf = nullptr;
  for (CLI::App* at = &app;;) {
    const auto subs = at->get_subcommands();
    if (subs.empty()) return leaf;
    leaf = at = subs.back();
  }
}

std::string commandName(CLI::App* leaf) {
  std::string name;
  for (CLI::App* at = leaf; at && at->get_parent(); at = at->get_parent()) {
    name = name.empty() ? at->get_name() : at->get_name() + " " + name;
  }
  return name;
}

/// Whether the command line asks for JSON: the parsed command's --json, or,
/// when parsing failed, a literal --json anywhere.
bool wantsJson(CLI::App* leaf, int argc, char** argv, bool parsed) {
  if (parsed) {
    const CLI::Option* o = leaf ? leaf->get_option_no_throw("--json") : nullptr;
    return o && o->count() > 0;
  }
  for (int k = 1; k < argc; ++k) {
    if (std::strcmp(argv[k], "--json") == 0) return true;
  }
  return false;
}

int finish(int rc, const std::string& cmd, bool json) {
  if (json && !errorList().empty()) {
    const nlohmann::json j = {{"command", cmd},
                              {"ok", false},
                              {"exit_code", rc},
                              {"error", errorList().front()["message"]},
                              {"errors", errorList()}};
    std::printf("%s\n", j.dump(2).c_str());
  }
  return rc;
}

}  // namespace

int usageError(const std::string& cmd, const std::string& msg) {
  printError(cmd, msg);
  errorList().push_back({{"message", withFlags(msg)}});
  return kUsage;
}

int reportProblems(const std::string& cmd, const std::vector<Problem>& problems) {
  for (const auto& p : problems) {
    printError(cmd, p.str());
    errorList().push_back({{"message", withFlags(p.message)}, {"file", withFlags(p.file)}, {"offset", p.offset}});
  }
  return kUsage;
}

}  // namespace sandtable::cli

int main(int argc, char** argv) {
  using namespace sandtable::cli;
  CLI::App app{"Sandtable: terrain-database toolchain and stealth viewer"};
  app.set_version_flag("--version", std::string(SANDTABLE_VERSION));
  app.require_subcommand(1);
  Commands commands;
  registerSynth(app, commands);
  registerBuild(app, commands);
  registerInfo(app, commands);
  registerValidate(app, commands);
  registerSample(app, commands);
  registerFly(app, commands);
  registerBench(app, commands);
  registerExport(app, commands);
  registerUpgrade(app, commands);
  registerIcons(app, commands);
  registerSim(app, commands);
  registerScript(app, commands);
  registerDis(app, commands);
  registerEdits(app, commands);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // CLI11's own words, in the form of every other error, with the way on.
    CLI::App* leaf = parsedLeaf(app);
    const std::string cmd = commandName(leaf);
    usageError(cmd, e.what());
    std::fprintf(stderr, "sandtable%s%s: run `sandtable%s%s --help` for the options\n", cmd.empty() ? "" : " ",
                 cmd.c_str(), cmd.empty() ? "" : " ", cmd.c_str());
    return finish(kUsage, cmd, wantsJson(leaf, argc, argv, false));
  }
  CLI::App* leaf = parsedLeaf(app);
  const bool json = wantsJson(leaf, argc, argv, true);
  for (auto& [sub, run] : commands.list) {
    if (sub->parsed()) {
      const std::string cmd = commandName(sub);
      int rc = kUsage;
      try {
        rc = run();
      } catch (const std::exception& e) {
        rc = usageError(cmd, e.what());
      }
      return finish(rc, cmd, json);
    }
  }
  return kUsage;
}
