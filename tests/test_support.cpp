#include "test_support.h"

#include <gdal_priv.h>
#include <unistd.h>

#include <fstream>
#include <memory>
#include <random>
#include <sstream>

#include "sandtable/formats/bytes.h"

namespace sandtable::test {
namespace fs = std::filesystem;

TempDir::TempDir(const std::string& tag) {
  std::random_device rd;
  path_ = (fs::temp_directory_path() / (tag + "-" + std::to_string(::getpid()) + "-" + std::to_string(rd()))).string();
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

namespace {
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
}  // namespace

CommandResult runCli(const std::vector<std::string>& args) {
  TempDir io("cli");
  std::string cmd = quote(SANDTABLE_CLI);
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive)
  // on `" " + std::string` here, and CI builds with -Werror.
  for (const auto& a : args) {
    cmd += ' ';
    cmd += quote(a);
  }
  cmd += " >";
  cmd += quote(io / "out");
  cmd += " 2>";
  cmd += quote(io / "err");
  cmd += " </dev/null";
  const int rc = std::system(cmd.c_str());
  CommandResult r;
  r.exitCode = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  r.out = slurpFile(io / "out");
  r.err = slurpFile(io / "err");
  return r;
}

std::string slurpFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void spit(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
}

void resealManifest(const std::string& db, const std::function<void(nlohmann::json&)>& edit) {
  const std::string path = db + "/manifest.json";
  nlohmann::json j = nlohmann::json::parse(slurpFile(path));
  j.erase("checksum");
  edit(j);
  j.erase("checksum");
  const std::string compact = j.dump();
  j["checksum"] = crcHex(crc32(std::as_bytes(std::span(compact.data(), compact.size()))));
  spit(path, j.dump(2) + "\n");
}

std::vector<std::string> filesUnder(const std::string& dir, const std::vector<std::string>& exts) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::string name = e.path().filename().string();
    for (const auto& x : exts) {
      if (name.size() > x.size() && name.compare(name.size() - x.size(), x.size(), x) == 0) {
        out.push_back(e.path().string());
        break;
      }
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

render::Image readPng(const std::string& path) {
  GDALAllRegister();
  render::Image img;
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds || ds->GetRasterCount() < 3) return img;
  img.width = std::uint32_t(ds->GetRasterXSize());
  img.height = std::uint32_t(ds->GetRasterYSize());
  img.rgba.assign(std::size_t(img.width) * img.height * 4, 255);
  int bands[3] = {1, 2, 3};
  const CPLErr e = ds->RasterIO(GF_Read, 0, 0, int(img.width), int(img.height), img.rgba.data(), int(img.width),
                                int(img.height), GDT_Byte, 3, bands, 4, GSpacing(img.width) * 4, 1, nullptr);
  if (e != CE_None) img = render::Image{};
  return img;
}

void resealFiles(const std::string& db) {
  resealManifest(db, [&](nlohmann::json& j) {
    for (auto& f : j["files"]) {
      const auto c = crc32File(db + "/" + f["path"].get<std::string>());
      ASSERT_TRUE(c.ok()) << c.error();
      f["bytes"] = c->bytes;
      f["crc32"] = crcHex(c->crc);
    }
  });
}

}  // namespace sandtable::test
