# `cmake --install`: the occmap program with its manual page, its example sites, the libraries with the public headers
# and an exported CMake package (find_package(occmap), occmap::occmap), the Python module; and
# `cpack -G DEB`. Layout: GNUInstallDirs (/usr/bin, /usr/lib/<multiarch>, /usr/include/occmap,
# /usr/share/occmap, /usr/lib/python3/dist-packages).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# The modules a user's program links (not serve, bench: the command line's own).
set(OCCMAP_INSTALLED_MODULES util geometry calib lut detect fusion objects track publish io site sim eval pipeline demo)
add_library(occmap_all INTERFACE)
target_link_libraries(occmap_all INTERFACE occmap_pipeline occmap_sim occmap_eval occmap_demo)
# The headers are C++20: a consumer under its compiler's default (C++17 for GCC 12) gets it too.
target_compile_features(occmap_all INTERFACE cxx_std_20)
set_target_properties(occmap_all PROPERTIES EXPORT_NAME occmap)
set(occmap_export_targets occmap_all occmap_opencv occmap_warnings)
foreach(m ${OCCMAP_INSTALLED_MODULES})
  set_target_properties(occmap_${m} PROPERTIES EXPORT_NAME ${m})
  list(APPEND occmap_export_targets occmap_${m})
endforeach()
install(TARGETS ${occmap_export_targets} EXPORT occmapTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT occmapTargets NAMESPACE occmap:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/occmap COMPONENT dev)
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/occmapConfig.cmake.in
  ${CMAKE_BINARY_DIR}/occmapConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/occmap)
write_basic_package_version_file(${CMAKE_BINARY_DIR}/occmapConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/occmapConfig.cmake ${CMAKE_BINARY_DIR}/occmapConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/occmap COMPONENT dev)

# Public headers: what site, tables, fusion, objects, trackers, run, simulator and evaluation
# include (cmake/public_headers.txt, checked by tests/install_test.sh); internal ones (the
# fast fusion's probe tables and *ForTesting hooks, split internals) stay out.
file(STRINGS ${CMAKE_SOURCE_DIR}/cmake/public_headers.txt occmap_public_headers REGEX "^occmap/")
foreach(h ${occmap_public_headers})
  get_filename_component(dir ${h} DIRECTORY)
  install(FILES ${CMAKE_SOURCE_DIR}/src/${h} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/${dir} COMPONENT dev)
endforeach()

install(TARGETS occmap RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT bin)
install(DIRECTORY ${CMAKE_SOURCE_DIR}/sites/ DESTINATION ${CMAKE_INSTALL_DATADIR}/occmap/sites COMPONENT bin
        FILES_MATCHING PATTERN "*.yaml")
install(FILES ${CMAKE_SOURCE_DIR}/README.md ${CMAKE_SOURCE_DIR}/docs/formats.md
        DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT bin)
# The guides the README links to (docs/NAME.md), so that its links hold in the installed folder.
install(DIRECTORY ${CMAKE_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs COMPONENT bin
        FILES_MATCHING PATTERN "*.md" PATTERN "perf-log.md" EXCLUDE)
if(TARGET occmap_man)
  install(FILES ${CMAKE_BINARY_DIR}/occmap.1.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT bin)
endif()

if(OCCMAP_PYTHON)
  set(OCCMAP_PYTHON_INSTALL_DIR lib/python3/dist-packages CACHE PATH
      "where `cmake --install` puts the Python package (Debian's python3 reads /usr/lib/python3/dist-packages)")
  install(TARGETS occmap_python LIBRARY DESTINATION ${OCCMAP_PYTHON_INSTALL_DIR}/occmap COMPONENT python)
  install(DIRECTORY ${CMAKE_SOURCE_DIR}/python/occmap/ DESTINATION ${OCCMAP_PYTHON_INSTALL_DIR}/occmap
          COMPONENT python FILES_MATCHING PATTERN "*.py")
endif()

# cpack -G DEB: one package with the program, libraries, headers and Python module; its
# dependencies from the binaries' shared libraries (dpkg-shlibdeps).
set(CPACK_PACKAGE_NAME occmap)
set(CPACK_PACKAGE_VENDOR "occmap")
set(CPACK_PACKAGE_CONTACT "occmap maintainers <occmap@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "floor occupancy from several calibrated cameras")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# The headers need the -dev packages of what they include; the Python module needs numpy.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "python3, python3-numpy")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "libopencv-dev, libeigen3-dev, libyaml-cpp-dev, nlohmann-json3-dev, libfmt-dev, libmosquitto-dev, libavcodec-dev, libavformat-dev, libswscale-dev, libavdevice-dev")
include(CPack)

# Not in sanitized builds: the consumer project would link their instrumented libraries plainly.
if(OCCMAP_BUILD_TESTS AND NOT CMAKE_CXX_FLAGS MATCHES "sanitize")
  # Install into a scratch prefix, a consumer project against it, the .deb unpacked and run.
  if(NOT OCCMAP_PYTHON_EXECUTABLE)
    set(OCCMAP_PYTHON_EXECUTABLE python3)
  endif()
  add_test(NAME occmap_install COMMAND bash ${CMAKE_SOURCE_DIR}/tests/install_test.sh ${CMAKE_BINARY_DIR}
           ${CMAKE_SOURCE_DIR} ${OCCMAP_DATASETS_DIR} ${OCCMAP_PYTHON_EXECUTABLE})
  set_tests_properties(occmap_install PROPERTIES TIMEOUT 900)
endif()
