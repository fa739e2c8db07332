# Install and export rules: `cmake --install BUILD --prefix P` gives P a
# find_package(treecut CONFIG) package with the imported targets
# treecut::core, treecut::culling, treecut::strategies and treecut::splat
# (static, position independent, so a plugin shared library can link them),
# treecut::treecut (all four, for a program that embeds the engine:
# docs/embedding.md), their headers, and the `treecut` program. Components: treecut_development (libraries, headers, CMake
# package) and treecut_runtime (the program).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(TREECUT_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/treecut)

# A plugin (a module or shared library) linking the installed static core gets
# its own private copy: --exclude-libs keeps the archives' symbols out of its
# dynamic symbol table, so it exports only its two entry points, whatever
# visibility the core was compiled with, and never interposes on the host's
# copy. Only for the installed targets and only for shared consumers.
set_property(TARGET treecut_core treecut_culling treecut_strategies APPEND PROPERTY INTERFACE_LINK_OPTIONS
  "$<INSTALL_INTERFACE:$<$<IN_LIST:$<TARGET_PROPERTY:TYPE>,MODULE_LIBRARY;SHARED_LIBRARY>:LINKER:--exclude-libs,ALL>>")

install(TARGETS treecut_core treecut_culling treecut_strategies treecut_splat treecut_all
        EXPORT treecutTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT treecut_development
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT treecut_development
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/lib/include/treecut
                  ${PROJECT_SOURCE_DIR}/lib/culling/include/treecut
                  ${PROJECT_SOURCE_DIR}/strategies/include/treecut
                  ${PROJECT_SOURCE_DIR}/splat/include/treecut
                  ${PROJECT_SOURCE_DIR}/demo/umbrella/include/treecut
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT treecut_development
  FILES_MATCHING PATTERN "*.hpp")
install(EXPORT treecutTargets NAMESPACE treecut:: DESTINATION ${TREECUT_INSTALL_CMAKEDIR}
  COMPONENT treecut_development)

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/treecutConfig.cmake.in
  ${PROJECT_BINARY_DIR}/treecutConfig.cmake INSTALL_DESTINATION ${TREECUT_INSTALL_CMAKEDIR})
# The plugin ABI carries C++ types, so only the same minor version is compatible.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/treecutConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/treecutConfig.cmake
              ${PROJECT_BINARY_DIR}/treecutConfigVersion.cmake
  DESTINATION ${TREECUT_INSTALL_CMAKEDIR} COMPONENT treecut_development)

if(TARGET treecut)
  install(TARGETS treecut RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT treecut_runtime)
endif()
