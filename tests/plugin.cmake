# The out-of-tree plugin round trip as one CTest test: install treecut from
# this build tree into a scratch prefix, configure and build
# strategies/example_plugin against it with find_package(treecut CONFIG), then
# load the plugin through a StrategyRegistry and run its strategy
# (plugin_gl_test's ExamplePlugin tests). Included from tests/CMakeLists.txt.
set(_treecut_plugin_flags "")
if(TREECUT_SANITIZE)
  set(_treecut_plugin_flags "-fsanitize=${TREECUT_SANITIZE}")
endif()
add_test(NAME example_plugin_roundtrip
  COMMAND ${CMAKE_COMMAND}
    -DBUILD_DIR=${PROJECT_BINARY_DIR}
    -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
    -DWORK_DIR=${PROJECT_BINARY_DIR}/test-scratch/example_plugin
    -DPLUGIN_TEST=$<TARGET_FILE:plugin_gl_test>
    -DTREECUT=$<TARGET_FILE:treecut>
    -DGENERATOR=${CMAKE_GENERATOR}
    -DCXX_COMPILER=${CMAKE_CXX_COMPILER}
    -DBUILD_TYPE=${CMAKE_BUILD_TYPE}
    -DEXTRA_FLAGS=${_treecut_plugin_flags}
    -P ${PROJECT_SOURCE_DIR}/cmake/plugin_roundtrip.cmake)
set_tests_properties(example_plugin_roundtrip PROPERTIES LABELS unit TIMEOUT 600)

# docs/embedding.md's program against the installed package, run headless on
# the bunny (cmake/embedding_roundtrip.cmake).
add_test(NAME embedding_roundtrip
  COMMAND ${CMAKE_COMMAND}
    -DBUILD_DIR=${PROJECT_BINARY_DIR}
    -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
    -DWORK_DIR=${PROJECT_BINARY_DIR}/test-scratch/embedding
    -DMODEL=${TREECUT_SHARED_DIR}/assets/bun_zipper.ply
    -DGENERATOR=${CMAKE_GENERATOR}
    -DCXX_COMPILER=${CMAKE_CXX_COMPILER}
    -DBUILD_TYPE=${CMAKE_BUILD_TYPE}
    -DEXTRA_FLAGS=${_treecut_plugin_flags}
    -P ${PROJECT_SOURCE_DIR}/cmake/embedding_roundtrip.cmake)
set_tests_properties(embedding_roundtrip PROPERTIES LABELS "unit;gl" TIMEOUT 600)

# A plugin whose strategies misbehave (tests/misbehaving_plugin.cpp): plugin_gl_test
# loads it to check that errors name the strategy and the plugin file, and that
# `treecut render` reports them. Built like a plugin author would (hidden
# visibility, the static core kept out of the dynamic symbol table).
add_library(treecut_misbehaving_plugin MODULE ${CMAKE_CURRENT_SOURCE_DIR}/misbehaving_plugin.cpp)
target_link_libraries(treecut_misbehaving_plugin PRIVATE treecut::core)
set_target_properties(treecut_misbehaving_plugin PROPERTIES
  CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON PREFIX "lib")
target_link_options(treecut_misbehaving_plugin PRIVATE "LINKER:--exclude-libs,ALL")
treecut_warnings(treecut_misbehaving_plugin)
add_dependencies(plugin_gl_test treecut_misbehaving_plugin treecut)
target_compile_definitions(plugin_gl_test PRIVATE
  TREECUT_MISBEHAVING_PLUGIN="$<TARGET_FILE:treecut_misbehaving_plugin>")

# Libraries that crash, exit or lie as they load (tests/odd_library.cpp, one
# per variant): plugin_gl_test checks that loading each is an error naming it.
foreach(odd crash exit0 exit42 data)
  string(TOUPPER ${odd} odd_upper)
  add_library(treecut_odd_${odd} MODULE ${CMAKE_CURRENT_SOURCE_DIR}/odd_library.cpp)
  target_compile_definitions(treecut_odd_${odd} PRIVATE TREECUT_ODD_${odd_upper})
  set_target_properties(treecut_odd_${odd} PROPERTIES PREFIX "lib")
  treecut_warnings(treecut_odd_${odd})
  add_dependencies(plugin_gl_test treecut_odd_${odd})
endforeach()
target_compile_definitions(plugin_gl_test PRIVATE
  TREECUT_ODD_LIBRARY_DIR="$<TARGET_FILE_DIR:treecut_odd_crash>")

# A plugin whose strategy posts GPU queries (tests/querying_plugin.cpp): none
# of the built-in ones does; render_command_gl_test runs `treecut render` with it
# to see the query columns of stats.csv and summary.json filled in.
add_library(treecut_querying_plugin MODULE ${CMAKE_CURRENT_SOURCE_DIR}/querying_plugin.cpp)
target_link_libraries(treecut_querying_plugin PRIVATE treecut::core)
set_target_properties(treecut_querying_plugin PROPERTIES
  CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON PREFIX "lib")
target_link_options(treecut_querying_plugin PRIVATE "LINKER:--exclude-libs,ALL")
treecut_warnings(treecut_querying_plugin)
add_dependencies(render_command_gl_test treecut_querying_plugin treecut)
target_compile_definitions(render_command_gl_test PRIVATE
  TREECUT_QUERYING_PLUGIN="$<TARGET_FILE:treecut_querying_plugin>")
