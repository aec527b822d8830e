#include "sandtable/render/gl_program.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <utility>

namespace sandtable::render {
namespace {

std::string infoLog(GLuint object, bool program) {
  GLint length = 0;
  program ? glGetProgramiv(object, GL_INFO_LOG_LENGTH, &length)
          : glGetShaderiv(object, GL_INFO_LOG_LENGTH, &length);
  std::string log(std::size_t(std::max(length, 1)), '\0');
  program ? glGetProgramInfoLog(object, length, nullptr, log.data())
          : glGetShaderInfoLog(object, length, nullptr, log.data());
  return log.c_str();
}

/// The compiled stage, or 0 with `error` holding the info log.
GLuint compileStage(GLenum stage, const std::string& source, std::string& error) {
  const GLuint s = glCreateShader(stage);
  const char* text = source.c_str();
  glShaderSource(s, 1, &text, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (ok) return s;
  error = std::string(stage == GL_VERTEX_SHADER ? "vertex" : "fragment") + " stage does not compile: " +
          infoLog(s, false);
  glDeleteShader(s);
  return 0;
}

}  // namespace

Result<GlProgram> GlProgram::build(const std::string& what, const std::string& vertexSource,
                                   const std::string& fragmentSource) {
  std::string error;
  const GLuint v = compileStage(GL_VERTEX_SHADER, vertexSource, error);
  const GLuint f = v ? compileStage(GL_FRAGMENT_SHADER, fragmentSource, error) : 0;
  if (!v || !f) {
    glDeleteShader(v);
    return Problem{kShaderProblem, 0, what + " shader: " + error};
  }
  const GLuint p = glCreateProgram();
  glAttachShader(p, v);
  glAttachShader(p, f);
  glLinkProgram(p);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    const std::string log = infoLog(p, true);
    glDeleteProgram(p);
    return Problem{kShaderProblem, 0, what + " shader: the stages do not link: " + log};
  }
  return GlProgram(p);
}

GlProgram::~GlProgram() { reset(); }

GlProgram::GlProgram(GlProgram&& other) noexcept : id_(std::exchange(other.id_, 0)) {}

GlProgram& GlProgram::operator=(GlProgram&& other) noexcept {
  if (this != &other) {
    reset();
    id_ = std::exchange(other.id_, 0);
  }
  return *this;
}

void GlProgram::reset() {
  if (id_) glDeleteProgram(id_);
  id_ = 0;
}

void GlProgram::use() const { glUseProgram(id_); }

int GlProgram::uniform(const char* name) const { return glGetUniformLocation(id_, name); }

void GlProgram::set(const char* name, int v) const { glProgramUniform1i(id_, uniform(name), v); }

void GlProgram::set(const char* name, float v) const { glProgramUniform1f(id_, uniform(name), v); }

void GlProgram::set(const char* name, float x, float y) const {
  glProgramUniform2f(id_, uniform(name), x, y);
}

void GlProgram::set(const char* name, float x, float y, float z) const {
  glProgramUniform3f(id_, uniform(name), x, y, z);
}

void GlProgram::setMatrix4(const char* name, const float* columnMajor) const {
  glProgramUniformMatrix4fv(id_, uniform(name), 1, GL_FALSE, columnMajor);
}

}  // namespace sandtable::render
