"""progiso.read_volume: the command's readers, returning numpy arrays."""

import collections
import os

from . import _progiso

VolumeFile = collections.namedtuple("VolumeFile", ["array", "spacing", "origin", "world"])
VolumeFile.__doc__ = """A volume read from a file.

array: the samples, shape (nz, ny, nx) (numpy axis order: the file's slowest axis first), in
    the file's sample type, in host byte order; the array owns its memory (no copy was made).
spacing, origin: per axis, in the same order, as the header gives them.
world: a 4x4 float64 matrix mapping (i, j, k, 1) of array indices to the world (scanner)
    coordinates the header declares (NIfTI's sform or qform, NRRD's space directions, DICOM's
    patient coordinates, ...), or None when it declares none.
"""


def read_volume(path, *, raw=None, spacing=None, series=None, volume=None, level=None):
    """Read a volume file: NRRD (.nrrd, .nhdr), NIfTI (.nii, .nii.gz, .hdr/.img), MetaImage
    (.mha, .mhd), legacy VTK (.vtk), VTK XML image data (.vti, .pvti), a DICOM series (a
    directory) or enhanced multi-frame DICOM file, TIFF stacks (.tif, or a directory), MRC
    maps (.mrc, .map, .ccp4, .rec) and Zarr arrays or OME-Zarr images (the directory); or a
    headerless raw file with
    ``raw={'shape': (nz, ny, nx), 'dtype': 'u16', 'big_endian': False}``.

    ``spacing`` (per axis) replaces the header's. ``series`` picks one series of a DICOM
    directory (its number or UID); ``volume`` one volume of a 4-D file (a NIfTI or MetaImage
    time series, a 4-D NRRD; an OME-Zarr image's time points and channels, row-major);
    ``level`` one level of an OME-Zarr pyramid (0, the default: the finest). Returns a
    ``VolumeFile`` (array, spacing, origin, world).

    Raises OSError with one line naming the file, what was expected and what was found, for a
    missing, unreadable, malformed or unsupported file; ValueError for bad arguments.
    """
    path = os.fspath(path)
    if raw is not None:
        raw = dict(raw)
        unknown = set(raw) - {"shape", "dtype", "big_endian"}
        if unknown:
            raise ValueError("raw: unknown keys %s (expected shape, dtype, big_endian)"
                             % sorted(unknown))
        if len(raw.get("shape", ())) != 3:
            raise ValueError("raw: expected shape (nz, ny, nx)")
        import numpy as np
        dt = raw.get("dtype")
        if not isinstance(dt, str) or dt not in ("u8", "i8", "u16", "i16", "u32", "i32",
                                                  "f32", "f64"):
            names = {"uint8": "u8", "int8": "i8", "uint16": "u16", "int16": "i16",
                     "uint32": "u32", "int32": "i32", "float32": "f32", "float64": "f64"}
            name = np.dtype(dt).name if dt is not None else None
            if name not in names:
                raise ValueError("raw dtype: expected one of u8 i8 u16 i16 u32 i32 f32 f64, "
                                 "found %r" % (dt,))
            raw["dtype"] = names[name]
        raw["shape"] = tuple(int(s) for s in raw["shape"])
    if spacing is not None:
        if len(spacing) != 3:
            raise ValueError("spacing: expected three numbers, found %r" % (spacing,))
        spacing = tuple(float(s) for s in spacing)
    if level is not None and (not isinstance(level, int) or level < 0):
        raise ValueError("level: expected a non-negative integer, found %r" % (level,))
    return VolumeFile(*_progiso._read_volume(path, raw, spacing, series, volume, level))
