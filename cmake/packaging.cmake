# `cpack -G DEB` in a build tree (after building everything the install rules name):
# kneedyn_<version>_amd64.deb with all that `cmake --install` installs (cmake/install.cmake,
# both components) under /usr: the programs, the sweep I/O plugin, the libraries, headers,
# CMake package, kneedyn.pc, the data (/usr/share/kneedyn) and the Python module (in
# Debian's /usr/lib/python3/dist-packages, python/CMakeLists.txt).
# Depends: dpkg-shlibdeps maps every ELF file's shared libraries to their Debian packages;
# the Python module adds the interpreter it was built for and NumPy (kneedyn/__init__.py).
# The ctest `deb_package` checks the file list and Depends against the install rules.
set(CPACK_GENERATOR DEB)
# cpack installs what is built, as `cmake --install` does: without this it first builds the
# target all (every test and benchmark, ~10 min from scratch) through "preinstall".
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)
set(CPACK_PACKAGE_NAME kneedyn)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "kneedyn")
set(CPACK_PACKAGE_CONTACT "kneedyn developers")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "3-D dynamic knee model under impact loading: solver, formulations, benchmarks")
set(CPACK_PACKAGE_DESCRIPTION
    "A verification and benchmark suite, with a reference solver, for the three-dimensional dynamic model of the human knee under impact loading of Hefzy and Abdel-Rahman: the kneedyn program, the kneedyn Python module, the model libraries with their headers, CMake package and pkg-config file, and the chapter's scenes and parameter set.")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)          # kneedyn_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_COMPRESSION_TYPE gzip)          # xz saves little here and costs seconds
if(KNEEDYN_WITH_PYTHON)
  execute_process(COMMAND ${KNEEDYN_PYTHON} -c "import sys; print('%d.%d' % sys.version_info[:2])"
                  OUTPUT_VARIABLE _kneedyn_py_version OUTPUT_STRIP_TRAILING_WHITESPACE)
  string(REGEX MATCH "^[0-9]+" _kneedyn_py_major "${_kneedyn_py_version}")
  string(REGEX MATCH "[0-9]+$" _kneedyn_py_minor "${_kneedyn_py_version}")
  math(EXPR _kneedyn_py_next "${_kneedyn_py_minor} + 1")
  # The extension is built for one interpreter ABI (cpython-3XY).
  set(CPACK_DEBIAN_PACKAGE_DEPENDS
      "python3 (>= ${_kneedyn_py_version}), python3 (<< ${_kneedyn_py_major}.${_kneedyn_py_next}), python3-numpy")
endif()
# Building against the installed libraries needs the headers of their dependencies
# (kneedynConfig.cmake's find_dependency, kneedyn.pc's Requires). The bundled SUNDIALS is
# in the package itself (lib/kneedyn/sundials, cmake/install.cmake).
set(kneedyn_suggests_sundials "")
if(KNEEDYN_SUNDIALS STREQUAL "system")
  set(kneedyn_suggests_sundials "libsundials-dev, ")
endif()
set(CPACK_DEBIAN_PACKAGE_SUGGESTS
    "cmake, pkg-config, libeigen3-dev, ${kneedyn_suggests_sundials}libceres-dev, nlohmann-json3-dev, libyaml-dev")
include(CPack)
