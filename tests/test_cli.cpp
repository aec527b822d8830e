// The CLI on bad inputs (clear error, exit 2, no output directory), help,
// and the end-to-end slice: build, info, sample, headless flight.
#include <algorithm>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "test_support.h"
#include "sandtable/testing/require.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;


/// Nothing named like the output, finished or partial, may exist.
void expectNoOutput(const TempDir& tmp) {
  for (const auto& e : fs::directory_iterator(tmp.path())) {
    EXPECT_EQ(e.path().filename().string().rfind("db", 0), std::string::npos) << "left behind: " << e.path();
  }
}

/// The subcommand names a `--help` text lists (CLI11: the lines after
/// "Subcommands:", each "  NAME  description", up to a blank line).
std::vector<std::string> subcommandsIn(const std::string& help) {
  std::vector<std::string> names;
  std::istringstream in(help);
  bool listing = false;
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("Subcommands:", 0) == 0 || l.rfind("SUBCOMMANDS:", 0) == 0) {
      listing = true;
    } else if (listing && l.find_first_not_of(' ') == std::string::npos) {
      listing = false;
    } else if (listing && l.rfind("  ", 0) == 0 && l.size() > 2 && l[2] != ' ') {  // not a wrapped description
      std::istringstream words(l);
      std::string name;
      words >> name;
      names.push_back(name);
    }
  }
  return names;
}

void expectHelp(const std::vector<std::string>& cmd) {
  std::vector<std::string> args = cmd;
  args.push_back("--help");
  const auto r = runCli(args);
  std::string name;
  for (const auto& c : cmd) name += c + " ";
  EXPECT_EQ(r.exitCode, 0) << name;
  EXPECT_NE(r.out.find("Usage"), std::string::npos) << name << ": " << r.out;
}

TEST(Cli, helpForEverySubcommand) {
  // The lists come from the help texts, so a new subcommand cannot be
  // missed; the known ones must be among them.
  const auto root = runCli({"--help"});
  EXPECT_EQ(root.exitCode, 0);
  const auto commands = subcommandsIn(root.out);
  for (const char* known : {"synth", "build", "info", "validate", "sample", "fly", "bench", "export"}) {
    EXPECT_NE(std::find(commands.begin(), commands.end(), known), commands.end()) << known << " in\n" << root.out;
  }
  for (const auto& cmd : commands) expectHelp({cmd});
  const auto bench = runCli({"bench", "--help"});
  EXPECT_EQ(bench.exitCode, 0);
  const auto benches = subcommandsIn(bench.out);
  for (const char* known : {"build", "make-db", "modules", "paging", "render", "sim", "dis"}) {
    EXPECT_NE(std::find(benches.begin(), benches.end(), known), benches.end()) << known << " in\n" << bench.out;
  }
  for (const auto& b : benches) expectHelp({"bench", b});
  EXPECT_EQ(runCli({}).exitCode, 2);
  EXPECT_EQ(runCli({"no-such-command"}).exitCode, 2);
  EXPECT_EQ(runCli({"build", "--bogus"}).exitCode, 2);
}

struct BadInput {
  const char* name;
  std::function<std::vector<std::string>(const TempDir&)> args;
  const char* expected;
};

TEST(Cli, badInputsGiveAClearErrorExit2AndNoOutput) {
  SANDTABLE_REQUIRE_DATA();
  const std::string dt0 = data("elevation/dted/n43.dt0");
  const BadInput cases[] = {
      {"missing file", [](const TempDir& t) { return std::vector<std::string>{t / "nope.dt1"}; }, "file not found"},
      {"non-raster file", [](const TempDir& t) {
         spit(t / "notes.tif", "this is text, not a raster\n");
         return std::vector<std::string>{t / "notes.tif"};
       }, "GDAL cannot open this as a raster"},
      {"truncated DTED", [&](const TempDir& t) {
         spit(t / "n43.dt0", slurpFile(dt0).substr(0, 5000));
         return std::vector<std::string>{t / "n43.dt0"};
       }, "truncated or corrupt"},
      {"DTED with a corrupt header", [&](const TempDir& t) {
         std::string b = slurpFile(dt0);
         b.replace(0, 4, "XXXX");  // the UHL1 sentinel
         spit(t / "n43.dt0", b);
         return std::vector<std::string>{t / "n43.dt0"};
       }, "GDAL cannot open this as a raster"},
      {"empty directory", [](const TempDir& t) {
         fs::create_directories(t / "empty");
         return std::vector<std::string>{t / "empty"};
       }, "no elevation files"},
      {"glob matching nothing", [](const TempDir& t) { return std::vector<std::string>{t / "*.dt2"}; },
       "matches no file"},
  };
  for (const auto& c : cases) {
    TempDir tmp("bad");
    auto args = std::vector<std::string>{"build", "--elevation"};
    for (auto& a : c.args(tmp)) args.push_back(a);
    args.insert(args.end(), {"-o", tmp / "db"});
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, 2) << c.name << ": " << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.name << ": " << r.err;
    expectNoOutput(tmp);
  }
  for (const char* crs : {"EPSG:3857", "EPSG:32601", "EPSG:4326", "EPSG:999999", "mercator"}) {
    TempDir tmp("crs");
    const auto r = runCli({"build", "--elevation", dt0, "--crs", crs, "-o", tmp / "db"});
    EXPECT_EQ(r.exitCode, 2) << crs << ": " << r.err;
    EXPECT_NE(r.err.find("crs"), std::string::npos) << crs << ": " << r.err;
    expectNoOutput(tmp);
  }
}

TEST(Cli, existingOutputIsKeptUnlessForced) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("force");
  const std::string dt0 = data("elevation/dted/n43.dt0");
  ASSERT_EQ(runCli({"build", "--elevation", dt0, "-o", tmp / "db"}).exitCode, 0);
  const auto again = runCli({"build", "--elevation", dt0, "-o", tmp / "db"});
  EXPECT_EQ(again.exitCode, 2);
  EXPECT_NE(again.err.find("--force"), std::string::npos);
  EXPECT_EQ(runCli({"build", "--elevation", dt0, "-o", tmp / "db", "--force", "--resample", "cubic"}).exitCode, 0);
  EXPECT_EQ(runCli({"validate", tmp / "db"}).exitCode, 0);
}

// The libraries name option fields (converters/test: OptionProblemsNameTheFieldNotAFlag);
// the CLI prints the flag that sets each, on stderr and in --json.
TEST(Cli, optionErrorsNameTheFlagNotTheLibraryField) {
  TempDir tmp("flags");
  const auto build = runCli({"build", "--elevation", tmp / "none.dt1", "--spacing=-30", "-o", tmp / "db"});
  EXPECT_EQ(build.exitCode, 2);
  EXPECT_NE(build.err.find("sandtable build: error: --spacing @0: build: --spacing must be positive"),
            std::string::npos)
      << build.err;
  EXPECT_EQ(build.err.find("ElevationOptions::"), std::string::npos) << build.err;
  const auto noModules =
      runCli({"build", "--elevation", tmp / "none.dt1", "--no-modules", "--culture", tmp / "c.gpkg", "-o", tmp / "db",
              "--json"});
  EXPECT_EQ(noModules.exitCode, 2);
  EXPECT_NE(noModules.err.find("build: --culture, --materials, --icons and --objects need load modules; drop --no-modules"),
            std::string::npos)
      << noModules.err;
  const auto j = nlohmann::json::parse(noModules.out);
  EXPECT_EQ(j["errors"][0]["file"], "--culture");
  EXPECT_EQ(j["error"], "build: --culture, --materials, --icons and --objects need load modules; drop --no-modules");
  const auto synth = runCli({"synth", "-o", tmp / "s", "--size-km", "0"});
  EXPECT_EQ(synth.exitCode, 2);
  EXPECT_NE(synth.err.find("sandtable synth: error: --size-km must be between 1 and 1000 (got 0)"), std::string::npos)
      << synth.err;
  EXPECT_EQ(synth.err.find("SynthOptions::"), std::string::npos) << synth.err;
  expectNoOutput(tmp);
}

TEST(Cli, buildInfoSampleFlyEndToEnd) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("e2e");
  const std::string db = tmp / "db";
  auto b = runCli({"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--spacing", "120", "-o", db, "--json"});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto built = nlohmann::json::parse(b.out);
  EXPECT_GT(built["posts"].get<std::uint64_t>(), 100000u);

  auto i = runCli({"info", db, "--json"});
  ASSERT_EQ(i.exitCode, 0) << i.err;
  const auto info = nlohmann::json::parse(i.out);
  for (const char* k : {"crs_wkt", "origin_easting", "origin_northing", "spacing_m", "posts_x", "posts_z",
                        "module_size_m", "levels", "min_elevation", "max_elevation"}) {
    EXPECT_TRUE(info.contains(k)) << k;
  }
  EXPECT_EQ(info["spacing_m"].get<double>(), 120.0);
  EXPECT_EQ(info["epsg"].get<int>(), 32632);  // UTM 32N holds 7-8 E
  EXPECT_EQ(info["levels"].get<int>(), 4);
  // 1 km rounded to whole coarsest-level posts: 8 squares of 120 m.
  EXPECT_EQ(info["module_size_m"].get<double>(), 960.0);

  spit(tmp / "pts.txt", "# Monaco, then the sea off Nice\n7.4200 43.7400\n7.3000 43.5500\n");
  auto s = runCli({"sample", db, "--points", tmp / "pts.txt", "--json"});
  ASSERT_EQ(s.exitCode, 0) << s.err;
  const auto pts = nlohmann::json::parse(s.out);
  ASSERT_EQ(pts.size(), 2u);
  for (const char* k : {"lon", "lat", "easting", "northing", "elevation", "material"}) EXPECT_TRUE(pts[0].contains(k));
  EXPECT_GT(pts[0]["elevation"].get<double>(), 20.0);
  EXPECT_NEAR(pts[1]["elevation"].get<double>(), 0.0, 1.0);
  EXPECT_EQ(pts[1]["material"].get<int>(), 1);  // water
  auto text = runCli({"sample", db, "--lonlat", "7.42", "43.74"});
  EXPECT_EQ(text.exitCode, 0);
  EXPECT_EQ(std::count(text.out.begin(), text.out.end(), ' '), 3) << text.out;
  EXPECT_EQ(runCli({"sample", db, "--lonlat", "20", "10"}).exitCode, 2);

  auto f = runCli({"fly", db, "--png", tmp / "frames", "--frames", "2", "--size", "320x240", "--at", "7.42", "43.70",
                   "--height", "400", "--heading", "300"});
  SANDTABLE_REQUIRE(!(f.exitCode == 2 && f.err.find("EGL") != std::string::npos), "EGL for sandtable fly: " << f.err);
  ASSERT_EQ(f.exitCode, 0) << f.err;
  EXPECT_TRUE(fs::exists(tmp / "frames/frame_00001.png"));
  const auto stats = nlohmann::json::parse(slurpFile(tmp / "frames/stats.json"));
  EXPECT_TRUE(stats.contains("frames"));
}

}  // namespace
}  // namespace sandtable::test
