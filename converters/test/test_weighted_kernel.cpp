// The weighted kernel as the grid stage runs it (weightedKernelProbe):
// every instruction-set variant gives the scalar reference's doubles bit for
// bit, and the reference agrees with a brute-force plane fit written here.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "sandtable/converters/elevation.h"

namespace sandtable::convert {
namespace {

/// Rough terrain over n x n posts: waves, noise, a block of voids and
/// scattered single voids.
std::vector<float> roughImage(int n) {
  std::vector<float> v(std::size_t(n) * n);
  std::uint32_t seed = 987654321u;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      seed = seed * 1664525u + 1013904223u;
      const double noise = double(seed >> 8) / double(1u << 24) - 0.5;
      float z = static_cast<float>(400 + 150 * std::sin(x * 0.21) * std::cos(y * 0.17) + 11 * noise);
      if ((y >= 20 && y < 26 && x >= 30 && x < 41) || (seed >> 27) == 0) z = NAN;
      v[std::size_t(y) * n + x] = z;
    }
  }
  return v;
}

/// Target positions in source posts: most inside, some by the image's edges.
void positions(int n, int count, std::vector<double>& px, std::vector<double>& py) {
  std::uint32_t seed = 42u;
  auto next = [&] {
    seed = seed * 1664525u + 1013904223u;
    return double(seed >> 8) / double(1u << 24);
  };
  for (int k = 0; k < count; ++k) {
    const double lo = k % 5 == 0 ? -1.0 : 4.0, hi = k % 5 == 0 ? n : n - 5.0;
    px.push_back(lo + (hi - lo) * next());
    py.push_back(lo + (hi - lo) * next());
  }
}

/// The kernel's definition, independently: every source post of the image,
/// its offset in metres through the inverse of the target steps, and the
/// public brute-force plane (hypot distances, d < radius).
double bruteForce(const std::vector<float>& img, int n, const WeightedProbe& p, double px, double py) {
  const double det = p.aXi * p.aYj - p.aXj * p.aYi;
  std::vector<double> e, nn, z;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const float v = img[std::size_t(y) * n + x];
      if (std::isnan(v)) continue;
      const double dx = x - px, dy = y - py;
      e.push_back(p.spacing * (p.aYj * dx - p.aXj * dy) / det);
      nn.push_back(p.spacing * (-p.aYi * dx + p.aXi * dy) / det);
      z.push_back(v);
    }
  }
  return weightedPlaneEstimate(e.data(), nn.data(), z.data(), z.size(), p.radius);
}

struct Case {
  const char* name;
  WeightedProbe probe;
};

std::vector<Case> cases(const std::vector<float>& img, int n) {
  // DTED2 at 42 N onto 30 m UTM (radius: a source post's diagonal); a
  // coarser target (radius: the spacing, about 50 source posts a target
  // post); and a frame turned 30 degrees with unequal axes.
  const double c30 = std::cos(0.5236), s30 = std::sin(0.5236);
  return {{"dted2-30m", {img.data(), n, n, 30.0, 38.8, 1.31, 0.021, -0.028, 0.97}},
          {"coarse-97m", {img.data(), n, n, 97.0, 97.0, 4.2, -0.1, 0.12, 3.1}},
          {"turned", {img.data(), n, n, 45.0, 60.0, 1.6 * c30, 1.6 * s30, -1.1 * s30, 1.1 * c30}}};
}

TEST(WeightedKernel, everyVariantGivesTheScalarDoublesBitForBit) {
  const int n = 64;
  const std::vector<float> img = roughImage(n);
  std::vector<double> px, py;
  positions(n, 333, px, py);  // not a multiple of 8 or 4: a short last batch
  const std::vector<std::string> variants = weightedKernelVariants();
  ASSERT_FALSE(variants.empty());
  EXPECT_EQ(variants.back(), "scalar");
  for (const auto& c : cases(img, n)) {
    const std::vector<double> reference = weightedKernelProbe("scalar", c.probe, px, py);
    ASSERT_EQ(reference.size(), px.size()) << c.name;
    for (const auto& v : variants) {
      const std::vector<double> got = weightedKernelProbe(v, c.probe, px, py);
      ASSERT_EQ(got.size(), px.size()) << c.name << " " << v;
      int differ = 0;
      for (std::size_t k = 0; k < got.size(); ++k) {
        if (std::memcmp(&got[k], &reference[k], sizeof(double)) != 0 && ++differ <= 3) {
          ADD_FAILURE() << c.name << " " << v << " post " << k << ": " << got[k] << " against scalar "
                        << reference[k];
        }
      }
      EXPECT_EQ(differ, 0) << c.name << " " << v;
    }
  }
  EXPECT_TRUE(weightedKernelProbe("no-such-isa", cases(img, n)[0].probe, px, py).empty());
}

TEST(WeightedKernel, scalarReferenceMatchesABruteForcePlane) {
  const int n = 64;
  const std::vector<float> img = roughImage(n);
  std::vector<double> px, py;
  positions(n, 333, px, py);
  for (const auto& c : cases(img, n)) {
    const std::vector<double> got = weightedKernelProbe("scalar", c.probe, px, py);
    ASSERT_EQ(got.size(), px.size());
    double worst = 0;
    int voids = 0;
    for (std::size_t k = 0; k < got.size(); ++k) {
      const double want = bruteForce(img, n, c.probe, px[k], py[k]);
      if (std::isnan(want) || std::isnan(got[k])) {
        EXPECT_EQ(std::isnan(want), std::isnan(got[k])) << c.name << " post " << k;
        ++voids;
        continue;
      }
      worst = std::max(worst, std::fabs(got[k] - want));
    }
    std::printf("[ weighted ] %s: %zu posts, %d without a source post, worst difference %.3g m\n", c.name,
                got.size(), voids, worst);
    EXPECT_LT(worst, 1e-6) << c.name;
  }
}

}  // namespace
}  // namespace sandtable::convert
