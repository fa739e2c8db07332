// Interposed GL query entry points for the in-frame traversals' tests
// (chc_gl_test, hlod_traversal_gl_test): which query's availability was seen,
// the reads of a result before it (a read that may block), and those while
// the traversal still had work (has_work). Every available result is first
// reported pending twice (hidden), so a traversal that skips the check reads
// early and is caught. One object at a time, render thread only; the real
// entry points come back when it goes (gl.hpp: the pointers may be swapped).
#pragma once

#include <GL/glcorearb.h>

#include <functional>
#include <map>
#include <utility>

#include "treecut/splat/gl.hpp"

namespace treecut::test {

struct QueryCheck {
  static inline PFNGLBEGINQUERYPROC real_begin = nullptr;
  static inline PFNGLGETQUERYOBJECTUIVPROC real_uiv = nullptr;
  static inline PFNGLGETQUERYOBJECTUI64VPROC real_ui64v = nullptr;
  static inline PFNGLCREATEQUERIESPROC real_create = nullptr;
  static inline std::map<GLuint, bool> seen;
  static inline std::map<GLuint, int> hide;  // polls still to report "pending"
  static inline int hidden = 0, early_reads = 0, early_with_work = 0, reads = 0, created = 0;
  /// Whether the traversal has work left (for early_with_work); may be empty.
  static inline std::function<bool()> has_work;

  static void APIENTRY begin(GLenum target, GLuint id) {
    seen[id] = false;
    hide[id] = 2;
    real_begin(target, id);
  }
  static void APIENTRY uiv(GLuint id, GLenum pname, GLuint* v) {
    real_uiv(id, pname, v);
    if (pname != GL_QUERY_RESULT_AVAILABLE) return;
    if (*v != GL_FALSE && hide[id] > 0) {
      --hide[id];
      ++hidden;
      *v = GL_FALSE;  // available in truth, reported pending
    }
    if (*v != GL_FALSE) seen[id] = true;
  }
  static void APIENTRY ui64v(GLuint id, GLenum pname, GLuint64* v) {
    if (pname == GL_QUERY_RESULT) {
      ++reads;
      if (!seen[id]) {
        ++early_reads;
        if (has_work && has_work()) ++early_with_work;
      }
    }
    real_ui64v(id, pname, v);
  }
  static void APIENTRY create(GLenum target, GLsizei n, GLuint* ids) {
    created += n;
    real_create(target, n, ids);
  }
  QueryCheck() {
    real_begin = std::exchange(gl::BeginQuery, &begin);
    real_uiv = std::exchange(gl::GetQueryObjectuiv, &uiv);
    real_ui64v = std::exchange(gl::GetQueryObjectui64v, &ui64v);
    real_create = std::exchange(gl::CreateQueries, &create);
    seen.clear();
    hide.clear();
    hidden = early_reads = early_with_work = reads = created = 0;
  }
  ~QueryCheck() {
    gl::BeginQuery = real_begin;
    gl::GetQueryObjectuiv = real_uiv;
    gl::GetQueryObjectui64v = real_ui64v;
    gl::CreateQueries = real_create;
    has_work = nullptr;
  }
  QueryCheck(const QueryCheck&) = delete;
  QueryCheck& operator=(const QueryCheck&) = delete;
};

}  // namespace treecut::test
