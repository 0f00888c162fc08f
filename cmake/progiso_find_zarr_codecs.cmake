# Defines progiso::blosc and progiso::zstd, the codecs of Zarr chunks (c-blosc and libzstd: Debian's
# libblosc-dev and libzstd-dev), from their headers and libraries alone, as for OpenJPEG (Debian's
# zstd package config names a static library its -dev package may not ship). Used by the build
# and by the installed progisoConfig.cmake.
foreach(_codec blosc zstd)
  if(NOT TARGET progiso::${_codec})
    string(TOUPPER ${_codec} _upper)
    find_path(PROGISO_${_upper}_INCLUDE_DIR ${_codec}.h)
    find_library(PROGISO_${_upper}_LIBRARY NAMES ${_codec})
    if(PROGISO_${_upper}_INCLUDE_DIR AND PROGISO_${_upper}_LIBRARY)
      add_library(progiso::${_codec} UNKNOWN IMPORTED)
      set_target_properties(progiso::${_codec} PROPERTIES
        IMPORTED_LOCATION "${PROGISO_${_upper}_LIBRARY}"
        INTERFACE_INCLUDE_DIRECTORIES "${PROGISO_${_upper}_INCLUDE_DIR}")
    endif()
  endif()
endforeach()
