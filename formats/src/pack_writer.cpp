// The pack writer (pack.h PackWriter): records compressed on the callers'
// threads, appended in order (v1) or spilled and copied in the index's
// order at finish (v2); the pack and then the index renamed into place.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <mutex>

#include "pack_internal.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::pack {
using namespace detail;

struct PackWriter::State {
  std::string directory, packPath, indexPath, packTmp, indexTmp;
  std::string spillTmp;  ///< v2: records in append order, copied into the pack by finish()
  int fd = -1;
  int spillFd = -1;
  std::uint64_t spillEnd = 0;
  PackLayout layout;
  int level = kDefaultZstdLevel;
  IndexHeader header;
  mutable std::mutex mutex;
  std::vector<Entry> entries;            ///< row-major; compressedBytes == 0 until added
  std::uint64_t end = kPackHeaderBytes;  ///< bytes written to the pack so far
  std::uint32_t crc = 0;                 ///< CRC-32 of the pack bytes so far
  Status failed;                         ///< first write error; poisons the writer
  bool finished = false;
  std::uint32_t indexCrc = 0;
  std::uint64_t indexBytes = 0;

  ~State() {
    if (fd >= 0) ::close(fd);
    if (spillFd >= 0) {
      ::close(spillFd);
      ::unlink(spillTmp.c_str());
    }
    if (!finished) {
      ::unlink(packTmp.c_str());
      ::unlink(indexTmp.c_str());
    }
  }
};

PackWriter::PackWriter(std::unique_ptr<State> s) : state_(std::move(s)) {}
PackWriter::~PackWriter() = default;

Result<std::unique_ptr<PackWriter>> PackWriter::create(const std::string& directory,
                                                       const IndexHeader& header, int zstdLevel,
                                                       const PackLayout& layout) {
  auto fail = [&](const std::string& msg) {
    return Result<std::unique_ptr<PackWriter>>(Problem{directory, 0, "pack writer: " + msg});
  };
  if (header.modulesX < 1 || header.modulesZ < 1 || header.modulesX > kMaxModulesPerAxis ||
      header.modulesZ > kMaxModulesPerAxis) {
    return fail("module counts " + str(header.modulesX) + " x " + str(header.modulesZ) +
                " are out of range (1 to " + str(kMaxModulesPerAxis) + " each)");
  }
  if (header.levels < 1 || header.levels > module::kMaxLevels) {
    return fail("level count " + str(header.levels) + " is out of range (1 to " +
                str(module::kMaxLevels) + ")");
  }
  if (header.moduleSquares < 1 || header.moduleSquares > module::kMaxSquaresPerAxis) {
    return fail("module squares " + str(header.moduleSquares) + " is out of range");
  }
  if (!(std::isfinite(header.moduleSize) && header.moduleSize > 0)) {
    return fail("module size is not a finite positive number");
  }
  if (zstdLevel < ZSTD_minCLevel() || zstdLevel > ZSTD_maxCLevel()) {
    return fail("zstd level " + std::to_string(zstdLevel) + " is out of range (" +
                std::to_string(ZSTD_minCLevel()) + " to " + std::to_string(ZSTD_maxCLevel()) + ")");
  }
  if (layout.version < kVersion1 || layout.version > kVersion) {
    return fail("version " + str(layout.version) + " is not supported (1 to " + str(kVersion) + ")");
  }
  if (layout.version >= kVersion2 && layout.coarseLevel >= header.levels) {
    return fail("coarse level " + str(layout.coarseLevel) + " is out of range (0 to " + str(header.levels - 1) +
                " for " + str(header.levels) + " levels)");
  }
  if (static_cast<std::uint32_t>(layout.order) >= kPackOrderCount) return fail("unknown record order");
  if (layout.encode.version < module::kVersion || layout.encode.version > module::kNewestVersion) {
    return fail("module version " + str(layout.encode.version) + " is not 1, 2 or 3");
  }
  auto s = std::make_unique<State>();
  s->directory = directory;
  s->layout = layout;
  s->packPath = join(directory, kPackFileName);
  s->indexPath = join(directory, kIndexFileName);
  const std::string pid = std::to_string(::getpid());
  s->packTmp = s->packPath + ".tmp." + pid;
  s->indexTmp = s->indexPath + ".tmp." + pid;
  s->level = zstdLevel;
  s->header = header;
  s->header.version = layout.version;
  s->header.coarseLevel = layout.version >= kVersion2 ? layout.coarseLevel : 0;
  s->header.order = layout.version >= kVersion2 ? layout.order : PackOrder::rowMajor;
  s->entries.resize(static_cast<std::size_t>(header.entryCount()));
  s->fd = ::open(s->packTmp.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (s->fd < 0) return fail("cannot create " + s->packTmp + ": " + std::strerror(errno));
  if (layout.version >= kVersion2) {
    s->spillTmp = s->packPath + ".spill.tmp." + pid;
    s->spillFd = ::open(s->spillTmp.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (s->spillFd < 0) return fail("cannot create " + s->spillTmp + ": " + std::strerror(errno));
  }
  const auto head = encodePackHeader(layout.version);
  if (const Status w = pwriteAll(s->fd, head.data(), head.size(), 0); !w) {
    return fail("cannot write " + s->packTmp + ": " + w.message());
  }
  s->crc = crc32(head);
  s->header.packHeaderCrc = s->crc;
  return std::unique_ptr<PackWriter>(new PackWriter(std::move(s)));
}

Status PackWriter::add(const module::Module& m) {
  auto r = compress(m);
  if (!r) return Status(r.problems());
  return append(std::move(r.value()));
}

namespace {

/// Checks, encodes and compresses one record's module (the whole module,
/// or the levels of one v2 part); fills the extent's sizes and CRCs.
std::string compressPart(const module::Module& m, int level, const module::EncodeOptions& encode,
                         const std::string& name, std::vector<std::byte>& out, Extent& x) {
  if (const Status e = module::checkEncodable(m); !e) return name + ": " + e.message();
  if (const std::uint64_t n = module::encodedBytes(m); n > kMaxModuleBytes) {
    return name + " encodes to " + str(n) + " bytes, more than the " + str(kMaxModuleBytes) + " allowed";
  }
  const std::vector<std::byte> raw = module::encode(m, encode);
  // Decoding our own encoding checks everything checkEncodable leaves out
  // (index ranges, group order, squares), so a pack never holds a module
  // that its reader would refuse.
  if (auto back = module::decode(raw, "encoded module"); !back) {
    const Problem& p = back.problems().front();
    return name + " is malformed: " + p.message + " (byte " + str(p.offset) + " of its encoding)";
  }
  out = sandtable::pack::compress(raw, level);
  if (out.empty()) return name + ": zstd compression failed (out of memory?)";
  if (out.size() > kMaxModuleBytes) return name + " compresses to more than the allowed size";
  x.compressedBytes = static_cast<std::uint32_t>(out.size());
  x.rawBytes = static_cast<std::uint32_t>(raw.size());
  x.compressedCrc = crc32(out);
  x.rawCrc = crc32(raw);
  return "";
}

}  // namespace

Result<PackWriter::Record> PackWriter::compress(const module::Module& m) const {
  const State& s = *state_;
  const std::string name = "pack writer: " + moduleName(m.kx, m.kz);
  // Problems name the module, not a file: the pack is not in place yet.
  auto fail = [](const std::string& msg) { return Problem{"", 0, msg}; };
  if (m.kx >= s.header.modulesX || m.kz >= s.header.modulesZ) {
    return fail(name + " is outside the pack's " + str(s.header.modulesX) + " x " +
                str(s.header.modulesZ) + " modules");
  }
  if (m.levels.size() != s.header.levels) {
    return fail(name + " has " + str(m.levels.size()) + " levels, the pack holds " +
                str(s.header.levels));
  }
  Record r;
  Entry& e = r.entry;
  e.kx = m.kx;
  e.kz = m.kz;
  if (s.header.version < kVersion2) {
    Extent x;
    if (std::string bad = compressPart(m, s.level, s.layout.encode, name, r.bytes, x); !bad.empty()) return fail(bad);
    e.compressedBytes = x.compressedBytes;
    e.rawBytes = x.rawBytes;
    e.compressedCrc = x.compressedCrc;
    e.rawCrc = x.rawCrc;
    return r;
  }
  // v2: each part is a module of its own levels (module::encode knows no
  // level numbers; the index's coarseLevel gives them back).
  const auto split = m.levels.begin() + std::ptrdiff_t(s.header.coarseLevel);
  // Both records carry every object, each with its own levels' elevations.
  const module::Module coarse{m.kx, m.kz, std::vector<module::Level>(split, m.levels.end()), m.objects, m.scattering};
  Extent c;
  module::EncodeOptions coarseEncode = s.layout.encode;
  if (s.header.coarseLevel > 0) coarseEncode.regenerateRules = false;  // the hole path decodes it (module.h)
  if (std::string bad = compressPart(coarse, s.level, coarseEncode, name + " (coarse record)", r.bytes, c); !bad.empty()) {
    return fail(bad);
  }
  e.compressedBytes = c.compressedBytes;
  e.rawBytes = c.rawBytes;
  e.compressedCrc = c.compressedCrc;
  e.rawCrc = c.rawCrc;
  if (s.header.coarseLevel > 0) {
    const module::Module fine{m.kx, m.kz, std::vector<module::Level>(m.levels.begin(), split), m.objects, m.scattering};
    if (std::string bad = compressPart(fine, s.level, s.layout.encode, name + " (fine record)", r.fineBytes, e.fine); !bad.empty()) {
      return fail(bad);
    }
  }
  return r;
}

Status PackWriter::append(Record r) {
  State& s = *state_;
  Entry& e = r.entry;
  auto fail = [](const std::string& msg) { return Status(Problem{"", 0, msg}); };
  const std::lock_guard lock(s.mutex);
  if (s.finished) return fail("pack writer: add() after finish()");
  if (!s.failed) return s.failed;
  const bool v2 = s.header.version >= kVersion2;
  const bool needFine = v2 && s.header.coarseLevel > 0;
  if (e.kx >= s.header.modulesX || e.kz >= s.header.modulesZ || e.compressedBytes != r.bytes.size() ||
      e.fine.compressedBytes != r.fineBytes.size() || (needFine != !r.fineBytes.empty())) {
    return fail("pack writer: append() of a record that compress() did not make");
  }
  Entry& slot = s.entries[std::size_t(e.kz) * s.header.modulesX + e.kx];
  if (slot.compressedBytes != 0) return fail("pack writer: " + moduleName(e.kx, e.kz) + " was added twice");
  if (!v2) {
    e.offset = s.end;
    if (const Status w = pwriteAll(s.fd, r.bytes.data(), r.bytes.size(), s.end); !w) {
      s.failed = fail("pack writer: cannot write " + s.packTmp + ": " + w.message() + " (is the disk full?)");
      return s.failed;
    }
    s.end += r.bytes.size();
    s.crc = crc32(r.bytes, s.crc);
    slot = e;
    return {};
  }
  // v2: spill both records; until finish() the offsets are in the spill file.
  e.offset = s.spillEnd;
  e.fine.offset = r.fineBytes.empty() ? 0 : s.spillEnd + r.bytes.size();  // no fine record: all zero
  for (const auto* bytes : {&r.bytes, &r.fineBytes}) {
    if (const Status w = pwriteAll(s.spillFd, bytes->data(), bytes->size(), s.spillEnd); !w) {
      s.failed = fail("pack writer: cannot write " + s.spillTmp + ": " + w.message() + " (is the disk full?)");
      return s.failed;
    }
    s.spillEnd += bytes->size();
  }
  slot = e;
  return {};
}

namespace {

/// Copies the records of `entries` (offsets in the spill file) into the
/// pack at `end` in the order given, coarse records of every module first,
/// then fine records, and points each entry at its place in the pack.
/// Extends the pack's running CRC. Returns the error, or "".
std::string copySpilled(int spillFd, int packFd, std::vector<Entry>& entries, const std::vector<std::uint32_t>& order,
                        std::uint64_t& end, std::uint32_t& crc) {
  std::vector<std::byte> buf;
  constexpr std::size_t kBatch = 4u << 20;  // write in batches of a few MB: few syscalls
  std::vector<std::byte> out;
  out.reserve(kBatch + kMaxModuleBytes / 64);
  std::uint64_t outAt = end;
  auto flush = [&]() -> std::string {
    if (out.empty()) return "";
    if (const Status w = pwriteAll(packFd, out.data(), out.size(), outAt); !w) return w.message();
    crc = crc32(out, crc);
    outAt += out.size();
    out.clear();
    return "";
  };
  for (const Part part : {Part::coarse, Part::fine}) {
    for (const std::uint32_t k : order) {
      Entry& e = entries[k];
      std::uint64_t& offset = part == Part::fine ? e.fine.offset : e.offset;
      const std::uint32_t n = part == Part::fine ? e.fine.compressedBytes : e.compressedBytes;
      if (n == 0) continue;
      buf.resize(n);
      if (const Status r = preadAll(spillFd, buf.data(), n, offset); !r) return "cannot read the spill file: " + r.message();
      offset = end;
      end += n;
      out.insert(out.end(), buf.begin(), buf.end());
      if (out.size() >= kBatch) {
        if (std::string bad = flush(); !bad.empty()) return bad;
      }
    }
  }
  return flush();
}

}  // namespace

Status PackWriter::finish() {
  State& s = *state_;
  auto fail = [](const std::string& msg) { return Status(Problem{"", 0, msg}); };
  const std::lock_guard lock(s.mutex);
  if (s.finished) return fail("pack writer: finish() was already called");
  if (!s.failed) return s.failed;
  std::uint64_t missing = 0;
  std::size_t firstMissing = 0;
  for (std::size_t k = 0; k < s.entries.size(); ++k) {
    if (s.entries[k].compressedBytes == 0 && missing++ == 0) firstMissing = k;
  }
  if (missing > 0) {
    const auto kx = static_cast<std::uint32_t>(firstMissing % s.header.modulesX);
    const auto kz = static_cast<std::uint32_t>(firstMissing / s.header.modulesX);
    return fail("pack writer: " + str(missing) + " of " + str(s.entries.size()) +
                " modules were not added (the first is " + moduleName(kx, kz) + ")");
  }
  auto failWith = [&](const std::string& what) {
    s.failed = fail("pack writer: " + what);
    return s.failed;
  };
  if (s.spillFd >= 0) {
    const auto order = moduleOrder(s.header.modulesX, s.header.modulesZ, s.header.order);
    if (std::string bad = copySpilled(s.spillFd, s.fd, s.entries, order, s.end, s.crc); !bad.empty()) {
      return failWith("cannot write " + s.packTmp + ": " + bad + " (is the disk full?)");
    }
    ::close(s.spillFd);
    s.spillFd = -1;
    ::unlink(s.spillTmp.c_str());
  }
  std::vector<std::byte> index(static_cast<std::size_t>(s.header.indexBytes()), std::byte{0});
  const std::uint32_t entryBytes = s.header.entryBytes();
  for (std::size_t k = 0; k < s.entries.size(); ++k) {
    encodeEntry(s.entries[k], std::span(index).subspan(kIndexHeaderBytes + std::size_t(entryBytes) * k),
                s.header.version);
  }
  s.header.packBytes = s.end;
  s.header.tableCrc = crc32(std::span(index).subspan(kIndexHeaderBytes));
  const auto head = encodeIndexHeader(s.header);
  std::copy(head.begin(), head.end(), index.begin());

  if (::fsync(s.fd) != 0)
    return failWith("cannot flush " + s.packTmp + ": " + std::strerror(errno));
  FdGuard idx{::open(s.indexTmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
  if (idx.fd < 0) return failWith("cannot create " + s.indexTmp + ": " + std::strerror(errno));
  std::string err = pwriteAll(idx.fd, index.data(), index.size(), 0).message();
  if (err.empty() && ::fsync(idx.fd) != 0) err = std::strerror(errno);
  if (!err.empty()) return failWith("cannot write " + s.indexTmp + ": " + err);
  // The pack first, the index last: an index under its final name always
  // describes the pack beside it.
  if (::rename(s.packTmp.c_str(), s.packPath.c_str()) != 0) {
    return failWith("cannot rename " + s.packTmp + ": " + std::strerror(errno));
  }
  if (::rename(s.indexTmp.c_str(), s.indexPath.c_str()) != 0) {
    const std::string e = std::strerror(errno);
    ::unlink(s.packPath.c_str());
    return failWith("cannot rename " + s.indexTmp + ": " + e);
  }
  FdGuard dir{::open(s.directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (dir.fd >= 0) ::fsync(dir.fd);
  s.finished = true;
  s.indexCrc = crc32(index);
  s.indexBytes = index.size();
  return {};
}

SizeStats PackWriter::stats() const {
  const State& s = *state_;
  const std::lock_guard lock(s.mutex);
  SizeStats st;
  std::vector<std::uint32_t> sizes;
  sizes.reserve(s.entries.size());
  for (const Entry& e : s.entries) {
    if (e.compressedBytes == 0) continue;
    sizes.push_back(static_cast<std::uint32_t>(e.storedBytes()));  // both records: at most 2 x 64 MiB
    st.totalCompressed += e.storedBytes();
    st.totalRaw += e.storedRawBytes();
  }
  st.count = sizes.size();
  if (sizes.empty()) return st;
  std::sort(sizes.begin(), sizes.end());
  const std::size_t n = sizes.size();
  st.minCompressed = sizes.front();
  st.maxCompressed = sizes.back();
  st.medianCompressed = sizes[(n + 1) / 2 - 1];
  st.p95Compressed = sizes[(95 * n + 99) / 100 - 1];
  return st;
}

std::uint32_t PackWriter::packCrc() const {
  const std::lock_guard lock(state_->mutex);
  return state_->crc;
}
std::uint32_t PackWriter::indexCrc() const {
  const std::lock_guard lock(state_->mutex);
  return state_->indexCrc;
}
std::uint64_t PackWriter::packBytes() const {
  const std::lock_guard lock(state_->mutex);
  return state_->end;
}
std::uint64_t PackWriter::indexBytes() const {
  const std::lock_guard lock(state_->mutex);
  return state_->indexBytes;
}

}  // namespace sandtable::pack
