// The `sandtable` CLI: a thin dispatcher over the subcommands.
#include <cstdio>
#include <exception>

#include "commands.h"

namespace sandtable::cli {
int usageError(const std::string& cmd, const std::string& msg) {
  std::fprintf(stderr, "sandtable %s: error: %s\n", cmd.c_str(), msg.c_str());
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
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kUsage;
  }
  for (auto& [sub, run] : commands.list) {
    if (sub->parsed()) {
      try {
        return run();
      } catch (const std::exception& e) {
        std::fprintf(stderr, "sandtable %s: error: %s\n", sub->get_name().c_str(), e.what());
        return kUsage;
      }
    }
  }
  return kUsage;
}
