// sandtable_bench without the CLI: bad options fail before any work with a
// message naming the option field (never a flag), and a tiny modules run
// reports figures that agree with its own JSON and with the run count.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "sandtable/bench/build.h"
#include "sandtable/bench/make_db.h"
#include "sandtable/bench/modules.h"
#include "sandtable/bench/paging.h"
#include "sandtable/bench/sim.h"

namespace sandtable::bench {
namespace {

namespace fs = std::filesystem;

/// The one problem of a failed result, which must have no file.
std::string onlyMessage(const std::vector<Problem>& ps) {
  EXPECT_EQ(ps.size(), 1u);
  if (ps.empty()) return "";
  EXPECT_EQ(ps[0].file, "");
  return ps[0].message;
}

TEST(BenchBuild, badKernelsNameTheField) {
  BuildBenchOptions o;
  o.kernels = {};
  auto r = runBuildBench(o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(onlyMessage(r.problems()), "BuildBenchOptions::kernels is empty");
  o.kernels = {"bilinear", "bilinear"};
  EXPECT_EQ(onlyMessage(runBuildBench(o).problems()), "kernel \"bilinear\" given twice");
  o.kernels = {"nearest"};
  EXPECT_NE(onlyMessage(runBuildBench(o).problems()).find("unknown kernel \"nearest\""), std::string::npos);
}

TEST(BenchBuild, aSpacingThatNeedsTooLargeASquareNamesTheFields) {
  BuildBenchOptions o;
  o.spacing = 300;  // 5000 posts at 300 m: 1560 km, over synth's 1000 km
  const std::string m = onlyMessage(runBuildBench(o).problems());
  EXPECT_EQ(m.rfind("BuildBenchOptions::spacing 300 needs", 0), 0u) << m;
  EXPECT_NE(m.find("BuildBenchOptions::sizeKm"), std::string::npos) << m;
  EXPECT_EQ(m.find("--"), std::string::npos) << m;
}

TEST(BenchMakeDb, anExistingOutputIsLeftAlone) {
  const fs::path dir = fs::temp_directory_path() / ("sandtable-bench-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "keep.txt") << "mine";
  MakeDbOptions o;
  o.output = dir.string();
  bool noted = false;
  Notes n;
  n.note = [&](const std::string&) { noted = true; };
  const std::string m = onlyMessage(makeBenchDatabase(o, n).problems());
  EXPECT_NE(m.find("MakeDbOptions::force"), std::string::npos) << m;
  EXPECT_FALSE(noted) << "the check comes before any work";
  EXPECT_TRUE(fs::exists(dir / "keep.txt"));
  EXPECT_FALSE(fs::exists(dir.string() + ".synth"));
  fs::remove_all(dir);
}

TEST(BenchPaging, aMissingDatabaseIsTheOpenersProblem) {
  PagingBenchOptions o;
  o.database = (fs::temp_directory_path() / "sandtable-bench-no-such-db").string();
  auto r = runPagingBench(o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.problems().front().file, o.database);
}

TEST(BenchModules, aTinyRunAgreesWithItsJson) {
  ModulesBenchOptions o;
  o.sizeKm = 2;
  o.repeat = 1;
  o.threads = 2;
  std::vector<std::string> notes;
  Notes n;
  n.note = [&](const std::string& line) { notes.push_back(line); };
  auto r = runModulesBench(o, n);
  ASSERT_TRUE(r.ok()) << r.error();
  const nlohmann::json& j = r->json;
  // One synth note and one per build: repeat x (elevation-only, full).
  ASSERT_EQ(notes.size(), 3u);
  EXPECT_EQ(notes[1].rfind("run 1 elevation-only ", 0), 0u) << notes[1];
  EXPECT_EQ(notes[2].rfind("run 1 full build ", 0), 0u) << notes[2];
  ASSERT_EQ(j["full_runs_s"].size(), 1u);
  ASSERT_EQ(j["elevation_runs_s"].size(), 1u);
  // The median of one run is that run.
  EXPECT_DOUBLE_EQ(r->fullBuildSeconds, j["full_runs_s"][0].get<double>());
  EXPECT_DOUBLE_EQ(r->elevationOnlySeconds, j["elevation_runs_s"][0].get<double>());
  EXPECT_DOUBLE_EQ(j["full_over_elevation"].get<double>(), r->fullBuildSeconds / r->elevationOnlySeconds);
  EXPECT_GT(r->modules, 0u);
  EXPECT_EQ(j["modules"].get<std::uint64_t>(), r->modules);
  EXPECT_DOUBLE_EQ(j["modules_per_second"].get<double>(), double(r->modules) / r->moduleStageSeconds);
  EXPECT_LE(r->moduleStageSeconds, r->fullBuildSeconds);
}

TEST(BenchSim, aRunStepsAsManyStepsAsSimAndTheViewerForItsTime) {
  SimBenchOptions o;
  o.entities = {3};
  o.objects = 20;
  o.sizeKm = 1;
  o.seconds = 1.01;       // 60.6 steps: 61, as `sim --duration 1.01` and a 1.01 s flight
  o.bruteSeconds = 0.51;  // 30.6 steps: 31
  o.repeat = 1;
  auto r = runSimBench(o);
  ASSERT_TRUE(r.ok()) << r.error();
  const nlohmann::json& c = r->json["cases"][0];
  EXPECT_EQ(c["grid"]["steps"].get<std::uint64_t>(), 61u);
  EXPECT_EQ(c["brute"]["steps"].get<std::uint64_t>(), 31u);
}

}  // namespace
}  // namespace sandtable::bench
