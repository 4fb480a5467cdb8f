# SUNDIALS for kneedyn, compiled like kneedyn.
#
# Debian 12's binary SUNDIALS 6.4.1 is compiled without optimization: its debian/rules
# passes -DCMAKE_C_FLAGS=-fcommon, which replaces dpkg-buildflags' -O2, so IDA, CVODE and
# ARKODE run their step logic at -O0 (a third of libsundials_ida.so's instructions address
# the stack frame through %rbp, against 4-6 % in Debian's Ceres and Simbody). A benchmark
# that compares them with methods compiled at -O3 compares compilers. So, by default
# (KNEEDYN_SUNDIALS=bundled), kneedyn builds SUNDIALS itself at configure time from
# Debian's source package of the same version (cmake/fetch_sundials.sh: apt-get source,
# checksums kept in cmake/sundials-source.sha256, Debian's patches applied):
#   - only the packages kneedyn links: IDAS, CVODES, ARKODE (each archive carries the
#     serial vector, dense matrix and dense linear solver);
#   - static, position-independent (the Python module is a shared object);
#   - with kneedyn's build type and its C++ flags for that type as the C flags.
# KNEEDYN_SUNDIALS=system links Debian's shared libraries instead, for A/B measurements.
#
# Result: KNEEDYN_SUNDIALS_LIBRARIES, the targets to link (every kneedyn target that calls
# SUNDIALS links this list), and KNEEDYN_SUNDIALS_ORIGIN / KNEEDYN_SUNDIALS_C_FLAGS for the
# benchmark's fairness manifest.

set(KNEEDYN_SUNDIALS "bundled" CACHE STRING
    "SUNDIALS to link: bundled (built from Debian's source package with kneedyn's flags) or system (Debian's binary package)")
set_property(CACHE KNEEDYN_SUNDIALS PROPERTY STRINGS bundled system)
set(KNEEDYN_SUNDIALS_VERSION "6.4.1+dfsg1-3")
set(kneedyn_sundials_packages idas cvodes arkode)

if(KNEEDYN_SUNDIALS STREQUAL "system")
  find_package(SUNDIALS 6.4 REQUIRED)
  set(KNEEDYN_SUNDIALS_LIBRARIES)
  foreach(p ${kneedyn_sundials_packages} nvecserial sunmatrixdense sunlinsoldense)
    list(APPEND KNEEDYN_SUNDIALS_LIBRARIES SUNDIALS::${p}_shared)
  endforeach()
  set(KNEEDYN_SUNDIALS_ORIGIN "Debian 12 binary package libsundials-dev ${SUNDIALS_VERSION} (shared)")
  # No ';' in these texts: version.cpp's COMPILE_DEFINITIONS is a CMake list.
  set(KNEEDYN_SUNDIALS_C_FLAGS "-fcommon (Debian's debian/rules, no -O)")
  message(STATUS "SUNDIALS: Debian's binary package (unoptimized; for A/B measurements)")
  return()
elseif(NOT KNEEDYN_SUNDIALS STREQUAL "bundled")
  message(FATAL_ERROR "KNEEDYN_SUNDIALS = '${KNEEDYN_SUNDIALS}': must be bundled or system")
endif()

set(kneedyn_sundials_root "${PROJECT_BINARY_DIR}/_deps/sundials")
set(KNEEDYN_SUNDIALS_SOURCE_DIR "${kneedyn_sundials_root}/src" CACHE PATH
    "Patched SUNDIALS ${KNEEDYN_SUNDIALS_VERSION} source tree (cmake/fetch_sundials.sh writes it)")
set(kneedyn_sundials_prefix "${kneedyn_sundials_root}/install")

if(NOT EXISTS "${KNEEDYN_SUNDIALS_SOURCE_DIR}/CMakeLists.txt")
  message(STATUS "SUNDIALS: fetching Debian's source package ${KNEEDYN_SUNDIALS_VERSION}")
  execute_process(COMMAND bash "${PROJECT_SOURCE_DIR}/cmake/fetch_sundials.sh" "${kneedyn_sundials_root}"
                  RESULT_VARIABLE fetch_result)
  if(NOT fetch_result EQUAL 0 OR NOT EXISTS "${KNEEDYN_SUNDIALS_SOURCE_DIR}/CMakeLists.txt")
    message(FATAL_ERROR "SUNDIALS source not available (cmake/fetch_sundials.sh failed, see above); "
                        "or configure with -DKNEEDYN_SUNDIALS=system")
  endif()
endif()

# kneedyn's optimization for its build type, as C flags (empty build type: Release, as the
# top-level CMakeLists.txt defaults to).
set(kneedyn_sundials_build_type "${CMAKE_BUILD_TYPE}")
if(NOT kneedyn_sundials_build_type)
  set(kneedyn_sundials_build_type Release)
endif()
string(TOUPPER "${kneedyn_sundials_build_type}" kneedyn_bt)
set(KNEEDYN_SUNDIALS_C_FLAGS "${CMAKE_CXX_FLAGS_${kneedyn_bt}}")
set(kneedyn_sundials_args
    -DCMAKE_BUILD_TYPE=${kneedyn_sundials_build_type}
    "-DCMAKE_C_FLAGS_${kneedyn_bt}=${KNEEDYN_SUNDIALS_C_FLAGS}"
    -DBUILD_SHARED_LIBS=OFF -DBUILD_STATIC_LIBS=ON -DCMAKE_POSITION_INDEPENDENT_CODE=ON
    -DBUILD_IDA=OFF -DBUILD_CVODE=OFF -DBUILD_KINSOL=OFF
    -DBUILD_IDAS=ON -DBUILD_CVODES=ON -DBUILD_ARKODE=ON
    -DBUILD_FORTRAN_MODULE_INTERFACE=OFF -DEXAMPLES_ENABLE_C=OFF -DEXAMPLES_ENABLE_CXX=OFF
    -DEXAMPLES_INSTALL=OFF -DSUNDIALS_INDEX_SIZE=64 -DSUNDIALS_PRECISION=double
    -DCMAKE_INSTALL_PREFIX=${kneedyn_sundials_prefix} -DCMAKE_INSTALL_LIBDIR=lib)
# Rebuilt when the arguments change (a different build type, compiler or flags).
string(SHA256 kneedyn_sundials_key "${CMAKE_C_COMPILER};${kneedyn_sundials_args}")
set(kneedyn_sundials_stamp "${kneedyn_sundials_prefix}/kneedyn-build-key")
set(kneedyn_sundials_key_now "")
if(EXISTS "${kneedyn_sundials_stamp}")
  file(READ "${kneedyn_sundials_stamp}" kneedyn_sundials_key_now)
endif()
if(NOT kneedyn_sundials_key_now STREQUAL kneedyn_sundials_key)
  message(STATUS "SUNDIALS: building ${KNEEDYN_SUNDIALS_VERSION} (IDAS, CVODES, ARKODE; static; C flags '${KNEEDYN_SUNDIALS_C_FLAGS}') into ${kneedyn_sundials_prefix}")
  file(REMOVE_RECURSE "${kneedyn_sundials_root}/build" "${kneedyn_sundials_prefix}")
  # The logs go here; with KNEEDYN_SUNDIALS_SOURCE_DIR pointing elsewhere nothing created it.
  file(MAKE_DIRECTORY "${kneedyn_sundials_root}")
  include(ProcessorCount)
  ProcessorCount(kneedyn_jobs)
  if(kneedyn_jobs EQUAL 0)
    set(kneedyn_jobs 2)
  endif()
  foreach(step configure build install)
    if(step STREQUAL "configure")
      set(cmd ${CMAKE_COMMAND} -S "${KNEEDYN_SUNDIALS_SOURCE_DIR}" -B "${kneedyn_sundials_root}/build"
              -DCMAKE_C_COMPILER=${CMAKE_C_COMPILER} ${kneedyn_sundials_args})
    elseif(step STREQUAL "build")
      set(cmd ${CMAKE_COMMAND} --build "${kneedyn_sundials_root}/build" -j ${kneedyn_jobs})
    else()
      set(cmd ${CMAKE_COMMAND} --install "${kneedyn_sundials_root}/build")
    endif()
    execute_process(COMMAND ${cmd} RESULT_VARIABLE rc
                    OUTPUT_FILE "${kneedyn_sundials_root}/${step}.log"
                    ERROR_FILE "${kneedyn_sundials_root}/${step}.log")
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "SUNDIALS ${step} failed (exit ${rc}); see ${kneedyn_sundials_root}/${step}.log")
    endif()
  endforeach()
  file(WRITE "${kneedyn_sundials_stamp}" "${kneedyn_sundials_key}")
endif()

find_package(SUNDIALS 6.4.1 EXACT REQUIRED CONFIG
             PATHS "${kneedyn_sundials_prefix}" NO_DEFAULT_PATH)
set(KNEEDYN_SUNDIALS_LIBRARIES)
foreach(p ${kneedyn_sundials_packages})
  list(APPEND KNEEDYN_SUNDIALS_LIBRARIES SUNDIALS::${p}_static)
endforeach()
# The check: every SUNDIALS archive kneedyn links is the one built here, never Debian's.
foreach(t ${KNEEDYN_SUNDIALS_LIBRARIES})
  get_target_property(loc ${t} IMPORTED_LOCATION_${kneedyn_bt})
  if(NOT loc)
    get_target_property(loc ${t} IMPORTED_LOCATION_RELEASE)
  endif()
  string(FIND "${loc}" "${kneedyn_sundials_prefix}/" at)
  if(NOT at EQUAL 0)
    message(FATAL_ERROR "SUNDIALS target ${t} resolves to '${loc}', not to the optimized build in ${kneedyn_sundials_prefix}")
  endif()
endforeach()
set(KNEEDYN_SUNDIALS_PREFIX "${kneedyn_sundials_prefix}")
set(KNEEDYN_SUNDIALS_ORIGIN "Debian 12 source package sundials ${KNEEDYN_SUNDIALS_VERSION}, built by kneedyn (static)")
message(STATUS "SUNDIALS: ${KNEEDYN_SUNDIALS_VERSION} built with '${KNEEDYN_SUNDIALS_C_FLAGS}' (${kneedyn_sundials_prefix})")
