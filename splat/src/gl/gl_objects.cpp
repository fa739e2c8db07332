#include "treecut/splat/gl_objects.hpp"

#include <cstdio>
#include <string>

namespace treecut::gl {

Buffer Buffer::create(std::size_t bytes, const void* data, GLbitfield flags) {
  GLuint id = 0;
  CreateBuffers(1, &id);
  Buffer b(id);
  // A zero-sized store is not allowed; keep one byte so the name is valid.
  NamedBufferStorage(id, static_cast<GLsizeiptr>(bytes == 0 ? 1 : bytes),
                     bytes == 0 ? nullptr : data, flags);
  check("glNamedBufferStorage");
  b.size_ = bytes;
  return b;
}

void Buffer::sub_data(std::size_t offset, std::span<const std::byte> bytes) const {
  if (bytes.empty()) return;
  NamedBufferSubData(id(), static_cast<GLintptr>(offset), static_cast<GLsizeiptr>(bytes.size()),
                     bytes.data());
}

VertexArray VertexArray::create() {
  GLuint id = 0;
  CreateVertexArrays(1, &id);
  return VertexArray(id);
}

Shader Shader::compile(GLenum stage, std::string_view source, std::string_view label) {
  Shader s(CreateShader(stage));
  if (!s) throw GlError(std::string(label) + ": glCreateShader failed");
  const char* text = source.data();
  const auto length = static_cast<GLint>(source.size());
  ShaderSource(s.id(), 1, &text, &length);
  CompileShader(s.id());
  GLint ok = 0;
  GetShaderiv(s.id(), GL_COMPILE_STATUS, &ok);
  if (ok == GL_FALSE) {
    GLint log_length = 0;
    GetShaderiv(s.id(), GL_INFO_LOG_LENGTH, &log_length);
    std::string log(static_cast<std::size_t>(log_length > 0 ? log_length : 1), '\0');
    GetShaderInfoLog(s.id(), log_length, nullptr, log.data());
    throw GlError(std::string(label) + ": shader compilation failed:\n" + log);
  }
  return s;
}

Program Program::link(std::span<const Shader* const> shaders, std::string_view label) {
  Program p(CreateProgram());
  if (!p) throw GlError(std::string(label) + ": glCreateProgram failed");
  for (const Shader* s : shaders) AttachShader(p.id(), s->id());
  LinkProgram(p.id());
  for (const Shader* s : shaders) DetachShader(p.id(), s->id());
  GLint ok = 0;
  GetProgramiv(p.id(), GL_LINK_STATUS, &ok);
  if (ok == GL_FALSE) {
    GLint log_length = 0;
    GetProgramiv(p.id(), GL_INFO_LOG_LENGTH, &log_length);
    std::string log(static_cast<std::size_t>(log_length > 0 ? log_length : 1), '\0');
    GetProgramInfoLog(p.id(), log_length, nullptr, log.data());
    throw GlError(std::string(label) + ": program link failed:\n" + log);
  }
  return p;
}

void Program::set(const char* name, int value) const {
  ProgramUniform1i(id(), GetUniformLocation(id(), name), value);
}
void Program::set(const char* name, float value) const {
  ProgramUniform1f(id(), GetUniformLocation(id(), name), value);
}
void Program::set(const char* name, float x, float y) const {
  ProgramUniform2f(id(), GetUniformLocation(id(), name), x, y);
}
void Program::set(const char* name, float x, float y, float z) const {
  ProgramUniform3f(id(), GetUniformLocation(id(), name), x, y, z);
}
void Program::set(const char* name, float x, float y, float z, float w) const {
  ProgramUniform4f(id(), GetUniformLocation(id(), name), x, y, z, w);
}
void Program::set_mat4(const char* name, const float* column_major) const {
  ProgramUniformMatrix4fv(id(), GetUniformLocation(id(), name), 1, GL_FALSE, column_major);
}

Texture Texture::create_2d(GLenum internal_format, int width, int height) {
  GLuint id = 0;
  CreateTextures(GL_TEXTURE_2D, 1, &id);
  Texture t(id);
  TextureStorage2D(id, 1, internal_format, width, height);
  TextureParameteri(id, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  TextureParameteri(id, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  TextureParameteri(id, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  TextureParameteri(id, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  check("glTextureStorage2D");
  return t;
}

Framebuffer Framebuffer::create() {
  GLuint id = 0;
  CreateFramebuffers(1, &id);
  return Framebuffer(id);
}

void Framebuffer::attach(GLenum attachment, const Texture& texture) const {
  NamedFramebufferTexture(id(), attachment, texture.id(), 0);
}

void Framebuffer::set_draw_buffers(std::span<const GLenum> buffers, std::string_view label) const {
  if (buffers.empty()) {
    NamedFramebufferDrawBuffer(id(), GL_NONE);
    NamedFramebufferReadBuffer(id(), GL_NONE);
  } else {
    NamedFramebufferDrawBuffers(id(), static_cast<GLsizei>(buffers.size()), buffers.data());
    NamedFramebufferReadBuffer(id(), buffers.front());
  }
  const GLenum status = CheckNamedFramebufferStatus(id(), GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    char code[16];
    std::snprintf(code, sizeof code, "0x%04x", status);
    throw GlError(std::string(label) + ": framebuffer incomplete (" + code + ")");
  }
}

Query Query::create(GLenum target) {
  GLuint id = 0;
  CreateQueries(target, 1, &id);
  return Query(id, target);
}

std::optional<std::uint64_t> Query::try_result() const {
  GLuint available = GL_FALSE;
  GetQueryObjectuiv(id(), GL_QUERY_RESULT_AVAILABLE, &available);
  if (available == GL_FALSE) return std::nullopt;
  GLuint64 value = 0;
  GetQueryObjectui64v(id(), GL_QUERY_RESULT, &value);
  return value;
}

}  // namespace treecut::gl
