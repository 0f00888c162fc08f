// progiso/mpi/detail/mpi_c.hpp — <mpi.h> with its C API alone: the deprecated C++ bindings
// (removed in MPI-3) that Open MPI and MPICH would also include warn under -Wall.
#pragma once

#ifndef OMPI_SKIP_MPICXX
#define OMPI_SKIP_MPICXX 1
#endif
#ifndef MPICH_SKIP_MPICXX
#define MPICH_SKIP_MPICXX 1
#endif
#include <mpi.h>
