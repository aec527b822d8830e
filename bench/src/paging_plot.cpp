// bench paging's plot: holes and degraded frames against speed, drawn as
// SVG text or into an image with the HUD's font and written as PNG.
#include "paging_plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include "sandtable/render/hud.h"
#include "sandtable/render/image.h"

namespace sandtable::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Series {
  std::string label;
  std::vector<std::array<double, 2>> points;  ///< speed km/h, % of frames
  render::Rgb color;
  bool dashed = false;
};

std::string speedLabel(double v) {
  char b[32];
  if (v >= 1e6) std::snprintf(b, sizeof b, "%gM", v / 1e6);
  else if (v >= 1000) std::snprintf(b, sizeof b, "%gk", v / 1000);
  else std::snprintf(b, sizeof b, "%g", v);
  return b;
}

std::vector<Series> plotSeries(const json& modes) {
  const std::map<std::string, render::Rgb> colors = {
      {"predictive", {0, 114, 178}}, {"demand", {213, 94, 0}}, {"mmap", {0, 158, 115}}, {"seed", {204, 121, 167}}};
  std::vector<Series> out;
  for (const auto& [mode, m] : modes.items()) {
    for (const char* what : {"hole_frames", "degraded_frames"}) {
      if (mode == "mmap" && std::string(what) == "degraded_frames") continue;  // one level: never degraded
      const bool holes = std::string(what) == "hole_frames";
      std::string label = mode + (holes ? " holes" : " degraded");
      if (holes) {
        const double z = m["max_speed_zero_holes_kmh"].get<double>();
        label += z > 0 ? ", 0 to " + speedLabel(z) : ", never 0";
      }
      Series s{label, {}, colors.at(mode), !holes};
      for (const json& p : m["speeds"]) {
        const double frames = p["frames"].get<double>();
        if (frames > 0) s.points.push_back({p["speed_kmh"].get<double>(), 100 * p[what].get<double>() / frames});
      }
      out.push_back(std::move(s));
    }
  }
  // Predictive last, so that its line at 0 % is drawn over the others.
  std::stable_partition(out.begin(), out.end(), [](const Series& s) { return s.label.rfind("predictive", 0) != 0; });
  return out;
}

/// Plot frame: log X (speed), linear Y (0..100 % of frames).
struct Axes {
  int w = 1120, h = 560, left = 80, right = 440, top = 70, bottom = 60;
  double x0 = 1000, x1 = 1e6;
  double px(double speed) const {
    return left + (std::log10(speed) - std::log10(x0)) / (std::log10(x1) - std::log10(x0)) * (w - left - right);
  }
  double py(double pct) const { return top + (1 - pct / 100) * (h - top - bottom); }
};

Axes axesFor(const std::vector<Series>& series) {
  Axes ax;
  double lo = 1e12, hi = 0;
  for (const Series& s : series) {
    for (const auto& p : s.points) lo = std::min(lo, p[0]), hi = std::max(hi, p[0]);
  }
  if (hi <= 0) lo = 1000, hi = 1e6;
  ax.x0 = std::pow(10, std::floor(std::log10(lo)));
  ax.x1 = std::pow(10, std::ceil(std::log10(hi) - 1e-9));
  if (ax.x1 <= ax.x0) ax.x1 = ax.x0 * 10;
  return ax;
}

std::string svgPlot(const std::vector<Series>& series, const std::string& title) {
  const Axes ax = axesFor(series);
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << ax.w << "' height='" << ax.h
    << "' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n";
  o << "<text x='" << ax.left << "' y='28' font-size='15'>" << title << "</text>\n";
  const double xr = ax.w - ax.right, yb = ax.h - ax.bottom;
  for (int pct = 0; pct <= 100; pct += 20) {
    o << "<line x1='" << ax.left << "' y1='" << ax.py(pct) << "' x2='" << xr << "' y2='" << ax.py(pct)
      << "' stroke='#ddd'/>\n<text x='" << ax.left - 8 << "' y='" << ax.py(pct) + 4 << "' text-anchor='end'>" << pct
      << "%</text>\n";
  }
  for (double v = ax.x0; v <= ax.x1 * 1.0001; v *= 10) {
    for (int m = 1; m < 10 && v * m <= ax.x1 * 1.0001; ++m) {
      const double x = ax.px(v * m);
      o << "<line x1='" << x << "' y1='" << ax.top << "' x2='" << x << "' y2='" << yb << "' stroke='"
        << (m == 1 ? "#bbb" : "#eee") << "'/>\n";
      if (m == 1 || m == 2 || m == 5) {
        o << "<text x='" << x << "' y='" << yb + 18 << "' text-anchor='middle'>" << speedLabel(v * m) << "</text>\n";
      }
    }
  }
  o << "<rect x='" << ax.left << "' y='" << ax.top << "' width='" << xr - ax.left << "' height='" << yb - ax.top
    << "' fill='none' stroke='black'/>\n";
  o << "<text x='" << (ax.left + xr) / 2 << "' y='" << ax.h - 18 << "' text-anchor='middle'>speed, km/h (log)</text>\n";
  o << "<text transform='translate(20," << (ax.top + yb) / 2
    << ") rotate(-90)' text-anchor='middle'>frames with a hole / degraded, % of frames</text>\n";
  int ly = ax.top + 10;
  for (const Series& s : series) {
    char rgb[16];
    std::snprintf(rgb, sizeof rgb, "#%02x%02x%02x", s.color.r, s.color.g, s.color.b);
    const std::string dash = s.dashed ? " stroke-dasharray='6,4'" : "";
    o << "<polyline fill='none' stroke='" << rgb << "' stroke-width='2'" << dash << " points='";
    for (const auto& p : s.points) o << ax.px(p[0]) << "," << ax.py(p[1]) << " ";
    o << "'/>\n";
    for (const auto& p : s.points) {
      o << "<circle cx='" << ax.px(p[0]) << "' cy='" << ax.py(p[1]) << "' r='3' fill='" << rgb << "'/>\n";
    }
    o << "<line x1='" << xr + 15 << "' y1='" << ly << "' x2='" << xr + 45 << "' y2='" << ly << "' stroke='" << rgb
      << "' stroke-width='2'" << dash << "/>\n<text x='" << xr + 52 << "' y='" << ly + 4 << "'>" << s.label
      << "</text>\n";
    ly += 20;
  }
  o << "</svg>\n";
  return o.str();
}

void dot(render::Image& img, int x, int y, render::Rgb c) {
  if (x < 0 || y < 0 || x >= int(img.width) || y >= int(img.height)) return;
  const std::size_t k = (std::size_t(y) * img.width + std::size_t(x)) * 4;
  img.rgba[k] = c.r, img.rgba[k + 1] = c.g, img.rgba[k + 2] = c.b, img.rgba[k + 3] = 255;
}

/// A line two pixels wide; `dashed` leaves gaps every 6 pixels.
void line(render::Image& img, double x0, double y0, double x1, double y1, render::Rgb c, bool dashed = false) {
  const double len = std::max(1.0, std::hypot(x1 - x0, y1 - y0));
  for (double t = 0; t <= len; t += 0.5) {
    if (dashed && int(t) % 10 >= 6) continue;
    const double x = x0 + (x1 - x0) * t / len, y = y0 + (y1 - y0) * t / len;
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) dot(img, int(x) + dx, int(y) + dy, c);
  }
}

std::string pngPlot(const std::string& file, const std::vector<Series>& series, const std::string& title) {
  const Axes ax = axesFor(series);
  render::Image img{std::uint32_t(ax.w), std::uint32_t(ax.h), {}};
  img.rgba.assign(std::size_t(ax.w) * ax.h * 4, 255);
  const render::Rgb grey{200, 200, 200}, black{0, 0, 0};
  const double xr = ax.w - ax.right, yb = ax.h - ax.bottom;
  for (int pct = 0; pct <= 100; pct += 20) {
    line(img, ax.left, ax.py(pct), xr, ax.py(pct), grey);
    const std::string t = std::to_string(pct) + "%";
    render::drawText(img, ax.left - 8 - render::textWidth(t, 2), int(ax.py(pct)) - 7, t, 2, black);
  }
  for (double v = ax.x0; v <= ax.x1 * 1.0001; v *= 10) {
    line(img, ax.px(v), ax.top, ax.px(v), yb, grey);
    const std::string t = speedLabel(v);
    render::drawText(img, int(ax.px(v)) - render::textWidth(t, 2) / 2, int(yb) + 8, t, 2, black);
  }
  line(img, ax.left, ax.top, xr, ax.top, black);
  line(img, ax.left, yb, xr, yb, black);
  line(img, ax.left, ax.top, ax.left, yb, black);
  line(img, xr, ax.top, xr, yb, black);
  render::drawText(img, ax.left, 14, title, 2, black);
  render::drawText(img, int(ax.left + xr) / 2 - 100, ax.h - 28, "SPEED KM/H (LOG)", 2, black);
  render::drawText(img, ax.left - 60, ax.top - 32, "% OF FRAMES", 2, black);
  int ly = ax.top + 10;
  for (const Series& s : series) {
    for (std::size_t i = 1; i < s.points.size(); ++i) {
      line(img, ax.px(s.points[i - 1][0]), ax.py(s.points[i - 1][1]), ax.px(s.points[i][0]), ax.py(s.points[i][1]),
           s.color, s.dashed);
    }
    for (const auto& p : s.points) {
      for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx) dot(img, int(ax.px(p[0])) + dx, int(ax.py(p[1])) + dy, s.color);
    }
    line(img, xr + 10, ly, xr + 40, ly, s.color, s.dashed);
    render::drawText(img, int(xr) + 46, ly - 6, s.label, 2, black);
    ly += 22;
  }
  return render::writePng(file, img).error();
}

}  // namespace

std::string writePlot(const std::string& file, const json& modes, const std::string& title) {
  const std::vector<Series> series = plotSeries(modes);
  const std::string ext = fs::path(file).extension().string();
  if (ext == ".png") return pngPlot(file, series, title);
  std::ofstream out(file);
  out << svgPlot(series, title);
  return out ? "" : "cannot write " + file;
}

}  // namespace sandtable::bench
