// An embedder's program: the finest surface of an analytic field through progiso::core alone;
// with progiso::io, that surface written as PLY; with progiso::scheduler, the engine's finest
// cut of the same field; with progiso::mpi, the engine across ranks (one rank here) to the same
// cut. Exits non-zero when a result is not what the library promises.
#include <cstdio>
#include <filesystem>

#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/refiner.hpp>
#if PROGISO_CONSUMER_IO
#include <progiso/io/mesh_io.hpp>
#endif
#if PROGISO_CONSUMER_SCHEDULER
#include <progiso/scheduler/engine.hpp>
#endif
#if PROGISO_CONSUMER_MPI
#include <mpi.h>

#include <progiso/mpi/distributed_engine.hpp>
#endif

int main(int argc, char** argv) {
  const progiso::volume vol = progiso::make_sphere_field({17, 17, 17}, {8.0, 8.0, 8.0});
  const progiso::extract_result r = progiso::extract_isosurface(vol, 6.0, {});
  if (r.mesh.triangles.empty()) {
    std::fprintf(stderr, "consumer: the sphere's surface is empty\n");
    return 1;
  }
#if PROGISO_CONSUMER_IO
  if (argc < 2) return 2;
  const std::filesystem::path out = std::filesystem::path(argv[1]) / "sphere.ply";
  progiso::write_ply(out, r.mesh);
  if (!std::filesystem::exists(out) || std::filesystem::file_size(out) == 0) return 1;
#endif
#if PROGISO_CONSUMER_SCHEDULER
  progiso::engine eng(vol, 6.0, {});
  eng.refine(progiso::refine_goal::full());
  if (eng.snapshot().triangle_count() != r.mesh.triangles.size()) {
    std::fprintf(stderr, "consumer: the engine's finest cut differs from the one-shot call's\n");
    return 1;
  }
#endif
#if PROGISO_CONSUMER_MPI
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_MULTIPLE, &provided);
  std::size_t triangles = 0;
  {
    progiso::distributed_engine eng(MPI_COMM_WORLD, vol, 6.0);
    eng.start(progiso::refine_goal::full());
    eng.wait();
    triangles = eng.snapshot()->mesh()->triangles.size();
  }
  MPI_Finalize();
  if (triangles != r.mesh.triangles.size()) {
    std::fprintf(stderr, "consumer: the engine across ranks ends on another cut\n");
    return 1;
  }
#endif
  (void)argc;
  (void)argv;
  std::puts("consumer: ok");
  return 0;
}
