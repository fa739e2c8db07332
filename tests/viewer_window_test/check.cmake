# Runs `treecut view` in a real window under Xvfb on a scripted path and checks
# the screenshots it took through its own screenshot function.
# -DTREECUT=<program> -DXVFB_RUN=<xvfb-run or empty> -DSCRIPT=<run.script> -DOUT=<folder>
if(NOT XVFB_RUN)
  message(FATAL_ERROR "xvfb-run not found: the window test needs Xvfb (apt install xvfb)")
endif()
file(REMOVE_RECURSE "${OUT}")
file(MAKE_DIRECTORY "${OUT}")
# No leak check here (ASan builds): Mesa's GLX/DRI driver, dlclosed when the
# window closes, leaks 255 strdup'ed strings (a minimal GLFW program under
# Xvfb reports the same), and its frames are unknown by then, so no
# suppression can name them. The leak check still covers the headless paths.
# The program's exit code is printed inside the X session: xvfb-run's own is
# not it (xvfb-run exits 5 when it cannot remove its temporary folder).
execute_process(
  COMMAND ${CMAKE_COMMAND} -E env LSAN_OPTIONS=detect_leaks=0
          "${XVFB_RUN}" -a -s "-screen 0 1024x768x24"
          sh -c "\"$0\" \"$@\"; echo \"treecut exit code $?\""
          "${TREECUT}" view --default-points 30000 --width 640 --height 400 --target-fps 0
          --script "${SCRIPT}" --screenshot-dir "${OUT}"
  RESULT_VARIABLE xvfb_rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 240)
message("${out}${err}")
if(NOT out MATCHES "treecut exit code ([0-9]+)")
  message(FATAL_ERROR "treecut view did not run (xvfb-run exited with ${xvfb_rc})")
endif()
if(NOT CMAKE_MATCH_1 EQUAL 0)
  message(FATAL_ERROR "treecut view exited with ${CMAKE_MATCH_1}")
endif()
# Each shot and its IHDR width and height: the window's framebuffer (640 x
# 400, 0x280 x 0x190), and big.png drawn at a size of its own (1280 x 800).
foreach(shot_size start.png:0000028000000190 start-hud.png:0000028000000190
                  start-nohud.png:0000028000000190 end.png:0000028000000190
                  big.png:0000050000000320)
  string(REPLACE ":" ";" pair "${shot_size}")
  list(GET pair 0 shot)
  list(GET pair 1 expected)
  set(png "${OUT}/${shot}")
  if(NOT EXISTS "${png}")
    message(FATAL_ERROR "${shot} was not written")
  endif()
  file(READ "${png}" head LIMIT 24 HEX)
  string(SUBSTRING "${head}" 0 16 magic)
  string(SUBSTRING "${head}" 32 16 size)
  if(NOT magic STREQUAL "89504e470d0a1a0a")
    message(FATAL_ERROR "${shot} is not a PNG (${magic})")
  endif()
  if(NOT size STREQUAL expected)
    message(FATAL_ERROR "${shot} has size ${size}, expected ${expected} (IHDR width, height)")
  endif()
  file(SIZE "${png}" bytes)
  # A flat frame compresses to a few KiB; a rendered model does not.
  if(bytes LESS 20000)
    message(FATAL_ERROR "${shot} is only ${bytes} bytes: nothing rendered?")
  endif()
endforeach()
file(SHA256 "${OUT}/start.png" a)
file(SHA256 "${OUT}/end.png" b)
if(a STREQUAL b)
  message(FATAL_ERROR "the camera path did not change the view")
endif()
# Issue 30: a screenshot is the scene alone unless asked with the HUD, and
# hiding the HUD leaves the scene's pixels as they were (the cut is still).
file(SHA256 "${OUT}/start-hud.png" with_hud)
file(SHA256 "${OUT}/start-nohud.png" hidden)
if(a STREQUAL with_hud)
  message(FATAL_ERROR "start-hud.png (screenshot NAME hud) does not show the HUD")
endif()
if(NOT a STREQUAL hidden)
  message(FATAL_ERROR "hiding the HUD changed the scene's pixels (start.png, start-nohud.png)")
endif()
# Picking: two pixels of the terrain give two points and their distance.
if(NOT out MATCHES "pick 320 200: [-0-9.]+ [-0-9.]+ [-0-9.]+, nearest point")
  message(FATAL_ERROR "pick 320 200 printed no point")
endif()
if(NOT out MATCHES "measure   distance [0-9]+\\.[0-9]+, height [-+][0-9.]+, horizontal")
  message(FATAL_ERROR "two picks printed no distance")
endif()
# (--target-fps 0: the default frame-rate control would change the cut
# between the screenshots.) It stays out of the way: at most a fifth of the window as it opens.
if(NOT out MATCHES "start-hud.png \\(HUD ([0-9]+)x([0-9]+) of ([0-9]+)x([0-9]+)\\)")
  message(FATAL_ERROR "no HUD size printed with start-hud.png")
endif()
math(EXPR hud_area "${CMAKE_MATCH_1} * ${CMAKE_MATCH_2} * 5")
math(EXPR window_area "${CMAKE_MATCH_3} * ${CMAKE_MATCH_4}")
if(hud_area GREATER window_area)
  message(FATAL_ERROR "the HUD covers more than a fifth of the window: "
                      "${CMAKE_MATCH_1}x${CMAKE_MATCH_2} of ${CMAKE_MATCH_3}x${CMAKE_MATCH_4}")
endif()
