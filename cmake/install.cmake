# `cmake --install BUILD --prefix P`: the kneedyn and kneedyn_catalog tools in
# P/bin, the libraries in P/lib, the headers in P/include/kneedyn/{solver,scene,formulations},
# reference-data/ as P/share/kneedyn (found there by the installed tools at run time), the
# CMake package kneedyn (find_package(kneedyn CONFIG REQUIRED); targets kneedyn::solver,
# kneedyn::scene, kneedyn::formulations) and pkg-config's kneedyn.pc.
# Two components: `runtime` (the programs, the data, and with them the sweep I/O plugin and
# the Python module: what `pip install .` packages, setup.py) and `development` (libraries,
# headers, CMake package, kneedyn.pc). `cpack -G DEB` packages both (cmake/packaging.cmake).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(KNEEDYN_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/kneedyn)

install(TARGETS kneedyn_solver kneedyn_scene kneedyn_formulations EXPORT kneedynTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT development
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT development
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/kneedyn)
install(TARGETS kneedyn kneedyn_catalog RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
# Public headers only: formulations/internal/ (SUNDIALS glue, the methods' shared machinery,
# test hooks) and scene/internal/ (the loader's sections, key table and YAML reader) are not
# installed.
foreach(dir solver scene formulations)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/kneedyn/${dir}
          COMPONENT development
          FILES_MATCHING PATTERN "*.hpp"
          PATTERN "internal" EXCLUDE)
endforeach()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/reference-data/ DESTINATION ${CMAKE_INSTALL_DATADIR}/kneedyn
        COMPONENT runtime)
# The two outside solvers docs/problem.md points to, beside the installed header and module.
install(FILES ${PROJECT_SOURCE_DIR}/examples/c/rk4_on_the_knee.c ${PROJECT_SOURCE_DIR}/examples/python/scipy_on_the_knee.py
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples COMPONENT development)

# The optimized SUNDIALS the libraries were linked against (cmake/sundials.cmake): its
# archives, headers and CMake package, private to kneedyn (lib/kneedyn/sundials); a
# program linking kneedyn's static libraries needs them, so they go with the development
# component.
set(KNEEDYN_SUNDIALS_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/kneedyn/sundials)
if(KNEEDYN_SUNDIALS STREQUAL "bundled")
  install(DIRECTORY ${KNEEDYN_SUNDIALS_PREFIX}/include ${KNEEDYN_SUNDIALS_PREFIX}/lib
          DESTINATION ${KNEEDYN_SUNDIALS_INSTALL_DIR} COMPONENT development)
  set(KNEEDYN_PC_SUNDIALS_CFLAGS "-I\${libdir}/kneedyn/sundials/include")
  set(KNEEDYN_PC_SUNDIALS_LIBS "-L\${libdir}/kneedyn/sundials/lib -lsundials_idas -lsundials_cvodes -lsundials_arkode")
else()
  set(KNEEDYN_PC_SUNDIALS_CFLAGS "")
  set(KNEEDYN_PC_SUNDIALS_LIBS "-lsundials_idas -lsundials_cvodes -lsundials_arkode -lsundials_nvecserial -lsundials_sunmatrixdense -lsundials_sunlinsoldense")
endif()

# The run-time plugins (the Ceres fallback, solver/CMakeLists.txt; the sweep I/O).
set(KNEEDYN_PLUGIN_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/kneedyn)

install(EXPORT kneedynTargets NAMESPACE kneedyn:: DESTINATION ${KNEEDYN_CMAKE_DIR} COMPONENT development)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/kneedynConfig.cmake.in
  ${PROJECT_BINARY_DIR}/kneedynConfig.cmake INSTALL_DESTINATION ${KNEEDYN_CMAKE_DIR}
  PATH_VARS CMAKE_INSTALL_DATADIR KNEEDYN_SUNDIALS_INSTALL_DIR KNEEDYN_PLUGIN_INSTALL_DIR)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/kneedynConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/kneedynConfig.cmake ${PROJECT_BINARY_DIR}/kneedynConfigVersion.cmake
        DESTINATION ${KNEEDYN_CMAKE_DIR} COMPONENT development)

# Relocatable: the prefix is found from the .pc file's own directory.
file(RELATIVE_PATH KNEEDYN_PC_TO_PREFIX "/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/")
string(REGEX REPLACE "/$" "" KNEEDYN_PC_TO_PREFIX "${KNEEDYN_PC_TO_PREFIX}")
configure_file(${PROJECT_SOURCE_DIR}/cmake/kneedyn.pc.in ${PROJECT_BINARY_DIR}/kneedyn.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/kneedyn.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig
        COMPONENT development)
