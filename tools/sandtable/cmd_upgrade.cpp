// sandtable upgrade: rewrite a database's load modules in the newest format version.
#include <cstdio>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "progress.h"
#include "sandtable/converters/modules.h"

namespace sandtable::cli {
namespace {

struct UpgradeArgs {
  std::string dir;
  convert::UpgradeOptions o;
  bool json = false;
};

int runUpgrade(const UpgradeArgs& a) {
  Progress progress(a.json);
  auto r = convert::upgradeDatabase(a.dir, a.o, [&](double f, const std::string& s) { progress.update(f, s); });
  progress.done();
  if (!r) {
    reportProblems("upgrade", r.problems());
    std::fprintf(stderr, "sandtable upgrade: %s is unchanged\n", a.dir.c_str());
    return kUsage;
  }
  const auto& u = r.value();
  if (a.json) {
    const nlohmann::json j = {{"database", a.dir},          {"upgraded", u.upgraded},
                              {"from_version", u.fromVersion}, {"to_version", module::kNewestVersion},
                              {"modules", u.modules},       {"pack_bytes_before", u.packBytesBefore},
                              {"pack_bytes_after", u.packBytesAfter}, {"height_step_m", a.o.heightStep},
                              {"seconds", u.seconds}};
    std::printf("%s\n", j.dump(2).c_str());
    return kOk;
  }
  if (!u.upgraded) {
    std::printf("%s: load modules are already version %u; nothing to do\n", a.dir.c_str(), module::kNewestVersion);
    return kOk;
  }
  std::printf("upgraded %s: %llu modules, version %u -> %u (height step %g m), pack %.1f MB -> %.1f MB, %.2f s\n",
              a.dir.c_str(), static_cast<unsigned long long>(u.modules), u.fromVersion, module::kNewestVersion,
              a.o.heightStep,
              double(u.packBytesBefore) / 1e6, double(u.packBytesAfter) / 1e6, u.seconds);
  return kOk;
}

}  // namespace

void registerUpgrade(CLI::App& root, Commands& c) {
  auto a = std::make_shared<UpgradeArgs>();
  auto* sub = root.add_subcommand("upgrade", "Rewrite a database's load modules in format version 6");
  sub->footer(
      "Example:\n  sandtable upgrade db\n"
      "The new modules, index and manifest are assembled beside DB and swapped in with one atomic rename;\n"
      "an interrupted upgrade leaves the old database in place. A version 6 database is left as it is; version 5 objects become explicit objects.");
  sub->add_option("database", a->dir, "Database directory to upgrade")->required();
  sub->add_option("--height-step", a->o.heightStep,
                  "Height quantisation step in metres; every module height stays within half a step "
                  "(0 keeps exact float heights)")
      ->default_val(convert::kBuildHeightStep)
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--zstd-level", a->o.zstdLevel, "Module compression level (1..22)")
      ->default_val(9)
      ->check(CLI::Range(1, 22));
  sub->add_flag("--json", a->json, "Print the upgrade report as JSON");
  c.add(sub, [a] { return runUpgrade(*a); });
}

}  // namespace sandtable::cli
