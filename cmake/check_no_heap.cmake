# Fails if the archive LIB references malloc/calloc/realloc/free (or their
# aligned cousins). Invoked after every build of the core and by CTest.
execute_process(COMMAND ${NM} -A --undefined-only ${LIB}
                OUTPUT_VARIABLE syms RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "nm failed on ${LIB}: ${err}")
endif()
string(REGEX MATCHALL "[^\n]*[ \t](malloc|calloc|realloc|free|aligned_alloc|posix_memalign|memalign|reallocarray)\n" hits "${syms}\n")
if(hits)
  message(FATAL_ERROR "The core must not use the heap; heap symbols referenced:\n${hits}")
endif()
message(STATUS "no-heap check passed: ${LIB}")
