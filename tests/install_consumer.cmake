# ctest install_consumer: installs the build into a fresh prefix, then configures,
# builds and runs tests/consumer (find_package(kneedyn CONFIG REQUIRED), kneedyn::formulations)
# against it, runs the installed kneedyn from an unrelated directory (data found in
# share/kneedyn), checks the pkg-config file and that no internal header is installed.
#   cmake -DBUILD=<build dir> -DSOURCE=<source dir> -DWORK=<scratch dir> -P install_consumer.cmake
set(REQUIRED_VARIABLES BUILD SOURCE WORK)
include(${CMAKE_CURRENT_LIST_DIR}/install_common.cmake)

run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${prefix})
foreach(f bin/kneedyn bin/kneedyn_catalog share/kneedyn/scenes/chapter_impact.yaml
          share/kneedyn/chapter_knee.yaml include/kneedyn/formulations/run.hpp
          include/kneedyn/scene/scene.hpp)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "not installed: ${prefix}/${f}")
  endif()
endforeach()
# Only the public API: formulations/internal/ (test hooks, SUNDIALS glue) and scene/internal/
# (the loader's sections, key table, YAML reader) are not installed.
file(GLOB_RECURSE internal_headers ${prefix}/include/kneedyn/formulations/internal/*
     ${prefix}/include/kneedyn/scene/internal/*
     ${prefix}/include/kneedyn/*/dae_testing.hpp ${prefix}/include/kneedyn/*/ida_phase.hpp
     ${prefix}/include/kneedyn/*/sections.hpp ${prefix}/include/kneedyn/*/yaml_field.hpp)
if(internal_headers)
  message(FATAL_ERROR "internal headers installed: ${internal_headers}")
endif()
file(GLOB_RECURSE config ${prefix}/*/kneedynConfig.cmake)
file(GLOB_RECURSE pc ${prefix}/*/kneedyn.pc)
if(NOT config OR NOT pc)
  message(FATAL_ERROR "no kneedynConfig.cmake ('${config}') or kneedyn.pc ('${pc}') under ${prefix}")
endif()

set(consumer_flags)
if(SANITIZE)
  set(consumer_flags "-DCMAKE_CXX_FLAGS=${sanitizer_flags}" "-DCMAKE_EXE_LINKER_FLAGS=${sanitizer_flags}")
endif()
run(${CMAKE_COMMAND} -S ${SOURCE}/tests/consumer -B ${WORK}/consumer-build
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix} ${consumer_flags})
run(${CMAKE_COMMAND} --build ${WORK}/consumer-build)
run(${WORK}/consumer-build/consumer)
message(STATUS "consumer: ${out}")

# The installed tool finds its data beside itself, from elsewhere, without the override.
file(MAKE_DIRECTORY ${WORK}/elsewhere)
execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=KNEEDYN_DATA_DIR
                ${prefix}/bin/kneedyn_catalog --case c1_law --out ${WORK}/elsewhere/catalog
                WORKING_DIRECTORY ${WORK}/elsewhere RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK}/elsewhere/catalog/hard_cases.md)
  message(FATAL_ERROR "installed kneedyn_catalog failed (${rc}):\n${out}\n${err}")
endif()

# The installed kneedyn loads its installed sweep I/O plugin (Open MPI + HDF5,
# <prefix>/<libdir>/kneedyn/kneedyn_sweep_io.so) for sweep.h5; the binary itself links neither.
file(GLOB_RECURSE plugin ${prefix}/*/kneedyn_sweep_io.so)
if(NOT plugin)
  message(FATAL_ERROR "not installed: kneedyn_sweep_io.so under ${prefix}")
endif()
file(WRITE ${WORK}/elsewhere/spec.yaml
  "scene: ${prefix}/share/kneedyn/scenes/chapter_impact.yaml\n"
  "parameters: [{name: pulse.amplitude, uniform: [90, 110]}]\n"
  "design: {type: lhs, samples: 2, seed: 1}\noutcomes: [liftoff_time]\n"
  "solver: {formulation: dae-reduced, rtol: 1.0e-6, atol: 1.0e-8}\n")
execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=KNEEDYN_DATA_DIR
                ${prefix}/bin/kneedyn sweep ${WORK}/elsewhere/spec.yaml --threads 1 --out ${WORK}/elsewhere/sweep
                WORKING_DIRECTORY ${WORK}/elsewhere RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK}/elsewhere/sweep/sweep.h5)
  message(FATAL_ERROR "installed kneedyn sweep failed (${rc}):\n${out}\n${err}")
endif()

find_program(PKG_CONFIG pkg-config)
if(PKG_CONFIG)
  get_filename_component(pcdir ${pc} DIRECTORY)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env PKG_CONFIG_PATH=${pcdir} ${PKG_CONFIG} --variable=includedir kneedyn
                  RESULT_VARIABLE rc OUTPUT_VARIABLE got ERROR_VARIABLE err)
  file(REAL_PATH ${prefix}/include/kneedyn want)
  string(STRIP "${got}" got)
  if(rc EQUAL 0)
    file(REAL_PATH "${got}" got)
  endif()
  if(NOT rc EQUAL 0 OR NOT got STREQUAL want)
    message(FATAL_ERROR "pkg-config --variable=includedir kneedyn: '${got}' (${rc}, ${err}); expected ${want}")
  endif()
endif()
file(REMOVE_RECURSE ${WORK})
