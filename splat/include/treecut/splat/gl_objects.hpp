// Move-only RAII owners of OpenGL objects (after magnum's GL layer): copy is
// deleted, move is noexcept and leaves the source in the "no object" state
// (id 0), which needs no context to construct or destroy. release() gives up
// ownership, wrap() adopts an existing name.
//
// Creating, using and destroying an object that holds a name needs the
// context it was made in to be current on the calling (render) thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <utility>

#include "treecut/splat/gl.hpp"

namespace treecut::gl {

/// Owns one GL name; Deleter::destroy(GLuint) frees it.
template <class Deleter>
class Handle {
 public:
  Handle() noexcept = default;
  ~Handle() { reset(); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, 0)) {}
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = std::exchange(other.id_, 0);
    }
    return *this;
  }

  [[nodiscard]] GLuint id() const noexcept { return id_; }
  explicit operator bool() const noexcept { return id_ != 0; }
  /// Gives up ownership; the caller deletes the returned name.
  [[nodiscard]] GLuint release() noexcept { return std::exchange(id_, 0); }
  /// Deletes the owned object (if any); back to the "no object" state.
  void reset() noexcept {
    if (id_ != 0) Deleter::destroy(id_);
    id_ = 0;
  }

 protected:
  explicit Handle(GLuint id) noexcept : id_(id) {}

 private:
  GLuint id_ = 0;
};

struct BufferDeleter {
  static void destroy(GLuint id) { DeleteBuffers(1, &id); }
};
struct VertexArrayDeleter {
  static void destroy(GLuint id) { DeleteVertexArrays(1, &id); }
};
struct ShaderDeleter {
  static void destroy(GLuint id) { DeleteShader(id); }
};
struct ProgramDeleter {
  static void destroy(GLuint id) { DeleteProgram(id); }
};
struct TextureDeleter {
  static void destroy(GLuint id) { DeleteTextures(1, &id); }
};
struct FramebufferDeleter {
  static void destroy(GLuint id) { DeleteFramebuffers(1, &id); }
};
struct QueryDeleter {
  static void destroy(GLuint id) { DeleteQueries(1, &id); }
};

/// An immutable-storage buffer (glNamedBufferStorage).
class Buffer : public Handle<BufferDeleter> {
 public:
  Buffer() noexcept = default;
  static Buffer wrap(GLuint id) noexcept { return Buffer(id); }
  /// `bytes` of storage, initialised from `data` if not null. `flags` as for
  /// glNamedBufferStorage (GL_DYNAMIC_STORAGE_BIT allows sub_data()).
  static Buffer create(std::size_t bytes, const void* data, GLbitfield flags);
  /// Overwrites [offset, offset + bytes.size()); needs GL_DYNAMIC_STORAGE_BIT.
  void sub_data(std::size_t offset, std::span<const std::byte> bytes) const;
  [[nodiscard]] std::size_t size() const noexcept { return size_; }

 private:
  using Handle::Handle;
  std::size_t size_ = 0;
};

class VertexArray : public Handle<VertexArrayDeleter> {
 public:
  VertexArray() noexcept = default;
  static VertexArray wrap(GLuint id) noexcept { return VertexArray(id); }
  static VertexArray create();

 private:
  using Handle::Handle;
};

class Shader : public Handle<ShaderDeleter> {
 public:
  Shader() noexcept = default;
  static Shader wrap(GLuint id) noexcept { return Shader(id); }
  /// Compiles; throws GlError with `label` and the info log on failure.
  static Shader compile(GLenum stage, std::string_view source, std::string_view label);

 private:
  using Handle::Handle;
};

class Program : public Handle<ProgramDeleter> {
 public:
  Program() noexcept = default;
  static Program wrap(GLuint id) noexcept { return Program(id); }
  /// Links the shaders; throws GlError with `label` and the info log on failure.
  static Program link(std::span<const Shader* const> shaders, std::string_view label);

  /// Uniform setters by name; a name the linker dropped is ignored (GL's own rule).
  void set(const char* name, int value) const;
  void set(const char* name, float value) const;
  void set(const char* name, float x, float y) const;
  void set(const char* name, float x, float y, float z) const;
  void set(const char* name, float x, float y, float z, float w) const;
  void set_mat4(const char* name, const float* column_major) const;

 private:
  using Handle::Handle;
};

class Texture : public Handle<TextureDeleter> {
 public:
  Texture() noexcept = default;
  static Texture wrap(GLuint id) noexcept { return Texture(id); }
  /// A 2D texture with immutable storage, one level, nearest filtering.
  static Texture create_2d(GLenum internal_format, int width, int height);

 private:
  using Handle::Handle;
};

class Framebuffer : public Handle<FramebufferDeleter> {
 public:
  Framebuffer() noexcept = default;
  static Framebuffer wrap(GLuint id) noexcept { return Framebuffer(id); }
  static Framebuffer create();
  void attach(GLenum attachment, const Texture& texture) const;
  /// Selects the draw buffers (GL_NONE for depth only); throws GlError if the
  /// framebuffer is then incomplete.
  void set_draw_buffers(std::span<const GLenum> buffers, std::string_view label) const;

 private:
  using Handle::Handle;
};

/// A query object (GL_SAMPLES_PASSED, GL_ANY_SAMPLES_PASSED, GL_TIME_ELAPSED...).
/// The result is only ever polled: try_result() never blocks the render thread,
/// so a strategy asking for occlusion results gets them some frames later.
class Query : public Handle<QueryDeleter> {
 public:
  Query() noexcept = default;
  static Query wrap(GLuint id, GLenum target) noexcept { return Query(id, target); }
  static Query create(GLenum target);
  [[nodiscard]] GLenum target() const noexcept { return target_; }
  void begin() const { BeginQuery(target_, id()); }
  void end() const { EndQuery(target_); }
  /// The result if the GL has it, nullopt while it is still pending.
  [[nodiscard]] std::optional<std::uint64_t> try_result() const;

 private:
  Query(GLuint id, GLenum target) noexcept : Handle(id), target_(target) {}
  GLenum target_ = 0;
};

}  // namespace treecut::gl
