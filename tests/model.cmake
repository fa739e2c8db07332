# The Feedback Stage's wait/process exchange, model-checked with spin:
# tests/model/exchange.pml must pass and every tests/model/exchange_broken_*.pml
# must be rejected (tests/model/check.sh). Needs the Debian packages spin and gcc.
# The check does not depend on how treecut is compiled, so the sanitizer
# configurations skip it (CI runs it once, in Release).
if(TREECUT_SANITIZE)
  return()
endif()
add_test(NAME exchange_model
         COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/model/check.sh ${CMAKE_CURRENT_BINARY_DIR}/model)
# About 50 s of one core, and CTest numbers it after every discovered test:
# a cost makes `ctest -j` start it first instead of leaving it as the tail.
set_tests_properties(exchange_model PROPERTIES LABELS model TIMEOUT 600 COST 1000)
