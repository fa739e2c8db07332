# Script (cmake -P) behind the example_plugin_roundtrip test; see tests/plugin.cmake.
include(${CMAKE_CURRENT_LIST_DIR}/package_roundtrip.cmake)
roundtrip_begin(plugin_roundtrip BUILD_DIR SOURCE_DIR WORK_DIR PLUGIN_TEST GENERATOR CXX_COMPILER)
build_against_package("plugin" "${SOURCE_DIR}/strategies/example_plugin" "${WORK_DIR}/build"
                      CMAKE_MODULE_LINKER_FLAGS)
set(plugin "${WORK_DIR}/build/libtreecut_example_plugin.so")
if(NOT EXISTS "${plugin}")
  message(FATAL_ERROR "plugin_roundtrip: ${plugin} was not built")
endif()
# Built as the guide says, the plugin exports its two entry points and nothing
# of the static core (docs/plugin-guide.md, section 2).
find_program(NM nm REQUIRED)
run("nm" ${NM} -D --defined-only "${plugin}")
string(REGEX MATCHALL "[^\n]+" symbol_lines "${run_output}")
set(exported "")
foreach(l IN LISTS symbol_lines)
  string(REGEX REPLACE "^[0-9a-fA-F]* *[A-Za-z] " "" name "${l}")
  list(APPEND exported "${name}")
endforeach()
list(SORT exported)
if(NOT exported STREQUAL "treecut_plugin_api_version;treecut_plugin_register")
  list(LENGTH exported count)
  message(FATAL_ERROR "plugin_roundtrip: ${plugin} exports ${count} symbols, expected the two "
                      "entry points only:\n${run_output}")
endif()
run("plugin load" ${CMAKE_COMMAND} -E env "TREECUT_EXAMPLE_PLUGIN=${plugin}"
    "${PLUGIN_TEST}" --gtest_filter=ExamplePlugin.*)
if(run_output MATCHES "SKIPPED" OR NOT run_output MATCHES "PASSED")
  message(FATAL_ERROR "plugin_roundtrip: the ExamplePlugin tests did not run:\n${run_output}")
endif()
message(STATUS "${run_output}")

# The plugin's named counter through the program: a stats.csv column and a
# summary.json entry, with the value its parameter asks for (depth 1.0: the
# deepest level).
if(DEFINED TREECUT AND NOT TREECUT STREQUAL "")
  run("render with the plugin" "${TREECUT}" render --plugin "${plugin}" -s uniform_depth
      -p depth=1 -n 3 --sync --no-png -o "${WORK_DIR}/render")
  file(GLOB stats "${WORK_DIR}/render/*stats.csv" "${WORK_DIR}/render/*/stats.csv")
  if(NOT stats)
    message(FATAL_ERROR "plugin_roundtrip: render wrote no stats.csv:\n${run_output}")
  endif()
  list(GET stats 0 stats)
  file(STRINGS "${stats}" rows)
  list(GET rows 0 header)
  string(REPLACE "," ";" header "${header}")
  list(FIND header "uniform_depth_target" column)
  if(column LESS 0)
    message(FATAL_ERROR "plugin_roundtrip: no uniform_depth_target column in ${stats}")
  endif()
  get_filename_component(stats_dir "${stats}" DIRECTORY)
  file(READ "${stats_dir}/summary.json" summary)
  string(JSON unit GET "${summary}" counters uniform_depth_target unit)
  string(JSON target GET "${summary}" counters uniform_depth_target mean)
  if(NOT target GREATER 0 OR NOT unit STREQUAL "levels")
    message(FATAL_ERROR "plugin_roundtrip: uniform_depth_target ${target} (${unit}), expected the "
                        "deepest level in levels")
  endif()
  message(STATUS "uniform_depth_target ${target} ${unit} in ${stats}")
endif()
