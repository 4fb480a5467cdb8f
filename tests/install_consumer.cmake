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

# The installed static libraries name no file of the build tree (they are its files, copied).
file(GLOB_RECURSE archives ${prefix}/*/libkneedyn_*.a)
foreach(archive ${archives})
  file(STRINGS ${archive} paths REGEX "/")
  foreach(path IN LISTS paths)
    string(FIND "${path}" "${BUILD}" at)
    if(NOT at EQUAL -1)
      message(FATAL_ERROR "${archive} names the build tree: '${path}'")
    endif()
  endforeach()
endforeach()
# A start the direct Newton path cannot take (an assembled pose at 30 degrees of abduction)
# loads the Ceres fallback plugin: a consumer outside the build tree finds the installed
# one through the run path its CMake package gave it (LD_DEBUG=libs names the file loaded).
file(READ ${prefix}/share/kneedyn/scenes/chapter_impact.yaml scene_text)
string(REPLACE "parameter_set: ../chapter_knee.yaml" "parameter_set: ${prefix}/share/kneedyn/chapter_knee.yaml"
       scene_text "${scene_text}")
string(REGEX REPLACE "initial_state:[^\n]*\n(  [^\n]*\n)*" "initial_state: {pose: assemble, coordinates: {alpha_deg: 30.0}}\n"
       scene_text "${scene_text}")
string(FIND "${scene_text}" "parameter_set: ${prefix}/share" at)
if(NOT scene_text MATCHES "pose: assemble" OR at EQUAL -1)
  message(FATAL_ERROR "could not write the assembled-start scene from chapter_impact.yaml:\n${scene_text}")
endif()
string(RANDOM LENGTH 10 ALPHABET abcdefghijklmnopqrstuvwxyz0123456789 tag)
set(outside /tmp/kneedyn_consumer_${tag})
file(MAKE_DIRECTORY ${outside})
file(WRITE ${outside}/assemble.yaml "${scene_text}")
file(COPY ${WORK}/consumer-build/consumer DESTINATION ${outside})
execute_process(COMMAND ${CMAKE_COMMAND} -E env LD_DEBUG=libs ${outside}/consumer ${outside}/assemble.yaml
                WORKING_DIRECTORY ${outside} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
file(REMOVE_RECURSE ${outside})
string(REGEX MATCH "calling init: ([^\n]*kneedyn_ceres_fallback\\.so)" loaded "${err}")
file(REAL_PATH ${prefix} real_prefix)
set(plugin_path "${CMAKE_MATCH_1}")
if(plugin_path)
  file(REAL_PATH "${plugin_path}" plugin_path)
endif()
string(FIND "${plugin_path}" "${real_prefix}/" at)
if(NOT rc EQUAL 0 OR NOT at EQUAL 0)
  message(FATAL_ERROR "consumer outside the build tree, assembled start (${rc}): loaded the Ceres fallback "
                      "'${plugin_path}', expected the one under ${real_prefix}\n${out}")
endif()
string(STRIP "${out}" out)
message(STATUS "consumer, assembled start: ${out}; Ceres fallback from ${plugin_path}")

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
  # The run path a pkg-config consumer gets: the directory of the Ceres fallback plugin.
  execute_process(COMMAND ${CMAKE_COMMAND} -E env PKG_CONFIG_PATH=${pcdir} ${PKG_CONFIG} --libs kneedyn
                  RESULT_VARIABLE rc OUTPUT_VARIABLE libs ERROR_VARIABLE err)
  string(REGEX MATCH "-Wl,-rpath,([^ \n]+)" rpath "${libs}")
  if(NOT rc EQUAL 0 OR NOT EXISTS "${CMAKE_MATCH_1}/kneedyn_ceres_fallback.so")
    message(FATAL_ERROR "pkg-config --libs kneedyn: '${libs}' (${rc}, ${err}): no -Wl,-rpath to the plugin directory")
  endif()
endif()
file(REMOVE_RECURSE ${WORK})
