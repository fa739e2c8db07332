# What the two round trips against an installed package share (the example
# plugin's, cmake/plugin_roundtrip.cmake, and the embedding program's,
# cmake/embedding_roundtrip.cmake): their inputs checked, commands run with
# one error line, the development component installed into a fresh prefix,
# and a project configured and built against it. Included by both (cmake -P).

# Fails unless every variable named after TAG is set; starts WORK_DIR empty
# with the package installed in ${prefix}.
macro(roundtrip_begin tag)
  set(roundtrip_tag ${tag})
  foreach(var ${ARGN})
    if(NOT DEFINED ${var} OR "${${var}}" STREQUAL "")
      message(FATAL_ERROR "${roundtrip_tag}: ${var} is not set")
    endif()
  endforeach()
  file(REMOVE_RECURSE "${WORK_DIR}")
  set(prefix "${WORK_DIR}/prefix")
  run("install" ${CMAKE_COMMAND} --install "${BUILD_DIR}" --prefix "${prefix}"
      --component treecut_development)
endmacro()

# Runs a command; a failure ends the script naming WHAT. Its output is left
# in run_output.
function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${roundtrip_tag}: ${what} failed (${rc}):\n${out}")
  endif()
  set(run_output "${out}" PARENT_SCOPE)
endfunction()

# Configures SOURCE into BUILD against the installed package with the test's
# generator, compiler, build type and flags (LINKER_FLAGS_VAR: the CMake
# variable the flags also go to at link time), and builds it.
function(build_against_package what source build linker_flags_var)
  run("${what} configure" ${CMAKE_COMMAND} -S "${source}" -B "${build}" -G "${GENERATOR}"
      "-DCMAKE_PREFIX_PATH=${prefix}" "-DCMAKE_BUILD_TYPE=${BUILD_TYPE}"
      "-DCMAKE_CXX_COMPILER=${CXX_COMPILER}" "-DCMAKE_CXX_FLAGS=${EXTRA_FLAGS}"
      "-D${linker_flags_var}=${EXTRA_FLAGS}")
  run("${what} build" ${CMAKE_COMMAND} --build "${build}")
endfunction()
