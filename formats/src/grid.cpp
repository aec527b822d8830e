#include "sandtable/formats/grid.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <map>

#include "sandtable/base/capped_problems.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::grid {
namespace {

std::uint64_t roundUpPage(std::uint64_t v) { return (v + kPageBytes - 1) / kPageBytes * kPageBytes; }

std::string at(const std::string& what) { return "grid header: " + what; }

bool allZero(std::span<const std::byte> s, std::uint64_t& firstNonZero) {
  for (std::size_t k = 0; k < s.size(); ++k) {
    if (s[k] != std::byte{0}) {
      firstNonZero = k;
      return false;
    }
  }
  return true;
}

}  // namespace

Header makeHeader(std::uint32_t postsX, std::uint32_t postsZ, double spacing,
                  double originEasting, double originNorthing) {
  Header h;
  h.postsX = postsX;
  h.postsZ = postsZ;
  h.blocksX = (postsX + kBlockPosts - 1) / kBlockPosts;
  h.blocksZ = (postsZ + kBlockPosts - 1) / kBlockPosts;
  h.spacing = spacing;
  h.originEasting = originEasting;
  h.originNorthing = originNorthing;
  h.blockTableOffset = kPageBytes;
  h.dataOffset = kPageBytes + roundUpPage(h.blockCount() * kBlockEntryBytes);
  h.fileBytes = h.dataOffset + h.blockCount() * kBlockBytes;
  return h;
}

std::vector<std::byte> encodeHeader(const Header& h) {
  std::vector<std::byte> page(kPageBytes, std::byte{0});
  std::byte* p = page.data();
  std::memcpy(p + field::magic, kMagic.data(), kMagic.size());
  storeLE<std::uint32_t>(p + field::version, h.version);
  storeLE<std::uint32_t>(p + field::headerBytes, static_cast<std::uint32_t>(kPageBytes));
  storeLE<std::uint32_t>(p + field::postsX, h.postsX);
  storeLE<std::uint32_t>(p + field::postsZ, h.postsZ);
  storeLE<std::uint32_t>(p + field::blockPosts, h.blockPosts);
  storeLE<std::uint32_t>(p + field::blocksX, h.blocksX);
  storeLE<std::uint32_t>(p + field::blocksZ, h.blocksZ);
  storeLE<std::uint32_t>(p + field::flags, h.flags);
  storeLE<double>(p + field::spacing, h.spacing);
  storeLE<double>(p + field::originEasting, h.originEasting);
  storeLE<double>(p + field::originNorthing, h.originNorthing);
  storeLE<float>(p + field::minElevation, h.minElevation);
  storeLE<float>(p + field::maxElevation, h.maxElevation);
  storeLE<std::uint64_t>(p + field::blockTableOffset, h.blockTableOffset);
  storeLE<std::uint64_t>(p + field::dataOffset, h.dataOffset);
  storeLE<std::uint64_t>(p + field::blockBytes, h.blockBytes);
  storeLE<std::uint64_t>(p + field::fileBytes, h.fileBytes);
  storeLE<std::uint32_t>(p + field::tableCrc, h.tableCrc);
  storeLE<std::uint32_t>(p + field::headerCrc, crc32(std::span(p, field::headerCrc)));
  return page;
}

Result<Header> decodeHeader(std::span<const std::byte> bytes, const std::string& file,
                            std::uint64_t fileSize) {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Result<Header>(Problem{file, off, at(msg)});
  };
  if (bytes.size() < kHeaderFieldBytes) {
    return fail(bytes.size(), "truncated: the header needs " + std::to_string(kHeaderFieldBytes) +
                                  " bytes, the file ends at byte " + std::to_string(bytes.size()) +
                                  "; rebuild the database");
  }
  const std::byte* p = bytes.data();
  if (std::memcmp(p, kMagic.data(), kMagic.size()) != 0) {
    return fail(0, "bad magic: not a sandtable grid file (expected \"SANDGRID\")");
  }
  Header h;
  h.version = loadLE<std::uint32_t>(p + field::version);
  if (h.version != kVersion) {
    return fail(field::version, "version " + std::to_string(h.version) +
                                    " is not supported (this reader knows version " +
                                    std::to_string(kVersion) + "); use a matching sandtable");
  }
  const std::uint32_t stored = loadLE<std::uint32_t>(p + field::headerCrc);
  const std::uint32_t actual = crc32(bytes.first(field::headerCrc));
  if (stored != actual) {
    return fail(field::headerCrc, "header checksum mismatch (stored " + crcHex(stored) +
                                      ", computed " + crcHex(actual) +
                                      "): the header is corrupt; rebuild the database");
  }
  if (loadLE<std::uint32_t>(p + field::headerBytes) != kPageBytes) {
    return fail(field::headerBytes, "header size must be 4096");
  }
  h.postsX = loadLE<std::uint32_t>(p + field::postsX);
  h.postsZ = loadLE<std::uint32_t>(p + field::postsZ);
  h.blockPosts = loadLE<std::uint32_t>(p + field::blockPosts);
  h.blocksX = loadLE<std::uint32_t>(p + field::blocksX);
  h.blocksZ = loadLE<std::uint32_t>(p + field::blocksZ);
  h.flags = loadLE<std::uint32_t>(p + field::flags);
  h.spacing = loadLE<double>(p + field::spacing);
  h.originEasting = loadLE<double>(p + field::originEasting);
  h.originNorthing = loadLE<double>(p + field::originNorthing);
  h.minElevation = loadLE<float>(p + field::minElevation);
  h.maxElevation = loadLE<float>(p + field::maxElevation);
  h.blockTableOffset = loadLE<std::uint64_t>(p + field::blockTableOffset);
  h.dataOffset = loadLE<std::uint64_t>(p + field::dataOffset);
  h.blockBytes = loadLE<std::uint64_t>(p + field::blockBytes);
  h.fileBytes = loadLE<std::uint64_t>(p + field::fileBytes);
  h.tableCrc = loadLE<std::uint32_t>(p + field::tableCrc);

  if (h.postsX < 2 || h.postsZ < 2 || h.postsX > kMaxPostsPerAxis || h.postsZ > kMaxPostsPerAxis) {
    return fail(h.postsX < 2 || h.postsX > kMaxPostsPerAxis ? field::postsX : field::postsZ, "post counts " + std::to_string(h.postsX) + " x " +
                                   std::to_string(h.postsZ) + " are out of range");
  }
  if (h.blockPosts != kBlockPosts) return fail(field::blockPosts, "block size must be 64 posts");
  if (h.flags != 0) return fail(field::flags, "flags must be 0 in version 1");
  if (!(std::isfinite(h.spacing) && h.spacing > 0) || !std::isfinite(h.originEasting) ||
      !std::isfinite(h.originNorthing)) {
    return fail(field::spacing, "spacing or origin is not a finite number");
  }
  const Header d = makeHeader(h.postsX, h.postsZ, h.spacing, h.originEasting, h.originNorthing);
  if (h.blocksX != d.blocksX || h.blocksZ != d.blocksZ) {
    return fail(field::blocksX, "block counts disagree with post counts");
  }
  if (h.blockTableOffset != d.blockTableOffset || h.dataOffset != d.dataOffset ||
      h.blockBytes != kBlockBytes || h.fileBytes != d.fileBytes) {
    return fail(field::blockTableOffset, "offsets or sizes disagree with the grid dimensions");
  }
  if (fileSize != h.fileBytes) {
    return fail(std::min(fileSize, h.fileBytes),
                "file is " + std::to_string(fileSize) + " bytes but the header says " +
                    std::to_string(h.fileBytes) +
                    (fileSize < h.fileBytes ? ": truncated" : ": trailing bytes") +
                    "; rebuild the database");
  }
  return h;
}

std::int16_t toSnorm(float v) {
  const float c = std::clamp(v, -1.0f, 1.0f);
  return static_cast<std::int16_t>(std::lround(c * 32767.0f));
}

void encodeBlock(const BlockData& b, std::span<std::byte> out) {
  assert(out.size() == kBlockBytes);
  std::memcpy(out.data() + kElevationPlane, b.elevation.data(), sizeof b.elevation);
  std::memcpy(out.data() + kNormalXPlane, b.normalX.data(), sizeof b.normalX);
  std::memcpy(out.data() + kNormalYPlane, b.normalY.data(), sizeof b.normalY);
  std::memcpy(out.data() + kNormalZPlane, b.normalZ.data(), sizeof b.normalZ);
  std::memcpy(out.data() + kMaterialPlane, b.material.data(), sizeof b.material);
}

// ---------------------------------------------------------------- writer


GridWriter::GridWriter(std::string path, std::string tmp, int fd, Header h)
    : path_(std::move(path)), tmp_(std::move(tmp)), fd_(fd), header_(h),
      entries_(h.blockCount()) {}

GridWriter::~GridWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (!finished_) ::unlink(tmp_.c_str());
}

Result<std::unique_ptr<GridWriter>> GridWriter::create(const std::string& path, const Header& h) {
  const std::string tmp = path + ".partial." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Problem{path, 0, std::string("grid writer: cannot create: ") + std::strerror(errno)};
  if (::ftruncate(fd, static_cast<off_t>(h.fileBytes)) != 0) {
    const std::string e = std::strerror(errno);
    ::close(fd);
    ::unlink(tmp.c_str());
    return Problem{path, 0, "grid writer: cannot size file to " + std::to_string(h.fileBytes) +
                                " bytes: " + e + " (is the disk full?)"};
  }
  return std::unique_ptr<GridWriter>(new GridWriter(path, tmp, fd, h));
}

Status GridWriter::writeBlock(std::uint32_t bx, std::uint32_t bz, const BlockData& b) {
  assert(bx < header_.blocksX && bz < header_.blocksZ);
  // One buffer per thread: encodeBlock overwrites all of it, and a fresh
  // zero-filled 44 KiB vector per block cost a memset of the whole file.
  thread_local std::vector<std::byte> buf(kBlockBytes);
  encodeBlock(b, buf);
  BlockEntry& e = entries_[std::size_t(bz) * header_.blocksX + bx];
  e.crc = crc32(buf);
  const auto [mn, mx] = std::minmax_element(b.elevation.begin(), b.elevation.end());
  e.minElevation = *mn;
  e.maxElevation = *mx;
  const std::uint64_t off =
      header_.dataOffset + (std::uint64_t(bz) * header_.blocksX + bx) * kBlockBytes;
  const Status w = pwriteAll(fd_, buf.data(), buf.size(), off);
  // Start writing the block back now, so finish()'s fsync has less to wait for.
  if (w) ::sync_file_range(fd_, static_cast<off_t>(off), static_cast<off_t>(buf.size()), SYNC_FILE_RANGE_WRITE);
  if (!w) return Problem{path_, 0, "grid writer: " + path_ + ": " + w.message()};
  return {};
}

Status GridWriter::writeEncodedBlock(std::uint32_t bx, std::uint32_t bz, std::span<const std::byte> bytes,
                                     const BlockEntry& e) {
  if (bx >= header_.blocksX || bz >= header_.blocksZ || bytes.size() != kBlockBytes || crc32(bytes) != e.crc) {
    return Problem{path_, 0, "grid writer: block (" + std::to_string(bx) + ", " + std::to_string(bz) +
                                 ") is outside the grid, of the wrong size, or does not match its CRC"};
  }
  entries_[std::size_t(bz) * header_.blocksX + bx] = {e.crc, e.minElevation, e.maxElevation, 0};
  const std::uint64_t off = header_.dataOffset + (std::uint64_t(bz) * header_.blocksX + bx) * kBlockBytes;
  if (const Status w = pwriteAll(fd_, bytes.data(), bytes.size(), off); !w) {
    return Problem{path_, 0, "grid writer: " + path_ + ": " + w.message()};
  }
  ::sync_file_range(fd_, static_cast<off_t>(off), static_cast<off_t>(bytes.size()), SYNC_FILE_RANGE_WRITE);
  return {};
}

Status GridWriter::finish() {
  std::vector<std::byte> table(header_.dataOffset - header_.blockTableOffset, std::byte{0});
  float mn = INFINITY, mx = -INFINITY;
  for (std::size_t k = 0; k < entries_.size(); ++k) {
    std::byte* p = table.data() + k * kBlockEntryBytes;
    storeLE(p + 0, entries_[k].crc);
    storeLE(p + 4, entries_[k].minElevation);
    storeLE(p + 8, entries_[k].maxElevation);
    storeLE(p + 12, std::uint32_t{0});
    mn = std::min(mn, entries_[k].minElevation);
    mx = std::max(mx, entries_[k].maxElevation);
  }
  header_.minElevation = mn;
  header_.maxElevation = mx;
  header_.tableCrc = crc32(std::span(table.data(), entries_.size() * kBlockEntryBytes));
  const auto head = encodeHeader(header_);
  // The file's CRC: header page, table (with its zero padding), blocks in order.
  {
    uLong c = crc32(std::span<const std::byte>(head));
    c = crc32_combine(c, crc32(std::span<const std::byte>(table)), static_cast<z_off_t>(table.size()));
    const uLong op = crc32_combine_gen(static_cast<z_off_t>(kBlockBytes));
    for (const BlockEntry& e : entries_) c = crc32_combine_op(c, e.crc, op);
    fileCrc_ = static_cast<std::uint32_t>(c);
  }
  std::string err = pwriteAll(fd_, table.data(), table.size(), header_.blockTableOffset).message();
  if (err.empty()) err = pwriteAll(fd_, head.data(), head.size(), 0).message();
  if (err.empty() && ::fsync(fd_) != 0) err = std::strerror(errno);
  if (err.empty() && ::rename(tmp_.c_str(), path_.c_str()) != 0) err = std::strerror(errno);
  if (!err.empty()) return Problem{path_, 0, "grid writer: " + path_ + ": " + err};
  finished_ = true;
  return {};
}

// ---------------------------------------------------------------- reader

GridFile::~GridFile() {
  if (base_) ::munmap(const_cast<std::byte*>(base_), size_);
}

Result<std::shared_ptr<const GridFile>> GridFile::open(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Problem{path, 0, std::string("grid: cannot open: ") + std::strerror(errno)};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return Problem{path, 0, "grid: not a regular file"};
  }
  const auto size = static_cast<std::size_t>(st.st_size);
  if (size == 0) {
    ::close(fd);
    return Problem{path, 0, at("truncated: the file is empty; rebuild the database")};
  }
  void* m = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, fd, 0);
  ::close(fd);
  if (m == MAP_FAILED) return Problem{path, 0, std::string("grid: mmap failed: ") + std::strerror(errno)};
  std::shared_ptr<GridFile> g(new GridFile());
  g->path_ = path;
  g->base_ = static_cast<const std::byte*>(m);
  g->size_ = size;
  auto h = decodeHeader(std::span(g->base_, std::min<std::size_t>(size, kPageBytes)), path, size);
  if (!h) return h.problems();
  g->header_ = h.value();
  return std::shared_ptr<const GridFile>(std::move(g));
}

const std::byte* GridFile::postAddress(std::uint32_t i, std::uint32_t j, std::uint64_t plane,
                                       std::uint32_t width) const {
  assert(i < header_.postsX && j < header_.postsZ);
  const std::uint32_t bx = i / kBlockPosts, bz = j / kBlockPosts;
  const std::uint32_t lx = i % kBlockPosts, lz = j % kBlockPosts;
  const std::uint64_t block = std::uint64_t(bz) * header_.blocksX + bx;
  if (remote_) [[unlikely]] ensureBlock(block);
  return base_ + header_.dataOffset + block * kBlockBytes + plane +
         std::uint64_t(lz * kBlockPosts + lx) * width;
}

float GridFile::elevation(std::uint32_t i, std::uint32_t j) const {
  return loadLE<float>(postAddress(i, j, kElevationPlane, 4));
}

std::array<float, 3> GridFile::normal(std::uint32_t i, std::uint32_t j) const {
  return {fromSnorm(loadLE<std::int16_t>(postAddress(i, j, kNormalXPlane, 2))),
          fromSnorm(loadLE<std::int16_t>(postAddress(i, j, kNormalYPlane, 2))),
          fromSnorm(loadLE<std::int16_t>(postAddress(i, j, kNormalZPlane, 2)))};
}

std::uint8_t GridFile::material(std::uint32_t i, std::uint32_t j) const {
  return loadLE<std::uint8_t>(postAddress(i, j, kMaterialPlane, 1));
}

std::span<const std::byte> GridFile::blockBytes(std::uint32_t bx, std::uint32_t bz) const {
  assert(bx < header_.blocksX && bz < header_.blocksZ);
  const std::uint64_t block = std::uint64_t(bz) * header_.blocksX + bx;
  if (remote_) [[unlikely]] ensureBlock(block);
  return {base_ + header_.dataOffset + block * kBlockBytes, kBlockBytes};
}

std::span<const std::byte> GridFile::bytes() const {
  if (remote_ && header_.blocksX > 0 && header_.blocksZ > 0) {
    (void)fetchBlocks(0, 0, header_.blocksX - 1, header_.blocksZ - 1);
    // Blocks another thread was fetching meanwhile are waited for.
    for (std::uint64_t b = 0; b < header_.blockCount(); ++b) ensureBlock(b);
  }
  return {base_, size_};
}

BlockEntry GridFile::blockEntry(std::uint32_t bx, std::uint32_t bz) const {
  const std::byte* p = base_ + header_.blockTableOffset +
                       (std::uint64_t(bz) * header_.blocksX + bx) * kBlockEntryBytes;
  return {loadLE<std::uint32_t>(p), loadLE<float>(p + 4), loadLE<float>(p + 8),
          loadLE<std::uint32_t>(p + 12)};
}

// ---------------------------------------------------------------- validate

namespace {

/// The grid file's problems, at most `kPerKind` of each kind listed.
class Report {
 public:
  explicit Report(std::string file) : file_(std::move(file)) {}
  void add(const std::string& kind, std::uint64_t off, const std::string& msg) { capped_.add(kind, {file_, off, msg}); }
  Status take() { return capped_.take("grid"); }

 private:
  static constexpr int kPerKind = 20;
  std::string file_;
  CappedProblems<> capped_{kPerKind};
};

constexpr float kMinPlausible = -12000.0f;  // below the Challenger Deep
constexpr float kMaxPlausible = 9000.0f;    // above Everest

void checkBlockContents(const GridFile& g, std::uint32_t bx, std::uint32_t bz,
                        std::uint64_t blockOff, Report& r) {
  const auto bytes = g.blockBytes(bx, bz);
  const BlockEntry e = g.blockEntry(bx, bz);
  float mn = INFINITY, mx = -INFINITY;
  const std::string where = "block (" + std::to_string(bx) + "," + std::to_string(bz) + ")";
  for (std::uint32_t k = 0; k < kPostsPerBlock; ++k) {
    const float z = loadLE<float>(bytes.data() + kElevationPlane + 4 * k);
    if (!std::isfinite(z)) {
      r.add("nan", blockOff + kElevationPlane + 4 * k,
            "grid: " + where + " post " + std::to_string(k) + " elevation is NaN or infinite");
      continue;
    }
    if (z < kMinPlausible || z > kMaxPlausible) {
      r.add("range", blockOff + kElevationPlane + 4 * k,
            "grid: " + where + " elevation " + std::to_string(z) + " m is implausible");
    }
    mn = std::min(mn, z);
    mx = std::max(mx, z);
    const float nx = fromSnorm(loadLE<std::int16_t>(bytes.data() + kNormalXPlane + 2 * k));
    const float ny = fromSnorm(loadLE<std::int16_t>(bytes.data() + kNormalYPlane + 2 * k));
    const float nz = fromSnorm(loadLE<std::int16_t>(bytes.data() + kNormalZPlane + 2 * k));
    const float len = std::sqrt(nx * nx + ny * ny + nz * nz);
    if (std::fabs(len - 1.0f) > 1e-3f || ny <= 0.0f) {
      r.add("normal", blockOff + kNormalXPlane + 2 * k,
            "grid: " + where + " post " + std::to_string(k) + " normal (" + std::to_string(nx) +
                "," + std::to_string(ny) + "," + std::to_string(nz) +
                ") is not a unit upward vector");
    }
  }
  if (mn != e.minElevation || mx != e.maxElevation) {
    r.add("minmax", g.header().blockTableOffset, "grid: " + where +
                                                    " min/max in the block table disagree with its posts");
  }
}

/// Edge padding (FORMAT.md §4.6): a post of an edge block beyond the grid
/// repeats, byte for byte, the nearest edge post, which lies in the same
/// block. Any difference is reported at the differing plane's bytes.
void checkEdgePadding(const GridFile& g, std::uint32_t bx, std::uint32_t bz, std::uint64_t blockOff, Report& r) {
  const Header& h = g.header();
  const std::uint32_t i0 = bx * kBlockPosts, j0 = bz * kBlockPosts;
  if (i0 + kBlockPosts <= h.postsX && j0 + kBlockPosts <= h.postsZ) return;
  const auto bytes = g.blockBytes(bx, bz);
  struct Plane {
    std::uint64_t offset;
    std::uint32_t width;
    const char* name;
  };
  static constexpr Plane kPlanes[] = {{kElevationPlane, 4, "elevation"}, {kNormalXPlane, 2, "normal x"},
                                      {kNormalYPlane, 2, "normal y"},    {kNormalZPlane, 2, "normal z"},
                                      {kMaterialPlane, 1, "material"}};
  for (std::uint32_t lz = 0; lz < kBlockPosts; ++lz) {
    for (std::uint32_t lx = 0; lx < kBlockPosts; ++lx) {
      const std::uint32_t i = i0 + lx, j = j0 + lz;
      if (i < h.postsX && j < h.postsZ) continue;
      const std::uint32_t si = std::min(i, h.postsX - 1), sj = std::min(j, h.postsZ - 1);
      const std::uint32_t k = lz * kBlockPosts + lx, sk = (sj - j0) * kBlockPosts + (si - i0);
      for (const Plane& p : kPlanes) {
        if (std::memcmp(bytes.data() + p.offset + std::uint64_t(p.width) * k,
                        bytes.data() + p.offset + std::uint64_t(p.width) * sk, p.width) == 0) {
          continue;
        }
        r.add("edge", blockOff + p.offset + std::uint64_t(p.width) * k,
              "grid: block (" + std::to_string(bx) + "," + std::to_string(bz) + ") post " + std::to_string(k) +
                  " lies beyond the grid at (" + std::to_string(i) + "," + std::to_string(j) + "), but its " +
                  p.name + " differs from edge post (" + std::to_string(si) + "," + std::to_string(sj) +
                  "), which edge padding must repeat");
      }
    }
  }
}

}  // namespace

Status validateGrid(const std::string& path, const Work& work) {
  auto opened = GridFile::open(path);
  if (!opened) return opened.problems();
  const GridFile& g = *opened.value();
  const Header& h = g.header();
  const auto all = g.bytes();
  Report r(path);
  std::uint64_t nz = 0;
  if (!allZero(all.subspan(kHeaderFieldBytes, kPageBytes - kHeaderFieldBytes), nz)) {
    r.add("padding", kHeaderFieldBytes + nz, "grid: header padding is not zero");
  }
  if (!allZero(all.subspan(field::reserved, field::headerCrc - field::reserved), nz)) {
    r.add("reserved", field::reserved + nz, "grid: header reserved bytes 108..123 are not zero");
  }
  const std::uint64_t tableBytes = h.blockCount() * kBlockEntryBytes;
  const auto table = all.subspan(h.blockTableOffset, tableBytes);
  const std::uint32_t tcrc = crc32(table);
  if (tcrc != h.tableCrc) {
    r.add("table", h.blockTableOffset, "grid: block table checksum mismatch (stored " +
                                           crcHex(h.tableCrc) + ", computed " + crcHex(tcrc) + ")");
  }
  const auto tablePad = all.subspan(h.blockTableOffset + tableBytes,
                                    h.dataOffset - h.blockTableOffset - tableBytes);
  if (!allZero(tablePad, nz)) {
    r.add("padding", h.blockTableOffset + tableBytes + nz, "grid: block table padding is not zero");
  }
  float mn = INFINITY, mx = -INFINITY;
  for (std::uint32_t bz = 0; bz < h.blocksZ; ++bz) {
    work.report(double(bz) / h.blocksZ, "checking grid");
    if (work.cancelled()) {
      auto out = r.take();
      out.add({path, 0, kCancelledMessage});
      return out;
    }
    for (std::uint32_t bx = 0; bx < h.blocksX; ++bx) {
      const std::uint64_t off = h.dataOffset + (std::uint64_t(bz) * h.blocksX + bx) * kBlockBytes;
      const BlockEntry e = g.blockEntry(bx, bz);
      const std::uint32_t c = crc32(g.blockBytes(bx, bz));
      if (c != e.crc) {
        r.add("crc", off, "grid: block (" + std::to_string(bx) + "," + std::to_string(bz) +
                              ") checksum mismatch (stored " + crcHex(e.crc) + ", computed " +
                              crcHex(c) + "): the block is corrupt");
      }
      if (e.reserved != 0) {
        r.add("reserved", h.blockTableOffset + (std::uint64_t(bz) * h.blocksX + bx) * kBlockEntryBytes + 12,
              "grid: block table reserved field is not zero");
      }
      checkBlockContents(g, bx, bz, off, r);
      checkEdgePadding(g, bx, bz, off, r);
      mn = std::min(mn, e.minElevation);
      mx = std::max(mx, e.maxElevation);
    }
  }
  if (mn != h.minElevation || mx != h.maxElevation) {
    r.add("minmax", field::minElevation, "grid: header min/max elevation disagree with the block table");
  }
  work.report(1.0, "checking grid");
  return r.take();
}

}  // namespace sandtable::grid
