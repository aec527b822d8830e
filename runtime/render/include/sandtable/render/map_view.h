#pragma once
// The 2-D map of the stealth viewer (seed chapter VI B, Figures 40 and 41),
// drawn on the CPU into a corner of a finished frame.
//
// Shading (Figure 41): land in COLORSTEP (16) grey bands from the lowest
// land elevation (dark) to the highest (white); sea level, meaning
// elevation <= seaLevel or a water material, in the seed's blue (0, 46,
// 113). An optional hillshade from the grid normals (light from the
// north-west) darkens slopes facing away; 0 gives the seed's pure ramp.
//
// Scales (Figure 40): 0 full (the whole database), 1 half, 2 quarter,
// 3 eighth, 4 sixteenth of the database's extent along each axis. A zoomed
// map is centred on the viewer and shifted to stay inside the database.
// Like the seed, the map stays put until the viewer leaves its inner box
// (the middle half of the window in each axis), then re-centres; only then
// is the base image redrawn from the grid, so a frame usually costs just a
// blit and the marker.
//
// World frame: X east, Z south of the grid's north-west corner post, in
// metres (grid.h); toWorld() converts projected coordinates.
//
// The posts come from a HeightField (the grid file or a field that
// changes): when its generation moves, the next compose() rescans the
// overview and redraws the base image.
//
// Thread safety: one MapView per thread (compose() caches its base image).
// The HeightField is shared and only read.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <optional>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/render/image.h"

namespace sandtable::render {

struct MapOptions {
  /// Largest side of the overview image (full-scale map, every k-th post).
  std::uint32_t overviewMaxSide = 512;
  double seaLevel = 0;
  /// Material indices drawn as water whatever their elevation (docs/FORMAT.md 4.7: 1).
  std::vector<std::uint8_t> waterMaterials = {1};
  int colorSteps = 16;  ///< Figure 41's COLORSTEP
  double hillshade = 0.35;  ///< 0: pure elevation ramp; 1: full Lambert shading
  /// The map's box as a fraction of the frame's shorter side.
  double sizeFraction = 0.4;
  int marginPx = 8;
  /// The viewer's arrow (the seed's red; the stealth viewer makes it
  /// yellow when entities of the red force share the map).
  Rgb markerFill{255, 40, 40};
};

/// An entity on the map: an arrow along its heading in its force's
/// colour (forceColour), dimmed and without heading when dead.
struct MapMark {
  double x = 0, z = 0;    ///< world metres (X east, Z south)
  double headingDeg = 0;  ///< clockwise from grid north
  std::uint8_t force = 0; ///< 0 neutral, 1 blue, 2 red, 3 green
  bool alive = true;
  bool selected = false;  ///< the entity the eye is attached to: drawn larger, with a white edge
  /// A terrain edit, not an entity, in kEditMarkColour under the entities:
  /// a small ring at (x, z) (a crater), or with `to` a line from (x, z) to
  /// it (a berm's or a ditch's segment, a flattened polygon's edge).
  bool edit = false;
  std::optional<std::array<double, 2>> to;
};

inline constexpr Rgb kEditMarkColour{235, 150, 40};

/// A force's map colour: 1 blue, 2 red, 3 green, anything else neutral grey.
Rgb forceColour(std::uint8_t force);
/// A dead entity's colour: its force's, dimmed towards black by half.
Rgb deadColour(std::uint8_t force);

inline constexpr Rgb kMapSeaBlue{0, 46, 113};  ///< Figure 41: "a nice blue color"

/// The ground shown by the map: x in [left, right], z in [top, bottom]
/// (Figure 40's names; top is the northern edge, smaller z).
struct MapWindow {
  double left = 0, right = 0, top = 0, bottom = 0;
  double width() const { return right - left; }
  double depth() const { return bottom - top; }
};

/// Where compose() drew, in frame pixels.
struct MapLayout {
  bool drawn = false;  ///< false when hidden (nothing was touched)
  int x = 0, y = 0, width = 0, height = 0;  ///< the map image, inside a 1-pixel border
  MapWindow window;
  bool markerVisible = false;  ///< false when the viewer is off the map
  int markerX = 0, markerY = 0;  ///< the viewer's pixel
};

class MapView {
 public:
  /// Scans the grid once (about overviewMaxSide^2 posts) for the land
  /// elevation range and the overview image.
  explicit MapView(std::shared_ptr<const grid::HeightField> heights, MapOptions options = {});
  /// Over the grid file's posts (a GridHeightField).
  explicit MapView(std::shared_ptr<const grid::GridFile> grid, MapOptions options = {});

  /// 0 full .. 4 sixteenth; clamped.
  void setScale(int scale);
  int scale() const { return scale_; }
  /// "FULL", "HALF", "QUARTER", "EIGHTH", "SIXTEENTH".
  static const char* scaleName(int scale);

  void setVisible(bool v) { visible_ = v; }
  bool visible() const { return visible_; }
  void toggle() { visible_ = !visible_; }

  /// Draws the map into the frame's top-right corner when visible: the
  /// terrain, the entities in `marks` (the dead first, then the living),
  /// the viewer as an arrow pointing along headingDeg (clockwise from grid
  /// north) over them unless `showViewer` is false (an eye attached to an
  /// entity: its selected mark is the viewer), and a label with the scale
  /// and the ground span. The map still centres on (eyeX, eyeZ).
  MapLayout compose(Image& frame, double eyeX, double eyeZ, double headingDeg,
                    const std::vector<MapMark>& marks = {}, bool showViewer = true);
  /// The frame pixel of world (x, z) on the map `layout` drew; false off it.
  static bool pixelOf(const MapLayout& layout, double x, double z, int& px, int& py);
  /// A terrain edit's line from world (xa, za) to (xb, zb), clipped to the map.
  static void drawEditLine(Image& frame, const MapLayout& box, double xa, double za, double xb, double zb);

  /// The window Figure 40 gives for a viewer at (eyeX, eyeZ), before any
  /// inner-box hysteresis: centred on the viewer, clamped to the database.
  MapWindow centredWindow(double eyeX, double eyeZ, int scale) const;

  /// Map colour of post (i, j) without hillshade (tests, legends).
  Rgb rampColor(float elevation, std::uint8_t material) const;

  /// The full-scale map at overview resolution, one pixel per k-th post.
  const Image& overview() const { return overview_; }
  float landMin() const { return landMin_; }
  float landMax() const { return landMax_; }
  double worldWidth() const { return worldW_; }
  double worldDepth() const { return worldD_; }

  /// Projected (easting, northing) to world (x, z) for this grid.
  static void toWorld(const grid::Header& h, double easting, double northing, double& x, double& z);

 private:
  Rgb postColor(std::uint32_t i, std::uint32_t j) const;
  bool isWater(float elevation, std::uint8_t material) const;
  void buildOverview();
  void renderBase(int w, int h);
  /// The arrow, clipped to clip = {x0, y0, x1, y1} (the map's box).
  void drawMarker(Image& frame, int cx, int cy, double headingDeg, int size,
                  std::array<int, 4> clip) const;
  void drawMarks(Image& frame, const MapLayout& box, const std::vector<MapMark>& marks) const;
  void drawLabel(Image& frame, const MapLayout& box) const;

  std::shared_ptr<const grid::HeightField> grid_;
  std::uint64_t generation_ = 0;  ///< the field's generation the overview shows
  MapOptions options_;
  double worldW_ = 0, worldD_ = 0;
  float landMin_ = 0, landMax_ = 0;
  Image overview_;
  int scale_ = 0;
  bool visible_ = false;
  // Cached base image: valid for (window_, baseScale_) at this pixel size.
  Image base_;
  MapWindow window_;
  int baseScale_ = -1;
};

}  // namespace sandtable::render
