#include <progiso/io/detail/file_input.hpp>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <limits>
#include <string>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::detail {

std::string quoted(std::string_view bytes, std::size_t limit) {
  constexpr std::string_view hex = "0123456789abcdef";
  std::string out = "\"";
  for (std::size_t i = 0; i < bytes.size() && i < limit; ++i) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if (c >= 0x20 && c < 0x7f && c != '"' && c != '\\') {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 0xfu];
    }
  }
  if (bytes.size() > limit) out += "...";
  return out + "\"";
}

std::string_view file_type_name(unsigned mode) noexcept {
  switch (mode & S_IFMT) {
    case S_IFREG:
      return "a regular file";
    case S_IFDIR:
      return "a directory";
    case S_IFIFO:
      return "a FIFO";
    case S_IFSOCK:
      return "a socket";
    case S_IFCHR:
      return "a character device";
    case S_IFBLK:
      return "a block device";
    default:
      return "a special file";
  }
}

input_file::input_file(const std::filesystem::path& file, std::string_view kind)
    : path_(file), kind_(kind) {
  const std::string name = file.string();
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer forever. It is
  // cleared again below, once the descriptor is known to be a regular file.
  const int fd = ::open(name.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) {
    throw error(name + ": cannot open " + kind_ + " file (" + errno_text(errno) + ")");
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int code = errno;
    ::close(fd);
    throw error(name + ": cannot open " + kind_ + " file (" + errno_text(code) + ")");
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw error(name + ": expected a regular " + kind_ + " file, found " +
                std::string(file_type_name(st.st_mode)));
  }
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
    const int code = errno;
    ::close(fd);
    throw error(name + ": cannot open " + kind_ + " file (" + errno_text(code) + ")");
  }
  file_ = ::fdopen(fd, "rb");
  if (file_ == nullptr) {
    const int code = errno;
    ::close(fd);
    throw error(name + ": cannot open " + kind_ + " file (" + errno_text(code) + ")");
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
}

input_file::~input_file() {
  if (file_ != nullptr) std::fclose(file_);
}

std::size_t input_file::read(void* data, std::size_t n) {
  const std::size_t got = std::fread(data, 1, n, file_);
  if (got < n && std::ferror(file_) != 0) {
    throw error(path_.string() + ": cannot read " + kind_ + " file (" + errno_text(errno) + ")");
  }
  return got;
}

void input_file::seek(std::uint64_t offset) {
  if (offset > static_cast<std::uint64_t>(INT64_MAX) ||
      ::fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0) {
    throw error(path_.string() + ": cannot seek to byte " + std::to_string(offset) + " of " +
                kind_ + " file");
  }
}

std::vector<char> input_file::read_all() {
  seek(0);
  std::vector<char> data(static_cast<std::size_t>(size_));
  data.resize(read(data.data(), data.size()));
  return data;
}

std::optional<mapped_bytes> map_bytes(const input_file& in, std::uint64_t offset,
                                      std::uint64_t n) noexcept {
  if (n == 0 || offset > in.size() || n > in.size() - offset) return std::nullopt;
  const auto page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
  const std::uint64_t start = offset - offset % page;
  const std::uint64_t length = n + (offset - start);
  if (length > std::numeric_limits<std::size_t>::max()) return std::nullopt;
  void* base = ::mmap(nullptr, static_cast<std::size_t>(length), PROT_READ, MAP_PRIVATE,
                      ::fileno(in.stream()), static_cast<off_t>(start));
  if (base == MAP_FAILED) return std::nullopt;
  struct mapping {
    void* base;
    std::size_t length;
    mapping(void* b, std::size_t l) noexcept : base(b), length(l) {}
    mapping(const mapping&) = delete;
    mapping& operator=(const mapping&) = delete;
    ~mapping() { ::munmap(base, length); }
  };
  try {
    auto keeper = std::make_shared<const mapping>(base, static_cast<std::size_t>(length));
    const auto* first = static_cast<const std::byte*>(base) + (offset - start);
    return mapped_bytes{{first, static_cast<std::size_t>(n)}, std::move(keeper)};
  } catch (...) {
    ::munmap(base, static_cast<std::size_t>(length));
    return std::nullopt;
  }
}

}  // namespace progiso::detail
