// Loads the shared object named on the command line and runs its progiso extraction; exits 0
// when it loads and returns a surface.
#include <dlfcn.h>

#include <cstddef>
#include <cstdio>

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  void* plugin = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
  if (plugin == nullptr) {
    std::fprintf(stderr, "dlopen failed: %s\n", dlerror());
    return 1;
  }
  using entry = std::size_t (*)();
  const auto run = reinterpret_cast<entry>(dlsym(plugin, "progiso_plugin_triangles"));
  if (run == nullptr) return 1;
  const std::size_t triangles = run();
  std::printf("the plugin extracted %zu triangles\n", triangles);
  return triangles > 0 ? 0 : 1;
}
