// The OpenGL 4.5 core entry points the splat renderer uses, resolved at run
// time through the active back end's GetProcAddress (OSMesaGetProcAddress or
// glfwGetProcAddress). There is no system GL loader, and linking libGL and
// libOSMesa into one process makes plain `glFoo` symbols ambiguous, so nothing
// in treecut calls a GL function by its link-time name.
//
// The pointers are process-wide: the first context that becomes current loads
// them, and every later context must come from the same back end (checked by
// load(), which throws otherwise). Call them only on the render thread, with a
// context current.
#pragma once

#include <GL/glcorearb.h>

#include <stdexcept>
#include <string>

namespace treecut::gl {

// The query executor's proxies: one instanced draw per batch, an instance
// per request.
#define TREECUT_GL_INSTANCING(X)                                               \
  X(PFNGLDRAWARRAYSINSTANCEDBASEINSTANCEPROC, DrawArraysInstancedBaseInstance) \
  X(PFNGLVERTEXARRAYBINDINGDIVISORPROC, VertexArrayBindingDivisor)

// The query executor's batches: per-request sample counters in a shader
// storage buffer, persistently mapped, read once the batch's fence is
// signaled (GL 4.4+ core).
#define TREECUT_GL_SAMPLE_COUNTERS(X)                          \
  X(PFNGLBINDBUFFERBASEPROC, BindBufferBase)                   \
  X(PFNGLCLEARNAMEDBUFFERSUBDATAPROC, ClearNamedBufferSubData) \
  X(PFNGLCOPYNAMEDBUFFERSUBDATAPROC, CopyNamedBufferSubData)   \
  X(PFNGLMAPNAMEDBUFFERRANGEPROC, MapNamedBufferRange)         \
  X(PFNGLMEMORYBARRIERPROC, MemoryBarrier)                     \
  X(PFNGLFENCESYNCPROC, FenceSync)                             \
  X(PFNGLCLIENTWAITSYNCPROC, ClientWaitSync)                   \
  X(PFNGLDELETESYNCPROC, DeleteSync)

// Scenes of many objects: every object's cut in one call per pass, one
// indirect command per object (GL 4.3+ core).
#define TREECUT_GL_MULTI_DRAW(X)     \
  X(PFNGLBINDBUFFERPROC, BindBuffer) \
  X(PFNGLMULTIDRAWELEMENTSINDIRECTPROC, MultiDrawElementsIndirect)

// X(type, name): every function here is called as treecut::gl::name(...), and
// is loaded from "gl" #name.
#define TREECUT_GL_FUNCTIONS(X)                                        \
  X(PFNGLGETERRORPROC, GetError)                                       \
  X(PFNGLGETSTRINGPROC, GetString)                                     \
  X(PFNGLGETINTEGERVPROC, GetIntegerv)                                 \
  X(PFNGLGETFLOATVPROC, GetFloatv)                                     \
  X(PFNGLENABLEPROC, Enable)                                           \
  X(PFNGLDISABLEPROC, Disable)                                         \
  X(PFNGLVIEWPORTPROC, Viewport)                                       \
  X(PFNGLDEPTHFUNCPROC, DepthFunc)                                     \
  X(PFNGLDEPTHMASKPROC, DepthMask)                                     \
  X(PFNGLCOLORMASKPROC, ColorMask)                                     \
  X(PFNGLBLENDFUNCPROC, BlendFunc)                                     \
  X(PFNGLBLENDEQUATIONPROC, BlendEquation)                             \
  X(PFNGLFINISHPROC, Finish)                                           \
  X(PFNGLFLUSHPROC, Flush)                                             \
  X(PFNGLPIXELSTOREIPROC, PixelStorei)                                 \
  X(PFNGLREADPIXELSPROC, ReadPixels)                                   \
  X(PFNGLDRAWARRAYSPROC, DrawArrays)                                   \
  X(PFNGLDRAWELEMENTSPROC, DrawElements)                               \
  X(PFNGLCREATEBUFFERSPROC, CreateBuffers)                             \
  X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                             \
  X(PFNGLNAMEDBUFFERSTORAGEPROC, NamedBufferStorage)                   \
  X(PFNGLNAMEDBUFFERDATAPROC, NamedBufferData)                         \
  X(PFNGLNAMEDBUFFERSUBDATAPROC, NamedBufferSubData)                   \
  X(PFNGLCREATEVERTEXARRAYSPROC, CreateVertexArrays)                   \
  X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                   \
  X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                         \
  X(PFNGLVERTEXARRAYVERTEXBUFFERPROC, VertexArrayVertexBuffer)         \
  X(PFNGLVERTEXARRAYELEMENTBUFFERPROC, VertexArrayElementBuffer)       \
  X(PFNGLVERTEXARRAYATTRIBFORMATPROC, VertexArrayAttribFormat)         \
  X(PFNGLVERTEXARRAYATTRIBBINDINGPROC, VertexArrayAttribBinding)       \
  X(PFNGLENABLEVERTEXARRAYATTRIBPROC, EnableVertexArrayAttrib)         \
  X(PFNGLCREATESHADERPROC, CreateShader)                               \
  X(PFNGLSHADERSOURCEPROC, ShaderSource)                               \
  X(PFNGLCOMPILESHADERPROC, CompileShader)                             \
  X(PFNGLGETSHADERIVPROC, GetShaderiv)                                 \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                       \
  X(PFNGLDELETESHADERPROC, DeleteShader)                               \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram)                             \
  X(PFNGLATTACHSHADERPROC, AttachShader)                               \
  X(PFNGLDETACHSHADERPROC, DetachShader)                               \
  X(PFNGLLINKPROGRAMPROC, LinkProgram)                                 \
  X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                               \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                     \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                             \
  X(PFNGLUSEPROGRAMPROC, UseProgram)                                   \
  X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                   \
  X(PFNGLPROGRAMUNIFORM1IPROC, ProgramUniform1i)                       \
  X(PFNGLPROGRAMUNIFORM1UIPROC, ProgramUniform1ui)                     \
  X(PFNGLPROGRAMUNIFORM1FPROC, ProgramUniform1f)                       \
  X(PFNGLPROGRAMUNIFORM2FPROC, ProgramUniform2f)                       \
  X(PFNGLPROGRAMUNIFORM3FPROC, ProgramUniform3f)                       \
  X(PFNGLPROGRAMUNIFORM4FPROC, ProgramUniform4f)                       \
  X(PFNGLPROGRAMUNIFORMMATRIX4FVPROC, ProgramUniformMatrix4fv)         \
  X(PFNGLCREATETEXTURESPROC, CreateTextures)                           \
  X(PFNGLDELETETEXTURESPROC, DeleteTextures)                           \
  X(PFNGLTEXTURESTORAGE2DPROC, TextureStorage2D)                       \
  X(PFNGLTEXTUREPARAMETERIPROC, TextureParameteri)                     \
  X(PFNGLBINDTEXTUREUNITPROC, BindTextureUnit)                         \
  X(PFNGLCREATEFRAMEBUFFERSPROC, CreateFramebuffers)                   \
  X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                   \
  X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                         \
  X(PFNGLNAMEDFRAMEBUFFERTEXTUREPROC, NamedFramebufferTexture)         \
  X(PFNGLNAMEDFRAMEBUFFERDRAWBUFFERSPROC, NamedFramebufferDrawBuffers) \
  X(PFNGLNAMEDFRAMEBUFFERDRAWBUFFERPROC, NamedFramebufferDrawBuffer)   \
  X(PFNGLNAMEDFRAMEBUFFERREADBUFFERPROC, NamedFramebufferReadBuffer)   \
  X(PFNGLCHECKNAMEDFRAMEBUFFERSTATUSPROC, CheckNamedFramebufferStatus) \
  X(PFNGLCLEARNAMEDFRAMEBUFFERFVPROC, ClearNamedFramebufferfv)         \
  X(PFNGLBLITNAMEDFRAMEBUFFERPROC, BlitNamedFramebuffer)               \
  X(PFNGLCREATEQUERIESPROC, CreateQueries)                             \
  X(PFNGLDELETEQUERIESPROC, DeleteQueries)                             \
  X(PFNGLBEGINQUERYPROC, BeginQuery)                                   \
  X(PFNGLENDQUERYPROC, EndQuery)                                       \
  X(PFNGLGETQUERYOBJECTUI64VPROC, GetQueryObjectui64v)                 \
  X(PFNGLGETQUERYOBJECTUIVPROC, GetQueryObjectuiv)                     \
  TREECUT_GL_INSTANCING(X)                                             \
  TREECUT_GL_MULTI_DRAW(X)                                             \
  TREECUT_GL_SAMPLE_COUNTERS(X)

// The pointers are plain variables on purpose: a test may interpose an entry
// point by assigning its own function after load() and restoring the old
// pointer afterwards (render thread only), e.g. to check that nothing reads a
// query's counters before the fence of its batch was seen signaled.
#define TREECUT_GL_DECLARE(type, name) extern type name;
TREECUT_GL_FUNCTIONS(TREECUT_GL_DECLARE)
#undef TREECUT_GL_DECLARE

/// A GL call failed or a GL object could not be made (shader compile/link log,
/// incomplete framebuffer, missing entry point, no context).
class GlError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Resolves a "glName" to its address, or null.
using ProcResolver = void* (*)(const char* name);

/// Loads every entry point through `resolve` for the back end called
/// `backend` ("egl", "osmesa", "glfw"). Idempotent for the same back end; throws
/// GlError if an entry point is missing or another back end loaded them first.
/// Render thread only, with a context of that back end current.
void load(const char* backend, ProcResolver resolve);

/// True once load() succeeded.
bool loaded();
/// The back end that loaded the entry points ("egl", "osmesa", "glfw"), or
/// null before load().
const char* loaded_backend();

/// Throws GlError naming `what` if glGetError reports an error (drains all).
void check(const char* what);

}  // namespace treecut::gl
