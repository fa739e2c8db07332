// The View including a strategy: tests/layers.cmake must name it.
#include <treecut/strategies/hoq.hpp>
