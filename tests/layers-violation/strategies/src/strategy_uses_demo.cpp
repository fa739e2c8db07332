// A strategy reaching a header of the program by name: tests/layers.cmake
// must name it (it is beside no file here).
#include "viewer_app.hpp"
#include "treecut/culling/hlod_blocks.hpp"
