#include "treecut/splat/gl.hpp"

#include <cstdio>
#include <cstring>
#include <mutex>
#include <string>

namespace treecut::gl {

#define TREECUT_GL_DEFINE(type, name) type name = nullptr;
TREECUT_GL_FUNCTIONS(TREECUT_GL_DEFINE)
#undef TREECUT_GL_DEFINE

namespace {
std::mutex g_mutex;
const char* g_backend = nullptr;  // string literal of the back end that loaded, or null
}  // namespace

void load(const char* backend, ProcResolver resolve) {
  std::lock_guard lock(g_mutex);
  if (g_backend != nullptr) {
    if (std::strcmp(g_backend, backend) == 0) return;
    throw GlError(std::string("GL entry points were loaded for ") + g_backend +
                  "; a second back end (" + backend + ") cannot share this process");
  }
  std::string missing;
  // Resolve into locals first so a failed load leaves every pointer null.
#define TREECUT_GL_RESOLVE(type, name)                              \
  auto* local_##name = reinterpret_cast<type>(resolve("gl" #name)); \
  if (local_##name == nullptr) missing += (missing.empty() ? "gl" : ", gl") + std::string(#name);
  TREECUT_GL_FUNCTIONS(TREECUT_GL_RESOLVE)
#undef TREECUT_GL_RESOLVE
  if (!missing.empty())
    throw GlError(std::string(backend) + ": missing GL entry points: " + missing);
#define TREECUT_GL_ASSIGN(type, name) name = local_##name;
  TREECUT_GL_FUNCTIONS(TREECUT_GL_ASSIGN)
#undef TREECUT_GL_ASSIGN
  g_backend = backend;
}

bool loaded() {
  std::lock_guard lock(g_mutex);
  return g_backend != nullptr;
}

const char* loaded_backend() {
  std::lock_guard lock(g_mutex);
  return g_backend;
}

void check(const char* what) {
  GLenum first = GL_NO_ERROR;
  for (GLenum e = GetError(); e != GL_NO_ERROR; e = GetError()) {
    if (first == GL_NO_ERROR) first = e;
  }
  if (first != GL_NO_ERROR) {
    char code[16];
    std::snprintf(code, sizeof code, "0x%04x", first);
    throw GlError(std::string(what) + ": GL error " + code);
  }
}

}  // namespace treecut::gl
