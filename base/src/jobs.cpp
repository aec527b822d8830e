#include "sandtable/base/jobs.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <deque>
#include <thread>
#include <utility>

namespace sandtable::jobs {

int threadCount(int requested) {
  if (requested > 0) return requested;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

namespace {

bool stopped(const std::atomic<bool>* cancel) {
  return cancel && cancel->load(std::memory_order_relaxed);
}

/// A worker limit means an arena of that size; the default arena when the
/// caller wants every core, so nested calls do not oversubscribe.
template <typename F>
void inArena(int threads, F&& f) {
  const int n = threadCount(threads);
  if (n >= tbb::this_task_arena::max_concurrency()) {
    f();
    return;
  }
  tbb::task_arena arena(n);
  arena.execute(f);
}

}  // namespace

void parallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& body,
                 const std::atomic<bool>* cancel) {
  if (n == 0) return;
  inArena(threads, [&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 1),
        [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) {
            if (stopped(cancel)) return;
            body(i);
          }
        },
        tbb::simple_partitioner());
  });
}

void parallelRanges(std::size_t n, int threads, std::size_t grain,
                    const std::function<void(std::size_t, std::size_t)>& body,
                    const std::atomic<bool>* cancel) {
  if (n == 0) return;
  inArena(threads, [&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, std::max<std::size_t>(1, grain)),
        [&](const tbb::blocked_range<std::size_t>& r) {
          if (!stopped(cancel)) body(r.begin(), r.end());
        },
        tbb::simple_partitioner());
  });
}

void both(int threads, const std::function<void()>& f, const std::function<void()>& g) {
  inArena(threads, [&] { tbb::parallel_invoke(f, g); });
}

void orderedPipeline(std::size_t n, int threads, std::size_t inFlight,
                     const std::function<void(std::size_t)>& work,
                     const std::function<void(std::size_t)>& finish,
                     const std::atomic<bool>* cancel) {
  if (n == 0) return;
  inArena(threads, [&] {
    std::size_t next = 0;
    tbb::parallel_pipeline(
        std::max<std::size_t>(inFlight, 1),
        tbb::make_filter<void, std::size_t>(tbb::filter_mode::serial_in_order,
                                            [&](tbb::flow_control& fc) -> std::size_t {
                                              if (next == n || stopped(cancel)) {
                                                fc.stop();
                                                return 0;
                                              }
                                              return next++;
                                            }) &
            tbb::make_filter<std::size_t, std::size_t>(tbb::filter_mode::parallel,
                                                       [&](std::size_t i) {
                                                         work(i);
                                                         return i;
                                                       }) &
            tbb::make_filter<std::size_t, void>(tbb::filter_mode::serial_in_order,
                                                [&](std::size_t i) { finish(i); }));
  });
}

struct SerialQueue::State {
  mutable std::mutex mutex;
  std::deque<std::function<void()>> items;
  std::size_t unfinished = 0;
  bool draining = false;
  tbb::task_group group;

  /// Runs items until none is left; one drain at a time (draining), so the
  /// items run in order and never concurrently.
  void drain() {
    for (;;) {
      std::function<void()> item;
      {
        std::lock_guard lock(mutex);
        if (items.empty()) {
          draining = false;
          return;
        }
        item = std::move(items.front());
        items.pop_front();
      }
      item();
      std::lock_guard lock(mutex);
      --unfinished;
    }
  }
};

SerialQueue::SerialQueue() : s_(std::make_unique<State>()) {}

SerialQueue::~SerialQueue() { s_->group.wait(); }

void SerialQueue::submit(std::function<void()> item) {
  bool start = false;
  {
    std::lock_guard lock(s_->mutex);
    s_->items.push_back(std::move(item));
    ++s_->unfinished;
    start = !std::exchange(s_->draining, true);
  }
  if (start) s_->group.run([s = s_.get()] { s->drain(); });
}

void SerialQueue::wait() {
  // Joins the group, so the waiting thread runs a drain itself when no
  // worker is free (one worker, or every worker busy in a build stage).
  s_->group.wait();
}

std::size_t SerialQueue::pending() const {
  std::lock_guard lock(s_->mutex);
  return s_->unfinished;
}

}  // namespace sandtable::jobs
