#pragma once
// A module source whose failed reads are tried again (issue 38: a web
// server that stops while viewers page from it). A module that fails to
// read is drawn as the pager's coarse placeholder; once its retry pause has
// passed, this source bumps the module's generation, so the pager reloads
// it as it reloads an edited module (reloadWhileStale), and the module
// comes back when the server does. The pause doubles per module while it
// keeps failing, up to maxPauseSeconds; a read that succeeds forgets the
// module. A module with nothing stored (missing()) is not tried again.
//
// Wraps a source without generations or changes of its own (PackSource).
// Thread contract: as ModuleSource's (every member const, any thread).
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "sandtable/paging/module_source.h"

namespace sandtable::paging {

struct RetryOptions {
  double firstPauseSeconds = 1.0;  ///< after a module's first failure
  double maxPauseSeconds = 30.0;   ///< the pause doubles up to this
};

class RetryingSource final : public ModuleSource {
 public:
  explicit RetryingSource(std::shared_ptr<const ModuleSource> inner, RetryOptions options = {});

  const pack::IndexHeader& header() const override { return inner_->header(); }
  ModuleInfo info(std::uint32_t kx, std::uint32_t kz) const override { return inner_->info(kx, kz); }
  /// The times the module's retry came due.
  std::uint64_t generation(std::uint32_t kx, std::uint32_t kz) const override;
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  std::uint32_t coarseLevel() const override { return inner_->coarseLevel(); }
  Result<std::uint64_t> readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  Status readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  void willNeed(std::span<const ModuleKey> keys, bool fine) const override { inner_->willNeed(keys, fine); }
  bool missing(std::uint32_t kx, std::uint32_t kz) const override { return inner_->missing(kx, kz); }
  /// Also promotes the failed modules whose pause has passed (the pager's
  /// main thread asks every update: a clock read and two atomic loads
  /// unless one is due).
  std::uint64_t changes() const override;
  std::uint64_t changedSince(std::uint64_t since, std::vector<ModuleKey>& out) const override;

  /// Modules failed and not read since (waiting for their retry).
  std::size_t failing() const;

 private:
  struct Failure {
    double due = 0, pause = 0;
    bool promoted = false;  ///< its generation was bumped for this pause
  };
  static std::uint64_t keyOf(std::uint32_t kx, std::uint32_t kz) { return (std::uint64_t(kz) << 32) | kx; }
  template <typename Read>
  Result<std::uint64_t> tracked(std::uint32_t kx, std::uint32_t kz, Read&& read) const;
  void noteFailure(std::uint64_t key) const;
  void noteSuccess(std::uint64_t key) const;

  std::shared_ptr<const ModuleSource> inner_;
  RetryOptions options_;
  mutable std::mutex mutex_;
  mutable std::unordered_map<std::uint64_t, Failure> failed_;
  mutable std::unordered_map<std::uint64_t, std::uint64_t> generations_;
  mutable std::vector<std::pair<std::uint64_t, std::uint64_t>> log_;  ///< (change number, key)
  mutable std::atomic<std::uint64_t> changes_{0};
  mutable std::atomic<double> nextDue_;
  mutable std::atomic<bool> anyGenerations_{false};
};

/// The pager's source for a pack: PackSource, wrapped in a RetryingSource
/// when the pack is read over HTTP (packFd() < 0). Null for a null pack.
std::shared_ptr<const ModuleSource> packSourceOf(std::shared_ptr<const pack::PackReader> pack);

}  // namespace sandtable::paging
