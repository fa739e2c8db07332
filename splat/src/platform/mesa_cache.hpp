// Mesa's shader cache, quiet where it cannot be made (context.cpp): every
// back end that may load Mesa (OSMesa, GLFW, EGL) calls it before its first
// context.
#pragma once

namespace treecut::splat {

/// Disables Mesa's shader cache up front where its folder cannot be made or
/// written (Mesa would print a line of its own and disable it), unless the
/// user chose a cache setting.
void quiet_mesa_shader_cache();

}  // namespace treecut::splat
