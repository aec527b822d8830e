// GpuArena (gpu_arena.h): sub-allocation of one persistent mapped buffer.
#include "gpu_arena.h"

#include <algorithm>
#include <iterator>

namespace sandtable::render::detail {
namespace {

/// The arena's first size; it doubles when full.
constexpr std::uint64_t kArenaInitialBytes = 8ull << 20;

void insertFree(std::map<std::uint64_t, std::uint64_t>& free, std::uint64_t offset, std::uint64_t bytes) {
  auto it = free.emplace(offset, bytes).first;
  if (auto next = std::next(it); next != free.end() && it->first + it->second == next->first) {
    it->second += next->second;
    free.erase(next);
  }
  if (it != free.begin()) {
    if (auto prev = std::prev(it); prev->first + prev->second == it->first) {
      prev->second += it->second;
      free.erase(it);
    }
  }
}

}  // namespace

GpuArena::~GpuArena() {
  for (auto& f : fenced_) glDeleteSync(f.fence);
  if (buffer_) {
    glUnmapNamedBuffer(buffer_);
    glDeleteBuffers(1, &buffer_);
  }
}

void GpuArena::grow(std::uint64_t atLeast) {
  const std::uint64_t old = capacity_;
  std::uint64_t bytes = std::max<std::uint64_t>(kArenaInitialBytes, 2 * old);
  while (bytes < old + atLeast) bytes *= 2;
  constexpr GLbitfield flags = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  GLuint next = 0;
  glCreateBuffers(1, &next);
  glNamedBufferStorage(next, GLsizeiptr(bytes), nullptr, flags);
  auto* map = static_cast<std::uint8_t*>(glMapNamedBufferRange(next, 0, GLsizeiptr(bytes), flags));
  if (buffer_) {
    // A copy on the GPU keeps every block at its offset.
    glCopyNamedBufferSubData(buffer_, next, 0, 0, GLsizeiptr(old));
    glUnmapNamedBuffer(buffer_);
    glDeleteBuffers(1, &buffer_);
  }
  buffer_ = next;
  map_ = map;
  capacity_ = bytes;
  insertFree(free_, old, bytes - old);
}

void GpuArena::recycle() {
  std::size_t done = 0;
  for (; done < fenced_.size(); ++done) {
    const GLenum r = glClientWaitSync(fenced_[done].fence, 0, 0);
    if (r != GL_ALREADY_SIGNALED && r != GL_CONDITION_SATISFIED) break;
    glDeleteSync(fenced_[done].fence);
    for (const Pending& p : fenced_[done].blocks) insertFree(free_, p.offset, p.bytes);
  }
  fenced_.erase(fenced_.begin(), fenced_.begin() + std::ptrdiff_t(done));
}

std::uint64_t GpuArena::allocate(std::uint64_t bytes) {
  const std::uint64_t need = std::max<std::uint64_t>((bytes + kUnit - 1) / kUnit * kUnit, kUnit);
  for (int attempt = 0; attempt < 3; ++attempt) {
    for (auto it = free_.begin(); it != free_.end(); ++it) {
      if (it->second < need) continue;
      const std::uint64_t offset = it->first, left = it->second - need;
      free_.erase(it);
      if (left > 0) free_.emplace(offset + need, left);
      return offset;
    }
    if (attempt == 0) recycle();
    else grow(need);
  }
  return 0;  // not reached: grow() made room
}

void GpuArena::release(std::uint64_t offset, std::uint64_t bytes) {
  if (bytes == 0) return;
  released_.push_back({offset, std::max<std::uint64_t>((bytes + kUnit - 1) / kUnit * kUnit, kUnit)});
}

void GpuArena::endFrame() {
  if (!released_.empty()) {
    fenced_.push_back({glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0), std::move(released_)});
    released_.clear();
  }
  recycle();
}

}  // namespace sandtable::render::detail
