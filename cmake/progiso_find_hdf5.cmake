# Defines progiso::hdf5, libhdf5's serial C library (Debian's libhdf5-dev installs it under
# hdf5/serial beside the Open MPI build, which progiso does not use: each rank reads its own
# files), from its header and library alone. Used by the build and by the installed
# progisoConfig.cmake.
if(NOT TARGET progiso::hdf5)
  find_path(PROGISO_HDF5_INCLUDE_DIR hdf5.h PATH_SUFFIXES hdf5/serial)
  find_library(PROGISO_HDF5_LIBRARY NAMES hdf5_serial hdf5 PATH_SUFFIXES hdf5/serial)
  if(PROGISO_HDF5_INCLUDE_DIR AND PROGISO_HDF5_LIBRARY)
    add_library(progiso::hdf5 UNKNOWN IMPORTED)
    set_target_properties(progiso::hdf5 PROPERTIES
      IMPORTED_LOCATION "${PROGISO_HDF5_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${PROGISO_HDF5_INCLUDE_DIR}")
  endif()
endif()
