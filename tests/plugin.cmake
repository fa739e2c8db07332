# The out-of-tree plugin round trip as one CTest test: install treecut from
# this build tree into a scratch prefix, configure and build
# strategies/example_plugin against it with find_package(treecut CONFIG), then
# load the plugin through a StrategyRegistry and run its strategy
# (plugin_test's ExamplePlugin tests). Included from tests/CMakeLists.txt.
set(_treecut_plugin_flags "")
if(TREECUT_SANITIZE)
  set(_treecut_plugin_flags "-fsanitize=${TREECUT_SANITIZE}")
endif()
add_test(NAME example_plugin_roundtrip
  COMMAND ${CMAKE_COMMAND}
    -DBUILD_DIR=${PROJECT_BINARY_DIR}
    -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
    -DWORK_DIR=${PROJECT_BINARY_DIR}/test-scratch/example_plugin
    -DPLUGIN_TEST=$<TARGET_FILE:plugin_test>
    -DGENERATOR=${CMAKE_GENERATOR}
    -DCXX_COMPILER=${CMAKE_CXX_COMPILER}
    -DBUILD_TYPE=${CMAKE_BUILD_TYPE}
    -DEXTRA_FLAGS=${_treecut_plugin_flags}
    -P ${PROJECT_SOURCE_DIR}/cmake/plugin_roundtrip.cmake)
set_tests_properties(example_plugin_roundtrip PROPERTIES LABELS unit TIMEOUT 600)
