// The GL test programs' precompiled header (tests/CMakeLists.txt,
// treecut_test_gl_pch): the CPU programs' one and the renderer's headers.
#pragma once

#include "test_pch.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/renderer.hpp"
