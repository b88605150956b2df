# Packaging and documentation (issue 9), included at the end of the top-level
# CMakeLists.txt:
#   - lib/pkgconfig/mvkp.pc            (pkg-config --cflags --libs mvkp)
#   - target `docs`                    (Doxygen API reference -> <build>/docs/html; `make docs`)
#   - CPack DEB, one package per install component (`make deb`):
#       dev    -> libmvkp-dev   static libraries, headers, CMake config, pkg-config file
#       cli    -> mvkp          the `mvkp` command line, `mvkp serve` and its web client linked in
#       python -> python3-mvkp  the Python module (python/, when built)
#   - the user guide's code snippets (docs/guide/*.md), built and run by CTest (cmake/doc_snippets.cmake)

# ---------------------------------------------------------------- pkg-config
# Libraries in link order: every component before the components it uses
# (static libraries: the linker resolves left to right).
set(_mvkp_pc_order "")
set(_mvkp_pc_visiting "")
function(_mvkp_pc_visit target)
  if(target IN_LIST _mvkp_pc_order)
    return()
  endif()
  if(target IN_LIST _mvkp_pc_visiting)
    message(FATAL_ERROR "mvkp.pc: dependency cycle through ${target}")
  endif()
  list(APPEND _mvkp_pc_visiting ${target})  # the current path (copied into callees)
  get_target_property(_deps ${target} LINK_LIBRARIES)
  if(_deps)
    foreach(_d IN LISTS _deps)
      string(REGEX REPLACE "^mvkp::" "mvkp_" _d "${_d}")
      if(_d IN_LIST _components)
        _mvkp_pc_visit(${_d})
      endif()
    endforeach()
  endif()
  list(APPEND _mvkp_pc_order ${target})  # dependencies first (post-order)
  set(_mvkp_pc_order ${_mvkp_pc_order} PARENT_SCOPE)
endfunction()
foreach(_c IN LISTS _components)
  _mvkp_pc_visit(${_c})
endforeach()
list(REVERSE _mvkp_pc_order)  # users first
set(MVKP_PC_LIBS "")
foreach(_c IN LISTS _mvkp_pc_order)
  string(APPEND MVKP_PC_LIBS " -l${_c}")
endforeach()
string(STRIP "${MVKP_PC_LIBS}" MVKP_PC_LIBS)
# External dependencies of the components, by their Debian 12 pkg-config names
# (nlohmann_json: header-only, Cflags only).
set(MVKP_PC_REQUIRES "opencv4 >= 4.5, sqlite3, libjpeg, libpng, zlib, nlohmann_json >= 3")
if(TARGET mvkp_geo)
  string(APPEND MVKP_PC_REQUIRES ", gdal")
endif()
if(TARGET mvkp_serve)
  string(APPEND MVKP_PC_REQUIRES ", cpp-httplib, openssl")  # libcpp-httplib-dev, libssl-dev (HTTPS)
endif()
# Relocatable: prefix from the .pc file's own directory (pkg-config's
# ${pcfiledir}), so the same file works under /usr, a PREFIX= install or an
# extracted .deb.
if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}")
  set(MVKP_PC_PREFIX "${CMAKE_INSTALL_PREFIX}")
  set(MVKP_PC_LIBDIR "${CMAKE_INSTALL_LIBDIR}")
else()
  file(RELATIVE_PATH _up "/_p/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/_p")
  string(REGEX REPLACE "/$" "" _up "${_up}")
  set(MVKP_PC_PREFIX "\${pcfiledir}/${_up}")
  set(MVKP_PC_LIBDIR "\${prefix}/${CMAKE_INSTALL_LIBDIR}")
endif()
if(IS_ABSOLUTE "${CMAKE_INSTALL_INCLUDEDIR}")
  set(MVKP_PC_INCLUDEDIR "${CMAKE_INSTALL_INCLUDEDIR}")
else()
  set(MVKP_PC_INCLUDEDIR "\${prefix}/${CMAKE_INSTALL_INCLUDEDIR}")
endif()
configure_file(${PROJECT_SOURCE_DIR}/cmake/mvkp.pc.in ${PROJECT_BINARY_DIR}/mvkp.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/mvkp.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT dev)

# ---------------------------------------------------------------- Doxygen (make docs)
find_package(Doxygen QUIET)
set(MVKP_DOCS_DIR ${PROJECT_BINARY_DIR}/docs)
if(DOXYGEN_FOUND)
  find_package(Python3 QUIET COMPONENTS Interpreter)
  set(MVKP_DOXYGEN_FILTER "")
  if(Python3_Interpreter_FOUND)
    # The headers document with plain // comments: the filter turns them into
    # Doxygen comments (docs/doxygen_filter.py).
    set(MVKP_DOXYGEN_FILTER "\"${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/docs/doxygen_filter.py\"")
  endif()
  configure_file(${PROJECT_SOURCE_DIR}/docs/Doxyfile.in ${MVKP_DOCS_DIR}/Doxyfile @ONLY)
  add_custom_target(docs
    COMMAND ${CMAKE_COMMAND} -E make_directory ${MVKP_DOCS_DIR}
    COMMAND ${DOXYGEN_EXECUTABLE} ${MVKP_DOCS_DIR}/Doxyfile
    COMMAND ${CMAKE_COMMAND} -DLOG=${MVKP_DOCS_DIR}/doxygen-warnings.log -DHTML=${MVKP_DOCS_DIR}/html
            -P ${PROJECT_SOURCE_DIR}/cmake/doxygen_summary.cmake
    WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
    COMMENT "Doxygen: API reference of the public headers -> ${MVKP_DOCS_DIR}/html"
    VERBATIM)
  if(MVKP_BUILD_TESTS)
    # The reference builds, from every public header, with few warnings.
    add_test(NAME api_docs
      COMMAND ${CMAKE_COMMAND} -DDOXYGEN=${DOXYGEN_EXECUTABLE} -DDOXYFILE=${MVKP_DOCS_DIR}/Doxyfile
              -DLOG=${MVKP_DOCS_DIR}/doxygen-warnings.log -DHTML=${MVKP_DOCS_DIR}/html -DMAX_WARNINGS=10
              -P ${PROJECT_SOURCE_DIR}/cmake/doxygen_summary.cmake
      WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
    set_tests_properties(api_docs PROPERTIES TIMEOUT 300)
  endif()
else()
  add_custom_target(docs
    COMMAND ${CMAKE_COMMAND} -E echo "make docs: doxygen not found (Debian: apt-get install doxygen, or make deps)"
    COMMAND ${CMAKE_COMMAND} -E false
    VERBATIM)
endif()

# ---------------------------------------------------------------- CPack: .deb packages (make deb)
# Python module: the `python` component of python/CMakeLists.txt.
set(MVKP_PACKAGE_PYTHON OFF)
if(TARGET mvkp_python)  # python/CMakeLists.txt defines it when pybind11 and python3-dev are there
  set(MVKP_PACKAGE_PYTHON ON)
endif()

set(CPACK_PACKAGE_NAME mvkp)
set(CPACK_PACKAGE_VENDOR "mvkp")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
# No CPACK_PACKAGE_DESCRIPTION_SUMMARY: CPackDeb would put it before each
# component description's own first line (the Debian synopsis).
set(CPACK_PACKAGE_CONTACT "mvkp maintainers <mvkp@localhost>")
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)  # executables and modules only; install() never strips static archives
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL dev cli)
if(MVKP_PACKAGE_PYTHON)
  list(APPEND CPACK_COMPONENTS_ALL python)
endif()

set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # <name>_<version>-<release>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${CPACK_PACKAGE_CONTACT}")
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_COMPRESSION_TYPE gzip)  # fast to build (CTest deb_install builds them); xz: ~30 % smaller, slower

# libmvkp-dev: static libraries, so everything a program linking them needs
# at build time (and, through those -dev packages, at run time).
set(CPACK_DEBIAN_DEV_PACKAGE_NAME libmvkp-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS
    "libopencv-dev (>= 4.5), libgdal-dev, libsqlite3-dev, nlohmann-json3-dev (>= 3), libjpeg-dev, libpng-dev, zlib1g-dev, libcpp-httplib-dev, libssl-dev")
set(CPACK_DEBIAN_DEV_PACKAGE_SUGGESTS "cmake (>= 3.25), pkg-config, g++ (>= 4:12)")
set(CPACK_COMPONENT_DEV_DISPLAY_NAME "mvkp development files")
set(CPACK_COMPONENT_DEV_DESCRIPTION
    "mvkp: fast planar image matching - development files\n\
Static libraries (one per component, and mvkp::mvkp gathering them), C++20\n\
headers under /usr/include/mvkp, the CMake package (find_package(mvkp),\n\
target mvkp::mvkp) and a pkg-config file (mvkp). Includes CDIKP (a\n\
cv::Feature2D), the FFVA exact nearest-neighbour index, target databases and\n\
recognition, and aerial photo to LiDAR registration.")

# mvkp: the command line, including `mvkp serve` (museum guide server; its web
# client is linked into the binary). Shared-library dependencies from dpkg-shlibdeps.
set(CPACK_DEBIAN_CLI_PACKAGE_NAME mvkp)
set(CPACK_DEBIAN_CLI_PACKAGE_SECTION graphics)
set(CPACK_DEBIAN_CLI_PACKAGE_SHLIBDEPS ON)
set(CPACK_COMPONENT_CLI_DISPLAY_NAME "mvkp command line")
set(CPACK_COMPONENT_CLI_DESCRIPTION
    "mvkp: fast planar image matching - command line and museum guide server\n\
The mvkp tool: train a target from one image and find it in frames (train,\n\
match, pair, video), target databases (db, recognize), the museum guide\n\
server with its web client (serve), nearest-neighbour search (knn), target\n\
quality, synthetic test data, and aerial photo to LiDAR registration\n\
(synth-city, segment, register).")

# python3-mvkp: the Python module (numpy arrays in and out).
set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-mvkp)
set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
set(CPACK_DEBIAN_PYTHON_PACKAGE_SHLIBDEPS ON)
set(_py_dep "python3")
find_package(Python3 QUIET COMPONENTS Interpreter)
if(Python3_Interpreter_FOUND)
  # The extension is built for this minor version (its .so name carries the ABI).
  math(EXPR _py_next "${Python3_VERSION_MINOR} + 1")
  set(_py_dep "python3 (>= ${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}~), python3 (<< ${Python3_VERSION_MAJOR}.${_py_next})")
endif()
set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS "${_py_dep}, python3-numpy")
# `python3 -m mvkp ...` forwards to the command line.
set(CPACK_DEBIAN_PYTHON_PACKAGE_RECOMMENDS "mvkp (= ${PROJECT_VERSION}-${CPACK_DEBIAN_PACKAGE_RELEASE})")
set(CPACK_COMPONENT_PYTHON_DISPLAY_NAME "mvkp Python module")
set(CPACK_COMPONENT_PYTHON_DESCRIPTION
    "mvkp: fast planar image matching - Python 3 module\n\
import mvkp: training, matching, recognition with a target database, CDIKP\n\
descriptors, the FFVA nearest-neighbour index and aerial registration, on\n\
numpy arrays (as cv2 gives them). Type stubs included.")

include(CPack)

# ---------------------------------------------------------------- user guide snippets
include(${CMAKE_CURRENT_LIST_DIR}/doc_snippets.cmake OPTIONAL)
