#pragma once
// The job system: every parallel build stage runs through here, on oneTBB.
// There are no hand-written thread pools in the build. (The pager's four
// directional loaders are dedicated threads by design, seed §7, and are
// not jobs.)
//
// Thread safety: any thread may call these; `body` runs concurrently on up
// to threadCount(threads) workers and must be safe for that. Calls may
// nest: an inner parallelFor shares the outer one's workers.
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

namespace sandtable::jobs {

/// The number of workers a stage asks for: `requested` when positive,
/// else every hardware thread (at least 1).
int threadCount(int requested);

/// Runs body(i) for every i in [0, n) on up to threadCount(threads)
/// workers, one index per task (build stages have few, heavy items) and
/// returns when all have run. Once `cancel` reads true, indices not yet
/// started are skipped; those already running finish.
void parallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& body,
                 const std::atomic<bool>* cancel = nullptr);

/// As parallelFor, but hands each worker a contiguous range [begin, end)
/// of about `grain` indices: for many light items (rows, posts).
void parallelRanges(std::size_t n, int threads, std::size_t grain,
                    const std::function<void(std::size_t begin, std::size_t end)>& body,
                    const std::atomic<bool>* cancel = nullptr);

/// Runs f and g at the same time on the shared workers (up to
/// threadCount(threads)) and returns when both have. For two independent
/// stages, so one's serial stretches are filled by the other's work.
void both(int threads, const std::function<void()>& f, const std::function<void()>& g);

/// Runs a two-stage pipeline over the items [0, n): work(i) on up to
/// threadCount(threads) workers, then finish(i) one item at a time in
/// index order, while later items are still being worked. At most
/// `inFlight` items (at least 1) are between the start of work and the end
/// of finish, which bounds the memory they hold. Once `cancel` reads true
/// no new item starts; items already started are worked and finished.
///
/// Thread contract: work runs concurrently with itself and with finish;
/// finish never runs concurrently with itself (on whichever worker is
/// free), so it may write a file or sum totals without a lock.
void orderedPipeline(std::size_t n, int threads, std::size_t inFlight,
                     const std::function<void(std::size_t)>& work,
                     const std::function<void(std::size_t)>& finish,
                     const std::atomic<bool>* cancel = nullptr);

/// orderedPipeline that hands work(i)'s result (a T) to finish(i, T&&).
/// The results wait in inFlight slots: item i uses slot i % inFlight,
/// which no other live item can hold (items enter in order and leave in
/// order, at most inFlight at a time).
template <typename T, typename Work, typename Finish>
void orderedPipeline(std::size_t n, int threads, std::size_t inFlight, Work&& work, Finish&& finish,
                     const std::atomic<bool>* cancel = nullptr) {
  inFlight = std::max<std::size_t>(inFlight, 1);
  std::vector<std::optional<T>> slots(inFlight);
  orderedPipeline(
      n, threads, inFlight, [&](std::size_t i) { slots[i % inFlight].emplace(work(i)); },
      [&](std::size_t i) {
        std::optional<T>& slot = slots[i % inFlight];
        finish(i, std::move(*slot));
        slot.reset();
      },
      cancel);
}

/// Scratch state kept across the items a stage runs: an open dataset,
/// grown buffers. Each use() lends one State that no other running use()
/// holds, made by default construction when none is free, and takes it
/// back afterwards; a stage therefore makes about as many as it has
/// workers, however many items it runs. (Not thread_local: a worker that
/// waits inside an item may start another item on the same thread.)
///
/// Thread safety: use() may be called from any threads at once.
template <typename State>
class Scratch {
 public:
  template <typename F>
  decltype(auto) use(F&& f) {
    std::unique_ptr<State> s = take();
    struct Back {
      Scratch& owner;
      std::unique_ptr<State>& s;
      ~Back() { owner.give(std::move(s)); }
    } back{*this, s};
    return f(*s);
  }

 private:
  std::unique_ptr<State> take() {
    {
      std::lock_guard lock(mutex_);
      if (!free_.empty()) {
        std::unique_ptr<State> s = std::move(free_.back());
        free_.pop_back();
        return s;
      }
    }
    return std::make_unique<State>();
  }
  void give(std::unique_ptr<State> s) {
    std::lock_guard lock(mutex_);
    free_.push_back(std::move(s));
  }

  std::mutex mutex_;
  std::vector<std::unique_ptr<State>> free_;
};

/// Background work run one item at a time, in the order submitted, on the
/// shared workers (a oneTBB task group): the dynamic-terrain editor
/// re-meshes modules off the render thread through one, and a later item
/// sees everything an earlier one did.
///
/// Thread safety: submit and pending may be called from any thread, wait
/// from one thread at a time (the owner's); items never run concurrently
/// with each other. The destructor waits for every item submitted.
class SerialQueue {
 public:
  SerialQueue();
  ~SerialQueue();
  SerialQueue(const SerialQueue&) = delete;
  SerialQueue& operator=(const SerialQueue&) = delete;
  /// Queues `item`; returns at once.
  void submit(std::function<void()> item);
  /// Returns once every item submitted before the call has run.
  void wait();
  /// Items submitted and not yet finished.
  std::size_t pending() const;

 private:
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace sandtable::jobs
