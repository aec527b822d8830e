// sandtable icons DEFS: check an icon definition file and every model it
// names, and say what the icon database would hold. sandtable icons --model
// FILE: import one model through assimp, as an icon would be, and say what
// came out: meshes, vertices, triangles, bounds, textures and the levels of
// detail.
#include <cstdio>
#include <filesystem>
#include <memory>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "icon_report.h"
#include "sandtable/icons/icon_build.h"
#include "sandtable/icons/model.h"
#include "sandtable/render/icon_sheet.h"

namespace sandtable::cli {
namespace {

struct IconsArgs {
  std::string defs;
  icons::PackOptions pack;
  std::string model;
  std::string up = "auto";
  icons::ImportOptions o;
  std::string out;
  bool json = false;
};

/// Icons per contact sheet page, so that a large pack stays a viewable image.
constexpr std::size_t kIconsPerSheet = 16;

/// Renders the pack's contact sheets into `dir` (created): contact_sheet.png,
/// then contact_sheet_2.png and on for every further kIconsPerSheet icons.
/// Returns the files written, or the problem.
Result<std::vector<std::string>> writeSheets(const iconpack::Pack& pack, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Problem{dir, 0, "cannot create the output folder: " + ec.message() + " (-o)"};
  std::vector<std::string> files;
  for (std::size_t first = 0, page = 1; first < pack.icons.size(); first += kIconsPerSheet, ++page) {
    auto sheet = render::renderIconSheet(pack, first, kIconsPerSheet);
    if (!sheet) return sheet.problems();
    for (const std::string& w : sheet->warnings) std::fprintf(stderr, "sandtable icons: warning: %s\n", w.c_str());
    std::string name = "contact_sheet";
    if (page > 1) name += "_" + std::to_string(page);
    name += ".png";
    const std::string path = (std::filesystem::path(dir) / name).string();
    if (Status st = render::writePng(path, sheet->image); !st.ok()) return st.problems();
    files.push_back(path);
  }
  return files;
}

/// The pack of one model alone, named after its file, with no built-in tree.
Result<iconpack::Pack> modelPack(const IconsArgs& a) {
  icons::Definitions defs;
  icons::IconDef def;
  def.name = std::filesystem::path(a.model).stem().string();
  def.alive = std::filesystem::absolute(a.model).string();
  def.import = a.o;
  defs.icons.push_back(def);
  icons::PackOptions po = a.pack;
  po.addDefaultTree = false;
  return icons::buildPack(defs, po);
}

nlohmann::json textures(const icons::Model& m) {
  nlohmann::json t = nlohmann::json::array();
  for (const icons::Material& mat : m.materials) {
    if (mat.texture.empty()) continue;
    t.push_back({{"material", mat.name},
                 {"name", mat.texture},
                 {"path", mat.texturePath},
                 {"embedded", mat.textureEmbedded},
                 {"found", mat.textureEmbedded || !mat.texturePath.empty()}});
  }
  return t;
}

nlohmann::json report(const icons::Model& m, const std::vector<icons::Level>& levels, const Warnings& w) {
  nlohmann::json mats = nlohmann::json::array(), lv = nlohmann::json::array(), warn = nlohmann::json::array();
  for (const icons::Material& mat : m.materials) mats.push_back({{"name", mat.name}, {"base_colour", mat.baseColour}});
  for (const icons::Level& l : levels) {
    lv.push_back({{"ratio", l.ratio}, {"triangles", l.triangleCount()}, {"error", l.error}});
  }
  for (const Problem& p : w) warn.push_back(p.message);
  return {{"model", m.source},
          {"source_meshes", m.sourceMeshes},
          {"meshes", m.meshes.size()},
          {"vertices", m.vertexCount()},
          {"triangles", m.triangleCount()},
          {"bounds", {{"min", m.bounds.min}, {"max", m.bounds.max}}},
          {"materials", mats},
          {"textures", textures(m)},
          {"levels", lv},
          {"warnings", warn}};
}

void printReport(const icons::Model& m, const std::vector<icons::Level>& levels) {
  const auto& b = m.bounds;
  std::printf("model      %s\n", m.source.c_str());
  std::printf("meshes     %zu with triangles, of %u in the file\n", m.meshes.size(), m.sourceMeshes);
  std::printf("vertices   %zu\ntriangles  %zu\n", m.vertexCount(), m.triangleCount());
  std::printf("bounds     x %.3f..%.3f, y %.3f..%.3f, z %.3f..%.3f m (%.3f x %.3f x %.3f m, Y up)\n", b.min[0],
              b.max[0], b.min[1], b.max[1], b.min[2], b.max[2], b.max[0] - b.min[0], b.max[1] - b.min[1],
              b.max[2] - b.min[2]);
  for (const icons::Material& mat : m.materials) {
    std::printf("material   %s: base colour %.3f %.3f %.3f %.3f", mat.name.c_str(), mat.baseColour[0],
                mat.baseColour[1], mat.baseColour[2], mat.baseColour[3]);
    if (mat.textureEmbedded) std::printf(", texture %s (embedded)", mat.texture.c_str());
    if (!mat.textureEmbedded && !mat.texture.empty()) {
      std::printf(", texture %s -> %s", mat.texture.c_str(), mat.texturePath.empty() ? "NOT FOUND" : mat.texturePath.c_str());
    }
    std::printf("\n");
  }
  for (std::size_t k = 0; k < levels.size(); ++k) {
    std::printf("level %zu    ratio %.2f: %zu triangles (simplifier error %.2f%% of the model's size)\n", k,
                double(levels[k].ratio), levels[k].triangleCount(), 100.0 * double(levels[k].error));
  }
}

int runDefinitions(const IconsArgs& a) {
  auto defs = icons::readDefinitions(a.defs);
  if (!defs) return reportProblems("icons", defs.problems());
  auto pack = icons::buildPack(defs.value(), a.pack);
  for (const Problem& w : pack.warnings()) std::fprintf(stderr, "sandtable icons: warning: %s\n", w.str().c_str());
  if (!pack) return reportProblems("icons", pack.problems());
  auto bytes = iconpack::encode(pack.value());
  if (!bytes) return reportProblems("icons", bytes.problems());
  std::vector<std::string> sheets;
  if (!a.out.empty()) {
    auto written = writeSheets(pack.value(), a.out);
    if (!written) return reportProblems("icons", written.problems());
    sheets = std::move(written.value());
  }
  if (a.json) {
    nlohmann::json warn = nlohmann::json::array();
    for (const Problem& w : pack.warnings()) warn.push_back(w.str());
    const nlohmann::json j{{"definitions", a.defs},
                           {"icons", iconsJson(pack.value())},
                           {"textures", pack->textures.size()},
                           {"pack_bytes", bytes->size()},
                           {"contact_sheets", sheets},
                           {"warnings", warn}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    printIcons(pack.value());
    std::printf("%zu icons, %zu textures: icons.pack would be %zu bytes\n", pack->icons.size(), pack->textures.size(),
                bytes->size());
    for (const std::string& f : sheets) std::printf("contact sheet %s\n", f.c_str());
  }
  return kOk;
}

int runIcons(IconsArgs& a) {
  if (a.defs.empty() == a.model.empty()) {
    return usageError("icons", "give a definition file (sandtable icons DEFS) or one model (--model FILE), not both");
  }
  if (!a.defs.empty()) return runDefinitions(a);
  a.o.up = a.up == "y" ? icons::UpAxis::kY : a.up == "z" ? icons::UpAxis::kZ : icons::UpAxis::kFromFile;
  auto r = icons::importModel(a.model, a.o);
  for (const Problem& w : r.warnings()) std::fprintf(stderr, "sandtable icons: warning: %s\n", w.str().c_str());
  if (!r) return reportProblems("icons", r.problems());
  const auto levels = icons::makeLevels(r.value());
  std::vector<std::string> sheets;
  if (!a.out.empty()) {
    auto pack = modelPack(a);
    if (!pack) return reportProblems("icons", pack.problems());
    auto written = writeSheets(pack.value(), a.out);
    if (!written) return reportProblems("icons", written.problems());
    sheets = std::move(written.value());
  }
  if (a.json) {
    nlohmann::json j = report(r.value(), levels, r.warnings());
    j["contact_sheets"] = sheets;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    printReport(r.value(), levels);
    for (const std::string& f : sheets) std::printf("contact sheet %s\n", f.c_str());
  }
  return kOk;
}

}  // namespace

void registerIcons(CLI::App& root, Commands& c) {
  auto a = std::make_shared<IconsArgs>();
  auto* sub = root.add_subcommand("icons", "Check an icon definition file, or import one model as an icon");
  sub->footer(
      "Examples:\n  sandtable icons samples/icons.txt -o out/icons\n  sandtable icons --model jeep1.3ds --json\n"
      "With DEFS: reads the definition file (docs/ICONS.md), imports every model it names, makes the levels\n"
      "of detail and the switch ranges, and prints per icon its triangles per level, ranges, bounds,\n"
      "cylinder and textures. The built-in tree is added unless DEFS defines 'tree'. Nothing is written\n"
      "unless -o DIR is given: then DIR/contact_sheet.png shows every icon at every level of detail with\n"
      "its name and triangle counts (16 icons a sheet; contact_sheet_2.png and on for more).\n"
      "With --model: reads"
      " any format assimp reads (glTF, 3DS, OBJ, OFF, FBX, Collada, ...), triangulates it, flattens its\n"
      "nodes, converts it to metres with Y up, and simplifies it into levels of detail (meshoptimizer).\n"
      "Exit status: 0 imported, 2 the model cannot become an icon (unreadable, no faces, NaN vertices,\n"
      "over --max-triangles). A texture that is not found is a warning: the material's base colour is used.");
  auto* defs = sub->add_option("defs", a->defs, "An icon definition file (sandtable-icons 1)");
  sub->add_option("--model", a->model, "One model file to import, without a definition file")->excludes(defs);
  sub->add_option("--pixel-error", a->pack.pixelError,
                  "Switch ranges the definitions leave out keep each level's error under this many pixels")
      ->default_val(a->pack.pixelError)
      ->check(CLI::PositiveNumber);
  sub->add_option("--up", a->up, "The model's up axis as assimp reads it: auto (the file's metadata, else y), y or z")
      ->check(CLI::IsMember({"auto", "y", "z"}))
      ->default_val("auto");
  sub->add_option("--unit-metres", a->o.unitMetres, "Metres per model unit (0: the file's unit metadata, else 1)")
      ->default_val(0.0)
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--scale", a->o.scale, "Scale applied after the unit conversion")
      ->default_val(1.0)
      ->check(CLI::PositiveNumber);
  sub->add_option("--max-triangles", a->o.maxTriangles, "Most triangles an icon may have")
      ->default_val(a->o.maxTriangles)
      ->check(CLI::PositiveNumber);
  sub->add_option("-o,--out", a->out, "Write the contact sheet PNG(s) into this folder");
  sub->add_flag("--json", a->json, "Print the report as JSON (keys vertices, triangles, bounds, textures, ...)");
  c.add(sub, [a] { return runIcons(*a); });
}

}  // namespace sandtable::cli
