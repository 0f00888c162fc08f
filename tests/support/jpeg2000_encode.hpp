// tests/support/jpeg2000_encode.hpp — JPEG 2000 codestreams (or JP2 files) encoded by OpenJPEG,
// for the tests of progiso's JPEG 2000 DICOM frames: lossless (reversible 5/3 wavelet, one
// layer) or lossy (irreversible 9/7 at a compression ratio), of one grey component of any
// precision and sign, optionally in tiles and with a number of resolutions. Header-only; the
// test binary links OpenJPEG.
#pragma once

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <openjpeg.h>

namespace progiso::test {

struct jpeg2000_options {
  unsigned precision = 16;
  bool is_signed = false;
  bool lossless = true;
  float ratio = 20.0f;  ///< lossy: the compression ratio
  bool jp2 = false;     ///< a JP2 file (signature and boxes) instead of a bare codestream
  int resolutions = 4;
  std::uint32_t tile = 0;  ///< tile width and height; 0: one tile
  /// Components: the samples repeated (colour images, to be refused).
  std::uint32_t components = 1;
};

/// `samples` (width × height, row by row) encoded; empty when OpenJPEG fails.
inline std::string encode_jpeg2000(const std::vector<std::int32_t>& samples, std::uint32_t width,
                                   std::uint32_t height, const jpeg2000_options& o) {
  std::vector<opj_image_cmptparm_t> parts(o.components);
  for (opj_image_cmptparm_t& c : parts) {
    std::memset(&c, 0, sizeof c);
    c.dx = 1;
    c.dy = 1;
    c.w = width;
    c.h = height;
    c.prec = o.precision;
    c.sgnd = o.is_signed ? 1 : 0;
  }
  opj_image_t* image = opj_image_create(o.components, parts.data(),
                                        o.components == 1 ? OPJ_CLRSPC_GRAY : OPJ_CLRSPC_SRGB);
  if (image == nullptr) return {};
  image->x0 = 0;
  image->y0 = 0;
  image->x1 = width;
  image->y1 = height;
  for (std::uint32_t c = 0; c < o.components; ++c) {
    std::memcpy(image->comps[c].data, samples.data(), samples.size() * sizeof(std::int32_t));
  }
  opj_cparameters_t p;
  opj_set_default_encoder_parameters(&p);
  p.tcp_numlayers = 1;
  p.cp_disto_alloc = 1;
  p.tcp_rates[0] = o.lossless ? 0.0f : o.ratio;
  p.irreversible = o.lossless ? 0 : 1;
  p.numresolution = o.resolutions;
  if (o.tile != 0) {
    p.tile_size_on = OPJ_TRUE;
    p.cp_tdx = static_cast<int>(o.tile);
    p.cp_tdy = static_cast<int>(o.tile);
  }
  opj_codec_t* codec = opj_create_compress(o.jp2 ? OPJ_CODEC_JP2 : OPJ_CODEC_J2K);
  std::string out;
  struct sink {
    std::string* bytes;
    std::size_t at = 0;
  } s{&out, 0};
  opj_stream_t* stream = opj_stream_create(std::size_t{1} << 16, OPJ_FALSE);
  opj_stream_set_user_data(stream, &s, nullptr);
  opj_stream_set_write_function(stream, [](void* data, OPJ_SIZE_T n, void* user) -> OPJ_SIZE_T {
    auto* k = static_cast<sink*>(user);
    if (k->bytes->size() < k->at + n) k->bytes->resize(k->at + n);
    std::memcpy(k->bytes->data() + k->at, data, n);
    k->at += n;
    return n;
  });
  opj_stream_set_skip_function(stream, [](OPJ_OFF_T n, void* user) -> OPJ_OFF_T {
    auto* k = static_cast<sink*>(user);
    k->at = static_cast<std::size_t>(static_cast<OPJ_OFF_T>(k->at) + n);
    if (k->bytes->size() < k->at) k->bytes->resize(k->at);
    return n;
  });
  opj_stream_set_seek_function(stream, [](OPJ_OFF_T to, void* user) -> OPJ_BOOL {
    auto* k = static_cast<sink*>(user);
    k->at = static_cast<std::size_t>(to);
    if (k->bytes->size() < k->at) k->bytes->resize(k->at);
    return OPJ_TRUE;
  });
  const bool ok = opj_setup_encoder(codec, &p, image) == OPJ_TRUE &&
                  opj_start_compress(codec, image, stream) == OPJ_TRUE &&
                  opj_encode(codec, stream) == OPJ_TRUE &&
                  opj_end_compress(codec, stream) == OPJ_TRUE;
  opj_stream_destroy(stream);
  opj_destroy_codec(codec);
  opj_image_destroy(image);
  return ok ? out : std::string();
}

}  // namespace progiso::test
