// RetryingSource: failed module reads tried again (retrying_source.h).
#include "sandtable/paging/retrying_source.h"

#include <algorithm>
#include <chrono>
#include <limits>

namespace sandtable::paging {
namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

constexpr double kNever = std::numeric_limits<double>::infinity();
/// Change-log entries kept; a caller further behind gets every module
/// that ever changed (a generation only grows, so re-reading is safe).
constexpr std::size_t kLogEntries = 4096;

}  // namespace

RetryingSource::RetryingSource(std::shared_ptr<const ModuleSource> inner, RetryOptions options)
    : inner_(std::move(inner)), options_(options), nextDue_(kNever) {}

std::uint64_t RetryingSource::generation(std::uint32_t kx, std::uint32_t kz) const {
  if (!anyGenerations_.load(std::memory_order_acquire)) return 0;
  const std::lock_guard lock(mutex_);
  const auto it = generations_.find(keyOf(kx, kz));
  return it == generations_.end() ? 0 : it->second;
}

template <typename Read>
Result<std::uint64_t> RetryingSource::tracked(std::uint32_t kx, std::uint32_t kz, Read&& read) const {
  const std::uint64_t gen = generation(kx, kz);
  auto r = read();
  if (r) {
    noteSuccess(keyOf(kx, kz));
    return gen;
  }
  if (!inner_->missing(kx, kz)) noteFailure(keyOf(kx, kz));
  return r.problems();
}

Result<std::uint64_t> RetryingSource::read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  return tracked(kx, kz, [&] { return inner_->read(kx, kz, into); });
}

Result<std::uint64_t> RetryingSource::readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  return tracked(kx, kz, [&] { return inner_->readCoarse(kx, kz, into); });
}

Status RetryingSource::readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const {
  // A failed fine record leaves the coarse levels drawn; the retry reloads
  // the whole module.
  Status st = inner_->readFine(kx, kz, into);
  if (!st) noteFailure(keyOf(kx, kz));
  return st;
}

void RetryingSource::noteFailure(std::uint64_t key) const {
  const std::lock_guard lock(mutex_);
  Failure& f = failed_[key];
  f.pause = f.pause == 0 ? options_.firstPauseSeconds : std::min(f.pause * 2, options_.maxPauseSeconds);
  f.due = now() + f.pause;
  f.promoted = false;
  if (f.due < nextDue_.load(std::memory_order_relaxed)) nextDue_.store(f.due, std::memory_order_release);
}

void RetryingSource::noteSuccess(std::uint64_t key) const {
  if (nextDue_.load(std::memory_order_acquire) == kNever && !anyGenerations_.load(std::memory_order_acquire)) return;
  const std::lock_guard lock(mutex_);
  failed_.erase(key);
}

std::uint64_t RetryingSource::changes() const {
  const double due = nextDue_.load(std::memory_order_acquire);
  if (due == kNever || now() < due) return changes_.load(std::memory_order_acquire);
  const std::lock_guard lock(mutex_);
  const double t = now();
  double next = kNever;
  std::uint64_t c = changes_.load(std::memory_order_relaxed);
  for (auto& [key, f] : failed_) {
    if (f.promoted) continue;
    if (f.due <= t) {
      f.promoted = true;  // until it fails again (noteFailure) or reads (noteSuccess)
      ++generations_[key];
      log_.emplace_back(++c, key);
    } else {
      next = std::min(next, f.due);
    }
  }
  if (log_.size() > kLogEntries) log_.erase(log_.begin(), log_.begin() + std::ptrdiff_t(log_.size() - kLogEntries));
  if (!generations_.empty()) anyGenerations_.store(true, std::memory_order_release);
  nextDue_.store(next, std::memory_order_release);
  changes_.store(c, std::memory_order_release);  // after the generations: changes() shows them
  return c;
}

std::uint64_t RetryingSource::changedSince(std::uint64_t since, std::vector<ModuleKey>& out) const {
  const std::lock_guard lock(mutex_);
  const std::uint64_t c = changes_.load(std::memory_order_acquire);
  const auto unpack = [](std::uint64_t key) { return ModuleKey{std::uint32_t(key), std::uint32_t(key >> 32)}; };
  if (!log_.empty() && log_.front().first > since + 1) {
    for (const auto& [key, gen] : generations_) out.push_back(unpack(key));
    return c;
  }
  for (const auto& [n, key] : log_) {
    if (n > since) out.push_back(unpack(key));
  }
  return c;
}

std::size_t RetryingSource::failing() const {
  const std::lock_guard lock(mutex_);
  return failed_.size();
}

std::shared_ptr<const ModuleSource> packSourceOf(std::shared_ptr<const pack::PackReader> pack) {
  if (!pack) return nullptr;
  const bool remote = pack->packFd() < 0;
  std::shared_ptr<const ModuleSource> source = std::make_shared<const PackSource>(std::move(pack));
  if (remote) source = std::make_shared<const RetryingSource>(std::move(source));
  return source;
}

}  // namespace sandtable::paging
