#include <progiso/io/detail/dicom_jpeg2000.hpp>

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>

#include <openjpeg.h>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_input.hpp>

namespace progiso::detail {
namespace {

constexpr std::uint8_t jp2_signature[12] = {0x00, 0x00, 0x00, 0x0c, 0x6a, 0x50,
                                            0x20, 0x20, 0x0d, 0x0a, 0x87, 0x0a};

// OpenJPEG reading a codestream in memory.
struct memory_stream {
  std::span<const std::uint8_t> data;
  std::size_t at = 0;
};

OPJ_SIZE_T read_memory(void* buffer, OPJ_SIZE_T n, void* user) {
  auto* m = static_cast<memory_stream*>(user);
  const std::size_t left = m->data.size() - m->at;
  if (left == 0) return static_cast<OPJ_SIZE_T>(-1);
  const std::size_t k = std::min<std::size_t>(n, left);
  std::memcpy(buffer, m->data.data() + m->at, k);
  m->at += k;
  return k;
}

OPJ_OFF_T skip_memory(OPJ_OFF_T n, void* user) {
  auto* m = static_cast<memory_stream*>(user);
  if (n < 0) {
    const auto back = std::min<std::size_t>(static_cast<std::size_t>(-n), m->at);
    m->at -= back;
    return -static_cast<OPJ_OFF_T>(back);
  }
  const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(n), m->data.size() - m->at);
  m->at += k;
  return static_cast<OPJ_OFF_T>(k);
}

OPJ_BOOL seek_memory(OPJ_OFF_T to, void* user) {
  auto* m = static_cast<memory_stream*>(user);
  if (to < 0 || static_cast<std::size_t>(to) > m->data.size()) return OPJ_FALSE;
  m->at = static_cast<std::size_t>(to);
  return OPJ_TRUE;
}

// OpenJPEG's first error, for ours; warnings and information dropped.
void on_error(const char* text, void* user) {
  auto* first = static_cast<std::string*>(user);
  if (first->empty() && text != nullptr) {
    std::string t = text;
    while (!t.empty() && (t.back() == '\n' || t.back() == '\r')) t.pop_back();
    *first = quoted(t, 160);
  }
}
void on_message(const char*, void*) {}

struct codec_deleter {
  void operator()(opj_codec_t* c) const { opj_destroy_codec(c); }
};
struct stream_deleter {
  void operator()(opj_stream_t* s) const { opj_stream_destroy(s); }
};
struct image_deleter {
  void operator()(opj_image_t* i) const { opj_image_destroy(i); }
};

}  // namespace

bool starts_jpeg2000_frame(std::span<const std::uint8_t> f) noexcept {
  if (f.size() >= 4 && f[0] == 0xff && f[1] == 0x4f && f[2] == 0xff && f[3] == 0x51) return true;
  return f.size() >= sizeof jp2_signature &&
         std::equal(std::begin(jp2_signature), std::end(jp2_signature), f.begin());
}

void decode_dicom_jpeg2000(std::span<const std::uint8_t> codestream, std::uint32_t rows,
                           std::uint32_t columns, std::size_t bytes, unsigned bits_stored,
                           bool is_signed, std::span<std::byte> out) {
  const std::uint64_t samples = std::uint64_t{rows} * columns;
  if (out.size() != samples * bytes) throw error("JPEG 2000 frame: buffer of the wrong size");
  if (samples * bytes > codestream.size() * jpeg2000_largest_expansion) {
    throw error("a JPEG 2000 codestream of " + std::to_string(codestream.size()) + " bytes for " +
                std::to_string(samples * bytes) + " bytes of samples (more than " +
                std::to_string(jpeg2000_largest_expansion) + " times its size)");
  }
  const bool jp2 =
      codestream.size() >= sizeof jp2_signature &&
      std::equal(std::begin(jp2_signature), std::end(jp2_signature), codestream.begin());
  std::unique_ptr<opj_codec_t, codec_deleter> codec(
      opj_create_decompress(jp2 ? OPJ_CODEC_JP2 : OPJ_CODEC_J2K));
  if (!codec) throw error("OpenJPEG could not make a decoder");
  std::string first_error;
  opj_set_error_handler(codec.get(), on_error, &first_error);
  opj_set_warning_handler(codec.get(), on_message, nullptr);
  opj_set_info_handler(codec.get(), on_message, nullptr);
  opj_dparameters_t parameters;
  opj_set_default_decoder_parameters(&parameters);
  const auto fail = [&](const std::string& what) {
    return error("JPEG 2000 frame: " + (first_error.empty() ? what : first_error));
  };
  if (opj_setup_decoder(codec.get(), &parameters) == OPJ_FALSE) throw fail("decoder setup failed");
  opj_decoder_set_strict_mode(codec.get(), OPJ_TRUE);  // a truncated codestream is an error

  memory_stream source{codestream, 0};
  std::unique_ptr<opj_stream_t, stream_deleter> stream(
      opj_stream_create(std::size_t{1} << 16, OPJ_TRUE));
  if (!stream) throw fail("OpenJPEG could not make a stream");
  opj_stream_set_user_data(stream.get(), &source, nullptr);
  opj_stream_set_user_data_length(stream.get(), codestream.size());
  opj_stream_set_read_function(stream.get(), read_memory);
  opj_stream_set_skip_function(stream.get(), skip_memory);
  opj_stream_set_seek_function(stream.get(), seek_memory);

  opj_image_t* raw_image = nullptr;
  if (opj_read_header(stream.get(), codec.get(), &raw_image) == OPJ_FALSE) {
    throw fail("unreadable codestream header");
  }
  std::unique_ptr<opj_image_t, image_deleter> image(raw_image);
  // The header against DICOM's, before any sample is decoded.
  const auto& head = *image;
  if (head.numcomps != 1) {
    throw error("a JPEG 2000 frame of " + std::to_string(head.numcomps) +
                " components, expected 1 (a grey image)");
  }
  const std::uint32_t width = head.x1 - head.x0;
  const std::uint32_t height = head.y1 - head.y0;
  const opj_image_comp_t& c = head.comps[0];
  if (head.x1 < head.x0 || head.y1 < head.y0 || width != columns || height != rows || c.dx != 1 ||
      c.dy != 1) {
    throw error("a JPEG 2000 frame of " + std::to_string(width) + "x" + std::to_string(height) +
                " samples (subsampled " + std::to_string(c.dx) + ", " + std::to_string(c.dy) +
                "), where the DICOM header says " + std::to_string(columns) + "x" +
                std::to_string(rows));
  }
  if (c.prec == 0 || c.prec > bits_stored || c.prec > 8 * bytes || (c.sgnd != 0) != is_signed) {
    throw error("a JPEG 2000 frame of " + std::to_string(c.prec) + "-bit " +
                (c.sgnd != 0 ? "signed" : "unsigned") + " samples, where the DICOM header says " +
                std::to_string(bits_stored) + "-bit " + (is_signed ? "signed" : "unsigned"));
  }
  if (opj_decode(codec.get(), stream.get(), image.get()) == OPJ_FALSE ||
      opj_end_decompress(codec.get(), stream.get()) == OPJ_FALSE) {
    throw fail("the codestream could not be decoded");
  }
  const opj_image_comp_t& d = image->comps[0];
  if (d.data == nullptr || d.w != columns || d.h != rows) throw fail("no samples decoded");
  std::byte* o = out.data();
  for (std::uint64_t i = 0; i < samples; ++i) {
    const std::int32_t v = d.data[i];
    if (bytes == 1) {
      o[i] = static_cast<std::byte>(static_cast<std::uint8_t>(v));
    } else if (bytes == 2) {
      const auto u = static_cast<std::uint16_t>(v);
      std::memcpy(o + 2 * i, &u, 2);
    } else {
      const auto u = static_cast<std::uint32_t>(v);
      std::memcpy(o + 4 * i, &u, 4);
    }
  }
}

}  // namespace progiso::detail
