// progiso extract across MPI ranks: `mpirun -np N progiso extract IN --full -o OUT.ply …`.
//
// The ranks split the grid's z planes into N shares (detail::finest_share, rank r the planes
// [nz·r/N, nz·(r+1)/N)). Each reads the volume's header and its samples (a mapped input is read
// only where its share and the two planes after it lie), counts its share's vertices and
// triangles, takes the counts of the ranks before it (MPI_Exscan) as its first ids, and meshes its
// share slab by slab into PLY records. Rank 0 writes the header for the totals, then every rank's
// vertex records in rank order, then every rank's face records: the file is the single
// process's, byte for byte, whatever N. Messages are Open MPI's (Debian's libopenmpi-dev), found
// by CMake; without MPI the command refuses to run under mpirun with more than one rank.
//
// Errors: what every rank meets while setting up (options, the input, the outputs) is agreed on
// (MPI_Allreduce) and said once, by the lowest rank that met it, every rank ending with status 2;
// a failure of one rank later (memory, a write) is said by that rank and ends the job
// (MPI_Abort); a rank that dies ends it through mpirun. No goal but --full, no --normals,
// --world or --hierarchy yet: refused with one line.
#pragma once

#include <string>
#include <vector>

namespace progiso::cli {

/// Whether this process was started by an MPI launcher (Open MPI's or a PMI one).
[[nodiscard]] bool launched_by_mpi() noexcept;
/// The size of the launcher's job (1 when not launched by one).
[[nodiscard]] int mpi_job_size() noexcept;
/// `progiso extract` as one rank of the job; `args` as main() has them. Returns the exit status.
[[nodiscard]] int run_mpi_extract(const std::vector<std::string>& args);
/// Whether this build has the MPI path.
[[nodiscard]] bool have_mpi() noexcept;

}  // namespace progiso::cli
