// The test programs' precompiled header (tests/CMakeLists.txt,
// treecut_test_pch; no renderer header, so CPU programs can use it): GoogleTest, the standard library and the project
// headers that most test files include. Parsing them was about half of a
// test file's compile (8.2 s -> 4.6 s for event_queue_test with GCC -O1);
// compiled once, every test program reuses it. A test file still includes
// what it uses: the header only saves the parse.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/strategies/builtin.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"
