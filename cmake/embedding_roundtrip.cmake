# The program of docs/embedding.md, built against an installed package and
# run headless: the ctest `embedding_roundtrip` (tests/plugin.cmake). The
# CMakeLists.txt and embed.cpp are the ```cmake and ```cpp blocks of the doc,
# so the doc cannot drift from what builds.
#
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... -DMODEL=a.ply
#         -DGENERATOR=... -DCXX_COMPILER=... [-DBUILD_TYPE=...] [-DEXTRA_FLAGS=...]
#         -P cmake/embedding_roundtrip.cmake
include(${CMAKE_CURRENT_LIST_DIR}/package_roundtrip.cmake)

# The one fenced block of LANGUAGE in the doc.
function(doc_block language out_file)
  file(READ "${SOURCE_DIR}/docs/embedding.md" doc)
  string(FIND "${doc}" "```${language}\n" begin)
  if(begin LESS 0)
    message(FATAL_ERROR "embedding_roundtrip: docs/embedding.md has no ```${language} block")
  endif()
  string(LENGTH "```${language}\n" fence)
  math(EXPR begin "${begin} + ${fence}")
  string(SUBSTRING "${doc}" ${begin} -1 rest)
  string(FIND "${rest}" "```" end)
  string(SUBSTRING "${rest}" 0 ${end} block)
  file(WRITE "${out_file}" "${block}")
endfunction()

roundtrip_begin(embedding_roundtrip BUILD_DIR SOURCE_DIR WORK_DIR MODEL GENERATOR CXX_COMPILER)
doc_block(cmake "${WORK_DIR}/src/CMakeLists.txt")
doc_block(cpp "${WORK_DIR}/src/embed.cpp")
build_against_package("embed" "${WORK_DIR}/src" "${WORK_DIR}/build" CMAKE_EXE_LINKER_FLAGS)
set(png "${WORK_DIR}/last.png")
# Its own cache folder: the run maps or builds MODEL's hierarchy there.
run("embed" ${CMAKE_COMMAND} -E env "XDG_CACHE_HOME=${WORK_DIR}/cache"
    "${WORK_DIR}/build/embed" "${MODEL}" "${png}")
if(NOT run_output MATCHES "splats, [1-9][0-9]* iterations")
  message(FATAL_ERROR "embedding_roundtrip: embed printed no frame summary:\n${run_output}")
endif()
file(READ "${png}" header LIMIT 8 HEX)
file(SIZE "${png}" png_size)
if(NOT header STREQUAL "89504e470d0a1a0a" OR png_size LESS 1000)
  message(FATAL_ERROR "embedding_roundtrip: ${png} is no PNG image (${png_size} bytes)")
endif()
# A program that is given no model fails with exit 2 and one line.
execute_process(COMMAND "${WORK_DIR}/build/embed" "${WORK_DIR}/no-such.ply" "${WORK_DIR}/x.png"
                RESULT_VARIABLE rc ERROR_VARIABLE err OUTPUT_QUIET)
if(NOT rc EQUAL 2 OR NOT err MATCHES "^embed: [^\n]*no-such.ply[^\n]*\n$")
  message(FATAL_ERROR "embedding_roundtrip: a missing model gave ${rc}: ${err}")
endif()
message(STATUS "${run_output}")
