// Conversion accuracy on every real DTED and SRTM file, against a bilinear
// interpolation of the source at the same lon/lat.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/elevation.h"
#include "sandtable/formats/database.h"
#include "sandtable/runtime/terrain.h"
#include "source_raster.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

struct ErrorStats {
  std::size_t n = 0;
  double rms = 0, p95 = 0, max = 0;
};

ErrorStats summarize(std::vector<double> errs) {
  ErrorStats s;
  s.n = errs.size();
  if (errs.empty()) return s;
  double sum = 0;
  for (double e : errs) sum += e * e;
  s.rms = std::sqrt(sum / double(errs.size()));
  std::sort(errs.begin(), errs.end(), [](double a, double b) { return std::fabs(a) < std::fabs(b); });
  s.p95 = std::fabs(errs[std::min(errs.size() - 1, std::size_t(0.95 * double(errs.size())))]);
  s.max = std::fabs(errs.back());
  return s;
}

/// Errors of the database against the source at random land points.
std::vector<double> landErrors(const Database& db, const SourceRaster& src, std::size_t want, unsigned seed) {
  runtime::Terrain terrain(db.grid);
  auto geo = convert::GeoTransformer::create(db.manifest.crsWkt);
  std::mt19937 rng(seed);
  const auto& m = db.manifest;
  std::uniform_real_distribution<double> ue(m.originEasting, m.eastEasting());
  std::uniform_real_distribution<double> un(m.southNorthing(), m.originNorthing);
  std::vector<double> errs;
  for (int tries = 0; tries < 200000 && errs.size() < want; ++tries) {
    const double e = ue(rng), n = un(rng);
    double lon, lat;
    if (!geo.value()->toLonLat(e, n, lon, lat)) continue;
    const auto ref = src.bilinear(lon, lat, 0.0);
    if (!ref) continue;
    const auto got = terrain.sampleEN(e, n);
    if (!got) continue;
    errs.push_back(got->elevation - *ref);
  }
  return errs;
}

std::vector<std::string> demFiles() {
  if (!haveData()) return {};
  auto files = filesUnder(data("elevation/dted"), {".dt0", ".dt1", ".dt2"});
  auto srtm = filesUnder(data("elevation/srtm"), {".hgt", ".hgt.zip"});
  files.insert(files.end(), srtm.begin(), srtm.end());
  return files;
}

std::string shortName(const std::string& path) {
  std::string s = path.substr(dataDir().size() + 1);
  std::replace_if(s.begin(), s.end(), [](char c) { return !std::isalnum(static_cast<unsigned char>(c)); }, '_');
  return s;
}

class ConversionAccuracy : public ::testing::TestWithParam<std::string> {};

TEST_P(ConversionAccuracy, bilinearAtNativeSpacingMatchesSource) {
  const std::string file = GetParam();
  TempDir tmp("acc");
  convert::ElevationOptions o;
  o.sources = {file};
  o.output = tmp / "db";
  o.resample = "bilinear";
  auto report = convert::buildElevation(o, nullptr);
  ASSERT_TRUE(report.ok()) << report.error();
  auto db = openDatabase(o.output);
  ASSERT_TRUE(db.ok()) << db.error();
  SourceRaster src(file);
  ASSERT_TRUE(src.ok());
  const auto s = summarize(landErrors(db.value(), src, 500, 7));
  RecordProperty("rms_m", std::to_string(s.rms));
  RecordProperty("p95_m", std::to_string(s.p95));
  std::printf("[ accuracy ] %s: %zu land points, spacing %.2f m, RMS %.3f m, p95 %.3f m, max %.2f m\n",
              shortName(file).c_str(), s.n, db->manifest.spacing, s.rms, s.p95, s.max);
  ASSERT_GE(s.n, 100u) << "too few land points to judge";
  EXPECT_LE(s.rms, 3.0);
  EXPECT_LE(s.p95, 6.0);
  EXPECT_TRUE(validateDatabase(o.output).empty());
}

INSTANTIATE_TEST_SUITE_P(RealData, ConversionAccuracy, ::testing::ValuesIn(demFiles()),
                         [](const auto& param) { return shortName(param.param); });
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(ConversionAccuracy);

}  // namespace
}  // namespace sandtable::test
