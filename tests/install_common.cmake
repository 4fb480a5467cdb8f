# Shared by the install tests (install_consumer.cmake, install_problem_c.cmake), included
# after they set REQUIRED_VARIABLES: each must be given with -D; WORK is emptied, `prefix` is
# WORK/prefix, and run(COMMAND...) runs a command that must succeed (its stdout in `out`).
# With -DSANITIZE=ON (a sanitizer build installs instrumented libraries) `sanitizer_flags`
# holds the compile and link flag a consumer needs to load the runtime first; else empty.
foreach(v ${REQUIRED_VARIABLES})
  if(NOT DEFINED ${v})
    get_filename_component(script ${CMAKE_SCRIPT_MODE_FILE} NAME)
    message(FATAL_ERROR "${script}: -D${v}=... is required")
  endif()
endforeach()
file(REMOVE_RECURSE ${WORK})
set(prefix ${WORK}/prefix)
set(sanitizer_flags)
if(SANITIZE)
  set(sanitizer_flags -fsanitize=address,undefined)
endif()

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()
