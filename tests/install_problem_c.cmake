# ctest install_problem_c: installs the build into a fresh prefix, then builds and runs the C
# program tests/consumer_c/c_consumer.c against the installed C interface kneedyn/problem.h
# twice: as a CMake project with find_package(kneedyn COMPONENTS problem_c) (target
# kneedyn::problem_c; the C++ libraries' dependencies hidden), and by
# hand with `pkg-config --cflags --libs kneedyn-problem` and the C compiler alone. Also checks
# that the installed library exports only kneedyn_* functions.
#   cmake -DBUILD=<build dir> -DSOURCE=<source dir> -DWORK=<scratch dir> -DCC=<C compiler> [-DSANITIZE=ON]
#         -P install_problem_c.cmake
set(REQUIRED_VARIABLES BUILD SOURCE WORK CC)
include(${CMAKE_CURRENT_LIST_DIR}/install_common.cmake)

run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${prefix})
if(NOT EXISTS ${prefix}/include/kneedyn/problem.h)
  message(FATAL_ERROR "not installed: ${prefix}/include/kneedyn/problem.h")
endif()
file(GLOB_RECURSE lib ${prefix}/*/libkneedyn_problem_c.so)
file(GLOB_RECURSE pc ${prefix}/*/kneedyn-problem.pc)
if(NOT lib OR NOT pc)
  message(FATAL_ERROR "no libkneedyn_problem_c.so ('${lib}') or kneedyn-problem.pc ('${pc}') under ${prefix}")
endif()
set(scene ${prefix}/share/kneedyn/scenes/chapter_impact.yaml)
set(consumer_flags)
if(SANITIZE)
  set(consumer_flags "-DCMAKE_C_FLAGS=${sanitizer_flags}" "-DCMAKE_EXE_LINKER_FLAGS=${sanitizer_flags}")
endif()

# 1. find_package(kneedyn COMPONENTS problem_c) in a C-only project, with the C++ libraries'
# dependencies hidden (as on a machine without libceres-dev, libeigen3-dev, ...).
run(${CMAKE_COMMAND} -S ${SOURCE}/tests/consumer_c -B ${WORK}/find_package-build -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_C_COMPILER=${CC} ${consumer_flags}
    -DCMAKE_DISABLE_FIND_PACKAGE_Eigen3=TRUE -DCMAKE_DISABLE_FIND_PACKAGE_SUNDIALS=TRUE
    -DCMAKE_DISABLE_FIND_PACKAGE_Ceres=TRUE -DCMAKE_DISABLE_FIND_PACKAGE_nlohmann_json=TRUE)
run(${CMAKE_COMMAND} --build ${WORK}/find_package-build)
run(${WORK}/find_package-build/c_consumer)
message(STATUS "find_package: ${out}")

# 2. pkg-config and the C compiler alone.
find_program(PKG_CONFIG pkg-config REQUIRED)
get_filename_component(pcdir ${pc} DIRECTORY)
execute_process(COMMAND ${CMAKE_COMMAND} -E env PKG_CONFIG_PATH=${pcdir} ${PKG_CONFIG} --cflags --libs kneedyn-problem
                RESULT_VARIABLE rc OUTPUT_VARIABLE flags ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "pkg-config --cflags --libs kneedyn-problem: ${rc} ${err}")
endif()
separate_arguments(flags UNIX_COMMAND "${flags}")
file(MAKE_DIRECTORY ${WORK}/pkg-config-build)
run(${CC} -std=c90 -pedantic-errors -Wall -Werror ${sanitizer_flags} ${SOURCE}/tests/consumer_c/c_consumer.c ${flags} -lm
    -o ${WORK}/pkg-config-build/c_consumer)  # runs from the prefix by the .pc's run path alone
run(${WORK}/pkg-config-build/c_consumer ${scene})
message(STATUS "pkg-config: ${out}")

# 3. The shared library exports the C interface only (kneedyn is linked in hidden).
find_program(NM nm)
if(NM)
  run(${NM} -D --defined-only ${lib})
  # Every kind nm lists as defined: code, data, bss, read-only, weak (W, V: inline functions,
  # typeinfo, vtables) and GNU-unique (u: template statics, which also keep dlclose from
  # unloading the library).
  string(REGEX MATCHALL "[0-9a-f]+ [TDBRWVu] [^\n]+" symbols "${out}")
  foreach(s ${symbols})
    string(REGEX REPLACE "^[0-9a-f]+ [TDBRWVu] " "" name "${s}")
    if(NOT name MATCHES "^kneedyn_" AND NOT name MATCHES "^_(init|fini|edata|end|_bss_start)$")
      message(FATAL_ERROR "libkneedyn_problem_c exports '${name}': only kneedyn_* functions belong to its ABI")
    endif()
  endforeach()
endif()
file(REMOVE_RECURSE ${WORK})
