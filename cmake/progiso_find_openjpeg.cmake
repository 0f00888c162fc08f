# Defines progiso::openjp2, OpenJPEG's decoder library, from its header and library alone.
# Debian's OpenJPEGConfig.cmake is not used because its exported targets name command-line tools
# that the -dev package does not ship, so loading it prints a warning for each one into every
# configure, the embedders' included. Used by the build and by the installed progisoConfig.cmake.
if(NOT TARGET progiso::openjp2)
  find_path(PROGISO_OPENJPEG_INCLUDE_DIR openjpeg.h
            PATH_SUFFIXES openjpeg-2.5 openjpeg-2.4 openjpeg-2.3)
  find_library(PROGISO_OPENJPEG_LIBRARY NAMES openjp2)
  if(PROGISO_OPENJPEG_INCLUDE_DIR AND PROGISO_OPENJPEG_LIBRARY)
    add_library(progiso::openjp2 UNKNOWN IMPORTED)
    set_target_properties(progiso::openjp2 PROPERTIES
      IMPORTED_LOCATION "${PROGISO_OPENJPEG_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${PROGISO_OPENJPEG_INCLUDE_DIR}")
  endif()
endif()
