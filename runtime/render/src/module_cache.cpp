// The GPU cache of (module, level) entries: uploads from the levels'
// meshes (LevelMesh, module_mesh.h) within the frame's budget, and release.
#include <chrono>
#include <cstddef>
#include <cstring>

#include "module_draw.h"

namespace sandtable::render::detail {
namespace {

/// Frames a GPU copy may go unused (e.g. turned away) before it is released.
constexpr std::uint64_t kKeepUnusedFrames = 90;

}  // namespace

void ModuleRenderer::storeEntry(Entry& e, const std::vector<GpuVertex>& vertices,
                                const std::vector<std::uint32_t>& indices) {
  freeEntry(e);
  e.vertexBytes = vertices.size() * sizeof(GpuVertex);
  e.indexBytes = indices.size() * sizeof(std::uint32_t);
  e.vertexOffset = arena_.allocate(e.vertexBytes);
  e.indexOffset = arena_.allocate(e.indexBytes);
  if (e.vertexBytes) std::memcpy(arena_.data() + e.vertexOffset, vertices.data(), e.vertexBytes);
  if (e.indexBytes) std::memcpy(arena_.data() + e.indexOffset, indices.data(), e.indexBytes);
  e.bytes = e.vertexBytes + e.indexBytes;
  gpuBytes_ += e.bytes;
  e.resident = true;
}

void ModuleRenderer::freeEntry(Entry& e) {
  if (!e.resident) return;
  arena_.release(e.vertexOffset, e.vertexBytes);
  arena_.release(e.indexOffset, e.indexBytes);
  gpuBytes_ -= e.bytes;
  e.resident = false;
  e.bytes = e.vertexBytes = e.indexBytes = 0;
}

const LevelMesh* ModuleRenderer::preparedMesh(const paging::ResidentRef& ref, std::uint32_t level, bool raise) {
  const auto& prepared = ref.module().prepared;
  if (level >= prepared.size()) return nullptr;
  const auto* mesh = dynamic_cast<const LevelMesh*>(prepared[level].get());
  if (!mesh || !mesh->settings) return nullptr;
  if (mesh->settings.get() != matchedSettings_) {
    if (!sameMeshSettings(*mesh->settings, *meshSettings_)) return nullptr;
    matchedSettings_ = mesh->settings.get();
  }
  // `raised` is read only once the guard saw every level resident.
  if (raise && !mesh->raised) return nullptr;
  return mesh;
}

void ModuleRenderer::upload(const scene::ModuleDraw& d, std::uint32_t levelIndex, Entry& e, RenderStats& stats) {
  // Levels finer than the finest resident may be written meanwhile: the
  // feet are raised only once every level is resident.
  const bool raise = d.ref.finestLevel() == 0;
  const LevelMesh* mesh = preparedMesh(d.ref, levelIndex, raise);
  if (!mesh) {
    const paging::ResidentModule& m = d.ref.module();
    buildLevelMesh(m, levelIndex, *meshSettings_, ownMesh_);
    ownMesh_.raised = false;
    if (raise) {
      std::vector<LevelMesh*> only(m.levels.size(), nullptr);
      only[levelIndex] = &ownMesh_;
      raiseSkirtFeet(m, only);
    }
    mesh = &ownMesh_;
  }
  storeEntry(e, mesh->vertices, mesh->indices);
  if (raise) {
    std::uint8_t* base = arena_.data() + e.vertexOffset;
    for (const auto& [v, y] : mesh->feet) {
      std::memcpy(base + std::size_t(v) * sizeof(GpuVertex) + offsetof(GpuVertex, y), &y, sizeof y);
    }
  }
  e.blocks = mesh->blocks;
  e.priorities = mesh->priorities;
  stats.underlayMissing += mesh->underlayMissing;
  e.generation = d.ref.generation();
  ++stats.uploads;
  stats.uploadBytes += e.bytes;
}

ModuleRenderer::Entry* ModuleRenderer::ready(std::uint64_t key) {
  auto it = cache_.find(key);
  return it != cache_.end() && it->second.resident ? &it->second : nullptr;
}

void ModuleRenderer::release(RenderStats& stats, const scene::DisplayBuffer& buf) {
  const paging::ModuleRect& w = buf.pagerWindow;
  for (auto it = cache_.begin(); it != cache_.end();) {
    const auto kx = std::int64_t(it->first & 0xFFFFF), kz = std::int64_t((it->first >> 20) & 0xFFFFF);
    const bool freed = !w.empty() && !w.contains(kx, kz);
    if (freed || it->second.lastFrame + kKeepUnusedFrames < buf.frame) {
      freeEntry(it->second);
      it = cache_.erase(it);
      ++stats.released;
    } else {
      ++it;
    }
  }
}

void ModuleRenderer::prepare(const scene::DisplayBuffer& buf, RenderStats& stats) {
  const auto t0 = std::chrono::steady_clock::now();
  nodeSquares_ = buf.nodeSquares;
  moduleSize_ = buf.moduleSize;
  if (!meshSettings_ || meshSettings_->nodeSquares != nodeSquares_ || meshSettings_->moduleSize != moduleSize_) {
    meshSettings_ = std::make_shared<const MeshSettings>(meshSettings(settings_, nodeSquares_, moduleSize_));
    matchedSettings_ = nullptr;
  }
  drawn_.clear();
  cells_.clear();
  moduleCells_.assign(buf.modules.size(), {0, 0});
  const std::uint64_t budget = settings_.uploadBudgetBytes;
  std::uint64_t spent = 0;
  // Uploads go nearest first (nodes are grouped by module, nearest module
  // first). Every module's coarsest level goes up whatever the budget (it
  // is small), so a module with anything resident is never a hole; finer
  // levels wait for a later frame once the budget is spent (at least one
  // goes up each frame), and are drawn coarser meanwhile.
  const auto ensure = [&](const scene::ModuleDraw& d, std::uint32_t level, bool force) {
    Entry& e = cache_[cacheKey(d.kx, d.kz, level)];
    e.lastFrame = buf.frame;
    if (e.resident && e.generation == d.ref.generation()) return;
    const module::Level& l = d.ref.level(level);
    const std::uint64_t estimate = l.vertices.size() * sizeof(GpuVertex) + l.indices.size() * sizeof(std::uint32_t);
    if (!force && budget > 0 && spent > 0 && spent + estimate > budget) {
      ++stats.uploadsDeferred;
      return;
    }
    upload(d, level, e, stats);
    spent += e.bytes;
  };
  for (std::size_t i0 = 0; i0 < buf.nodes.size();) {
    std::size_t i1 = i0;
    while (i1 < buf.nodes.size() && buf.nodes[i1].module == buf.nodes[i0].module) ++i1;
    const scene::ModuleDraw& d = buf.modules[buf.nodes[i0].module];
    const auto levels = std::uint32_t(d.ref.module().levels.size());
    ensure(d, levels - 1, true);
    for (std::size_t k = i0; k < i1; ++k) ensure(d, buf.nodes[k].level, false);
    resolveModule(buf, i0, i1, stats);
    i0 = i1;
  }
  stats.uploadMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  buildCommands(buf);
}

}  // namespace sandtable::render::detail
