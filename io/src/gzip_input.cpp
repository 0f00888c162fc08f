#include <progiso/io/detail/gzip_input.hpp>

#include <zlib.h>

#include <algorithm>
#include <climits>
#include <limits>
#include <new>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>

namespace progiso::detail {

namespace {
constexpr std::size_t chunk_bytes = 64 * 1024;
}  // namespace

bool gzip_can_hold(std::uint64_t compressed, std::uint64_t bytes) noexcept {
  if (compressed >
      (std::numeric_limits<std::uint64_t>::max() - gzip_slack_bytes) / gzip_max_ratio) {
    return true;
  }
  return bytes <= compressed * gzip_max_ratio + gzip_slack_bytes;
}

bool starts_with_gzip_magic(input_file& in) {
  unsigned char magic[2] = {0, 0};
  in.seek(0);
  const std::size_t got = in.read(magic, sizeof magic);
  in.seek(0);
  return got == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
}

struct gzip_input::state {
  z_stream zs{};
  std::vector<unsigned char> input = std::vector<unsigned char>(chunk_bytes);
  bool input_done = false;
  bool ended = false;  // the last member ended and no input follows
};

gzip_input::gzip_input(input_file& in, std::string label)
    : in_(in), label_(std::move(label)), state_(std::make_unique<state>()) {
  // 15 + 32: a 32 KiB window, and the gzip or zlib header detected automatically.
  if (inflateInit2(&state_->zs, 15 + 32) != Z_OK) {
    throw error(in_.path().string() + ": cannot start zlib's inflate");
  }
}

gzip_input::~gzip_input() { inflateEnd(&state_->zs); }

std::size_t gzip_input::read(std::span<std::byte> out) {
  state& s = *state_;
  z_stream& zs = s.zs;
  const auto refill = [&] {
    const std::size_t got = in_.read(s.input.data(), s.input.size());
    s.input_done = got == 0;
    zs.next_in = s.input.data();
    zs.avail_in = static_cast<uInt>(got);
  };
  auto* const dst = reinterpret_cast<unsigned char*>(out.data());
  std::size_t produced = 0;
  while (produced < out.size() && !s.ended) {
    if (zs.avail_in == 0 && !s.input_done) refill();
    const std::uint64_t room = std::min<std::uint64_t>(out.size() - produced, UINT_MAX);
    zs.next_out = dst + produced;
    zs.avail_out = static_cast<uInt>(room);
    const int rc = inflate(&zs, Z_NO_FLUSH);
    produced += static_cast<std::size_t>(room - zs.avail_out);
    if (rc == Z_STREAM_END) {
      // Another gzip member may follow.
      if (zs.avail_in == 0 && !s.input_done) refill();
      if (zs.avail_in == 0 || inflateReset(&zs) != Z_OK) s.ended = true;
      continue;
    }
    if (rc == Z_DATA_ERROR || rc == Z_NEED_DICT || rc == Z_STREAM_ERROR) {
      throw error(in_.path().string() + ": corrupt " + label_ + " (zlib: " +
                  (zs.msg != nullptr ? std::string(zs.msg) : std::string("needs a dictionary")) +
                  ")");
    }
    if (rc == Z_MEM_ERROR) throw std::bad_alloc();
    if (rc == Z_BUF_ERROR && s.input_done) s.ended = true;  // no progress possible: data ended
  }
  return produced;
}

std::uint64_t gzip_input::skip(std::uint64_t n) {
  std::vector<std::byte> scratch(static_cast<std::size_t>(std::min<std::uint64_t>(n, chunk_bytes)));
  std::uint64_t skipped = 0;
  while (skipped < n) {
    const auto want =
        static_cast<std::size_t>(std::min<std::uint64_t>(n - skipped, scratch.size()));
    const std::size_t got = read(std::span<std::byte>(scratch.data(), want));
    skipped += got;
    if (got < want) break;
  }
  return skipped;
}

sequential_input::sequential_input(const std::filesystem::path& file, std::string_view kind,
                                   std::string gzip_label)
    : in_(file, kind) {
  if (starts_with_gzip_magic(in_)) gz_ = std::make_unique<gzip_input>(in_, std::move(gzip_label));
}

std::size_t sequential_input::read(std::span<std::byte> out) {
  if (gz_) return gz_->read(out);
  return in_.read(out.data(), out.size());
}

bool sequential_input::skip_to(std::uint64_t to) {
  if (gz_) return gz_->skip(to) == to;
  if (to > in_.size()) return false;
  in_.seek(to);
  return true;
}

}  // namespace progiso::detail
