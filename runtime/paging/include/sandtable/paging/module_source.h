#pragma once
// Where the pager's load modules come from (docs/PAGER.md, "Module
// sources"). The pager asks a source for a decoded module, and the source
// says which generation of the module it gave. The pack is one source
// (PackSource, every module at generation 0, never changing); the
// dynamic-terrain overlay will be another, whose modules are replaced by
// newer generations while the viewer flies: the pager polls changes() on
// every update and reloads each changed module in its window, keeping the
// older generation drawn until the newer one is published.
//
// Thread contract: every member is const and may be called from any
// thread at once: the four loader threads read, the main thread polls
// changes() and changedSince(), and Pager::open sizes the pool. A source
// must outlive every pager opened on it (the pager holds a shared_ptr).
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/jobs.h"
#include "sandtable/base/result.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/pack.h"

namespace sandtable::paging {

struct ModuleKey {
  std::uint32_t kx = 0;
  std::uint32_t kz = 0;
  bool operator==(const ModuleKey&) const = default;
};

/// What a source holds for one module, known without reading it.
struct ModuleInfo {
  std::uint64_t storedBytes = 0;  ///< bytes a read fetches (compressed, in the pack); 0: none stored
  std::uint64_t rawBytes = 0;     ///< encoded (uncompressed) size, to size the pool
  std::uint64_t fineBytes = 0;    ///< of storedBytes, what readFine fetches (0: no separate fine part)
};

class ModuleSource {
 public:
  virtual ~ModuleSource() = default;
  /// The module layout (modules across and down, levels, squares, edge),
  /// fixed for the source's life.
  virtual const pack::IndexHeader& header() const = 0;
  /// kx < modulesX, kz < modulesZ.
  virtual ModuleInfo info(std::uint32_t kx, std::uint32_t kz) const = 0;
  /// The generation of module (kx, kz) now. Never decreases. Cheap: no I/O
  /// and no lock held for long, so the loaders may ask before every read.
  virtual std::uint64_t generation(std::uint32_t kx, std::uint32_t kz) const = 0;
  /// Decodes module (kx, kz) into `into`, reusing its capacity (a reader
  /// that allocates nothing in steady state keeps the pager's steady state
  /// allocation-free), and returns the generation of what it read: the
  /// bytes and the generation are of one version of the module. Problems
  /// name the file and offset as PackReader's do.
  virtual Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const = 0;
  /// Levels coarseLevel() .. levels-1 come in readCoarse, the others in
  /// readFine. 0 (the default): readCoarse reads every level.
  virtual std::uint32_t coarseLevel() const { return 0; }
  /// Reads only the coarse levels (coarseLevel() and coarser) into `into`,
  /// sized to the layout's level count, each level at its own number; the
  /// finer levels are left as they were. Same contract as read(). Default:
  /// read().
  virtual Result<std::uint64_t> readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
    return read(kx, kz, into);
  }
  /// Reads levels 0 .. coarseLevel()-1 into `into` (the coarse levels left
  /// as they were) at the generation readCoarse gave. Default: nothing.
  virtual Status readFine(std::uint32_t /*kx*/, std::uint32_t /*kz*/, module::Module& /*into*/) const { return {}; }
  /// A hint that these modules' coarse parts (and with `fine` their fine
  /// parts) will be read soon, so the source can start the I/O. Must not
  /// block for long; any thread. Default: nothing.
  virtual void willNeed(std::span<const ModuleKey> /*keys*/, bool /*fine*/) const {}
  /// After a failed read: true when the module is missing (nothing is
  /// stored for it), false when what is stored is damaged.
  virtual bool missing(std::uint32_t kx, std::uint32_t kz) const = 0;
  /// A count bumped after each generation change, once generation() shows
  /// the new value. The pager's main thread compares it every update, so
  /// it must be one atomic load.
  virtual std::uint64_t changes() const = 0;
  /// Appends to `out` every module whose generation changed since changes()
  /// read `since` (a module may appear more than once) and returns the
  /// changes() value the list is complete up to. Called only when
  /// changes() != since; may allocate.
  virtual std::uint64_t changedSince(std::uint64_t since, std::vector<ModuleKey>& out) const = 0;
};

/// Today's modules.pack as a source: generation 0 for every module, no
/// changes. read() is PackReader::readInto (per record: one pread, CRC,
/// zstd, decode); readCoarse/readFine read one record of a v2 pack each.
class PackSource final : public ModuleSource {
 public:
  explicit PackSource(std::shared_ptr<const pack::PackReader> pack);
  const std::shared_ptr<const pack::PackReader>& pack() const { return pack_; }

  const pack::IndexHeader& header() const override { return pack_->header(); }
  ModuleInfo info(std::uint32_t kx, std::uint32_t kz) const override;
  std::uint64_t generation(std::uint32_t, std::uint32_t) const override { return 0; }
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  /// No record in the index, or a record that lies (partly) beyond the end
  /// of modules.pack now (a truncated pack).
  bool missing(std::uint32_t kx, std::uint32_t kz) const override;
  std::uint32_t coarseLevel() const override { return pack_->coarseLevel(); }
  Result<std::uint64_t> readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  Status readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  /// The records, sorted by offset and merged where they lie within 64 KB
  /// of each other (pack v2 in Morton order puts a strip's coarse records
  /// in a few runs): posix_fadvise(WILLNEED) over a local pack; over a
  /// remote one, each run read in one request off the caller's thread (a
  /// jobs::SerialQueue, coarse runs before fine ones), into the caches the
  /// loaders then read from. At most 4 strips queued; past that, none.
  void willNeed(std::span<const ModuleKey> keys, bool fine) const override;
  std::uint64_t changes() const override { return 0; }
  std::uint64_t changedSince(std::uint64_t since, std::vector<ModuleKey>&) const override { return since; }
  ~PackSource() override;

 private:
  void prefetchRemote(const RangeSource& remote, std::span<const ModuleKey> keys, bool fine) const;
  std::shared_ptr<const pack::PackReader> pack_;
  std::unique_ptr<jobs::SerialQueue> prefetches_;  ///< a remote pack's; waited for by the destructor
};

}  // namespace sandtable::paging
