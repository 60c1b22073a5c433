# The compile-time tie of message and link (docs/map-message.md "Message and
# link"): the robot app's map-message code (meeting.c) and the
# authentication decorator compile in every profile, and refuse to compile
# when the largest message would not fit HAL_LINK_MAX_PAYLOAD.
# cmake -DCC=... -DSRCS="a.c;b.c" -DINCS="dir;dir" -P check_msg_fits_link.cmake
set(_incs "")
foreach(_i ${INCS})
  list(APPEND _incs -I${_i})
endforeach()
cmake_minimum_required(VERSION 3.22)
set(fails 0)
# (label | extra definitions | expected: ok or fail)
set(_cases
  "default||ok"
  "large|COSLAM_PROFILE_LARGE=1|ok"
  "host|COSLAM_PROFILE_HOST=1|ok"
  "default, 221 landmarks per message|COSLAM_MAX_MSG_LANDMARKS=221,COSLAM_MAX_LANDMARKS=256|ok"
  "default, 222 landmarks per message|COSLAM_MAX_MSG_LANDMARKS=222,COSLAM_MAX_LANDMARKS=256|fail"
  "host, 1024 landmarks per message|COSLAM_PROFILE_HOST=1,COSLAM_MAX_MSG_LANDMARKS=1024|fail")
foreach(_c ${_cases})
  string(REPLACE "|" ";" _p "${_c}")
  list(GET _p 0 _label)
  list(GET _p 1 _extra)
  list(GET _p 2 _want)
  string(REPLACE "," ";" _extra "${_extra}")
  set(_x "")
  foreach(_d ${_extra})
    list(APPEND _x -D${_d})
  endforeach()
  foreach(_src ${SRCS})
    get_filename_component(_n ${_src} NAME)
    execute_process(COMMAND ${CC} -std=c11 -fsyntax-only ${_x} ${_incs} ${_src}
                    RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err)
    if(_want STREQUAL "ok")
      if(NOT _rc EQUAL 0)
        message(SEND_ERROR "FAIL ${_label}: ${_n} does not compile:\n${_err}")
        math(EXPR fails "${fails} + 1")
      else()
        message(STATUS "ok   ${_label}: ${_n} compiles")
      endif()
    else()
      if(_rc EQUAL 0)
        message(SEND_ERROR "FAIL ${_label}: ${_n} compiles, but its largest message exceeds the link payload")
        math(EXPR fails "${fails} + 1")
      elseif(NOT _err MATCHES "exceeds HAL_LINK_MAX_PAYLOAD|does not fit HAL_LINK_MAX_PAYLOAD")
        message(SEND_ERROR "FAIL ${_label}: ${_n} fails, but not on the payload assertion:\n${_err}")
        math(EXPR fails "${fails} + 1")
      else()
        message(STATUS "ok   ${_label}: ${_n} refused by the payload assertion")
      endif()
    endif()
  endforeach()
endforeach()
if(fails GREATER 0)
  message(FATAL_ERROR "${fails} case(s) failed")
endif()
