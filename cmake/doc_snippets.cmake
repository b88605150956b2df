# The user guide's snippets (docs/guide/[0-9]*.md): each page's ```cpp blocks
# are extracted (scripts/doc_snippets.py, #line directives point at the page)
# and built against mvkp::mvkp as <build>/docs/snippets/<page>; CTest's
# `doc_snippets` runs every page's sh, C++ and Python blocks on bundled data.
# Included by cmake/packaging.cmake.
option(MVKP_BUILD_DOC_SNIPPETS "Build and test the user guide's code snippets (docs/guide)" ${MVKP_BUILD_TESTS})
if(NOT MVKP_BUILD_DOC_SNIPPETS)
  return()
endif()
find_package(Python3 QUIET COMPONENTS Interpreter)
if(NOT Python3_Interpreter_FOUND)
  message(WARNING "docs/guide snippets: no python3, not built")
  return()
endif()

file(GLOB _mvkp_guide_pages CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/docs/guide/[0-9]*.md)
set(_snippet_dir ${PROJECT_BINARY_DIR}/docs/snippets)
set(_snippet_targets "")
foreach(_page IN LISTS _mvkp_guide_pages)
  get_filename_component(_stem ${_page} NAME_WE)
  string(MAKE_C_IDENTIFIER "${_stem}" _id)
  set(_cc ${_snippet_dir}/src/${_stem}.cc)
  add_custom_command(OUTPUT ${_cc}
    COMMAND ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/scripts/doc_snippets.py extract ${_page} ${_cc}
    DEPENDS ${_page} ${PROJECT_SOURCE_DIR}/scripts/doc_snippets.py
    COMMENT "docs/guide/${_stem}.md: C++ snippet"
    VERBATIM)
  add_executable(mvkp_doc_${_id} ${_cc})
  # opencv_videoio: the webcam page reads frames with cv::VideoCapture.
  target_link_libraries(mvkp_doc_${_id} PRIVATE mvkp::mvkp opencv_videoio)
  set_target_properties(mvkp_doc_${_id} PROPERTIES OUTPUT_NAME ${_stem} RUNTIME_OUTPUT_DIRECTORY ${_snippet_dir})
  list(APPEND _snippet_targets mvkp_doc_${_id})
endforeach()

if(MVKP_BUILD_TESTS AND MVKP_BUILD_APPS AND _mvkp_guide_pages)
  # The Python blocks need the module in <build>/python (skipped, not failed,
  # when the build has none: MVKP_BUILD_PYTHON=OFF, or no pybind11).
  set(_require_python "")
  if(TARGET mvkp_python)
    set(_require_python --require-python)  # built: its absence is a failure, not a skip
  endif()
  add_test(NAME doc_snippets
    COMMAND ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/scripts/doc_snippets.py run
            --build ${PROJECT_BINARY_DIR} --source ${PROJECT_SOURCE_DIR}
            --snippets ${_snippet_dir} --python-path ${PROJECT_BINARY_DIR}/python ${_require_python})
  set_tests_properties(doc_snippets PROPERTIES TIMEOUT 900)
endif()
