# Cross-compile the drive drivers (omni kinematics + cia402) for a Cortex-M7
# with the strict firmware flags: proves they need no OS, links no heap, and
# reports the size of their state structs on the target.
#   cmake -DARM_GCC=... -DOUT=dir -DSRCS="a.c;b.c" -DINCS="dir;dir" -P cortexm_check.cmake
string(REGEX REPLACE "gcc$" "nm" ARM_NM "${ARM_GCC}")
string(REGEX REPLACE "gcc$" "size" ARM_SIZE "${ARM_GCC}")
file(MAKE_DIRECTORY ${OUT})
set(flags -mcpu=cortex-m7 -mthumb -mfpu=fpv5-d16 -mfloat-abi=hard -std=c11 -O2 -ffunction-sections
          -fdata-sections -DNDEBUG -Wall -Wextra -Wpedantic -Wconversion -Wdouble-promotion -Wshadow
          -Wstrict-prototypes -Wmissing-prototypes -Wvla -Wundef -Werror)
foreach(i ${INCS})
  list(APPEND flags -I${i})
endforeach()
file(WRITE ${OUT}/probe.c "#include \"cia402/cia402_omni.h\"\ncia402_omni_t coslam_probe_omni;\ncia402_drive_t coslam_probe_drive;\n")
set(objs "")
foreach(src ${SRCS} ${OUT}/probe.c)
  get_filename_component(n ${src} NAME_WE)
  execute_process(COMMAND ${ARM_GCC} ${flags} -c ${src} -o ${OUT}/${n}.o RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "Cortex-M compile of ${src} failed:\n${err}")
  endif()
  list(APPEND objs ${OUT}/${n}.o)
endforeach()
execute_process(COMMAND ${ARM_NM} -u ${objs} OUTPUT_VARIABLE undef)
if(undef MATCHES "[ \t](malloc|calloc|realloc|free)\n")
  message(FATAL_ERROR "the drivers reference the heap:\n${undef}")
endif()
execute_process(COMMAND ${ARM_NM} -S ${OUT}/probe.o OUTPUT_VARIABLE syms)
string(REGEX MATCH "[0-9a-f]+ ([0-9a-f]+) [BC] coslam_probe_omni" _ "${syms}")
math(EXPR omni "0x${CMAKE_MATCH_1}")
string(REGEX MATCH "[0-9a-f]+ ([0-9a-f]+) [BC] coslam_probe_drive" _ "${syms}")
math(EXPR drive "0x${CMAKE_MATCH_1}")
list(REMOVE_ITEM objs ${OUT}/probe.o)
execute_process(COMMAND ${ARM_SIZE} -B -t ${objs} OUTPUT_VARIABLE sz)
string(REGEX MATCH "\n *([0-9]+)[ \t]+([0-9]+)[ \t]+([0-9]+)[ \t]+[0-9]+[ \t]+[0-9a-f]+[ \t]+\\(TOTALS\\)" _ "${sz}")
file(WRITE ${OUT}/drivers_footprint.txt
  "DRIVERS cortex-m7 text=${CMAKE_MATCH_1} data=${CMAKE_MATCH_2} bss=${CMAKE_MATCH_3} sizeof(cia402_omni_t)=${omni} sizeof(cia402_drive_t)=${drive}\n")
file(READ ${OUT}/drivers_footprint.txt txt)
message(STATUS "${txt}")
