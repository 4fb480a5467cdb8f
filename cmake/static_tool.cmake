# The kneedyn tools (kneedyn, kneedyn_catalog) link the static archives Debian
# ships of their libraries — Ceres' dependencies (glog, gflags, SuiteSparse, CXSparse,
# LAPACK/BLAS/ATLAS), SUNDIALS and libyaml — instead of the shared objects, so
# that the dynamic loader maps and relocates 3 objects at start-up (libc, libm, the loader)
# instead of 31
# (benchmarks/performance-log.md, "Start-up"). Everything else keeps the shared libraries: the
# libraries' consumers (the installed CMake package, kneedyn.pc), the tests, the Python
# module (a shared object, which cannot take these archives) and the Simbody cross-check.
#
# How: kneedyn_ceres_headers (Ceres' headers, which kneedyn_solver links; libceres itself
# is in the plugin kneedyn_ceres_fallback.so, solver/ceres_fallback.hpp) gets, in its link
# interface and only for a target whose property KNEEDYN_STATIC_TOOL is true, the archives
# in one linker group. They come after the kneedyn libraries on the link line, so they resolve
# every symbol those need; the shared libraries named later are then unused and, with
# -Wl,--as-needed (Debian's GCC default, made explicit here), not recorded as DT_NEEDED.
# SUNDIALS: the <package>_static twin of each SUNDIALS::<package>_shared the kneedyn
# libraries link, whatever they are (ida or idas...).
# libstdc++ and libgcc are linked statically too (-static-libstdc++ -static-libgcc): the
# loader then relocates libc and libm only (`kneedyn --version` 3.31 -> 1.48 M instructions).
# The plugins (kneedyn_ceres_fallback.so, kneedyn_sweep_io.so) bring the shared libstdc++
# with them; nothing C++ crosses their C interfaces (no objects, no exceptions), so the two
# copies never meet. Before Ceres moved to its plugin this was not possible: glog's archive
# needed libunwind.so, whose _Unwind_RaiseException then took GCC's place.
#
#   kneedyn_static_tool(<target>...)   after every kneedyn library is defined

function(kneedyn_static_tool)
  set(missing)
  set(archives)
  foreach(name glog gflags spqr cholmod amd camd ccolamd colamd suitesparseconfig cxsparse
               lapack f77blas atlas blas cblas yaml)
    string(MAKE_C_IDENTIFIER "KNEEDYN_ARCHIVE_${name}" var)
    find_library(${var} NAMES lib${name}.a)
    if(${var})
      list(APPEND archives ${${var}})
    else()
      list(APPEND missing lib${name}.a)
    endif()
  endforeach()
  set(sundials)
  foreach(lib kneedyn_solver kneedyn_scene kneedyn_formulations kneedyn_ensembles kneedyn_sensitivity)
    if(TARGET ${lib})
      get_target_property(deps ${lib} LINK_LIBRARIES)
      foreach(dep IN LISTS deps)
        if(dep MATCHES "^SUNDIALS::(.+)_shared$")
          if(TARGET SUNDIALS::${CMAKE_MATCH_1}_static)
            list(APPEND sundials "$<TARGET_FILE:SUNDIALS::${CMAKE_MATCH_1}_static>")
          else()
            list(APPEND missing SUNDIALS::${CMAKE_MATCH_1}_static)
          endif()
        endif()
      endforeach()
    endif()
  endforeach()
  list(REMOVE_DUPLICATES sundials)
  find_library(KNEEDYN_RUNTIME_METIS NAMES metis libmetis.so.5)  # SuiteSparse: no -dev link
  if(NOT KNEEDYN_RUNTIME_METIS)
    list(APPEND missing libmetis)
  endif()
  if(missing)
    message(STATUS "KNEEDYN_STATIC_TOOL: not found ${missing}; the kneedyn tools link the shared libraries")
    return()
  endif()
  # Runtime libraries the archives may need, shared (--as-needed: recorded only if used;
  # with Ceres in its plugin none of these is).
  set(runtime ${KNEEDYN_RUNTIME_METIS} -lgomp -lgfortran -lpthread -lrt -ldl -lm)
  set(static_link "-Wl,--as-needed" "-Wl,--start-group" ${archives} ${sundials} "-Wl,--end-group" ${runtime})
  set_property(TARGET kneedyn_ceres_headers APPEND PROPERTY INTERFACE_LINK_LIBRARIES
    "$<$<BOOL:$<TARGET_PROPERTY:KNEEDYN_STATIC_TOOL>>:${static_link}>")
  foreach(tool ${ARGN})
    set_property(TARGET ${tool} PROPERTY KNEEDYN_STATIC_TOOL ON)
    target_link_options(${tool} PRIVATE -static-libstdc++ -static-libgcc)
  endforeach()
  message(STATUS "KNEEDYN_STATIC_TOOL: ${ARGN} link static archives of Ceres' dependencies, SUNDIALS, libyaml")
endfunction()
