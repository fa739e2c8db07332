// A core file that reaches the renderer: tests/layers.cmake must name it.
#include "treecut/splat/renderer.hpp"
