#include "sandtable/render/map_view.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "sandtable/render/hud.h"

namespace sandtable::render {
namespace {

constexpr Rgb kMarkerEdge{0, 0, 0};
constexpr Rgb kSelectedEdge{255, 255, 255};
constexpr Rgb kBorder{255, 255, 255};
constexpr Rgb kLabel{255, 255, 0};

void put(Image& img, int x, int y, Rgb c) {
  if (x < 0 || y < 0 || x >= int(img.width) || y >= int(img.height)) return;
  const std::size_t k = (std::size_t(y) * img.width + std::size_t(x)) * 4;
  img.rgba[k] = c.r;
  img.rgba[k + 1] = c.g;
  img.rgba[k + 2] = c.b;
  img.rgba[k + 3] = 255;
}

struct Pt {
  double x, y;
};

double edge(Pt a, Pt b, Pt p) { return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x); }

/// Fills a triangle, clipped to the rectangle [x0, x1) x [y0, y1).
void fillTriangle(Image& img, Pt a, Pt b, Pt c, Rgb color, int x0, int y0, int x1, int y1) {
  const int minX = std::max(x0, int(std::floor(std::min({a.x, b.x, c.x}))));
  const int maxX = std::min(x1 - 1, int(std::ceil(std::max({a.x, b.x, c.x}))));
  const int minY = std::max(y0, int(std::floor(std::min({a.y, b.y, c.y}))));
  const int maxY = std::min(y1 - 1, int(std::ceil(std::max({a.y, b.y, c.y}))));
  const double area = edge(a, b, c);
  if (area == 0) return;
  for (int y = minY; y <= maxY; ++y) {
    for (int x = minX; x <= maxX; ++x) {
      const Pt p{x + 0.5, y + 0.5};
      // Same sign as the whole triangle on all three edges: inside,
      // whichever way the heading winds the corners.
      const double w0 = edge(b, c, p) * area, w1 = edge(c, a, p) * area, w2 = edge(a, b, p) * area;
      if (w0 >= 0 && w1 >= 0 && w2 >= 0) put(img, x, y, color);
    }
  }
}

}  // namespace

MapView::MapView(std::shared_ptr<const grid::HeightField> heights, MapOptions options)
    : grid_(std::move(heights)), options_(std::move(options)) {
  options_.colorSteps = std::max(1, options_.colorSteps);
  options_.hillshade = std::clamp(options_.hillshade, 0.0, 1.0);
  worldW_ = grid_->spacing() * (grid_->postsX() - 1);
  worldD_ = grid_->spacing() * (grid_->postsZ() - 1);
  generation_ = grid_->generation();
  buildOverview();
}

MapView::MapView(std::shared_ptr<const grid::GridFile> grid, MapOptions options)
    : MapView(grid::heightField(std::move(grid)), std::move(options)) {}

void MapView::toWorld(const grid::Header& h, double easting, double northing, double& x, double& z) {
  x = easting - h.originEasting;
  z = h.originNorthing - northing;
}

const char* MapView::scaleName(int scale) {
  static constexpr std::array<const char*, 5> names = {"FULL", "HALF", "QUARTER", "EIGHTH", "SIXTEENTH"};
  return names[std::size_t(std::clamp(scale, 0, 4))];
}

void MapView::setScale(int scale) { scale_ = std::clamp(scale, 0, 4); }

bool MapView::isWater(float elevation, std::uint8_t material) const {
  if (elevation <= options_.seaLevel) return true;
  return std::find(options_.waterMaterials.begin(), options_.waterMaterials.end(), material) !=
         options_.waterMaterials.end();
}

Rgb MapView::rampColor(float elevation, std::uint8_t material) const {
  if (isWater(elevation, material)) return kMapSeaBlue;
  // Figure 41: colorstep = range / COLORSTEP, colordelta = 255 / (COLORSTEP
  // + 1); banded so the grey steps read as contour bands, as the seed
  // wanted ("too many colors ... doesn't look good").
  const int steps = options_.colorSteps;
  const double range = double(landMax_) - double(landMin_);
  const int band = range > 0 ? std::clamp(int((elevation - landMin_) / (range / steps)), 0, steps) : steps;
  const int delta = 255 / (steps + 1);
  const auto g = std::uint8_t(std::min(255, delta * (band + 1)));
  return {g, g, g};
}

Rgb MapView::postColor(std::uint32_t i, std::uint32_t j) const {
  const float e = grid_->elevation(i, j);
  const std::uint8_t m = grid_->material(i, j);
  Rgb c = rampColor(e, m);
  if (options_.hillshade <= 0 || isWater(e, m)) return c;
  // Light from the north-west and above: X east, Y up, Z south.
  const auto n = grid_->normal(i, j);
  const double l = (-n[0] + n[1] - n[2]) / std::sqrt(3.0);
  const double flat = 1 / std::sqrt(3.0);
  const double f = 1 - options_.hillshade * (1 - std::clamp(l / flat, 0.0, 1.0));
  auto shade = [f](std::uint8_t v) { return std::uint8_t(std::lround(v * f)); };
  return {shade(c.r), shade(c.g), shade(c.b)};
}

void MapView::buildOverview() {
  const std::uint32_t px = grid_->postsX(), pz = grid_->postsZ();
  const std::uint32_t side = std::max<std::uint32_t>(1, options_.overviewMaxSide);
  const std::uint32_t step = std::max<std::uint32_t>(1, (std::max(px, pz) + side - 1) / side);
  const std::uint32_t ow = (px - 1) / step + 1, oh = (pz - 1) / step + 1;
  bool anyLand = false;
  for (std::uint32_t j = 0; j < pz; j += step) {
    for (std::uint32_t i = 0; i < px; i += step) {
      const float e = grid_->elevation(i, j);
      if (isWater(e, grid_->material(i, j))) continue;
      landMin_ = anyLand ? std::min(landMin_, e) : e;
      landMax_ = anyLand ? std::max(landMax_, e) : e;
      anyLand = true;
    }
  }
  overview_.width = ow;
  overview_.height = oh;
  overview_.rgba.assign(std::size_t(ow) * oh * 4, 255);
  for (std::uint32_t y = 0; y < oh; ++y) {
    for (std::uint32_t x = 0; x < ow; ++x) put(overview_, int(x), int(y), postColor(x * step, y * step));
  }
}

MapWindow MapView::centredWindow(double eyeX, double eyeZ, int scale) const {
  // Figure 40, per axis (the seed's database was square; ours need not be).
  const double zoom = double(1 << std::clamp(scale, 0, 4));
  const double halfW = worldW_ / zoom / 2, halfD = worldD_ / zoom / 2;
  MapWindow w{eyeX - halfW, eyeX + halfW, eyeZ - halfD, eyeZ + halfD};
  if (w.left < 0) {
    w.right -= w.left;
    w.left = 0;
  }
  if (w.right > worldW_) {
    w.left -= w.right - worldW_;
    w.right = worldW_;
  }
  if (w.top < 0) {
    w.bottom -= w.top;
    w.top = 0;
  }
  if (w.bottom > worldD_) {
    w.top -= w.bottom - worldD_;
    w.bottom = worldD_;
  }
  return w;
}

void MapView::renderBase(int w, int h) {
  base_.width = std::uint32_t(w);
  base_.height = std::uint32_t(h);
  base_.rgba.assign(std::size_t(w) * std::size_t(h) * 4, 255);
  const double s = grid_->spacing();
  const auto maxI = grid_->postsX() - 1, maxJ = grid_->postsZ() - 1;
  for (int y = 0; y < h; ++y) {
    const double z = window_.top + (y + 0.5) / h * window_.depth();
    const auto j = std::uint32_t(std::clamp(std::lround(z / s), 0L, long(maxJ)));
    for (int x = 0; x < w; ++x) {
      const double wx = window_.left + (x + 0.5) / w * window_.width();
      const auto i = std::uint32_t(std::clamp(std::lround(wx / s), 0L, long(maxI)));
      put(base_, x, y, postColor(i, j));
    }
  }
}

void MapView::drawMarker(Image& frame, int cx, int cy, double headingDeg, int size,
                         std::array<int, 4> clip) const {
  const double h = headingDeg * std::numbers::pi / 180.0;
  const double dx = std::sin(h), dy = -std::cos(h);  // north is up the image
  const Pt c{cx + 0.5, cy + 0.5};
  auto tri = [&](double s) {
    return std::array<Pt, 3>{Pt{c.x + dx * s, c.y + dy * s},
                             Pt{c.x - dx * s * 0.6 - dy * s * 0.6, c.y - dy * s * 0.6 + dx * s * 0.6},
                             Pt{c.x - dx * s * 0.6 + dy * s * 0.6, c.y - dy * s * 0.6 - dx * s * 0.6}};
  };
  const int x0 = std::max(0, clip[0]), y0 = std::max(0, clip[1]);
  const int x1 = std::min(int(frame.width), clip[2]), y1 = std::min(int(frame.height), clip[3]);
  const auto outer = tri(size + 1.5), inner = tri(size);
  fillTriangle(frame, outer[0], outer[1], outer[2], kMarkerEdge, x0, y0, x1, y1);
  fillTriangle(frame, inner[0], inner[1], inner[2], options_.markerFill, x0, y0, x1, y1);
}

Rgb forceColour(std::uint8_t force) {
  switch (force) {
    case 1: return {40, 110, 255};
    case 2: return {235, 30, 30};
    case 3: return {40, 200, 60};
    default: return {170, 170, 170};
  }
}

Rgb deadColour(std::uint8_t force) {
  const Rgb c = forceColour(force);
  return {std::uint8_t(c.r / 2), std::uint8_t(c.g / 2), std::uint8_t(c.b / 2)};
}

bool MapView::pixelOf(const MapLayout& layout, double x, double z, int& px, int& py) {
  if (!layout.drawn || !(layout.window.width() > 0) || !(layout.window.depth() > 0)) return false;
  const double u = (x - layout.window.left) / layout.window.width();
  const double v = (z - layout.window.top) / layout.window.depth();
  if (!(u >= 0 && u < 1 && v >= 0 && v < 1)) return false;
  px = layout.x + int(std::floor(u * layout.width));
  py = layout.y + int(std::floor(v * layout.height));
  return true;
}

void MapView::drawEditLine(Image& frame, const MapLayout& box, double xa, double za, double xb, double zb) {
  if (!box.drawn || !(box.window.width() > 0)) return;
  // One sample per pixel along it; the parts off the map are skipped.
  const double pixels = std::hypot(xb - xa, zb - za) * box.width / box.window.width();
  const int n = int(std::min(4096.0, std::ceil(pixels))) + 1;
  for (int k = 0; k <= n; ++k) {
    const double t = double(k) / n;
    int px = 0, py = 0;
    if (!pixelOf(box, xa + t * (xb - xa), za + t * (zb - za), px, py)) continue;
    if (px >= 0 && px < int(frame.width) && py >= 0 && py < int(frame.height)) put(frame, px, py, kEditMarkColour);
  }
}

void MapView::drawMarks(Image& frame, const MapLayout& box, const std::vector<MapMark>& marks) const {
  const int x0 = std::max(0, box.x), y0 = std::max(0, box.y);
  const int x1 = std::min(int(frame.width), box.x + box.width), y1 = std::min(int(frame.height), box.y + box.height);
  const int size = std::max(3, box.width / 60);
  // Terrain edits first, as rings; the dead under the living, the selected
  // one last (on top).
  for (const MapMark& m : marks) {
    int px = 0, py = 0;
    if (m.edit && m.to) {
      drawEditLine(frame, box, m.x, m.z, (*m.to)[0], (*m.to)[1]);
      continue;
    }
    if (!m.edit || !pixelOf(box, m.x, m.z, px, py)) continue;
    const int r = std::max(2, size / 2);
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const int d2 = dx * dx + dy * dy;
        if (d2 > r * r || d2 < (r - 1) * (r - 1)) continue;
        if (px + dx >= x0 && px + dx < x1 && py + dy >= y0 && py + dy < y1) put(frame, px + dx, py + dy, kEditMarkColour);
      }
    }
  }
  for (const int pass : {0, 1, 2}) {
    for (const MapMark& m : marks) {
      if (m.edit || pass != (m.selected ? 2 : m.alive ? 1 : 0)) continue;
      int px = 0, py = 0;
      if (!pixelOf(box, m.x, m.z, px, py)) continue;
      if (!m.alive) {
        // A dimmed dot: no heading on a wreck.
        const Rgb c = deadColour(m.force);
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            if (px + dx >= x0 && px + dx < x1 && py + dy >= y0 && py + dy < y1) put(frame, px + dx, py + dy, c);
          }
        }
        continue;
      }
      const int s = m.selected ? size + 2 : size;
      const double h = m.headingDeg * std::numbers::pi / 180.0;
      const double dx = std::sin(h), dy = -std::cos(h);  // north is up the image
      const Pt c{px + 0.5, py + 0.5};
      auto tri = [&](double r) {
        return std::array<Pt, 3>{Pt{c.x + dx * r, c.y + dy * r},
                                 Pt{c.x - dx * r * 0.7 - dy * r * 0.7, c.y - dy * r * 0.7 + dx * r * 0.7},
                                 Pt{c.x - dx * r * 0.7 + dy * r * 0.7, c.y - dy * r * 0.7 - dx * r * 0.7}};
      };
      const auto outer = tri(s + 1.2), inner = tri(s);
      fillTriangle(frame, outer[0], outer[1], outer[2], m.selected ? kSelectedEdge : kMarkerEdge, x0, y0, x1, y1);
      fillTriangle(frame, inner[0], inner[1], inner[2], forceColour(m.force), x0, y0, x1, y1);
      // The entity's own pixel always holds its colour, however thin the arrow.
      if (px >= x0 && px < x1 && py >= y0 && py < y1) put(frame, px, py, forceColour(m.force));
    }
  }
}

MapLayout MapView::compose(Image& frame, double eyeX, double eyeZ, double headingDeg,
                           const std::vector<MapMark>& marks, bool showViewer) {
  MapLayout out;
  if (!visible_ || worldW_ <= 0 || worldD_ <= 0) return out;
  if (const std::uint64_t g = grid_->generation(); g != generation_) {
    // The terrain changed under the map: rescan the overview, redraw the base.
    generation_ = g;
    buildOverview();
    baseScale_ = -1;
  }
  const int box = int(std::lround(std::min(frame.width, frame.height) * options_.sizeFraction));
  const bool wide = worldW_ >= worldD_;
  const int pw = wide ? box : std::max(1, int(std::lround(box * worldW_ / worldD_)));
  const int ph = wide ? std::max(1, int(std::lround(box * worldD_ / worldW_))) : box;
  if (pw < 16 || ph < 16) return out;  // too small a frame to show anything useful
  out.drawn = true;
  out.width = pw;
  out.height = ph;
  out.x = int(frame.width) - options_.marginPx - 1 - pw;
  out.y = options_.marginPx + 1;

  // Figure 40's "inner box": re-centre only when the viewer leaves the
  // middle half of the current window (or the scale or size changed).
  const bool sameBase = baseScale_ == scale_ && int(base_.width) == pw && int(base_.height) == ph;
  const bool inside = std::abs(eyeX - (window_.left + window_.right) / 2) <= window_.width() / 4 &&
                      std::abs(eyeZ - (window_.top + window_.bottom) / 2) <= window_.depth() / 4;
  if (!sameBase || !inside) {
    const MapWindow next = centredWindow(eyeX, eyeZ, scale_);
    const bool moved = next.left != window_.left || next.top != window_.top ||
                       next.right != window_.right || next.bottom != window_.bottom;
    if (!sameBase || moved) {
      window_ = next;
      baseScale_ = scale_;
      renderBase(pw, ph);
    }
  }
  out.window = window_;

  for (int y = -1; y <= ph; ++y) {
    for (int x = -1; x <= pw; ++x) {
      if (x < 0 || y < 0 || x == pw || y == ph) put(frame, out.x + x, out.y + y, kBorder);
    }
  }
  for (int y = 0; y < ph; ++y) {
    const int fy = out.y + y;
    if (fy < 0 || fy >= int(frame.height)) continue;
    const int x0 = std::max(0, -out.x), x1 = std::min(pw, int(frame.width) - out.x);
    if (x1 <= x0) continue;
    std::copy_n(&base_.rgba[(std::size_t(y) * pw + std::size_t(x0)) * 4], std::size_t(x1 - x0) * 4,
                &frame.rgba[(std::size_t(fy) * frame.width + std::size_t(out.x + x0)) * 4]);
  }

  drawMarks(frame, out, marks);
  const double u = (eyeX - window_.left) / window_.width();
  const double v = (eyeZ - window_.top) / window_.depth();
  out.markerVisible = u >= 0 && u < 1 && v >= 0 && v < 1;
  out.markerX = out.x + int(std::floor(u * pw));
  out.markerY = out.y + int(std::floor(v * ph));
  if (out.markerVisible && showViewer) {
    // Drawn wholly inside the map: at the database's edge the arrow moves
    // in by its own size rather than hanging over the frame.
    const int size = std::max(4, pw / 24), reach = size + 3;
    const int cx = std::clamp(out.markerX, out.x + reach, std::max(out.x + reach, out.x + pw - 1 - reach));
    const int cy = std::clamp(out.markerY, out.y + reach, std::max(out.y + reach, out.y + ph - 1 - reach));
    drawMarker(frame, cx, cy, headingDeg, size, {out.x, out.y, out.x + pw, out.y + ph});
  }
  drawLabel(frame, out);
  return out;
}

void MapView::drawLabel(Image& frame, const MapLayout& box) const {
  // The longest form that fits the map's width: the scale's name goes
  // first, then the text shrinks, then only the fraction is left.
  char full[64], shorter[32], fraction[16];
  std::snprintf(full, sizeof full, "1/%d %s %.1f KM", 1 << scale_, scaleName(scale_),
                window_.width() / 1000.0);
  std::snprintf(shorter, sizeof shorter, "1/%d %.1f KM", 1 << scale_, window_.width() / 1000.0);
  std::snprintf(fraction, sizeof fraction, "1/%d", 1 << scale_);
  const int big = frame.width >= 800 ? 2 : 1;
  for (int ts : {big, 1}) {
    for (const char* text : {full, shorter, fraction}) {
      if (textWidth(text, ts) + 6 * ts > box.width) continue;
      drawText(frame, box.x + 3 * ts, box.y + box.height - (kGlyphHeight + 2) * ts, text, ts, kLabel);
      return;
    }
  }
}

}  // namespace sandtable::render
