#include <progiso/core/detail/file_output.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <random>
#include <system_error>

#include <progiso/core/error.hpp>

namespace progiso::detail {

namespace fs = std::filesystem;

std::string errno_text(int code) {
  return std::error_code(code, std::generic_category()).message();
}

std::string lower_extension(const fs::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](char c) {
    return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  });
  return ext;
}

atomic_output::atomic_output(const fs::path& target) : target_(target) {
  const fs::path dir = target.parent_path();
  const std::string stem = target.filename().string();
  std::random_device entropy;
  std::mt19937_64 rng((std::uint64_t{entropy()} << 32) ^ entropy());
  constexpr std::string_view alphabet = "abcdefghijklmnopqrstuvwxyz0123456789";
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1);
  // A handful of attempts is plenty: a collision needs another writer to draw the same 36^6
  // suffix for the same target at the same moment.
  for (int attempt = 0; attempt < 64; ++attempt) {
    std::string name = stem + ".tmp-";
    for (int i = 0; i < 6; ++i) name += alphabet[pick(rng)];
    temp_ = dir / name;
    // "x": exclusive creation (C11), fails with EEXIST instead of reusing someone's file.
    file_ = std::fopen(temp_.string().c_str(), "wbx");
    if (file_ != nullptr) break;
    if (errno != EEXIST) {
      const int code = errno;
      throw error(target_.string() + ": cannot create the file in \"" +
                  (dir.empty() ? std::string(".") : dir.string()) + "\" (" + errno_text(code) +
                  ")");
    }
  }
  if (file_ == nullptr) {
    throw error(target_.string() + ": cannot find an unused temporary file name");
  }
  // A large buffer: the writers hand over a few bytes at a time.
  std::setvbuf(file_, nullptr, _IOFBF, std::size_t{1} << 20);
}

atomic_output::~atomic_output() {
  if (file_ != nullptr) std::fclose(file_);
  if (!committed_) {
    std::error_code ignored;
    fs::remove(temp_, ignored);
  }
}

void atomic_output::write(const void* data, std::size_t size) {
  if (std::fwrite(data, 1, size, file_) != size) fail("cannot write", errno);
}

void atomic_output::commit() {
  if (std::fflush(file_) != 0 || std::ferror(file_) != 0) fail("cannot write", errno);
  std::FILE* f = file_;
  file_ = nullptr;
  if (std::fclose(f) != 0) fail("cannot close", errno);
  std::error_code ec;
  fs::rename(temp_, target_, ec);
  if (ec) {
    throw error(target_.string() + ": cannot move the finished temporary file onto it (" +
                ec.message() + ")");
  }
  committed_ = true;
}

void atomic_output::fail(const char* what, int code) const {
  throw error(target_.string() + ": " + what + " (" +
              (code != 0 ? errno_text(code) : std::string("I/O error")) + ")");
}

}  // namespace progiso::detail
