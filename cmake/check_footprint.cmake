# Passes if the Cortex-M cross build produced its footprint report.
if(NOT EXISTS "${FOOTPRINT}")
  message(FATAL_ERROR "no Cortex-M footprint report at ${FOOTPRINT}: is gcc-arm-none-eabi installed (make deps)?")
endif()
file(READ "${FOOTPRINT}" txt)
message("${txt}")
if(NOT txt MATCHES "FASTSLAM" OR NOT txt MATCHES "EKFSLAM")
  message(FATAL_ERROR "footprint report incomplete")
endif()
