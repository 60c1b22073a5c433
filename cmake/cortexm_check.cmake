# Cross-compile firmware sources for a Cortex-M7 with the strict firmware
# flags: proves they need no OS, checks they reference no heap function, and
# reports .text/.data/.bss plus the size of named state structs on the target.
#   cmake -DARM_GCC=... -DOUT=dir -DLABEL=NAME -DSRCS="a.c;b.c" -DINCS="dir;dir"
#         -DPROBE_HEADER=x/y.h -DPROBE_TYPES=a_t,b_t -P cortexm_check.cmake
# Writes <OUT>/<label>_footprint.txt (label lower-cased).
string(REGEX REPLACE "gcc$" "nm" ARM_NM "${ARM_GCC}")
string(REGEX REPLACE "gcc$" "size" ARM_SIZE "${ARM_GCC}")
file(MAKE_DIRECTORY ${OUT})
string(TOLOWER "${LABEL}" label)
string(REPLACE "," ";" PROBE_TYPES "${PROBE_TYPES}") # comma-separated on the command line
set(flags -mcpu=cortex-m7 -mthumb -mfpu=fpv5-d16 -mfloat-abi=hard -std=c11 -O2 -ffunction-sections
          -fdata-sections -DNDEBUG -Wall -Wextra -Wpedantic -Wconversion -Wdouble-promotion -Wshadow
          -Wstrict-prototypes -Wmissing-prototypes -Wvla -Wundef -Werror)
foreach(i ${INCS})
  list(APPEND flags -I${i})
endforeach()
set(probe "#include \"${PROBE_HEADER}\"\n")
foreach(t ${PROBE_TYPES})
  string(APPEND probe "${t} coslam_probe_${t};\n")
endforeach()
file(WRITE ${OUT}/probe.c "${probe}")
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
  message(FATAL_ERROR "${LABEL} references the heap:\n${undef}")
endif()
execute_process(COMMAND ${ARM_NM} -S ${OUT}/probe.o OUTPUT_VARIABLE syms)
set(sizes "")
foreach(t ${PROBE_TYPES})
  string(REGEX MATCH "[0-9a-f]+ ([0-9a-f]+) [BC] coslam_probe_${t}" _ "${syms}")
  math(EXPR sz "0x${CMAKE_MATCH_1}")
  string(APPEND sizes " sizeof(${t})=${sz}")
endforeach()
list(REMOVE_ITEM objs ${OUT}/probe.o)
execute_process(COMMAND ${ARM_SIZE} -B -t ${objs} OUTPUT_VARIABLE sz)
string(REGEX MATCH "\n *([0-9]+)[ \t]+([0-9]+)[ \t]+([0-9]+)[ \t]+[0-9]+[ \t]+[0-9a-f]+[ \t]+\\(TOTALS\\)" _ "${sz}")
file(WRITE ${OUT}/${label}_footprint.txt
  "${LABEL} cortex-m7 text=${CMAKE_MATCH_1} data=${CMAKE_MATCH_2} bss=${CMAKE_MATCH_3}${sizes}\n")
file(READ ${OUT}/${label}_footprint.txt txt)
message(STATUS "${txt}")
