// tests/support/scratch_dir.hpp — a fresh directory under the system temporary directory,
// removed with everything in it when the object goes away. Used by the I/O tests.
#pragma once

#include <algorithm>
#include <filesystem>
#include <random>
#include <string>
#include <system_error>
#include <vector>

namespace progiso::test {

class scratch_dir {
 public:
  explicit scratch_dir(const std::string& prefix = "progiso-test-") {
    std::random_device entropy;
    for (;;) {
      path_ = std::filesystem::temp_directory_path() /
              (prefix + std::to_string(entropy()) + std::to_string(entropy()));
      if (std::filesystem::create_directory(path_)) break;
    }
  }
  scratch_dir(const scratch_dir&) = delete;
  scratch_dir& operator=(const scratch_dir&) = delete;
  ~scratch_dir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  [[nodiscard]] std::filesystem::path operator/(const std::string& name) const {
    return path_ / name;
  }
  /// Names of the entries directly inside, sorted.
  [[nodiscard]] std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(path_)) {
      names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace progiso::test
