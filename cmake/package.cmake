# The installed C++ package (docs/cpp.md): headers under include/specula/, one static library and one export set per
# component, and a specula-config.cmake that finds only the dependencies of the components asked for.
include(CMakePackageConfigHelpers)

set(SPECULA_CMAKE_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/specula CACHE STRING
    "Where cmake --install puts specula-config.cmake (relative to the prefix)")

foreach(lib IN LISTS SPECULA_LIBRARIES)
  install(TARGETS specula_${lib} EXPORT specula-${lib}-targets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev)
  install(DIRECTORY ${lib}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/specula/${lib} COMPONENT dev
          FILES_MATCHING PATTERN "*.h")
  install(EXPORT specula-${lib}-targets NAMESPACE specula:: DESTINATION ${SPECULA_CMAKE_INSTALL_DIR} COMPONENT dev)
endforeach()
install(FILES ${SPECULA_INCLUDE_DIR}/specula/version.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/specula COMPONENT dev)

configure_package_config_file(cmake/specula-config.cmake.in ${CMAKE_CURRENT_BINARY_DIR}/specula-config.cmake
                              INSTALL_DESTINATION ${SPECULA_CMAKE_INSTALL_DIR})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/specula-config-version.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/specula-config.cmake ${CMAKE_CURRENT_BINARY_DIR}/specula-config-version.cmake
        DESTINATION ${SPECULA_CMAKE_INSTALL_DIR} COMPONENT dev)
