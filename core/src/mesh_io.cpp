#include <progiso/core/mesh_io.hpp>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <progiso/core/assert.hpp>
#include <progiso/core/error.hpp>

namespace progiso {
namespace {

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

// ---------------------------------------------------------------------------------------------
// All-or-nothing output: a unique temporary file beside the target, renamed onto it by commit().
// If commit() is never reached (an exception on the way), the destructor removes the temporary.

class atomic_output {
 public:
  explicit atomic_output(const fs::path& target) : target_(target) {
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

  atomic_output(const atomic_output&) = delete;
  atomic_output& operator=(const atomic_output&) = delete;

  ~atomic_output() {
    if (file_ != nullptr) std::fclose(file_);
    if (!committed_) {
      std::error_code ignored;
      fs::remove(temp_, ignored);
    }
  }

  void write(const void* data, std::size_t size) {
    if (std::fwrite(data, 1, size, file_) != size) fail("cannot write", errno);
  }
  void write(std::string_view text) { write(text.data(), text.size()); }

  /// Flushes, checks and closes the temporary, then renames it onto the target.
  void commit() {
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

 private:
  [[noreturn]] void fail(const char* what, int code) const {
    throw error(target_.string() + ": " + what + " (" +
                (code != 0 ? errno_text(code) : std::string("I/O error")) + ")");
  }

  fs::path target_;
  fs::path temp_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
};

/// Collects small pieces in a buffer of its own and hands them to the file in large blocks.
class block_writer {
 public:
  explicit block_writer(atomic_output& out) : out_(out) { buffer_.reserve(capacity); }

  void bytes(const void* data, std::size_t size) {
    if (buffer_.size() + size > capacity) flush();
    const auto* p = static_cast<const char*>(data);
    buffer_.insert(buffer_.end(), p, p + size);
  }
  void text(std::string_view s) { bytes(s.data(), s.size()); }
  void u8(std::uint8_t v) { bytes(&v, 1); }
  void u32_le(std::uint32_t v) {
    const char b[4] = {static_cast<char>(v & 0xffu), static_cast<char>((v >> 8) & 0xffu),
                       static_cast<char>((v >> 16) & 0xffu), static_cast<char>(v >> 24)};
    bytes(b, 4);
  }
  void f32_le(float v) { u32_le(std::bit_cast<std::uint32_t>(v)); }
  template <class T>
  void number(T v) {
    char b[40];
    const auto r = std::to_chars(b, b + sizeof b, v);
    PROGISO_ASSERT(r.ec == std::errc{});
    // The min() only tells gcc's -Warray-bounds what to_chars guarantees.
    bytes(b, std::min(sizeof b, static_cast<std::size_t>(r.ptr - b)));
  }
  void flush() {
    out_.write(buffer_.data(), buffer_.size());
    buffer_.clear();
  }

 private:
  static constexpr std::size_t capacity = std::size_t{1} << 16;
  atomic_output& out_;
  std::vector<char> buffer_;
};

void check_indices(const triangle_mesh& mesh) {
#if defined(PROGISO_ENABLE_ASSERTS)
  for (const auto& t : mesh.triangles) {
    for (std::uint32_t v : t) PROGISO_ASSERT(v < mesh.vertices.size());
  }
#else
  (void)mesh;
#endif
}

// ---------------------------------------------------------------------------------------------
// PLY reading helpers.

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

std::uint32_t load_u32_le(const unsigned char* p) {
  return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
         (std::uint32_t{p[3]} << 24);
}

struct ply_element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<std::vector<std::string>> properties;
};

bool is_one_of(std::string_view word, std::initializer_list<std::string_view> options) {
  return std::find(options.begin(), options.end(), word) != options.end();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Writers.

void write_ply(const std::filesystem::path& file, const triangle_mesh& mesh) {
  check_indices(mesh);
  if (mesh.vertices.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw error(file.string() +
                ": PLY int indices allow at most 2147483647 vertices, the mesh has " +
                std::to_string(mesh.vertices.size()));
  }
  atomic_output out(file);
  block_writer w(out);
  w.text("ply\nformat binary_little_endian 1.0\ncomment generated by progiso\nelement vertex ");
  w.number(mesh.vertices.size());
  w.text("\nproperty float x\nproperty float y\nproperty float z\nelement face ");
  w.number(mesh.triangles.size());
  w.text("\nproperty list uchar int vertex_indices\nend_header\n");
  for (const vec3& p : mesh.vertices) {
    for (double c : p) w.f32_le(static_cast<float>(c));
  }
  for (const auto& t : mesh.triangles) {
    w.u8(3);
    for (std::uint32_t v : t) w.u32_le(v);
  }
  w.flush();
  out.commit();
}

void write_obj(const std::filesystem::path& file, const triangle_mesh& mesh) {
  check_indices(mesh);
  atomic_output out(file);
  block_writer w(out);
  w.text("# generated by progiso\n");
  for (const vec3& p : mesh.vertices) {
    w.text("v ");
    w.number(p[0]);
    w.text(" ");
    w.number(p[1]);
    w.text(" ");
    w.number(p[2]);
    w.text("\n");
  }
  for (const auto& t : mesh.triangles) {
    w.text("f ");
    w.number(std::uint64_t{t[0]} + 1);
    w.text(" ");
    w.number(std::uint64_t{t[1]} + 1);
    w.text(" ");
    w.number(std::uint64_t{t[2]} + 1);
    w.text("\n");
  }
  w.flush();
  out.commit();
}

void write_mesh(const std::filesystem::path& file, const triangle_mesh& mesh) {
  const std::string ext = lower_extension(file);
  if (ext == ".ply") return write_ply(file, mesh);
  if (ext == ".obj") return write_obj(file, mesh);
  throw error(file.string() + ": unknown mesh format \"" + file.extension().string() +
              "\" (expected .ply or .obj)");
}

// ---------------------------------------------------------------------------------------------
// Reader.

triangle_mesh read_ply(const std::filesystem::path& file) {
  const std::string name = file.string();
  const auto fail = [&](const std::string& what) -> error { return error(name + ": " + what); };

  struct closer {
    void operator()(std::FILE* f) const noexcept { std::fclose(f); }
  };
  std::unique_ptr<std::FILE, closer> f(std::fopen(name.c_str(), "rb"));
  if (!f) throw fail("cannot open PLY file (" + errno_text(errno) + ")");
  std::vector<unsigned char> data;
  {
    unsigned char block[1 << 16];
    std::size_t got = 0;
    while ((got = std::fread(block, 1, sizeof block, f.get())) > 0) {
      data.insert(data.end(), block, block + got);
    }
    if (std::ferror(f.get()) != 0) throw fail("cannot read PLY file (I/O error)");
  }

  // ---- Header: lines up to "end_header".
  std::vector<ply_element> elements;
  std::size_t pos = 0;
  int line_no = 0;
  bool ended = false;
  constexpr std::size_t max_header = std::size_t{1} << 16;
  while (!ended) {
    const auto nl = std::find(data.begin() + static_cast<std::ptrdiff_t>(pos), data.end(),
                              static_cast<unsigned char>('\n'));
    if (nl == data.end() || static_cast<std::size_t>(nl - data.begin()) > max_header) {
      throw fail("expected a PLY header ending in \"end_header\", found none");
    }
    const auto end = static_cast<std::size_t>(nl - data.begin());
    std::string_view line(reinterpret_cast<const char*>(data.data()) + pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = end + 1;
    ++line_no;
    const std::vector<std::string_view> w = split_words(line);

    if (line_no == 1) {
      if (line != "ply") throw fail("not a PLY file (expected \"ply\" on the first line)");
      continue;
    }
    if (line_no == 2) {
      if (w.size() != 3 || w[0] != "format" || w[1] != "binary_little_endian" || w[2] != "1.0") {
        throw fail("expected \"format binary_little_endian 1.0\", found \"" + std::string(line) +
                   "\"");
      }
      continue;
    }
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") {
      ended = true;
    } else if (w[0] == "element") {
      std::uint64_t count = 0;
      const bool ok =
          w.size() == 3 && std::from_chars(w[2].data(), w[2].data() + w[2].size(), count).ptr ==
                               w[2].data() + w[2].size();
      if (!ok) throw fail("malformed PLY header line \"" + std::string(line) + "\"");
      elements.push_back({std::string(w[1]), count, {}});
    } else if (w[0] == "property") {
      if (elements.empty()) throw fail("PLY property before any element");
      elements.back().properties.emplace_back(w.begin(), w.end());
    } else {
      throw fail("unknown PLY header keyword \"" + std::string(w[0]) + "\"");
    }
  }

  // ---- Layout: exactly write_ply's.
  const auto layout_error = [&]() {
    return fail(
        "unsupported PLY layout (expected element vertex with float x, y, z, then element face "
        "with list uchar int vertex_indices)");
  };
  if (elements.size() != 2 || elements[0].name != "vertex" || elements[1].name != "face") {
    throw layout_error();
  }
  const auto& vprops = elements[0].properties;
  if (vprops.size() != 3) throw layout_error();
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& p = vprops[i];
    const char axis[2] = {static_cast<char>('x' + i), '\0'};
    if (p.size() != 3 || !is_one_of(p[1], {"float", "float32"}) || p[2] != axis) {
      throw layout_error();
    }
  }
  const auto& fprops = elements[1].properties;
  if (fprops.size() != 1) throw layout_error();
  const auto& fp = fprops[0];
  if (fp.size() != 5 || fp[1] != "list" || !is_one_of(fp[2], {"uchar", "uint8"}) ||
      !is_one_of(fp[3], {"int", "int32", "uint", "uint32"}) ||
      !is_one_of(fp[4], {"vertex_indices", "vertex_index"})) {
    throw layout_error();
  }
  const bool signed_indices = is_one_of(fp[3], {"int", "int32"});

  // ---- Body: the size must match the counts exactly (this also bounds the allocations).
  const std::uint64_t nv = elements[0].count;
  const std::uint64_t nf = elements[1].count;
  const std::uint64_t body = data.size() - pos;
  const bool fits = nv <= body / 12 && nf <= body / 13 && nv * 12 + nf * 13 == body;
  if (!fits) {
    throw fail(
        "header announces " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
        " triangles, but " + std::to_string(body) + " bytes of data follow (expected " +
        (nv <= body && nf <= body ? std::to_string(nv * 12 + nf * 13) : std::string("more")) + ")");
  }

  triangle_mesh mesh;
  mesh.vertices.resize(static_cast<std::size_t>(nv));
  const unsigned char* p = data.data() + pos;
  for (vec3& v : mesh.vertices) {
    for (double& c : v) {
      c = static_cast<double>(std::bit_cast<float>(load_u32_le(p)));
      p += 4;
    }
  }
  mesh.triangles.resize(static_cast<std::size_t>(nf));
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    if (*p != 3) {
      throw fail("face " + std::to_string(t) + " has " + std::to_string(*p) +
                 " vertices, expected a triangle");
    }
    ++p;
    for (std::uint32_t& v : mesh.triangles[t]) {
      v = load_u32_le(p);
      p += 4;
      const bool negative = signed_indices && v > std::uint32_t{0x7fffffff};
      if (negative || v >= nv) {
        throw fail("face " + std::to_string(t) + " has vertex index " +
                   (negative ? std::to_string(static_cast<std::int32_t>(v)) : std::to_string(v)) +
                   ", expected 0 to " + std::to_string(nv) + " - 1");
      }
    }
  }
  return mesh;
}

}  // namespace progiso
