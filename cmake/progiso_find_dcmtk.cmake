# Defines progiso::dcmjpeg: DCMTK's lossless JPEG decoders (dcmjpeg on the IJG 8-, 12- and 16-bit
# libraries) with the DCMTK libraries they stand on, from the headers and libraries alone.
# DCMTK's own CMake config is not used because it pulls in every DCMTK module and their
# dependencies. Used by the build and by the installed progisoConfig.cmake.
if(NOT TARGET progiso::dcmjpeg)
  find_path(PROGISO_DCMTK_INCLUDE_DIR dcmtk/dcmjpeg/djdijg16.h)
  set(_progiso_dcmtk_libraries)
  set(_progiso_dcmtk_found TRUE)
  foreach(_lib dcmjpeg ijg8 ijg12 ijg16 dcmimgle dcmdata oflog ofstd)
    find_library(PROGISO_DCMTK_${_lib}_LIBRARY NAMES ${_lib})
    if(NOT PROGISO_DCMTK_${_lib}_LIBRARY)
      set(_progiso_dcmtk_found FALSE)
    endif()
    list(APPEND _progiso_dcmtk_libraries ${PROGISO_DCMTK_${_lib}_LIBRARY})
  endforeach()
  if(PROGISO_DCMTK_INCLUDE_DIR AND _progiso_dcmtk_found)
    add_library(progiso::dcmjpeg INTERFACE IMPORTED)
    set_target_properties(progiso::dcmjpeg PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${PROGISO_DCMTK_INCLUDE_DIR}"
      INTERFACE_LINK_LIBRARIES "${_progiso_dcmtk_libraries}")
  endif()
  unset(_progiso_dcmtk_libraries)
  unset(_progiso_dcmtk_found)
endif()
