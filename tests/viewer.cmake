# viewer_window_test: `treecut view` in a real window under Xvfb, on the
# scripted path of tests/viewer_window_test/run.script; it must open, render,
# take screenshots through its own screenshot function and exit with 0.
# Include from tests/CMakeLists.txt (needs the `treecut` target).
find_program(TREECUT_XVFB_RUN xvfb-run)
add_test(NAME viewer_window_test
         COMMAND ${CMAKE_COMMAND} -DTREECUT=$<TARGET_FILE:treecut> -DXVFB_RUN=${TREECUT_XVFB_RUN}
                 -DSCRIPT=${CMAKE_CURRENT_SOURCE_DIR}/viewer_window_test/run.script
                 -DOUT=${CMAKE_CURRENT_BINARY_DIR}/viewer_window_test
                 -P ${CMAKE_CURRENT_SOURCE_DIR}/viewer_window_test/check.cmake)
set_tests_properties(viewer_window_test PROPERTIES LABELS "window" TIMEOUT 300)
