// progiso/io/volume_io.hpp — reading volumes from headerless raw files, NRRD, NIfTI,
// MetaImage, legacy VTK, VTK XML image data, DICOM series, TIFF stacks and MRC maps.
//
// Nine kinds of input are supported. A headerless raw file holds nothing but the samples, x
// varying fastest, then y, then z; its layout (dims, sample type, byte order) comes from the
// caller, usually the command line's --dims and --type, and the file size must match it exactly.
// NRRD files (.nrrd with attached data, .nhdr with detached data files) describe themselves;
// progiso reads them with its own bounded parser (detail/nrrd_reader.hpp): raw, gzip, ascii
// and hex encodings, either byte order, one data file, a LIST of them or a %d pattern. NIfTI-1
// and NIfTI-2 files (.nii, .nii.gz, or a .hdr with its .img), the formats of MRI and much
// research CT, are read by detail/nifti_reader.hpp: either byte order, plain or gzip, scaled to
// physical values by scl_slope and scl_inter. MetaImage files (.mha with the data after the
// header, .mhd with it in other files), ITK's format and that of many CT collections, are read by
// detail/metaimage_reader.hpp: raw, zlib-compressed or ASCII data, either byte order, one data
// file, a LIST of them or a %d pattern. Legacy VTK files (.vtk) holding STRUCTURED_POINTS, the
// classic output of simulation codes, VTK and ParaView, are read by
// detail/vtk_legacy_reader.hpp: ASCII or big-endian binary point scalars. A directory holding
// one DICOM series (a file per slice, as CT and MRI scanners write them) is read by
// detail/dicom_reader.hpp: uncompressed pixel data, slices ordered along their normal, rescaled
// to the units the files give (Hounsfield units for CT); so are enhanced multi-frame DICOM files
// (Enhanced CT and MR), whose one file holds every frame. VTK XML image data (.vti, and .pvti
// with its pieces), ParaView's format for a regular grid, is read by detail/vti_reader.hpp.
// TIFF stacks (a multi-page .tif, or a directory of .tif slices), as micro-CT scanners and
// microscopes export volumes, are read by detail/tiff_reader.hpp through libtiff. MRC and CCP4
// maps (.mrc, .map, .ccp4, .rec, plain or gzip: cryo-EM maps, tomograms, X-ray electron
// density) are read by detail/mrc_reader.hpp.
// read_volume() picks the reader the way the command-line tool does: an explicit raw layout
// wins, otherwise the file extension decides. volume_input_files() names the files a read
// would open, from the header alone, and read_volume_world() gives the orientation the header
// declares; a volume_source answers all three from one parse of the header.
//
// Every reader returns a volume whose samples are in host byte order. Every file is opened
// through detail::input_file, so only regular files are read (never a FIFO, a directory or a
// device). Every failure caused by the input — a missing file, a size that does not match the
// layout, a malformed, hostile or unsupported header, data that is short or corrupt — throws
// progiso::error with one line that names the file, what was expected and what was found.
// Nothing here aborts on malformed input.
//
// Cost: one pass over the file; raw and gzip data are read or inflated straight into the
// volume's buffer, then swapped in place when the byte order differs. Memory follows the data
// present, never the size a header declares: the buffer is allocated only once the data files
// are known to be able to hold it. A header is parsed in time linear in its size.
//
// Thread safety: the functions may be called concurrently; they share no state.
#pragma once

#include <array>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso {

/// Which volume to read from an input that holds several: for a DICOM directory with several
/// series, `series` is one's SeriesInstanceUID or its number (1-based) in the list the error
/// for an unchosen directory gives (series ordered by UID); for a NIfTI time series (dim[4] > 1:
/// fMRI, diffusion, perfusion), `volume` is the index of one of its 3-D volumes, 0-based (the
/// index FSL, AFNI and nibabel give), and the same for a MetaImage series (NDims 4, the fourth
/// size > 1), a 4-D NRRD (its series axis, see read_nrrd()) and a DICOM series that holds as
/// many frames at every position (time points of a 4-D CT or cine MR, echoes: see read_dicom()).
/// Empty: the input must hold one, which `volume` 0 also names for any input. For an OME-Zarr
/// image, `volume` indexes its leading axes (time, channel) in row-major order, for an Imaris or
/// BigDataViewer file its timepoints and channels (setups), and `level` picks a pyramid level
/// (0, the default: the finest); any other input has level 0 alone.
struct volume_choice {
  std::optional<std::string> series = {};
  std::optional<std::int64_t> volume = {};
  std::optional<std::int64_t> level = {};
};

/// The layout of a headerless raw file: grid dims (x fastest), sample type and byte order.
struct raw_layout {
  index3 dims;
  sample_type type;
  bool big_endian = false;
};

/// Reads a headerless raw volume with the given layout and converts it to host byte order.
/// Throws progiso::error when the file is missing or unreadable, when a dim is < 2, or when
/// the file size differs from dims × sample_size(layout.type) (the message gives both byte
/// counts, the dims and the type), or when spacing/origin are rejected by the volume.
[[nodiscard]] volume read_raw(const std::filesystem::path& file, const raw_layout& layout,
                              std::array<double, 3> spacing = {1.0, 1.0, 1.0},
                              std::array<double, 3> origin = {0.0, 0.0, 0.0});

/// Reads a NRRD file (.nrrd, or a .nhdr header with its detached data files). The array must
/// have 3 axes of 2 to 32769 samples each, or 4 of which one is a series of volumes (the one
/// axis whose kind is not domain or space, else the one whose space direction is "none", else
/// the last; it must be the first, as in diffusion MRI, or the last, as in Slicer's sequences):
/// `choice.volume` picks one, which must exist, and is required when there are several. The
/// sample type must be one of u8 i8 u16 i16
/// u32 i32 f32 f64 (every NRRD spelling of them); the encoding raw, gzip, ascii or hex.
/// Spacing per axis is the length of the axis' "space directions" vector when present, else
/// the magnitude of its "spacings" entry; an unknown, zero or non-finite spacing becomes 1.
/// The origin is the "space origin" (its finite first three components) when present, else
/// 0. Throws progiso::error naming the file (the data file for detached data) on any failure:
/// a header that does not parse, data that cannot hold the declared size, data that ends
/// early or is corrupt. See docs/formats.md "Reading NRRD" for the accepted features and
/// the bounds.
[[nodiscard]] volume read_nrrd(const std::filesystem::path& file, const volume_choice& choice = {});

/// An affine map from grid indices to scanner (world) coordinates: world = m · (i, j, k, 1).
struct index_to_world {
  std::array<std::array<double, 4>, 3> m{};
  /// The determinant of the 3 × 3 part: negative when the map mirrors (triangles then need
  /// their winding reversed to keep facing the same way).
  [[nodiscard]] double determinant() const noexcept;
  [[nodiscard]] std::array<double, 3> apply(const std::array<double, 3>& index) const noexcept;
};

/// The orientation a volume file declares, from its header alone: for NIfTI the sform when
/// sform_code > 0, else the qform when qform_code > 0; for NRRD the "space directions" (as
/// columns) and "space origin" of a 3-D space; for MetaImage the TransformMatrix (row i the
/// direction of index axis i, as ITK reads it; identity when absent) scaled by ElementSpacing,
/// and Offset; for legacy VTK origin + index × SPACING (structured points are axis-aligned);
/// for a DICOM series the patient (LPS) coordinates its ImageOrientationPatient, PixelSpacing
/// and ImagePositionPatient give; for an MRC map the unit cell's axes over MX, MY, MZ (oblique
/// when CELLB's angles are not right) and its origin; nullopt for files without one (NIfTI with
/// both codes 0, NRRD without space directions, raw files), whose positions are origin + index ×
/// spacing only. Throws progiso::error like read_volume() for an unknown format and header
/// errors.
[[nodiscard]] std::optional<index_to_world> read_volume_world(const std::filesystem::path& file,
                                                              const std::optional<raw_layout>& raw,
                                                              const volume_choice& choice = {});

/// Reads a NIfTI-1 or NIfTI-2 volume: a .nii (plain or gzip) or a .hdr header whose data lies
/// in the .img (or .img.gz) beside it. The array must be 3-D (trailing dimensions of size 1
/// allowed) with 2 to 32769 samples per axis, of type u8 i8 u16 i16 u32 i32 f32 or f64. Spacing
/// is |pixdim| per axis (zero or non-finite: 1); the origin is the sform's translation when
/// sform_code > 0, else the qform's when qform_code > 0, else 0 (rotations and flips are not
/// applied here: read_volume_world() gives the whole map). Samples with a scl_slope other than
/// 0 and (1, 0) are scaled to physical values, as f32 (f64 for 32-bit integer and f64 data).
/// A time series (dim[4] > 1, dimensions above the fourth of size 1) reads one volume, the one
/// `choice.volume` names (see volume_choice; refused without it). Throws progiso::error naming
/// the file on any failure; see detail/nifti_reader.hpp and docs/formats.md "Reading
/// NIfTI".
[[nodiscard]] volume read_nifti(const std::filesystem::path& file,
                                const volume_choice& choice = {});

/// Reads a MetaImage volume: a .mha or .mhd header (one "Key = Value" field per line, up to
/// ElementDataFile) and its data (LOCAL: in the same file; else the files it names). NDims 3
/// (sizes above the third of 1 allowed), or 4 for a series of volumes (the fourth size, one of
/// which `choice.volume` names, as for NIfTI), 2 to 32769 samples per axis, ElementType MET_UCHAR,
/// MET_CHAR, MET_USHORT, MET_SHORT, MET_UINT, MET_INT, MET_ULONG, MET_LONG (4 bytes), MET_FLOAT
/// or MET_DOUBLE, one channel; binary (either byte order, zlib-compressed or not) or ASCII data.
/// Spacing is |ElementSpacing| per axis, the origin Offset (or Position, Origin);
/// TransformMatrix is not applied (read_volume_world() gives the whole map). Throws
/// progiso::error naming the file on any failure; see detail/metaimage_reader.hpp and
/// docs/formats.md "Reading MetaImage".
[[nodiscard]] volume read_metaimage(const std::filesystem::path& file,
                                    const volume_choice& choice = {});

/// Reads a legacy VTK file (.vtk) of DATASET STRUCTURED_POINTS: DIMENSIONS 2 to 32769 per axis,
/// SPACING (or ASPECT_RATIO), ORIGIN, and POINT_DATA whose first attribute is SCALARS with one
/// component (or a FIELD whose first array has one), of type unsigned_char, char,
/// signed_char, unsigned_short, short, unsigned_int, int, float or double, ASCII or binary
/// (big-endian). Spacing is |SPACING|, the origin ORIGIN. Throws progiso::error naming the file
/// on any failure; see detail/vtk_legacy_reader.hpp and docs/formats.md "Reading legacy
/// VTK".
[[nodiscard]] volume read_vtk_legacy(const std::filesystem::path& file);

/// Reads a VTK XML image data file (.vti), as VTK and ParaView write it: one piece, the point
/// array named by PointData's Scalars attribute (else its first array), of one component and
/// type Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32 or Float64; ascii, base64 or
/// appended (raw or base64) data, uncompressed or zlib-compressed, either byte order, UInt32 or
/// UInt64 block headers; 2 to 32769 points per axis. Spacing is |Spacing|, the origin the
/// extent's first point (Origin + Spacing ⊙ the extent's start). Throws progiso::error naming
/// the file on any failure; see detail/vti_reader.hpp and docs/formats.md "Reading VTK XML
/// image data".
[[nodiscard]] volume read_vti(const std::filesystem::path& file);

/// Reads a VTK XML parallel image (.pvti, as ParaView and parallel simulation codes save a grid
/// in pieces): the whole extent assembled from the pieces' .vti files it names (each read as
/// read_vti() reads a file, the array the .pvti's PPointData Scalars names, else its first), the
/// geometry from its PImageData. Every point must come from a piece. Throws progiso::error
/// naming the file at fault; see docs/formats.md "Reading VTK XML image data".
[[nodiscard]] volume read_pvti(const std::filesystem::path& file);

/// Reads the DICOM series in `directory` (or in one enhanced multi-frame file): every DICOM
/// Part 10 file there with pixel data gives its frames as slices (other files are skipped), a
/// classic file one, an enhanced file (Enhanced CT, MR) each frame its per-frame functional
/// groups place, an RT dose grid each frame its GridFrameOffsetVector places (values ×
/// DoseGridScaling: Gy); one series, at least 2 slices of one size, orientation and pixel spacing,
/// evenly spaced along their normal; transfer syntax implicit or explicit VR little endian,
/// explicit VR big endian, lossless JPEG (process 14), RLE Lossless or JPEG 2000; 8, 16 or 32
/// bits, signed or
/// not, one sample per pixel. Spacing is (column spacing, row spacing, slice step), the origin the
/// first slice's ImagePositionPatient; samples with a RescaleSlope or RescaleIntercept other than 1
/// and 0 become f32 in the rescaled units. Throws progiso::error naming the directory or the file
/// (and frame) at fault; see detail/dicom_reader.hpp and docs/formats.md "Reading DICOM".
/// `choice.series` picks one of several series; `choice.volume` one of several volumes of a series
/// that holds the same number of frames at every position (frames at a position ordered by
/// TemporalPositionIndex, else InstanceNumber, then file and frame), required when there are
/// several.
[[nodiscard]] volume read_dicom(const std::filesystem::path& directory,
                                const volume_choice& choice = {});

/// Reads a TIFF stack (micro-CT scanners', confocal and light-sheet microscopes', ImageJ's and
/// Fiji's volumes): one multi-page .tif/.tiff file, or a directory of them, whose pages are the
/// slices in order (files in natural order of their names: slice2 before slice10; other files
/// ignored; thumbnails skipped). One grey channel of 8, 16 or 32-bit integers or 32 or 64-bit
/// floats per page, one size and type for all, in strips or tiles, uncompressed, LZW, Deflate or
/// PackBits. Spacing 1, or from ImageJ's description (pixels per unit in XResolution and
/// YResolution, "spacing=" for z) or an OME-TIFF's PhysicalSizeX/Y/Z (µm); an ImageJ hyperstack
/// of several frames, or an OME-TIFF of several time points, is a time series whose volume
/// `choice.volume` picks. Origin 0. Throws progiso::error naming the file and page
/// at fault; see detail/tiff_reader.hpp and docs/formats.md "Reading TIFF stacks".
[[nodiscard]] volume read_tiff(const std::filesystem::path& input,
                               const volume_choice& choice = {});

/// Reads an MRC or CCP4 map (.mrc, .mrcs, .map, .ccp4, .rec, plain or gzip): cryo-EM maps as
/// EMDB distributes them, IMOD's tomograms, crystallographic electron density. Modes 0 (8-bit
/// integers), 1 (int16), 2 (float32), 6 (uint16) and 12 (float16, read as float32), either byte
/// order, columns, rows and sections along any permutation of X, Y, Z (returned x fastest),
/// 2 to 32769 samples per axis. Spacing is CELLA / (MX, MY, MZ), the origin ORIGIN when given,
/// else the start indices × spacing; an oblique unit cell's skew is in read_volume_world()'s map
/// only. A volume stack (ISPG 401–630) is a series whose volume `choice.volume` picks. Throws
/// progiso::error naming the file on any failure; see detail/mrc_reader.hpp and
/// docs/formats.md "Reading MRC maps".
[[nodiscard]] volume read_mrc(const std::filesystem::path& file, const volume_choice& choice = {});

/// Reads a Zarr v2 array or an OME-Zarr multiscale image (OME-NGFF 0.1–0.4): the directory that
/// holds `.zarray`, or `.zattrs` with "multiscales". Level `choice.level` (0: the finest) of
/// volume `choice.volume` (over the leading axes); blosc, zstd, zlib, gzip or no compression;
/// u8 i8 u16 i16 u32 i32 f32 f64 (and bool as u8), either byte order, C or F order; missing
/// chunks are fill_value. Spacing and origin from the level's scale and translation. Throws
/// progiso::error naming the file on any failure; see detail/zarr_reader.hpp and docs/formats.md.
[[nodiscard]] volume read_zarr(const std::filesystem::path& dir, const volume_choice& choice = {});

/// Reads an Imaris (.ims) or BigDataViewer (.h5) resolution pyramid through libhdf5: level
/// `choice.level` (0: the finest) of volume `choice.volume` (timepoint × channels + channel, or
/// × setups + setup); deflate and shuffle filters; u8 i8 u16 i16 u32 i32 f32 f64 (BigDataViewer's
/// int16 read as unsigned, as it stores 16-bit data). Spacing and origin from Imaris's extent, or
/// BigDataViewer's level factors (level 0: spacing 1). Throws progiso::error naming the file on any
/// failure; see detail/hdf5_reader.hpp and docs/formats.md.
[[nodiscard]] volume read_hdf5(const std::filesystem::path& file, const volume_choice& choice = {});

/// Reads a volume the way the command-line tool does: with a raw layout, read_raw(); else, for
/// a directory holding .tif or .tiff files or for a .tif or .tiff file, read_tiff(); for a
/// directory holding .zattrs or .zarray, read_zarr(); for .ims, .h5, .hdf5 and .hdf, or a file
/// with the HDF5 signature, read_hdf5(); for another directory or a .dcm file,
/// read_dicom(); for the extensions .nrrd and .nhdr, read_nrrd(); for
/// .nii, .nii.gz, .hdr and .hdr.gz, read_nifti(); for .mha and .mhd, read_metaimage(); for .vtk,
/// read_vtk_legacy(); for .vti, read_vti(); for .pvti, read_pvti(); for .mrc, .mrcs, .map, .ccp4
/// and .rec (each optionally .gz), read_mrc() (case-insensitive); any other file that starts as
/// DICOM Part 10 does ("DICM" at byte 128), read_dicom(), or that holds MRC2014's "MAP " at byte
/// 208, read_mrc(). A single DICOM
/// file must be a multi-frame image (one slice alone is refused). A `choice` that names a series
/// is refused for anything but DICOM, one that names a volume other than 0 for anything but a
/// NIfTI, MetaImage, NRRD, DICOM, ImageJ or MRC series that has it. A given `spacing` replaces the
/// one from the header (or the default 1,1,1 for raw files). Throws progiso::error "FILE: unknown
/// volume format (…)" for any other file, and whatever the chosen reader throws.
[[nodiscard]] volume read_volume(const std::filesystem::path& file,
                                 const std::optional<raw_layout>& raw,
                                 std::optional<std::array<double, 3>> spacing,
                                 const volume_choice& choice = {});

namespace detail {
struct volume_source_state;
struct plane_window_state;
}  // namespace detail

/// A level of a chunked input (an OME-Zarr image or a Zarr array, an Imaris or BigDataViewer
/// file) read a window of z planes at a time, for passes that go through the grid in z order and
/// read a few planes at once: the finest surface made share by share (detail::finest_share), an MPI
/// rank's planes. field() is the whole level's grid, but only the planes held are in memory: the
/// level is reserved as address space, and hold() commits, decodes and gives back planes, so the
/// memory held is the window's planes (rounded out to whole chunk rows, since a chunk decodes
/// whole), not the level's. A plane not held is not mapped: reading it ends the process, so a pass
/// that reads beyond its window cannot go unnoticed. It keeps what it reads by (a copy of the
/// metadata), so it may outlive the volume_source that made it. Move-only; not for concurrent
/// hold() calls (passes may read the held planes from any thread between them).
class plane_window {
 public:
  explicit plane_window(std::unique_ptr<detail::plane_window_state> state) noexcept;
  plane_window(plane_window&&) noexcept;
  plane_window& operator=(plane_window&&) noexcept;
  plane_window(const plane_window&) = delete;
  plane_window& operator=(const plane_window&) = delete;
  ~plane_window();

  /// The level: its grid, sample type, spacing and origin; its samples readable in the planes
  /// held. Its value_range() is the sample type's (see range_seen()).
  [[nodiscard]] const volume& field() const noexcept;
  /// The z planes of one chunk row: the unit of decoding.
  [[nodiscard]] std::int64_t chunk_planes() const noexcept;
  /// Makes planes [z_begin, z_end) readable (0 ≤ z_begin ≤ z_end ≤ dims[2]) and gives back the
  /// memory of every plane below z_begin. The chunk rows of planes not yet held are decoded,
  /// their chunks at once through `run`; a window that does not go forward (z_begin below the
  /// last one's) starts again from nothing. Throws progiso::error naming the chunk file as the
  /// reader does, naming the array for a non-finite sample (its x, y, z) or when the planes'
  /// memory cannot be had (a limit on the process's data).
  void hold(std::int64_t z_begin, std::int64_t z_end, const parallel_loop& run = {});
  /// The smallest and largest sample of every plane decoded so far ({+inf, −inf} before any).
  [[nodiscard]] std::array<double, 2> range_seen() const noexcept;
  /// The most bytes of samples committed at once so far (whole pages).
  [[nodiscard]] std::uint64_t peak_bytes() const noexcept;

 private:
  std::unique_ptr<detail::plane_window_state> state_;
};

/// An input opened the way read_volume() opens it, its header (or a DICOM directory's headers,
/// a .pvti's piece list) parsed once: the files a read opens, the orientation the file declares,
/// then the samples. The command-line tool checks its outputs against files() and reads world()
/// before read(), without parsing anything twice. Construction throws what read_volume() throws
/// for an unknown format, a refused choice or a header error; read() what the format's reader
/// throws for its data. A text header's or .vti's file stays open from construction to read().
/// Move-only.
class volume_source {
 public:
  volume_source(const std::filesystem::path& file, const std::optional<raw_layout>& raw,
                const volume_choice& choice = {});
  volume_source(volume_source&&) noexcept;
  volume_source& operator=(volume_source&&) noexcept;
  volume_source(const volume_source&) = delete;
  volume_source& operator=(const volume_source&) = delete;
  ~volume_source();

  /// What volume_input_files() returns.
  [[nodiscard]] const std::vector<std::filesystem::path>& files() const noexcept;
  /// What read_volume_world() returns.
  [[nodiscard]] const std::optional<index_to_world>& world() const noexcept;
  /// The volume, as read_volume() returns it (a given `spacing` replaces the header's).
  [[nodiscard]] volume read(std::optional<std::array<double, 3>> spacing = std::nullopt);
  /// The pyramid levels the input holds: an OME-Zarr image's datasets, an Imaris or
  /// BigDataViewer file's resolution levels, 1 for any other input.
  [[nodiscard]] std::size_t levels() const noexcept;
  /// Level `level` (0: the finest; below levels()) of the chosen volume, whatever level the
  /// choice named, with its own spacing (a given `spacing` is level 0's, scaled as the header
  /// scales the level's). `stop`, when not empty, is asked between chunks; once it answers true
  /// the read ends and nothing is returned. Throws as read().
  [[nodiscard]] std::optional<volume> read_level(
      std::size_t level, std::optional<std::array<double, 3>> spacing = std::nullopt,
      const std::function<bool()>& stop = {});
  /// The chosen level as a plane_window (a given `spacing` as read()'s), when the input is read
  /// in chunks (OME-Zarr and Zarr; Imaris and BigDataViewer, each window's planes read by an
  /// HDF5 child as read() reads a level); nullopt for every other input (a mapped file is already
  /// read on demand by the kernel, and the other formats are read whole). Checks what read()
  /// checks before anything is decoded (enough chunks present); the samples are decoded by
  /// plane_window::hold().
  [[nodiscard]] std::optional<plane_window> window(
      std::optional<std::array<double, 3>> spacing = std::nullopt);

 private:
  std::unique_ptr<detail::volume_source_state> state_;
};

/// The files read_volume(file, raw, …) would read: `file` itself, then, for a NRRD header,
/// every detached data file in order (patterns expanded, paths resolved against the header's
/// directory), for a MetaImage header the data files it names (none for LOCAL data), for a
/// NIfTI header and data pair its .img (or .img.gz), for a .pvti its pieces' files, and for a
/// DICOM directory every slice file in order. Parses only the header; the data files need not
/// exist. Throws progiso::error like read_volume() for an unknown format
/// and for header errors.
[[nodiscard]] std::vector<std::filesystem::path> volume_input_files(
    const std::filesystem::path& file, const std::optional<raw_layout>& raw,
    const volume_choice& choice = {});

}  // namespace progiso
