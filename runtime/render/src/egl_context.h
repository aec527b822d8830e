#pragma once
// A headless OpenGL 4.5 core context through EGL. Private to the renderer:
// it must be created, used and destroyed on the render thread.
#include <memory>
#include <string>

#include "sandtable/base/result.h"

namespace sandtable::runtime {

class EglContext {
 public:
  /// Tries Mesa's surfaceless platform first (no window system, no GPU
  /// needed with llvmpipe), then the default display with a pbuffer. The
  /// context is current on the calling thread when this returns.
  static Result<std::unique_ptr<EglContext>> create();
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  /// "surfaceless" or "default display + pbuffer".
  const std::string& platform() const { return platform_; }

 private:
  EglContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
  void* surface_ = nullptr;
  std::string platform_;
};

}  // namespace sandtable::runtime
