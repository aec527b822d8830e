#pragma once
// Internals of `sandtable synth`, shared by synth.cpp, synth_terrain.cpp and
// synth_culture.cpp. Not part of the library's API.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::convert::synth {

struct Vec2 {
  double x = 0, y = 0;
};

inline double clamp01(double v) { return v < 0 ? 0 : (v > 1 ? 1 : v); }
inline double smoothstep(double e0, double e1, double v) {
  const double t = clamp01((v - e0) / (e1 - e0));
  return t * t * (3 - 2 * t);
}
inline double lerp(double a, double b, double t) { return a + (b - a) * t; }

/// Local metres east/north of the square's centre. Equirectangular about the
/// centre latitude: affine in lon/lat, so a grid in metres is also a regular
/// lon/lat grid and polygons convert exactly.
struct Frame {
  double lon0 = 0, lat0 = 0;
  double mPerDegLon = 1, mPerDegLat = 1;

  Frame() = default;
  Frame(double lon, double lat);
  Vec2 toLocal(double lon, double lat) const {
    return {(lon - lon0) * mPerDegLon, (lat - lat0) * mPerDegLat};
  }
  double lonOf(double x) const { return lon0 + x / mPerDegLon; }
  double latOf(double y) const { return lat0 + y / mPerDegLat; }
};

/// A regular grid of cell centres in local metres: (x0 + i*step, y0 + j*step),
/// j growing northwards.
struct Grid {
  double x0 = 0, y0 = 0, step = 1;
  int nx = 0, ny = 0;

  std::size_t size() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
  std::size_t index(int i, int j) const {
    return static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i);
  }
  Vec2 at(int i, int j) const { return {x0 + i * step, y0 + j * step}; }
  Vec2 at(std::size_t k) const {
    return at(static_cast<int>(k % static_cast<std::size_t>(nx)),
              static_cast<int>(k / static_cast<std::size_t>(nx)));
  }
};

/// A lake: a star-shaped blob around centre whose inside is flat at level.
struct Lake {
  Vec2 centre;
  double radius = 0;  ///< mean rim radius, m
  double level = 0;   ///< water surface, whole metres so DTED stays flat
  double margin = 0;  ///< shore blend width outside the rim, m
  std::array<double, 3> amp{};    ///< harmonic amplitudes (fractions of radius)
  std::array<double, 3> phase{};

  double rimRadius(double theta) const {
    double f = 1.0;
    for (std::size_t k = 0; k < amp.size(); ++k) {
      f += amp[k] * std::sin(static_cast<double>(k + 1) * theta + phase[k]);
    }
    return radius * f;
  }
  double maxRadius() const { return radius * (1.0 + amp[0] + amp[1] + amp[2]); }
};

/// The terrain parameters that follow from the options.
struct TerrainSpec {
  double size = 20000;   ///< side of the square, m
  std::uint32_t seed = 1;
  Vec2 inland{0, 1};     ///< unit vector pointing away from the sea
  double coastOffset = 6000;  ///< centre to mean coastline, m
};

/// The elevation function. base() is the landform before rivers and lakes;
/// landform() fills closed basins and carves river valleys (precomputed
/// grids, interpolated); elevation() also flattens lakes. All const methods
/// are thread-safe.
class Terrain {
 public:
  explicit Terrain(const TerrainSpec& spec);

  double base(Vec2 p) const;
  /// base with basins filled and river valleys carved (interpolated grids).
  double landform(Vec2 p) const;
  double elevation(Vec2 p) const { return withLakes(p, landform(p)); }
  /// Signed distance inland from the coastline (m); negative at sea.
  double inland(Vec2 p) const;
  double withLakes(Vec2 p, double h) const;
  /// True inside a lake rim.
  bool inLake(Vec2 p) const;

  /// At each grid cell: h = base + fill, then min(h, shape * h + offset)
  /// (offset = bed * (1 - shape)) carves the valleys.
  void setValleys(const Grid& g, std::vector<float> fill, std::vector<float> shape, std::vector<float> offset);
  void setLakes(std::vector<Lake> lakes);
  const std::vector<Lake>& lakes() const { return lakes_; }
  const TerrainSpec& spec() const { return spec_; }

 private:
  TerrainSpec spec_;
  double plainWidth_, rampWidth_, rangeBlend_;
  Grid valleyGrid_;
  std::vector<float> basinFill_, valleyShape_, valleyOffset_;
  std::vector<Lake> lakes_;
  // Lakes bucketed on a coarse grid so a post tests only nearby lakes.
  Grid lakeGrid_;
  std::vector<std::vector<std::uint32_t>> lakeBuckets_;
};

struct River {
  std::string name;
  double width = 0;  ///< m
  std::vector<Vec2> pts;
};

struct Road {
  std::string type;
  double width = 0;  ///< m
  std::vector<Vec2> pts;
};

/// A building footprint: a rectangle of half sides (a, b) turned by angle.
struct Building {
  Vec2 centre;
  double a = 0, b = 0;  ///< half sides, m
  double angle = 0;     ///< radians, anticlockwise from east
  double height = 0;    ///< m, the `height` attribute
};

/// Everything derived once per run: the terrain function and the culture.
struct World {
  Frame frame;
  TerrainSpec spec;
  std::unique_ptr<Terrain> terrain;
  double half = 0;  ///< half side of the square, m
  std::vector<River> rivers;
  std::vector<Road> roads;
  std::vector<Vec2> towns;
  Grid grid;                         ///< analysis grid (square + margin)
  std::vector<float> height;         ///< final terrain on grid
  std::vector<float> riverDist;      ///< distance to the nearest river, m (large when none near)
  std::vector<std::uint8_t> forest;  ///< 1 = forest, on grid
  std::vector<Building> buildings;   ///< villages round the towns
};

using Fraction = std::function<void(double)>;

/// Runs fn(begin, end) over contiguous ranges covering [0, n), on the job
/// system's workers (jobs::parallelRanges, about four ranges per worker).
void parallelFor(std::size_t n, int threads, const std::function<void(std::size_t, std::size_t)>& fn);

/// Seeded integer hash, used for every random choice so runs are reproducible.
std::uint32_t hash32(std::uint32_t a, std::uint32_t b = 0, std::uint32_t c = 0);
/// Uniform in [0, 1) from a hash.
inline double unit(std::uint32_t h) { return (h >> 8) * (1.0 / 16777216.0); }

/// Seeded gradient noise summed over octaves, roughly in [-1, 1].
double fbm(double x, double y, std::uint32_t seed, int octaves);

TerrainSpec makeSpec(double sizeM, std::uint64_t seed);

/// Builds the terrain (rivers, valleys, lakes) and the culture model.
World buildWorld(const Frame& frame, double sizeM, std::uint64_t seed, int threads,
                 bool withCulture, const Fraction& progress);

/// Towns, roads and the forest mask, from world.height (synth_culture.cpp).
void buildCulture(World& world);

// Polyline helpers (local metres).
/// Corner cutting, endpoints kept; values (one per point) are carried along.
void chaikin(std::vector<Vec2>& pts, std::vector<double>* values, int iterations);
/// Points every `spacing` metres along the line, endpoints kept.
void resample(std::vector<Vec2>& pts, std::vector<double>* values, double spacing);
/// Extra points on segments longer than maxGap; the line keeps its shape.
void densify(std::vector<Vec2>& pts, double maxGap);
/// The parts of a polyline inside the square |x|, |y| <= half.
std::vector<std::vector<Vec2>> clipToSquare(const std::vector<Vec2>& pts, double half);

/// Culture feature counts written by writeCulture.
struct CultureCounts {
  int roads = 0, rivers = 0, lakes = 0, forests = 0, buildings = 0;
};

/// Writes culture.gpkg (EPSG:4326) in one transaction.
Result<CultureCounts> writeCulture(const World& world, const std::string& path);

}  // namespace sandtable::convert::synth
