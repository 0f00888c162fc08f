#include <progiso/io/detail/file_output.hpp>

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <random>
#include <system_error>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_input.hpp>

namespace progiso::detail {

namespace fs = std::filesystem;

// =============================================================================================
// The registry of temporaries, emptied by remove_registered_temporaries() from signal handlers.
//
// A fixed table of slots with their own path buffers, so the handler reads no memory that a
// thread might free under it. A slot's state is the handshake: the registering thread writes
// the path, then release-stores the state (1) in register_path(); the handler's acquire-load
// of the state (2) in remove_registered_temporaries() makes the path visible. Unregistering
// stores 0 (relaxed: the handler then merely skips the slot, or removes a path that is already
// gone, which is harmless).

namespace {

enum slot_state : int { slot_free = 0, slot_claimed = 1, slot_file = 2, slot_directory = 3 };

struct registry_slot {
  std::atomic<int> state{slot_free};
  char path[4096] = {};
};

constexpr std::size_t registry_slots = 64;
std::array<registry_slot, registry_slots> registry;

/// Registers `p` (a file or a directory); returns its slot, or -1 when the path is too long or
/// every slot is taken (the temporary is then merely not removed on a signal).
int register_path(const fs::path& p, slot_state kind) noexcept {
  const std::string& text = p.native();
  if (text.size() >= sizeof registry[0].path) return -1;
  for (std::size_t i = 0; i < registry.size(); ++i) {
    int expected = slot_free;
    // relaxed: claiming a slot orders nothing; the release store below publishes it.
    if (registry[i].state.compare_exchange_strong(expected, slot_claimed,
                                                  std::memory_order_relaxed)) {
      std::memcpy(registry[i].path, text.c_str(), text.size() + 1);
      // (1) release-store, pairs with the acquire-load (2) in remove_registered_temporaries().
      registry[i].state.store(kind, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

void unregister_path(int slot) noexcept {
  // relaxed: see the registry's comment.
  if (slot >= 0)
    registry[static_cast<std::size_t>(slot)].state.store(slot_free, std::memory_order_relaxed);
}

/// Removes the files directly inside `dir` and then `dir`, with async-signal-safe calls only.
void remove_directory_signal_safe(const char* dir) noexcept {
  const int fd = ::open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    alignas(8) char buffer[4096];
    for (;;) {
      const long n = ::syscall(SYS_getdents64, fd, buffer, sizeof buffer);
      if (n <= 0) break;
      bool removed = false;
      for (long at = 0; at < n;) {
        // struct linux_dirent64: u64 ino, s64 off, u16 reclen, u8 type, char name[].
        unsigned short reclen = 0;
        std::memcpy(&reclen, buffer + at + 16, sizeof reclen);
        const char* name = buffer + at + 19;
        if (std::strcmp(name, ".") != 0 && std::strcmp(name, "..") != 0) {
          removed = ::unlinkat(fd, name, 0) == 0 || removed;
        }
        at += reclen;
      }
      if (!removed) break;
      ::lseek(fd, 0, SEEK_SET);
    }
    ::close(fd);
  }
  ::rmdir(dir);
}

}  // namespace

void remove_registered_temporaries() noexcept {
  for (registry_slot& slot : registry) {
    // (2) acquire-load, pairs with the release-store (1) in register_path().
    const int state = slot.state.load(std::memory_order_acquire);
    if (state == slot_file) {
      ::unlink(slot.path);
    } else if (state == slot_directory) {
      remove_directory_signal_safe(slot.path);
    }
  }
}

// =============================================================================================
// Helpers.

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

std::string temporary_suffix() {
  thread_local std::mt19937_64 rng = [] {
    std::random_device entropy;
    return std::mt19937_64((std::uint64_t{entropy()} << 32) ^ entropy());
  }();
  constexpr std::string_view alphabet = "abcdefghijklmnopqrstuvwxyz0123456789";
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1);
  std::string s;
  for (int i = 0; i < 6; ++i) s += alphabet[pick(rng)];
  return s;
}

namespace {

/// "NAME.tmp-XXXXXX" beside `file`, with NAME shortened so the whole fits in a file name.
fs::path temporary_beside(const fs::path& file) {
  std::string stem = file.filename().string();
  constexpr std::size_t room = 255 - 11;  // ".tmp-XXXXXX"
  if (stem.size() > room) stem.resize(room);
  return file.parent_path() / (stem + ".tmp-" + temporary_suffix());
}

std::string directory_text(const fs::path& dir) {
  return dir.empty() ? std::string(".") : dir.string();
}

}  // namespace

// =============================================================================================
// atomic_output

atomic_output::atomic_output(const fs::path& target) : target_(target), final_(target) {
  const std::string name = target.string();
  if (name.empty()) throw error("expected an output file name, found an empty one");

  struct stat st {};
  bool exists = ::stat(name.c_str(), &st) == 0;
  if (!exists && errno != ENOENT) {
    throw error(name + ": cannot use as an output file (" + errno_text(errno) + ")");
  }
  mode_t mode = 0666;
  if (exists) {
    if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) {
      // Written into, never replaced. O_NONBLOCK: a FIFO without a reader fails (ENXIO)
      // instead of waiting forever; it is cleared once the descriptor is open.
      const int fd = ::open(name.c_str(), O_WRONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
      if (fd < 0) {
        const int code = errno;
        throw error(name + ": cannot write to " + std::string(file_type_name(st.st_mode)) + " (" +
                    (code == ENXIO ? std::string("no process is reading it") : errno_text(code)) +
                    ")");
      }
      const int flags = ::fcntl(fd, F_GETFL);
      if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
      file_ = ::fdopen(fd, "wb");
      if (file_ == nullptr) {
        const int code = errno;
        ::close(fd);
        throw error(name + ": cannot write to it (" + errno_text(code) + ")");
      }
      direct_ = true;
      return;
    }
    if (!S_ISREG(st.st_mode)) {
      throw error(name +
                  ": expected a regular file, a character device or a FIFO as output, found " +
                  std::string(file_type_name(st.st_mode)));
    }
    // Replace the file a symbolic link names, not the link.
    std::error_code ec;
    const fs::path real = fs::canonical(target, ec);
    if (!ec) final_ = real;
    mode = st.st_mode & 07777;
  }

  int fd = -1;
  // A handful of attempts is plenty: a collision needs another writer to draw the same 36^6
  // suffix for the same target at the same moment.
  for (int attempt = 0; attempt < 64 && fd < 0; ++attempt) {
    temp_ = temporary_beside(final_);
    // Registered before it exists, so that no signal can come between the creation and the
    // registration (removing a name that does not exist yet is harmless).
    slot_ = register_path(temp_, slot_file);
    fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, mode);
    if (fd < 0) {
      const int code = errno;
      unregister_path(slot_);
      slot_ = -1;
      if (code != EEXIST) {
        throw error(name + ": cannot create the file in \"" + directory_text(final_.parent_path()) +
                    "\" (" + errno_text(code) + ")");
      }
    }
  }
  if (fd < 0) throw error(name + ": cannot find an unused temporary file name");
  // The creation mode was filtered by the umask; an existing file keeps its own permissions.
  if (exists) (void)::fchmod(fd, mode);
  file_ = ::fdopen(fd, "wb");
  if (file_ == nullptr) {
    const int code = errno;
    ::close(fd);
    ::unlink(temp_.c_str());
    unregister_path(slot_);
    throw error(name + ": cannot create the file (" + errno_text(code) + ")");
  }
  // A large buffer: the writers hand over a few bytes at a time.
  std::setvbuf(file_, nullptr, _IOFBF, std::size_t{1} << 20);
}

atomic_output::~atomic_output() {
  if (file_ != nullptr) std::fclose(file_);
  if (!direct_ && !published_) {
    ::unlink(temp_.c_str());
    unregister_path(slot_);
  }
}

void atomic_output::write(const void* data, std::size_t size) {
  PROGISO_ASSERT(file_ != nullptr);
  if (std::fwrite(data, 1, size, file_) != size) fail("cannot write", errno);
}

fs::path atomic_output::scratch_directory() const {
  if (direct_) return fs::temp_directory_path();
  const fs::path dir = final_.parent_path();
  return dir.empty() ? fs::path(".") : dir;
}

scratch_file::scratch_file(const fs::path& directory, std::string for_errors)
    : name_(std::move(for_errors)) {
  fd_ = ::open(directory.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd_ < 0 && (errno == EOPNOTSUPP || errno == EISDIR || errno == EINVAL)) {
    // No O_TMPFILE here: a named file, unlinked as soon as it exists (a signal in between
    // leaves it behind; the registry's slot removes it).
    for (int attempt = 0; attempt < 64 && fd_ < 0; ++attempt) {
      const fs::path named = temporary_beside(directory / "scratch");
      const int slot = register_path(named, slot_file);
      fd_ = ::open(named.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
      const int code = errno;
      if (fd_ >= 0) ::unlink(named.c_str());
      unregister_path(slot);
      if (fd_ < 0 && code != EEXIST) {
        errno = code;
        break;
      }
    }
  }
  if (fd_ < 0) {
    throw error(name_ + ": cannot make a scratch file in \"" + directory_text(directory) + "\" (" +
                errno_text(errno) + ")");
  }
}

scratch_file::~scratch_file() {
  if (fd_ >= 0) ::close(fd_);
}

void scratch_file::write(const void* data, std::size_t size) {
  const auto* p = static_cast<const char*>(data);
  while (size > 0) {
    const ::ssize_t n = ::write(fd_, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      throw error(name_ + ": cannot write a scratch file (" + errno_text(n < 0 ? errno : ENOSPC) +
                  ")");
    }
    p += n;
    size -= static_cast<std::size_t>(n);
    size_ += static_cast<std::uint64_t>(n);
  }
}

void scratch_file::copy_into(atomic_output& out) {
  std::vector<char> block(std::size_t{1} << 20);
  std::uint64_t at = 0;
  while (at < size_) {
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(block.size(), size_ - at));
    const ::ssize_t n = ::pread(fd_, block.data(), want, static_cast<::off_t>(at));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      throw error(name_ + ": cannot read back a scratch file (" +
                  (n < 0 ? errno_text(errno) : std::string("it is shorter than written")) + ")");
    }
    out.write(block.data(), static_cast<std::size_t>(n));
    at += static_cast<std::uint64_t>(n);
  }
}

void atomic_output::finish() {
  if (finished_) return;
  if (std::fflush(file_) != 0 || std::ferror(file_) != 0) fail("cannot write", errno);
  std::FILE* f = file_;
  file_ = nullptr;
  if (std::fclose(f) != 0) fail("cannot close", errno);
  finished_ = true;
}

void atomic_output::publish() {
  PROGISO_ASSERT(finished_);
  if (direct_ || published_) return;
  if (::rename(temp_.c_str(), final_.c_str()) != 0) {
    const int code = errno;
    throw error(target_.string() + ": cannot move the finished temporary file onto it (" +
                errno_text(code) + ")");
  }
  published_ = true;
  unregister_path(slot_);
}

void atomic_output::fail(const char* what, int code) const {
  throw error(target_.string() + ": " + what + " (" +
              (code != 0 ? errno_text(code) : std::string("I/O error")) + ")");
}

// =============================================================================================
// staged_directory

staged_directory::staged_directory(const fs::path& target) : target_(target) {
  const std::string name = target.string();
  if (name.empty()) throw error("expected a directory name, found an empty one");
  struct stat st {};
  if (::stat(name.c_str(), &st) == 0) {
    if (!S_ISDIR(st.st_mode)) {
      throw error(name + ": expected a directory, found " +
                  std::string(file_type_name(st.st_mode)));
    }
  } else if (errno != ENOENT) {
    throw error(name + ": cannot use as a directory (" + errno_text(errno) + ")");
  }
  // Beside the target, so that publish() renames within one file system.
  fs::path base = target;
  while (!base.empty() && base.filename().empty()) base = base.parent_path();  // "dir/"
  for (int attempt = 0; attempt < 64; ++attempt) {
    staging_ = temporary_beside(base);
    slot_ = register_path(staging_, slot_directory);  // before it exists, as for files
    if (::mkdir(staging_.c_str(), 0777) == 0) return;
    const int code = errno;
    unregister_path(slot_);
    slot_ = -1;
    if (code != EEXIST) {
      throw error(name + ": cannot create the directory in \"" +
                  directory_text(base.parent_path()) + "\" (" + errno_text(code) + ")");
    }
  }
  throw error(name + ": cannot find an unused temporary directory name");
}

staged_directory::~staged_directory() {
  if (published_) return;
  std::error_code ignored;
  fs::remove_all(staging_, ignored);
  unregister_path(slot_);
}

void staged_directory::publish() {
  if (published_) return;
  const std::string name = target_.string();
  if (::rename(staging_.c_str(), target_.c_str()) != 0) {
    // The directory exists (EEXIST / ENOTEMPTY): move the files into it one by one.
    const int code = errno;
    if (code != EEXIST && code != ENOTEMPTY) {
      throw error(name + ": cannot move the finished directory onto it (" + errno_text(code) + ")");
    }
    for (const auto& entry : fs::directory_iterator(staging_)) {
      if (::rename(entry.path().c_str(), (target_ / entry.path().filename()).c_str()) != 0) {
        const int c = errno;
        throw error(name + ": cannot move " + entry.path().filename().string() + " into it (" +
                    errno_text(c) + ")");
      }
    }
    ::rmdir(staging_.c_str());
  }
  published_ = true;
  unregister_path(slot_);
}

}  // namespace progiso::detail
