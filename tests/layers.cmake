# The layers depend one way (docs/architecture.md, "## Layers"):
#
#     treecut::core  <-  treecut::culling  <-  treecut::splat       <-  demo/
#                                          <-  treecut::strategies  <-
#
# CMake's link interfaces enforce the libraries; this script checks the
# sources, so an include of a header above its layer fails even when the
# libraries happen to link: lib/ (core) includes no culling, strategies,
# splat or demo header; lib/culling/ none of strategies, splat or demo;
# splat/ none of strategies or demo; strategies/ none of splat or demo.
# demo/ includes demo/tools/ (treecut::tools), so treecut/tools/ counts as
# demo's, and so does the umbrella header treecut/treecut.hpp (demo/umbrella).
#
#     cmake -DROOT=<a source tree> -P tests/layers.cmake
#
# prints one line per offending include (FILE:LINE: includes HEADER, a header
# of LAYER) and fails. A quoted include that is not a treecut/ header must be
# a file beside the includer or in its own library's src/ folder: a layer
# cannot reach demo/'s headers by name either. Two ctests run it: on this
# tree (must pass) and on tests/layers-violation/, a small tree of three
# offending files (must fail), so the check is known to be able to fail.
if(DEFINED ROOT)
  get_filename_component(ROOT "${ROOT}" ABSOLUTE)
endif()
if(NOT DEFINED ROOT)
  message(FATAL_ERROR "layers.cmake: give -DROOT=<source tree>")
endif()

# layer | its folders | the include prefixes it must not use
set(layer_names core culling splat strategies)
set(core_dirs lib/include lib/src)
set(core_banned "treecut/culling/" "treecut/strategies/" "treecut/splat/" "treecut/tools/"
                "treecut/treecut.hpp")
set(culling_dirs lib/culling)
set(culling_banned "treecut/strategies/" "treecut/splat/" "treecut/tools/" "treecut/treecut.hpp")
set(splat_dirs splat)
set(splat_banned "treecut/strategies/" "treecut/tools/" "treecut/treecut.hpp")
set(strategies_dirs strategies)
set(strategies_banned "treecut/splat/" "treecut/tools/" "treecut/treecut.hpp")

set(problems 0)
foreach(layer IN LISTS layer_names)
  foreach(dir IN LISTS ${layer}_dirs)
    file(GLOB_RECURSE sources "${ROOT}/${dir}/*.cpp" "${ROOT}/${dir}/*.hpp")
    foreach(source IN LISTS sources)
      get_filename_component(source_dir "${source}" DIRECTORY)
      file(STRINGS "${source}" lines REGEX "^[ \t]*#[ \t]*include")
      file(STRINGS "${source}" all_lines)
      foreach(line IN LISTS lines)
        if(NOT line MATCHES "#[ \t]*include[ \t]*([<\"])([^>\"]+)[>\"]")
          continue()
        endif()
        set(delimiter "${CMAKE_MATCH_1}")
        set(header "${CMAKE_MATCH_2}")
        set(reason "")
        foreach(banned IN LISTS ${layer}_banned)
          string(FIND "${header}" "${banned}" at)
          if(at EQUAL 0)
            set(reason "a header of a layer above ${layer}")
          endif()
        endforeach()
        if(reason STREQUAL "" AND delimiter STREQUAL "\"" AND NOT header MATCHES "^treecut/")
          # A private header: beside the includer, or in the library's src/.
          string(REGEX MATCH "^[^/]+(/culling)?" library "${dir}")
          if(NOT EXISTS "${source_dir}/${header}" AND NOT EXISTS "${ROOT}/${library}/src/${header}")
            set(reason "not a header of ${layer} (a private header must be beside it or in ${library}/src/)")
          endif()
        endif()
        if(NOT reason STREQUAL "")
          list(FIND all_lines "${line}" index)
          math(EXPR line_number "${index} + 1")
          file(RELATIVE_PATH shown "${ROOT}" "${source}")
          message("${shown}:${line_number}: includes ${header}, ${reason}")
          math(EXPR problems "${problems} + 1")
        endif()
      endforeach()
    endforeach()
  endforeach()
endforeach()

if(problems GREATER 0)
  message(FATAL_ERROR "${problems} include(s) against the layers")
endif()
message("layers: every include of core, culling, splat and strategies is of its own layer or one below")
