# coslam_add_hal_conformance(<name> SUITES <contract>... SOURCES <src>... LIBS <lib>...)
# One HAL conformance binary (GoogleTest, CTest labels "hal;conformance"):
# the suites suite_<contract>.cpp of this folder plus your backend sources
# (a harness and an INSTANTIATE_TEST_SUITE_P line each). Include this file
# from any test folder, whatever its position in the build:
#   include(${PROJECT_SOURCE_DIR}/test/hal_conformance/conformance.cmake)
# See docs/hal.md, "Adding a backend to the conformance suites".
include_guard(GLOBAL)
function(coslam_add_hal_conformance name)
  cmake_parse_arguments(A "" "" "SUITES;SOURCES;LIBS" ${ARGN})
  set(COSLAM_HAL_CONFORMANCE_DIR ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  set(_s "")
  foreach(s ${A_SUITES})
    list(APPEND _s ${COSLAM_HAL_CONFORMANCE_DIR}/suite_${s}.cpp)
  endforeach()
  coslam_add_cpp_test(${name} SOURCES ${_s} ${A_SOURCES} LIBS coslam_hal ${A_LIBS} LABELS hal conformance)
  target_include_directories(${name} PRIVATE ${COSLAM_HAL_CONFORMANCE_DIR})
endfunction()
