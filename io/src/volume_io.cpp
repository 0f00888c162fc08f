#include <progiso/io/volume_io.hpp>

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/dicom_reader.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/detail/hdf5_reader.hpp>
#include <progiso/io/detail/metaimage_reader.hpp>
#include <progiso/io/detail/mrc_reader.hpp>
#include <progiso/io/detail/nifti_reader.hpp>
#include <progiso/io/detail/nrrd_reader.hpp>
#include <progiso/io/detail/plane_window.hpp>
#include <progiso/io/detail/tiff_reader.hpp>
#include <progiso/io/detail/vti_reader.hpp>
#include <progiso/io/detail/vtk_legacy_reader.hpp>
#include <progiso/io/detail/zarr_reader.hpp>

namespace progiso {
namespace {

namespace fs = std::filesystem;

std::string dims_text(const index3& dims) {
  return std::to_string(dims[0]) + "," + std::to_string(dims[1]) + "," + std::to_string(dims[2]);
}

using detail::lower_extension;

/// a × b, or nullopt when it does not fit in 64 bits.
std::optional<std::uint64_t> checked_mul(std::uint64_t a, std::uint64_t b) {
  if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a) return std::nullopt;
  return a * b;
}

/// Builds the volume, prefixing the volume's own complaints (bad spacing, dims too large) with
/// the file name so that every message names its file.
volume make_volume(const fs::path& file, const index3& dims, sample_type type,
                   std::vector<std::byte> samples, const std::array<double, 3>& spacing,
                   const std::array<double, 3>& origin) {
  try {
    return volume(dims, type, std::move(samples), spacing, origin);
  } catch (const error& e) {
    throw error(file.string() + ": " + e.what());
  }
}

/// A volume over mapped samples (map_bytes()), errors naming `file`.
volume borrowed_volume(const fs::path& file, const index3& dims, sample_type type,
                       detail::mapped_bytes mapped, const std::array<double, 3>& spacing,
                       const std::array<double, 3>& origin) {
  try {
    return volume::borrow(dims, type, mapped.bytes, std::move(mapped.keeper), spacing, origin);
  } catch (const error& e) {
    throw error(file.string() + ": " + e.what());
  }
}

enum class volume_format {
  nrrd,
  nifti,
  metaimage,
  vtk_legacy,
  vti,
  pvti,
  dicom,
  tiff,
  mrc,
  zarr,
  hdf5
};

/// The format a file name asks for; throws "FILE: unknown volume format (…)" for any other.
volume_format format_of(const fs::path& file) {
  std::error_code ec;
  // A directory of TIFF slices (a micro-CT or microscope's export), else of DICOM files.
  if (fs::is_directory(file, ec)) {
    if (detail::is_zarr_directory(file)) return volume_format::zarr;
    return detail::is_tiff_directory(file) ? volume_format::tiff : volume_format::dicom;
  }
  if (detail::has_tiff_name(file)) return volume_format::tiff;
  // One DICOM file: an enhanced multi-frame image (one slice alone is refused by the reader).
  if (lower_extension(file) == ".dcm") return volume_format::dicom;
  if (detail::has_nifti_name(file)) return volume_format::nifti;
  if (detail::has_metaimage_name(file)) return volume_format::metaimage;
  if (detail::has_vtk_legacy_name(file)) return volume_format::vtk_legacy;
  if (detail::has_vti_name(file)) return volume_format::vti;
  if (detail::has_pvti_name(file)) return volume_format::pvti;
  if (detail::has_mrc_name(file)) return volume_format::mrc;
  if (detail::has_hdf5_name(file)) return volume_format::hdf5;
  const std::string ext = lower_extension(file);
  if (ext == ".nrrd" || ext == ".nhdr") return volume_format::nrrd;
  // Scanners and PACS name DICOM files without an extension (IM0001, a UID).
  if (detail::has_dicom_preamble(file)) return volume_format::dicom;
  // MRC2014 files carry "MAP " at byte 208 whatever their name.
  if (detail::has_mrc_identifier(file)) return volume_format::mrc;
  // Imaris and BigDataViewer files by their HDF5 signature whatever their name.
  if (detail::has_hdf5_signature(file)) return volume_format::hdf5;
  throw error(
      file.string() +
      ": unknown volume format (expected .nrrd, .nhdr, .nii, .nii.gz, .hdr, .mha, .mhd, "
      ".vtk, .vti, .pvti, .tif, .tiff, .mrc, .map, .ccp4, .rec, .ims, .h5, a directory of DICOM "
      "files or of TIFF slices, a Zarr or OME-Zarr directory, an enhanced DICOM file, or a raw "
      "file with --dims and --type)");
}

/// The header of a NRRD, MetaImage or legacy VTK file (each reads its data through
/// read_nrrd_samples).
detail::nrrd_header parse_text_header(detail::input_file& in, volume_format format) {
  switch (format) {
    case volume_format::metaimage:
      return detail::parse_metaimage_header(in);
    case volume_format::vtk_legacy:
      return detail::parse_vtk_legacy_header(in);
    case volume_format::nrrd:
    case volume_format::nifti:
    case volume_format::vti:
    case volume_format::pvti:
    case volume_format::dicom:
    case volume_format::tiff:
    case volume_format::mrc:
    case volume_format::zarr:
    case volume_format::hdf5:
      break;
  }
  return detail::parse_nrrd_header(in);
}

std::string_view format_kind(volume_format format) {
  switch (format) {
    case volume_format::metaimage:
      return "MetaImage";
    case volume_format::vtk_legacy:
      return "VTK";
    case volume_format::vti:
    case volume_format::pvti:
      return "VTK XML";
    case volume_format::nrrd:
    case volume_format::nifti:
    case volume_format::dicom:
    case volume_format::tiff:
    case volume_format::mrc:
    case volume_format::zarr:
    case volume_format::hdf5:
      break;
  }
  return "NRRD";
}

/// A chosen series applies to DICOM directories only.
void check_choice(const fs::path& file, bool dicom, const volume_choice& choice) {
  if (choice.series && !dicom) {
    throw error(file.string() + ": a series (" + detail::quoted(*choice.series, 64) +
                ") was chosen, but the input is not a DICOM directory");
  }
}

/// The volume to read of an input that holds `volumes` (a NIfTI time series, a MetaImage of
/// NDims 4; 1 for any other input), whose count the header gives in `field` ("dim[4]"): the
/// chosen one, which must exist, or the only one.
std::int64_t pick_volume(const fs::path& file, std::int64_t volumes, const volume_choice& choice,
                         std::string_view field = "dim[4]") {
  const std::string last = std::to_string(volumes - 1);
  if (!choice.volume) {
    if (volumes == 1) return 0;
    throw error(file.string() + ": a time series of " + std::to_string(volumes) + " volumes (" +
                std::string(field) + " = " + std::to_string(volumes) +
                "): choose one by its index, 0 to " + last);
  }
  const std::int64_t k = *choice.volume;
  if (k < 0 || k >= volumes) {
    throw error(file.string() + ": volume " + std::to_string(k) + " was chosen, but the input " +
                (volumes == 1 ? std::string("holds one volume (0)")
                              : "is a time series of " + std::to_string(volumes) +
                                    " volumes (0 to " + last + ")"));
  }
  return k;
}

/// Where a text header gives its count of volumes (pick_volume()): a MetaImage's fourth DimSize,
/// a 4-D NRRD's series axis (the first or the last of its sizes).
std::string_view volumes_field(volume_format format, const detail::nrrd_header& header) {
  if (format == volume_format::metaimage) return "DimSize[3]";
  return header.interleaved ? "sizes[0]" : "sizes[3]";
}

using spacing_override = std::optional<std::array<double, 3>>;

// ---------------------------------------------------------------------------------------------
// Opened inputs: one kind per format, each parsing its header(s) once, on construction.

}  // namespace

/// What every opened input knows after its headers: the files a read opens and the map the
/// file declares. read() decodes the samples.
struct detail::volume_source_state {
  std::vector<fs::path> files;
  std::optional<index_to_world> world;

  volume_source_state() = default;
  volume_source_state(const volume_source_state&) = delete;
  volume_source_state& operator=(const volume_source_state&) = delete;
  virtual ~volume_source_state() = default;
  virtual volume read(const spacing_override& spacing) = 0;
  // Pyramid levels (volume_source::levels()); the inputs that have one level read it whole.
  [[nodiscard]] virtual std::size_t levels() const noexcept { return 1; }
  virtual std::optional<volume> read_level(std::size_t level, const spacing_override& spacing,
                                           const std::function<bool()>& stop) {
    PROGISO_ASSERT(level == 0);
    (void)level;
    (void)stop;
    return read(spacing);
  }
  // The chosen level in windows of planes (volume_source::window()); inputs not read in chunks
  // have none.
  virtual std::optional<plane_window> window(const spacing_override& spacing) {
    (void)spacing;
    return std::nullopt;
  }
};

namespace {

using source_state = detail::volume_source_state;

struct raw_source final : source_state {
  fs::path file;
  raw_layout layout;
  raw_source(const fs::path& f, const raw_layout& l) : file(f), layout(l) { files = {f}; }
  volume read(const spacing_override& spacing) override {
    return read_raw(file, layout, spacing.value_or(std::array<double, 3>{1.0, 1.0, 1.0}));
  }
};

/// NRRD, MetaImage and legacy VTK: a text header, then data through read_nrrd_samples. The
/// header's file stays open for attached data.
struct text_source final : source_state {
  fs::path file;
  detail::input_file in;
  detail::nrrd_header header;
  std::int64_t volume_index = 0;
  text_source(const fs::path& f, volume_format format, const volume_choice& choice)
      : file(f), in(f, format_kind(format)), header(parse_text_header(in, format)) {
    volume_index = pick_volume(f, header.volumes, choice, volumes_field(format, header));
    world = header.world;
    files.reserve(1 + header.data_files.size());
    files.push_back(f);
    files.insert(files.end(), header.data_files.begin(), header.data_files.end());
  }
  volume read(const spacing_override& spacing) override {
    if (std::optional<detail::mapped_bytes> m =
            detail::map_nrrd_samples(header, in, volume_index)) {
      return borrowed_volume(file, header.dims, header.type, std::move(*m),
                             spacing.value_or(header.spacing), header.origin);
    }
    std::vector<std::byte> samples = detail::read_nrrd_samples(header, in, volume_index);
    return make_volume(file, header.dims, header.type, std::move(samples),
                       spacing.value_or(header.spacing), header.origin);
  }
};

struct nifti_source final : source_state {
  fs::path file;
  detail::nifti_header header;
  std::int64_t volume_index = 0;
  nifti_source(const fs::path& f, const volume_choice& choice)
      : file(f), header(detail::read_nifti_header(f)) {
    volume_index = pick_volume(f, header.volumes, choice);
    world = header.world;
    files = {f};
    if (header.data_file) files.push_back(*header.data_file);
  }
  volume read(const spacing_override& spacing) override {
    if (std::optional<detail::mapped_bytes> m =
            detail::map_nifti_samples(header, file, volume_index)) {
      return borrowed_volume(header.data_file ? *header.data_file : file, header.dims,
                             header.volume_type(), std::move(*m), spacing.value_or(header.spacing),
                             header.origin);
    }
    std::vector<std::byte> samples = detail::read_nifti_samples(header, file, volume_index);
    return make_volume(header.data_file ? *header.data_file : file, header.dims,
                       header.volume_type(), std::move(samples), spacing.value_or(header.spacing),
                       header.origin);
  }
};

/// An MRC or CCP4 map: its header read once; a volume stack's volume chosen.
struct mrc_source final : source_state {
  fs::path file;
  detail::mrc_header header;
  std::int64_t volume_index = 0;
  mrc_source(const fs::path& f, const volume_choice& choice)
      : file(f), header(detail::read_mrc_header(f)) {
    volume_index = pick_volume(f, header.volumes, choice, "NZ / MZ");
    world = header.world;
    files = {f};
  }
  volume read(const spacing_override& spacing) override {
    if (std::optional<detail::mapped_bytes> m =
            detail::map_mrc_samples(header, file, volume_index)) {
      return borrowed_volume(file, header.dims, header.volume_type(), std::move(*m),
                             spacing.value_or(header.spacing), header.origin);
    }
    std::vector<std::byte> samples = detail::read_mrc_samples(header, file, volume_index);
    return make_volume(file, header.dims, header.volume_type(), std::move(samples),
                       spacing.value_or(header.spacing), header.origin);
  }
};

/// The pyramid level a choice names (0 when it names none), checked against the image's count.
std::size_t pick_level(const fs::path& file, std::size_t count, const volume_choice& choice) {
  const auto levels = static_cast<std::int64_t>(count);
  const std::int64_t k = choice.level.value_or(0);
  if (k < 0 || k >= levels) {
    throw error(file.string() + ": level " + std::to_string(k) + " was chosen, but the image has " +
                (levels == 1 ? std::string("one level (0)")
                             : std::to_string(levels) + " levels (0 to " +
                                   std::to_string(levels - 1) + ")"));
  }
  return static_cast<std::size_t>(k);
}

/// A Zarr array or OME-Zarr image: its metadata read once; a level and a volume chosen.
struct zarr_source final : source_state {
  fs::path dir;
  detail::zarr_image image;
  std::int64_t volume_index = 0;
  std::size_t level = 0;
  zarr_source(const fs::path& d, const volume_choice& choice)
      : dir(d), image(detail::read_zarr_header(d)) {
    volume_index = pick_volume(d, image.volumes, choice, "its leading axes");
    level = pick_level(d, image.levels.size(), choice);
    files = image.files;
  }
  volume read(const spacing_override& spacing) override { return *read_level(level, spacing, {}); }
  [[nodiscard]] std::size_t levels() const noexcept override { return image.levels.size(); }
  std::optional<volume> read_level(std::size_t k, const spacing_override& spacing,
                                   const std::function<bool()>& stop) override {
    PROGISO_ASSERT(k < image.levels.size());
    const detail::zarr_level& l = image.levels[k];
    std::optional<std::vector<std::byte>> samples =
        detail::read_zarr_samples(image, k, volume_index, stop);
    if (!samples) return std::nullopt;
    return make_volume(l.dir, l.dims(), l.type, std::move(*samples), level_spacing(k, spacing),
                       l.origin);
  }
  std::optional<plane_window> window(const spacing_override& spacing) override {
    const detail::zarr_level& l = image.levels[level];
    detail::check_zarr_chunks(image, level, volume_index);
    const std::size_t n = l.chunks.size();
    return detail::make_plane_window(
        l.dir, l.dims(), l.type, l.chunks[n - 3], level_spacing(level, spacing), l.origin,
        // The window outlives the source (an MPI rank keeps it, not the source): it keeps its
        // own copy of the metadata.
        [im = image, k = level, v = volume_index](
            std::int64_t z0, std::int64_t z1, std::span<std::byte> out, const parallel_loop& run) {
          (void)detail::read_zarr_planes(im, k, v, z0, z1, out, run);
        });
  }
  // Level k's spacing: the header's, or, given level 0's, it times the header's ratio.
  [[nodiscard]] std::array<double, 3> level_spacing(std::size_t k,
                                                    const spacing_override& spacing) const {
    const detail::zarr_level& l = image.levels[k];
    std::array<double, 3> s = l.spacing;
    if (spacing) {
      for (std::size_t q = 0; q < 3; ++q)
        s[q] = (*spacing)[q] * l.spacing[q] / image.levels[0].spacing[q];
    }
    return s;
  }
};

/// An Imaris or BigDataViewer pyramid: its structure read once; a level and a volume chosen.
struct hdf5_source final : source_state {
  detail::hdf5_image image;
  std::int64_t volume_index = 0;
  std::size_t level = 0;
  hdf5_source(const fs::path& f, const volume_choice& choice) : image(detail::read_hdf5_header(f)) {
    volume_index = pick_volume(f, image.volumes(), choice,
                               image.layout == detail::hdf5_layout::imaris ? "timepoints x channels"
                                                                           : "timepoints x setups");
    level = pick_level(f, image.levels.size(), choice);
    files = {f};
  }
  volume read(const spacing_override& spacing) override { return *read_level(level, spacing, {}); }
  [[nodiscard]] std::size_t levels() const noexcept override { return image.levels.size(); }
  std::optional<volume> read_level(std::size_t k, const spacing_override& spacing,
                                   const std::function<bool()>& stop) override {
    PROGISO_ASSERT(k < image.levels.size());
    const detail::hdf5_level& l = image.levels[k];
    std::optional<detail::mapped_bytes> samples =
        detail::read_hdf5_samples(image, k, volume_index, stop);
    if (!samples) return std::nullopt;
    const auto [s, o] = level_geometry(k, spacing);
    return borrowed_volume(image.file, l.dims, image.type, std::move(*samples), s, o);
  }
  std::optional<plane_window> window(const spacing_override& spacing) override {
    const detail::hdf5_level& l = image.levels[level];
    const std::int64_t unit = detail::check_hdf5_samples(image, level, volume_index);
    const auto [s, o] = level_geometry(level, spacing);
    return detail::make_plane_window(
        image.file, l.dims, image.type, unit, s, o,
        // As for Zarr: the window keeps its own copy of the structure.
        [im = image, k = level, v = volume_index](std::int64_t z0, std::int64_t z1,
                                                  std::span<std::byte> out, const parallel_loop&) {
          detail::read_hdf5_planes(im, k, v, z0, z1, out);
        });
  }
  // Level k's spacing and origin: the file's, or, given level 0's spacing, scaled by its ratio
  // (BigDataViewer's origins are in level-0 voxels, so they scale too).
  [[nodiscard]] std::pair<std::array<double, 3>, std::array<double, 3>> level_geometry(
      std::size_t k, const spacing_override& spacing) const {
    const detail::hdf5_level& l = image.levels[k];
    std::array<double, 3> s = l.spacing;
    std::array<double, 3> o = l.origin;
    if (spacing) {
      for (std::size_t q = 0; q < 3; ++q) {
        const double ratio = (*spacing)[q] / image.levels[0].spacing[q];
        s[q] = l.spacing[q] * ratio;
        o[q] = l.origin[q] * ratio;
      }
    }
    return {s, o};
  }
};

struct dicom_source final : source_state {
  fs::path directory;
  detail::dicom_series series;
  dicom_source(const fs::path& d, const volume_choice& choice)
      : directory(d), series(detail::read_dicom_series(d, choice.series, choice.volume)) {
    world = series.world;
    // The directory (or the one file), then each file once: an enhanced image's frames share
    // theirs.
    files.push_back(d);
    std::set<fs::path> listed{d};
    for (const detail::dicom_slice& s : series.slices) {
      if (listed.insert(s.file).second) files.push_back(s.file);
    }
  }
  volume read(const spacing_override& spacing) override {
    std::vector<std::byte> samples = detail::read_dicom_samples(series);
    return make_volume(directory, series.dims, series.volume_type(), std::move(samples),
                       spacing.value_or(series.spacing), series.origin);
  }
};

/// A TIFF stack (one multi-page file or a directory of slices): every page's header read; an
/// ImageJ hyperstack's frame chosen.
struct tiff_source final : source_state {
  detail::tiff_stack stack;
  std::size_t first = 0;  // the chosen frame's first page
  tiff_source(const fs::path& input, const volume_choice& choice)
      : stack(detail::read_tiff_stack(input)) {
    const std::int64_t k = pick_volume(input, stack.volumes, choice, "ImageJ frames");
    first = static_cast<std::size_t>(k * stack.dims[2]);
    if (stack.files.size() != 1 || stack.files[0] != input) files.push_back(input);
    files.insert(files.end(), stack.files.begin(), stack.files.end());
  }
  volume read(const spacing_override& spacing) override {
    std::vector<std::byte> samples = detail::read_tiff_samples(stack, first);
    return make_volume(stack.input, stack.dims, stack.type, std::move(samples),
                       spacing.value_or(stack.spacing), {0.0, 0.0, 0.0});
  }
};

/// A .vti: its header parsed up to the appended data; the file stays open for the samples.
struct vti_source final : source_state {
  fs::path file;
  detail::input_file in;
  detail::vti_header header;
  explicit vti_source(const fs::path& f)
      : file(f), in(f, "VTK XML"), header(detail::parse_vti_header(in)) {
    world = header.world;
    files = {f};
  }
  volume read(const spacing_override& spacing) override {
    std::vector<std::byte> samples = detail::read_vti_samples(header, in);
    return make_volume(file, header.dims, header.type, std::move(samples),
                       spacing.value_or(header.spacing), header.origin);
  }
};

struct pvti_source final : source_state {
  fs::path file;
  detail::pvti_header header;
  explicit pvti_source(const fs::path& f) : file(f) {
    detail::input_file in(f, "VTK XML");
    header = detail::parse_pvti_header(in);
    world = header.world;
    files.reserve(1 + header.pieces.size());
    files.push_back(f);
    for (const detail::pvti_piece& p : header.pieces) files.push_back(p.file);
  }
  volume read(const spacing_override& spacing) override {
    std::vector<std::byte> samples = detail::read_pvti_samples(header, file);
    return make_volume(file, header.dims, header.type, std::move(samples),
                       spacing.value_or(header.spacing), header.origin);
  }
};

std::unique_ptr<source_state> open_source(const fs::path& file,
                                          const std::optional<raw_layout>& raw,
                                          const volume_choice& choice) {
  if (choice.level && *choice.level != 0 &&
      !(!raw && (detail::is_zarr_directory(file) || detail::has_hdf5_name(file) ||
                 detail::has_hdf5_signature(file)))) {
    throw error(file.string() + ": level " + std::to_string(*choice.level) +
                " was chosen, but the input is not a multiscale (OME-Zarr, Imaris or "
                "BigDataViewer) image: it has level 0 alone");
  }
  if (raw) {
    check_choice(file, false, choice);
    (void)pick_volume(file, 1, choice);
    return std::make_unique<raw_source>(file, *raw);
  }
  const volume_format format = format_of(file);
  check_choice(file, format == volume_format::dicom, choice);
  switch (format) {
    case volume_format::nifti:
      return std::make_unique<nifti_source>(file, choice);
    case volume_format::dicom:
      return std::make_unique<dicom_source>(file, choice);
    case volume_format::tiff:
      return std::make_unique<tiff_source>(file, choice);
    case volume_format::mrc:
      return std::make_unique<mrc_source>(file, choice);
    case volume_format::zarr:
      return std::make_unique<zarr_source>(file, choice);
    case volume_format::hdf5:
      return std::make_unique<hdf5_source>(file, choice);
    case volume_format::vti:
      (void)pick_volume(file, 1, choice);
      return std::make_unique<vti_source>(file);
    case volume_format::pvti:
      (void)pick_volume(file, 1, choice);
      return std::make_unique<pvti_source>(file);
    case volume_format::nrrd:
    case volume_format::metaimage:
    case volume_format::vtk_legacy:
      break;
  }
  return std::make_unique<text_source>(file, format, choice);
}

}  // namespace

volume_source::volume_source(const std::filesystem::path& file,
                             const std::optional<raw_layout>& raw, const volume_choice& choice)
    : state_(open_source(file, raw, choice)) {}

volume_source::volume_source(volume_source&&) noexcept = default;
volume_source& volume_source::operator=(volume_source&&) noexcept = default;
volume_source::~volume_source() = default;

const std::vector<std::filesystem::path>& volume_source::files() const noexcept {
  return state_->files;
}

const std::optional<index_to_world>& volume_source::world() const noexcept { return state_->world; }

volume volume_source::read(std::optional<std::array<double, 3>> spacing) {
  return state_->read(spacing);
}

std::size_t volume_source::levels() const noexcept { return state_->levels(); }

std::optional<volume> volume_source::read_level(std::size_t level,
                                                std::optional<std::array<double, 3>> spacing,
                                                const std::function<bool()>& stop) {
  PROGISO_ASSERT(level < levels());
  return state_->read_level(level, spacing, stop);
}

std::optional<plane_window> volume_source::window(std::optional<std::array<double, 3>> spacing) {
  return state_->window(spacing);
}

// ---------------------------------------------------------------------------------------------
// Raw files.

volume read_raw(const std::filesystem::path& file, const raw_layout& layout,
                std::array<double, 3> spacing, std::array<double, 3> origin) {
  const std::string name = file.string();
  const index3& dims = layout.dims;
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2) {
    throw error(name + ": dims must be at least 2 per axis, found " + dims_text(dims));
  }
  detail::input_file in(file, "volume");
  const std::uint64_t size = in.size();
  const std::size_t item = sample_size(layout.type);

  std::optional<std::uint64_t> expected = static_cast<std::uint64_t>(item);
  for (std::int64_t d : dims) {
    if (expected) expected = checked_mul(*expected, static_cast<std::uint64_t>(d));
  }
  if (!expected || *expected != size) {
    throw error(name + ": size " + std::to_string(size) + " bytes does not match dims " +
                dims_text(dims) + " × " + std::string(to_string(layout.type)) + " = " +
                (expected ? std::to_string(*expected) : std::string("more than 2^64")) + " bytes");
  }

  const bool host_big = std::endian::native == std::endian::big;
  const bool swap = item > 1 && layout.big_endian != host_big;
  if (!swap && size >= detail::map_min_bytes) {
    if (std::optional<detail::mapped_bytes> m = detail::map_bytes(in, 0, size)) {
      return borrowed_volume(file, dims, layout.type, std::move(*m), spacing, origin);
    }
  }
  std::vector<std::byte> samples(static_cast<std::size_t>(*expected));
  const std::size_t got = in.read(samples.data(), samples.size());
  if (got != samples.size()) {
    throw error(name + ": read only " + std::to_string(got) + " of " +
                std::to_string(samples.size()) + " bytes");
  }
  if (swap) detail::swap_sample_bytes(samples, item);
  return make_volume(file, dims, layout.type, std::move(samples), spacing, origin);
}

// ---------------------------------------------------------------------------------------------
// NRRD and NIfTI files, and dispatch.

volume read_nrrd(const std::filesystem::path& file, const volume_choice& choice) {
  return text_source(file, volume_format::nrrd, choice).read(std::nullopt);
}

volume read_metaimage(const std::filesystem::path& file, const volume_choice& choice) {
  return text_source(file, volume_format::metaimage, choice).read(std::nullopt);
}

volume read_dicom(const std::filesystem::path& directory, const volume_choice& choice) {
  return dicom_source(directory, choice).read(std::nullopt);
}

volume read_tiff(const std::filesystem::path& input, const volume_choice& choice) {
  return tiff_source(input, choice).read(std::nullopt);
}

volume read_mrc(const std::filesystem::path& file, const volume_choice& choice) {
  return mrc_source(file, choice).read(std::nullopt);
}

volume read_vtk_legacy(const std::filesystem::path& file) {
  return text_source(file, volume_format::vtk_legacy, {}).read(std::nullopt);
}

volume read_vti(const std::filesystem::path& file) { return vti_source(file).read(std::nullopt); }

volume read_pvti(const std::filesystem::path& file) { return pvti_source(file).read(std::nullopt); }

volume read_hdf5(const std::filesystem::path& file, const volume_choice& choice) {
  return hdf5_source(file, choice).read(std::nullopt);
}

volume read_zarr(const std::filesystem::path& dir, const volume_choice& choice) {
  return zarr_source(dir, choice).read(std::nullopt);
}

volume read_nifti(const std::filesystem::path& file, const volume_choice& choice) {
  return nifti_source(file, choice).read(std::nullopt);
}

volume read_volume(const std::filesystem::path& file, const std::optional<raw_layout>& raw,
                   std::optional<std::array<double, 3>> spacing, const volume_choice& choice) {
  return volume_source(file, raw, choice).read(spacing);
}

double index_to_world::determinant() const noexcept {
  return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
         m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
         m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

std::array<double, 3> index_to_world::apply(const std::array<double, 3>& index) const noexcept {
  std::array<double, 3> out{};
  for (std::size_t r = 0; r < 3; ++r) {
    out[r] = m[r][0] * index[0] + m[r][1] * index[1] + m[r][2] * index[2] + m[r][3];
  }
  return out;
}

std::optional<index_to_world> read_volume_world(const std::filesystem::path& file,
                                                const std::optional<raw_layout>& raw,
                                                const volume_choice& choice) {
  return volume_source(file, raw, choice).world();
}

std::vector<std::filesystem::path> volume_input_files(const std::filesystem::path& file,
                                                      const std::optional<raw_layout>& raw,
                                                      const volume_choice& choice) {
  volume_source source(file, raw, choice);
  return source.files();
}

}  // namespace progiso
