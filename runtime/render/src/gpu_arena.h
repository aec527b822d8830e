#pragma once
// The module renderer's vertex and index memory: one persistent, coherent,
// mapped GL buffer sub-allocated from a free list (module_draw.h, "Memory").
// Render thread only (it calls GL).
#include <epoxy/gl.h>

#include <cstdint>
#include <map>
#include <vector>

namespace sandtable::render::detail {

/// One persistent, coherent, write-mapped GL buffer, sub-allocated in
/// blocks of kUnit bytes (first fit, coalescing free list). Released
/// blocks wait behind a fence until the GPU can no longer read them.
class GpuArena {
 public:
  static constexpr std::uint64_t kUnit = 32;  ///< a GpuVertex: vertex blocks start on a vertex
  GpuArena() = default;
  ~GpuArena();
  GpuArena(const GpuArena&) = delete;
  GpuArena& operator=(const GpuArena&) = delete;

  /// Byte offset of a block of at least `bytes`; grows the buffer (a new
  /// GL name: rebind) when no free block fits.
  std::uint64_t allocate(std::uint64_t bytes);
  /// Gives a block back once the GPU has finished the frames drawn so far.
  void release(std::uint64_t offset, std::uint64_t bytes);
  /// Marks the end of a frame: blocks released before it become free once
  /// its fence has passed (checked without waiting).
  void endFrame();
  std::uint8_t* data() { return map_; }
  GLuint buffer() const { return buffer_; }
  std::uint64_t capacity() const { return capacity_; }

 private:
  void grow(std::uint64_t atLeast);
  void recycle();
  GLuint buffer_ = 0;
  std::uint8_t* map_ = nullptr;
  std::uint64_t capacity_ = 0;
  std::map<std::uint64_t, std::uint64_t> free_;  ///< offset -> bytes
  struct Pending {
    std::uint64_t offset, bytes;
  };
  std::vector<Pending> released_;  ///< this frame's, not yet fenced
  struct Fenced {
    GLsync fence;
    std::vector<Pending> blocks;
  };
  std::vector<Fenced> fenced_;
};

}  // namespace sandtable::render::detail
