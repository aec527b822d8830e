#include "flags.h"

#include <string_view>
#include <utility>

namespace sandtable::cli {
namespace {

/// Longest first where one field name starts another.
constexpr std::pair<std::string_view, std::string_view> kFieldFlags[] = {
    {"ElevationOptions::sources", "--elevation"},
    {"Edit::radius", "--radius"},
    {"Edit::depth", "--depth"},
    {"Edit::width", "--width"},
    {"Edit::height", "--height"},
    {"Edit::sideSlope", "--slope"},
    {"Edit::points", "--lonlat/--xy, --line or --polygon"},
    {"Edit::scale", "--scale"},
    {"Edit::heading", "--heading"},
    {"SocketOptions::address", "--dis"},
    {"SocketOptions::port", "--dis"},
    {"SocketOptions::interface", "--dis-interface"},
    {"SocketOptions::multicastTtl", "--dis (multicast TTL)"},
    {"ElevationOptions::output", "-o"},
    {"ElevationOptions::crs", "--crs"},
    {"ElevationOptions::spacing", "--spacing"},
    {"ElevationOptions::resample", "--resample"},
    {"ElevationOptions::fit", "--fit"},
    {"ElevationOptions::extent", "--extent"},
    {"ElevationOptions::moduleSize", "--module-size"},
    {"ElevationOptions::levels", "--levels"},
    {"ElevationOptions::culture", "--culture"},
    {"ElevationOptions::materials", "--materials"},
    {"ElevationOptions::icons", "--icons"},
    {"ElevationOptions::objects", "--objects"},
    {"ElevationOptions::modules = false", "--no-modules"},
    {"ElevationOptions::zstdLevel", "--zstd-level"},
    {"ElevationOptions::moduleVersion", "--module-version"},
    {"ElevationOptions::moduleNormals", "--module-normals"},
    {"ElevationOptions::maxScaleError", "--max-scale-error"},
    {"ElevationOptions::seaFromVoids = false", "--no-sea-from-voids"},
    {"ElevationOptions::force", "--force"},
    {"ElevationOptions::threads", "--threads"},
    {"CultureOptions::sources", "--culture"},
    {"SynthOptions::outDir", "-o DIR"},
    {"SynthOptions::sizeKm", "--size-km"},
    {"SynthOptions::centerLon, centerLat", "--center LON LAT"},
    {"SynthOptions::seed", "--seed"},
    {"SynthOptions::force", "--force"},
    {"SynthOptions::threads", "--threads"},
    {"RenderOptions::mode = ", "--mode "},
    {"RenderOptions::samples", "--msaa"},
    {"RenderOptions::objectFade", "--object-fade"},
    {"RenderOptions::impostorPixels", "--impostor-pixels"},
    {"RenderOptions::objectThinPixels", "--object-thin-pixels"},
    {"RenderOptions::mode", "--mode"},
    {"OutputOptions::frames", "--frames"},
    {"ViewOptions::width/height", "--size"},
    {"RenderSettings::width/height", "--size"},
    {"ViewOptions::hfovDeg", "--fov"},
    {"ViewOptions::fogDensity", "--fog-density"},
    {"ViewOptions::maxViewDistance", "--max-view-distance"},
    {"ViewOptions::viewDistance", "--view-distance"},
    {"MotionOptions::pitchDeg", "--pitch"},
    {"MotionOptions::speedKmh", "--speed"},
    {"MotionOptions::headingDeg", "--heading"},
    {"MotionOptions::heightAgl", "--height"},
    {"MotionOptions::path", "--path"},
    {"PagerSettings::loaders", "pager loaders"},
    {"PagerSettings::budgetBytes", "--memory-budget-mb"},
    {"LodOptions::rings", "--rings"},
    {"LodOptions::pixelError", "--pixel-error"},
    {"FlySessionSettings::screenshotDir", "--screenshot-dir"},
    {"FlySessionSettings::altitude", "--altitude"},
    {"FlySessionSettings::mapScale", "--map-scale"},
    {"FlySessionSettings::path", "--path"},
    {"FlySessionSettings::freeFlight", "--free-flight"},
    {"ImportOptions::maxTriangles", "--max-triangles"},
    {"FlySessionSettings::map", "--map"},
    {"SocketOptions::address", "--dis"},
    {"SocketOptions::port", "--dis"},
    {"SocketOptions::interface", "--interface"},
};

}  // namespace

std::string withFlags(std::string message) {
  for (const auto& [field, flag] : kFieldFlags) {
    for (std::size_t at = message.find(field); at != std::string::npos; at = message.find(field, at)) {
      message.replace(at, field.size(), flag);
      at += flag.size();
    }
  }
  return message;
}

std::string flagFor(const std::string& field) {
  for (const auto& [f, flag] : kFieldFlags) {
    if (field == f) return std::string(flag);
  }
  return {};
}

}  // namespace sandtable::cli
