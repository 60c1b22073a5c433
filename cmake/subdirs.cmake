# coslam_add_all_subdirs(): add every immediate subfolder of the current
# source dir that has a CMakeLists.txt, in name order. Areas (drivers, sim
# devices, host tools, test groups) plug in by adding their own folder.
macro(coslam_add_all_subdirs)
  file(GLOB _coslam_subs CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*/CMakeLists.txt)
  list(SORT _coslam_subs)
  foreach(_f ${_coslam_subs})
    get_filename_component(_d ${_f} DIRECTORY)
    add_subdirectory(${_d})
  endforeach()
endmacro()
