// The pack reader (pack.h PackReader): the mapped index, one pread per
// record, records checked and decoded into reused buffers.
#include <cassert>

#include "pack_internal.h"
#include "sandtable/base/range_source.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::pack {
using namespace detail;

struct PackReader::State {
  std::string packPath, indexPath;
  MappedFile index;
  std::vector<std::byte> indexOwned;  ///< the index's bytes when they came from elsewhere (openRemote)
  FdGuard pack;
  std::shared_ptr<const RangeSource> remote;  ///< the pack's bytes when not a local file
  IndexHeader header;
  std::span<const std::byte> indexBytes() const {
    return indexOwned.empty() ? index.bytes() : std::span<const std::byte>(indexOwned);
  }
  Source source() const { return {pack.fd, remote.get()}; }
};

PackReader::PackReader(std::unique_ptr<State> s) : state_(std::move(s)) {}
PackReader::~PackReader() = default;

Result<std::shared_ptr<const PackReader>> PackReader::open(const std::string& directory) {
  auto s = std::make_unique<State>();
  s->packPath = join(directory, kPackFileName);
  s->indexPath = join(directory, kIndexFileName);
  if (const Status mapped = s->index.open(s->indexPath); !mapped) {
    return Problem{s->indexPath, 0, "pack index: " + mapped.message()};
  }
  auto h = decodeIndexHeader(s->index.bytes(), s->indexPath, s->index.size());
  if (!h) return h.problems();
  s->header = h.value();
  if (const Status table = checkTableCrc(s->header, s->index.bytes(), s->indexPath); !table) {
    return table.problems();
  }
  Status pack;
  s->pack.fd = openPack(s->packPath, &s->header, pack);
  if (!pack) return pack.problems();
  return std::shared_ptr<const PackReader>(new PackReader(std::move(s)));
}

Result<std::shared_ptr<const PackReader>> PackReader::openRemote(std::vector<std::byte> index, const std::string& indexName,
                                                                std::shared_ptr<const RangeSource> pack) {
  auto s = std::make_unique<State>();
  s->indexPath = indexName;
  s->packPath = pack->name();
  s->indexOwned = std::move(index);
  if (s->indexOwned.empty()) return Problem{indexName, 0, "pack index: empty"};
  auto h = decodeIndexHeader(s->indexOwned, s->indexPath, s->indexOwned.size());
  if (!h) return h.problems();
  s->header = h.value();
  if (const Status table = checkTableCrc(s->header, s->indexOwned, s->indexPath); !table) return table.problems();
  std::vector<std::byte> head(std::size_t(std::min<std::uint64_t>(pack->size(), kPackHeaderBytes)));
  Status checked;
  // As for a record: a header that fails its checks is read once more past
  // any cache (refresh) before it is an error.
  for (int attempt = 0; attempt < 2; ++attempt) {
    if (attempt > 0) pack->refresh(0, head.size());
    if (const Status read = pack->read(0, head); !read) {
      return Problem{s->packPath, 0, "pack: cannot read the header: " + read.message()};
    }
    checked = {};
    checkPackHead(head, pack->size(), s->packPath, &s->header, checked);
    if (checked) break;
  }
  if (!checked) return checked.problems();
  s->remote = std::move(pack);
  return std::shared_ptr<const PackReader>(new PackReader(std::move(s)));
}

const IndexHeader& PackReader::header() const { return state_->header; }
const RangeSource* PackReader::remote() const { return state_->remote.get(); }
int PackReader::packFd() const { return state_->pack.fd; }
std::string PackReader::packPath() const { return state_->packPath; }
std::string PackReader::indexPath() const { return state_->indexPath; }

Entry PackReader::entry(std::uint32_t kx, std::uint32_t kz) const {
  const IndexHeader& h = state_->header;
  assert(kx < h.modulesX && kz < h.modulesZ);
  return decodeEntry(state_->indexBytes().subspan(entryOffset(h, kx, kz), h.entryBytes()), h.version);
}

std::uint32_t PackReader::coarseLevel() const { return state_->header.coarseLevel; }

Result<std::vector<std::byte>> PackReader::unpack(std::uint32_t kx, std::uint32_t kz,
                                                  std::span<const std::byte> record, Part part) const {
  const Entry e = entry(kx, kz);
  if (const Status checked = checkEntry(state_->header, e, kx, kz, state_->indexPath); !checked) {
    return checked.problems();
  }
  if (part == Part::fine && partLevels(state_->header, Part::fine) == 0) {
    return Problem{state_->indexPath, 0, "pack: " + moduleName(kx, kz) + " has no fine record (version " +
                                             str(state_->header.version) + ", coarse level " +
                                             str(state_->header.coarseLevel) + ")"};
  }
  return unpackRecord(extentOf(e, part), kx, kz, part, record, state_->packPath, true);
}

namespace {

/// One pread of a record of (kx, kz), checked and decompressed.
Result<std::vector<std::byte>> readRecord(const IndexHeader& h, const Entry& e, std::uint32_t kx,
                                          std::uint32_t kz, Part part, const Source& src, const std::string& packPath,
                                          const std::string& indexPath, bool checkRawCrc) {
  if (const Status checked = checkEntry(h, e, kx, kz, indexPath); !checked) return checked.problems();
  if (partLevels(h, part) == 0) {
    return Problem{indexPath, 0, "pack: " + moduleName(kx, kz) + " has no fine record (version " + str(h.version) +
                                     ", coarse level " + str(h.coarseLevel) + ")"};
  }
  const Extent x = extentOf(e, part);
  thread_local std::vector<std::byte> record;  // reused: no allocation per read
  record.resize(x.compressedBytes);
  if (const Status read = src.read(record.data(), record.size(), x.offset); !read) {
    return Problem{packPath, x.offset,
                   "pack: cannot read the record of " + partName(kx, kz, part) + ": " + read.message()};
  }
  return unpackRecord(x, kx, kz, part, record, packPath, checkRawCrc);
}

/// Reads one record of (kx, kz) and decodes it into `out` (the part's
/// levels only), reusing per-thread buffers and out's capacity.
Status readPartInto(const IndexHeader& h, const Extent& x, std::uint32_t kx, std::uint32_t kz, Part part,
                    const Source& src, const std::string& packPath, module::Module& out) {
  thread_local std::vector<std::byte> record, raw;  // reused: no allocation per read
  record.resize(x.compressedBytes);
  // The name only on failure: "fine module (kx,kz)" is too long for the
  // small-string buffer, and a sound read must not allocate.
  auto fail = [&](const std::string& msg) {
    return Status(Problem{packPath, x.offset, "pack: " + partName(kx, kz, part) + msg});
  };
  if (const Status read = src.read(record.data(), record.size(), x.offset); !read) {
    return fail(": cannot read the record: " + read.message());
  }
  if (src.remote && crc32(record) != x.compressedCrc) {
    // Altered or cut on the way (a proxy, a torn response): fetched again
    // once, past the remote's cache, before it counts as corrupt.
    src.remote->refresh(x.offset, record.size());
    if (const Status again = src.read(record.data(), record.size(), x.offset); !again) {
      return fail(": cannot read the record: " + again.message());
    }
  }
  if (const std::uint32_t c = crc32(record); c != x.compressedCrc) {
    return fail(" record checksum mismatch (stored " + crcHex(x.compressedCrc) + ", computed " + crcHex(c) +
                "): the pack is corrupt; rebuild the database");
  }
  if (const Status z = decompress(record, x.rawBytes, raw); !z) {
    return fail(" record does not decompress: " + z.message());
  }
  if (const Status d = module::decodeInto(raw, packPath, 0, out); !d) {
    const Problem& p = d.problems().front();
    return fail(", decompressed byte " + str(p.offset) + ": " + p.message);
  }
  if (const std::string bad = checkDecoded(h, out, kx, kz, part); !bad.empty()) return fail(bad);
  return {};
}

/// Moves the levels of a decoded part into `out` at level `first` by
/// swapping vectors, so both keep their capacity from read to read.
void placeLevels(module::Module& part, std::uint32_t first, std::uint32_t levels, module::Module& out) {
  out.kx = part.kx;
  out.kz = part.kz;
  if (out.levels.size() != levels) out.levels.resize(levels);
  for (std::size_t l = 0; l < part.levels.size(); ++l) std::swap(part.levels[l], out.levels[first + l]);
  std::swap(part.objects, out.objects);  // the records' lists are the same (validate compares them)
  std::swap(part.scattering, out.scattering);
}

}  // namespace

Result<std::vector<std::byte>> PackReader::readRaw(std::uint32_t kx, std::uint32_t kz, Part part) const {
  const State& s = *state_;
  return readRecord(s.header, entry(kx, kz), kx, kz, part, s.source(), s.packPath, s.indexPath, true);
}

Result<module::Module> PackReader::read(std::uint32_t kx, std::uint32_t kz) const {
  module::Module m;
  if (Status r = readInto(kx, kz, m); !r) return r.problems();
  return m;
}

Status PackReader::readCoarseInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const {
  const State& s = *state_;
  const Entry e = entry(kx, kz);
  if (Status checked = checkEntry(s.header, e, kx, kz, s.indexPath); !checked) return checked.problems().front();
  if (s.header.version < kVersion2) {
    // The whole module decodes straight into `out`.
    return readPartInto(s.header, e.coarse(), kx, kz, Part::coarse, s.source(), s.packPath, out);
  }
  thread_local module::Module part;  // its vectors trade places with out's: no allocation once warm
  if (Status r = readPartInto(s.header, e.coarse(), kx, kz, Part::coarse, s.source(), s.packPath, part); !r) return r;
  placeLevels(part, s.header.coarseLevel, s.header.levels, out);
  return {};
}

Status PackReader::readFineInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const {
  const State& s = *state_;
  if (partLevels(s.header, Part::fine) == 0 || s.header.version < kVersion2) {
    if (out.levels.size() != s.header.levels) out.levels.resize(s.header.levels);
    return {};
  }
  const Entry e = entry(kx, kz);
  if (Status checked = checkEntry(s.header, e, kx, kz, s.indexPath); !checked) return checked.problems().front();
  thread_local module::Module part;
  if (Status r = readPartInto(s.header, e.fine, kx, kz, Part::fine, s.source(), s.packPath, part); !r) return r;
  placeLevels(part, 0, s.header.levels, out);
  return {};
}

Status PackReader::readInto(std::uint32_t kx, std::uint32_t kz, module::Module& out) const {
  if (Status c = readCoarseInto(kx, kz, out); !c) return c;
  return readFineInto(kx, kz, out);
}

}  // namespace sandtable::pack
