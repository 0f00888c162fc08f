#!/usr/bin/env python3
"""Seed inputs for the fuzz harnesses in tests/fuzz/.

    make_seeds.py OUT_DIR [SHARED_DATA_DIR]

writes OUT_DIR/<harness>/<name> for the harnesses raw, extract, nrrd, nifti, metaimage, vtk, vti, pvti, dicom, tiff, mrc, zarr, hdf5 (when h5py imports), jpeg, pgm, png, ply, obj and cli: small
valid files of every kind the readers accept, and the hostile cases of issue 11 (printf field
widths in data file names, declared sizes far beyond the data, NaN samples, numbers beyond
their types …). With SHARED_DATA_DIR (../shared/data), it adds crops of the real volumes and
images there, in every encoding. The committed corpus (tests/fuzz/corpus/) is this script's
output without SHARED_DATA_DIR plus every input that ever crashed a harness; scripts/fuzz.sh
adds the shared-data seeds to its working corpus, outside the repository.
"""
import gzip
import math
import os
import struct
import sys
import zlib


def put(out, harness, name, data):
    if harness == "raw":  # the extract harness reads the same layout
        put(out, "extract", name, data)
    d = os.path.join(out, harness)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode("latin-1"))


# ---- raw: 6 header bytes (dims, type/flags, spacing selector, isovalue selector), then data.

def raw_seed(dims, type_code, big, fit, spacing_sel, iso_sel, body):
    flags = type_code | (8 if big else 0) | (16 if fit else 0)
    return bytes([(d - 1) % 24 for d in dims] + [flags, spacing_sel, iso_sel]) + body


def raw_seeds(out, crops):
    cube = bytes((x * 7 + y * 13 + z * 29) % 251 for z in range(6) for y in range(6) for x in range(6))
    put(out, "raw", "u8_cube", raw_seed((6, 6, 6), 0, False, False, 1, 128, cube))
    put(out, "raw", "u8_fit", raw_seed((5, 7, 3), 0, False, True, 2, 90, cube[:50]))
    f32 = b"".join(struct.pack("<f", math.sin(i * 0.3)) for i in range(64))
    put(out, "raw", "f32", raw_seed((4, 4, 4), 6, False, False, 3, 120, f32))
    f32_nan = b"".join(struct.pack("<f", float("nan") if i % 2 else i) for i in range(64))
    put(out, "raw", "f32_every_other_nan", raw_seed((4, 4, 4), 6, False, False, 3, 120, f32_nan))
    f64_be = b"".join(struct.pack(">d", i * 0.5 - 10) for i in range(27))
    put(out, "raw", "f64_big_endian", raw_seed((3, 3, 3), 7, True, False, 1, 60, f64_be))
    i16 = b"".join(struct.pack("<h", (i * 997) % 4000 - 2000) for i in range(64))
    put(out, "raw", "i16", raw_seed((4, 4, 4), 3, False, False, 0, 200, i16))
    put(out, "raw", "spacing_nan_bits", raw_seed((4, 4, 4), 0, False, True, 201,
                                                 10, struct.pack("<d", float("nan")) + cube))
    put(out, "raw", "spacing_1e308", raw_seed((8, 8, 8), 0, False, True, 202, 10,
                                              struct.pack("<d", 1e308) + cube))
    put(out, "raw", "size_mismatch", raw_seed((24, 24, 24), 4, False, False, 1, 1, cube))
    for name, (dims, data) in crops.items():
        put(out, "raw", "shared_" + name, raw_seed(dims, 0, False, True, 1, 100, data))
    put(out, "raw", "image_one_sample_thick", raw_seed((24, 16, 1), 0, False, True, 1, 128,
                                                       bytes((x * 11 + y * 5) % 256 for y in range(16) for x in range(24))))


# ---- nrrd: attached files, and detached headers "\0DATA\0" data.

SEP = b"\0DATA\0"


def nrrd_seeds(out, crops):
    cube = bytes((x * 7 + y * 13 + z * 29) % 251 for z in range(4) for y in range(4) for x in range(4))
    base = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\n"
    put(out, "nrrd", "raw_u8", (base + "encoding: raw\n\n").encode() + cube)
    put(out, "nrrd", "gzip_u8", (base + "spacings: 1 2 3\nencoding: gzip\n\n").encode() + gzip.compress(cube))
    i16 = b"".join(struct.pack(">h", v * 37 - 900) for v in range(64))
    put(out, "nrrd", "gzip_i16_big", ("NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\n"
                                      "endian: big\nencoding: gzip\n\n").encode() + gzip.compress(i16))
    put(out, "nrrd", "ascii_float", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n"
        "1 2.5 -3 4e2\n1e-320 6 7 8\n")
    put(out, "nrrd", "hex_u16", "NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 2 2\nendian: little\n"
        "encoding: hex\n\n0102030405060708090a0b0c0d0e0f10\n")
    # 4-D series: three volumes last (a Slicer sequence, gzip) and first (interleaved, as DWI).
    put(out, "nrrd", "series_last_gzip", ("NRRD0005\ntype: uchar\ndimension: 4\nsizes: 4 4 4 3\n"
        "kinds: domain domain domain list\nspace: RAS\nspace directions: (1,0,0) (0,2,0) (0,0,3) none\n"
        "encoding: gzip\n\n").encode() + gzip.compress(cube * 3))
    put(out, "nrrd", "series_first_raw", ("NRRD0005\ntype: short\ndimension: 4\nsizes: 3 4 4 4\n"
        "kinds: list domain domain domain\nendian: big\nencoding: raw\n\n").encode()
        + b"".join(struct.pack(">h", v * 3 + k) for v in range(64) for k in range(3)))
    put(out, "nrrd", "series_default_ascii", "NRRD0005\ntype: float\ndimension: 4\nsizes: 2 2 2 3\n"
        "encoding: ascii\n\n" + " ".join("%g" % (v * 0.5) for v in range(24)) + "\n")
    put(out, "nrrd", "space_directions",
        "NRRD0005\n# comment\ntype: uint8\ndimension: 3\nspace: right-anterior-superior\nsizes: 4 4 4\n"
        "space directions: (0.5,0,0) (0,-2,0) (0,0,3)\nspace origin: (1.5,-2,30)\nkinds: domain domain domain\n"
        "key:=value\nencoding: raw\n\n".encode() + cube)
    put(out, "nrrd", "byte_skip_minus_one", (base + "encoding: raw\nbyte skip: -1\n\n").encode() + b"junk" + cube)
    put(out, "nrrd", "line_skip", (base + "encoding: raw\nline skip: 2\n\n").encode() + b"a\nb\n" + cube)
    put(out, "nrrd", "declared_2000x2000x1000",
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2000 2000 1000\nencoding: raw\n\n".encode() + bytes(2000))
    put(out, "nrrd", "declared_gzip_doubles",
        "NRRD0004\ntype: double\ndimension: 3\nsizes: 2000 2000 1000\nendian: little\nencoding: gzip\n\n".encode()
        + gzip.compress(bytes(100000)))
    put(out, "nrrd", "many_keys", (base + "".join("k%d:=v\n" % i for i in range(2000)) + "encoding: raw\n\n").encode() + cube)
    det = base + "encoding: raw\n"
    put(out, "nrrd", "detached_single", (det + "data file: d.raw\n").encode() + SEP + cube)
    put(out, "nrrd", "detached_gzip", (base + "encoding: gzip\ndata file: d.raw.gz\n").encode() + SEP + gzip.compress(cube))
    put(out, "nrrd", "detached_list", (det + "data file: LIST\nd0.raw\nd1.raw\nd2.raw\nd.raw\n").encode() + SEP + cube[:16])
    put(out, "nrrd", "detached_pattern", (det + "data file: d%d.raw 0 2 1 2\n").encode() + SEP + cube)
    for width in ("%64d", "%100000d", "%s", "%n", "%d%d", "%0999999999d", "%%d%d"):
        put(out, "nrrd", "pattern_" + width.replace("%", "pct"), (det + "data file: " + width + " 0 1 1\n").encode() + SEP + cube)
    put(out, "nrrd", "data_file_dev_zero", (det + "data file: /dev/zero\n").encode() + SEP)
    for name, (dims, data) in crops.items():
        head = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: %d %d %d\n" % dims
        put(out, "nrrd", "shared_%s_raw" % name, (head + "encoding: raw\n\n").encode() + data)
        put(out, "nrrd", "shared_%s_gzip" % name, (head + "encoding: gzip\n\n").encode() + gzip.compress(data))


# ---- nifti: single files (plain or gzip), and pairs "header \0DATA\0 image".

def nifti_header(version, dims, datatype, bitpix, big=False, pair=False, vox_offset=None,
                 slope=0.0, inter=0.0, pixdim=(1.0, 1.0, 1.0), extension=b""):
    e = ">" if big else "<"
    size = 348 if version == 1 else 540
    dim = [len(dims)] + list(dims) + [1] * (7 - len(dims))
    if vox_offset is None:
        vox_offset = 0 if pair else size + 4 + len(extension)
    h = bytearray(size)
    struct.pack_into(e + "i", h, 0, size)
    pix = [1.0] + list(pixdim) + [1.0] * 4
    if version == 1:
        struct.pack_into(e + "8h", h, 40, *dim)
        struct.pack_into(e + "hh", h, 70, datatype, bitpix)
        struct.pack_into(e + "8f", h, 76, *pix)
        struct.pack_into(e + "fff", h, 108, vox_offset, slope, inter)
        struct.pack_into(e + "hh", h, 252, 0, 1)
        struct.pack_into(e + "4f", h, 280, pixdim[0], 0, 0, -12.5)
        struct.pack_into(e + "4f", h, 296, 0, pixdim[1], 0, 7.0)
        struct.pack_into(e + "4f", h, 312, 0, 0, pixdim[2], 3.25)
        h[344:348] = b"ni1\0" if pair else b"n+1\0"
    else:
        h[4:12] = (b"ni2\0" if pair else b"n+2\0") + b"\r\n\x1a\n"
        struct.pack_into(e + "hh", h, 12, datatype, bitpix)
        struct.pack_into(e + "8q", h, 16, *dim)
        struct.pack_into(e + "8d", h, 104, *pix)
        struct.pack_into(e + "q", h, 168, vox_offset)
        struct.pack_into(e + "dd", h, 176, slope, inter)
        struct.pack_into(e + "ii", h, 344, 1, 0)
        struct.pack_into(e + "ddd", h, 376, 4.0, -5.0, 6.0)
    if not pair:
        h += (b"\1" if extension else b"\0") + b"\0\0\0" + extension
    return bytes(h)


def nifti_seeds(out, crops):
    cube = bytes((x * 7 + y * 13 + z * 29) % 251 for z in range(4) for y in range(4) for x in range(4))
    put(out, "nifti", "n1_u8", nifti_header(1, (4, 4, 4), 2, 8, pixdim=(1.0, 2.0, 0.5)) + cube)
    put(out, "nifti", "n1_u8_gzip", gzip.compress(nifti_header(1, (4, 4, 4), 2, 8) + cube))
    i16 = b"".join(struct.pack(">h", (i * 997) % 4000 - 2000) for i in range(64))
    put(out, "nifti", "n2_i16_big_scaled",
        nifti_header(2, (4, 4, 4), 4, 16, big=True, slope=0.5, inter=-1024.0) + i16)
    f32 = b"".join(struct.pack("<f", math.sin(i * 0.3)) for i in range(64))
    put(out, "nifti", "n1_f32_4d_one_point", nifti_header(1, (4, 4, 4, 1), 16, 32) + f32)
    ext = struct.pack("<ii", 32, 4) + b"x" * 24
    put(out, "nifti", "n1_extension", nifti_header(1, (4, 4, 4), 2, 8, extension=ext) + cube)
    put(out, "nifti", "pair_ni1", nifti_header(1, (4, 4, 4), 2, 8, pair=True) + SEP + cube)
    put(out, "nifti", "pair_ni2_gzip", nifti_header(2, (4, 4, 4), 2, 8, pair=True) + SEP + gzip.compress(cube))
    put(out, "nifti", "time_series", nifti_header(1, (4, 4, 4, 3), 2, 8) + cube * 3)
    put(out, "nifti", "time_series_gzip",
        gzip.compress(nifti_header(2, (4, 4, 4, 3), 2, 8, slope=2.0, inter=1.0) + cube * 3))
    put(out, "nifti", "time_series_pair", nifti_header(1, (4, 4, 4, 3), 2, 8, pair=True) + SEP + cube * 3)
    put(out, "nifti", "declared_2000x2000x1000",
        nifti_header(1, (2000, 2000, 1000), 2, 8) + cube)
    put(out, "nifti", "declared_gzip_doubles",
        gzip.compress(nifti_header(2, (2000, 2000, 1000), 64, 64) + bytes(1 << 16)))
    f32_nan = b"".join(struct.pack("<f", float("nan") if i % 2 else i) for i in range(64))
    put(out, "nifti", "f32_every_other_nan", nifti_header(1, (4, 4, 4), 16, 32) + f32_nan)
    for name, (dims, data) in crops.items():
        put(out, "nifti", "shared_%s" % name, nifti_header(1, dims, 2, 8) + data)
        put(out, "nifti", "shared_%s_gzip" % name, gzip.compress(nifti_header(2, dims, 2, 8) + data))


# ---- images.

# ---- metaimage: .mha with the data after the header, and .mhd headers "\0DATA\0" data.

def metaimage_seeds(out, crops):
    cube = bytes((x * 7 + y * 13 + z * 29) % 251 for z in range(4) for y in range(4) for x in range(4))
    base = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\n"
    put(out, "metaimage", "local_u8", (base + "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n").encode() + cube)
    i16 = b"".join(struct.pack(">h", v * 37 - 900) for v in range(64))
    put(out, "metaimage", "local_i16_msb_geometry",
        (base + "ElementSpacing = 0.5 2 1.25\nOffset = -3 4.5 100\nTransformMatrix = 0 1 0 1 0 0 0 0 1\n"
         "ElementByteOrderMSB = True\nElementType = MET_SHORT\nElementDataFile = LOCAL\n").encode() + i16)
    z = zlib.compress(cube)
    put(out, "metaimage", "local_zlib", (base + "CompressedData = True\nCompressedDataSize = %d\n"
                                         "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" % len(z)).encode() + z)
    put(out, "metaimage", "local_ascii_float", "NDims = 3\nDimSize = 2 2 2\nBinaryData = False\n"
        "ElementType = MET_FLOAT\nElementDataFile = LOCAL\n1 2.5 -3 4e2\n1e-30 6 7 8\n")
    put(out, "metaimage", "local_header_size_minus_one",
        (base + "HeaderSize = -1\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n").encode() + b"junk" + cube)
    put(out, "metaimage", "declared_2000x2000x1000",
        "NDims = 3\nDimSize = 2000 2000 1000\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n".encode()
        + bytes(2000))
    put(out, "metaimage", "declared_zlib_doubles",
        "NDims = 3\nDimSize = 2000 2000 1000\nElementType = MET_DOUBLE\nCompressedData = True\n"
        "ElementDataFile = LOCAL\n".encode() + zlib.compress(bytes(100000)))
    series = "NDims = 4\nDimSize = 4 4 4 3\nElementSpacing = 1 1 1 5\nElementType = MET_UCHAR\n"
    put(out, "metaimage", "series_local", (series + "ElementDataFile = LOCAL\n").encode() + cube * 3)
    put(out, "metaimage", "series_ascii", (series + "BinaryData = False\nElementDataFile = LOCAL\n").encode()
        + " ".join(str(b) for b in cube * 3).encode())
    put(out, "metaimage", "series_list", (series + "ElementDataFile = LIST\nd.raw\nd1.raw\nd2.raw\n").encode()
        + SEP + cube)
    det = base + "ElementType = MET_UCHAR\n"
    put(out, "metaimage", "detached_single", (det + "ElementDataFile = d.raw\n").encode() + SEP + cube)
    put(out, "metaimage", "detached_skip", (det + "HeaderSize = 3\nElementDataFile = d.raw\n").encode()
        + SEP + b"abc" + cube)
    put(out, "metaimage", "detached_zlib", (det + "CompressedData = True\nElementDataFile = d.raw\n").encode()
        + SEP + z)
    put(out, "metaimage", "detached_list", (det + "ElementDataFile = LIST\nd.raw\nd1.raw\nd2.raw\nd3.raw\n").encode()
        + SEP + cube[:16])
    put(out, "metaimage", "detached_list_3d", (det + "ElementDataFile = LIST 3D\nd.raw\n").encode() + SEP + cube)
    put(out, "metaimage", "detached_pattern", (det + "ElementDataFile = d%d.raw 1 2 1 3D\n").encode()
        + SEP + cube)
    for width in ("%64d", "%s", "%n", "%d%d", "%0999999999d"):
        put(out, "metaimage", "pattern_" + width.replace("%", "pct"),
            (det + "ElementDataFile = " + width + " 1 4 1\n").encode() + SEP + cube[:16])
    put(out, "metaimage", "data_file_dev_zero", (det + "ElementDataFile = /dev/zero\n").encode() + SEP)
    for name, (dims, data) in crops.items():
        head = "NDims = 3\nDimSize = %d %d %d\nElementType = MET_UCHAR\n" % dims
        put(out, "metaimage", "shared_%s_local" % name, (head + "ElementDataFile = LOCAL\n").encode() + data)
        put(out, "metaimage", "shared_%s_zlib" % name,
            (head + "CompressedData = True\nElementDataFile = LOCAL\n").encode() + zlib.compress(data))


# ---- vtk: legacy STRUCTURED_POINTS files.

def vtk_seeds(out, crops):
    cube = bytes((x * 7 + y * 13 + z * 29) % 251 for z in range(4) for y in range(4) for x in range(4))
    head = "# vtk DataFile Version 3.0\nseed\n%s\nDATASET STRUCTURED_POINTS\nDIMENSIONS 4 4 4\n" \
           "SPACING 0.5 2 1.25\nORIGIN -3 4.5 100\nPOINT_DATA 64\n"
    put(out, "vtk", "binary_u8", (head % "BINARY" + "SCALARS s unsigned_char 1\nLOOKUP_TABLE default\n").encode()
        + cube + b"\n")
    i16 = b"".join(struct.pack(">h", v * 37 - 900) for v in range(64))
    put(out, "vtk", "binary_short_field", (head % "BINARY" + "FIELD FieldData 1\ns 1 64 short\n").encode() + i16)
    put(out, "vtk", "ascii_float", head % "ASCII" + "SCALARS s float\nLOOKUP_TABLE default\n"
        + " ".join("%g" % (v * 0.25 - 3) for v in range(64)) + "\n")
    put(out, "vtk", "lower_case_aspect", ("# vtk DataFile Version 1.0\nold\nbinary\ndataset structured_points\n"
        "dimensions 4 4 4\naspect_ratio 1 1 1\norigin 0 0 0\npoint_data 64\nscalars s char\n"
        "lookup_table default\n").encode() + cube)
    put(out, "vtk", "declared_2000x2000x1000", ("# vtk DataFile Version 3.0\nbig\nBINARY\n"
        "DATASET STRUCTURED_POINTS\nDIMENSIONS 2000 2000 1000\nPOINT_DATA 4000000000\n"
        "SCALARS s double\nLOOKUP_TABLE default\n").encode() + bytes(2000))
    put(out, "vtk", "vectors_first", head % "BINARY" + "VECTORS v float\n")
    for name, (dims, data) in crops.items():
        h = ("# vtk DataFile Version 3.0\n%s\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS %d %d %d\n"
             "POINT_DATA %d\nSCALARS s unsigned_char\nLOOKUP_TABLE default\n"
             % (name, dims[0], dims[1], dims[2], dims[0] * dims[1] * dims[2]))
        put(out, "vtk", "shared_%s" % name, h.encode() + data)


# ---- vti: VTK XML image data (ascii, inline base64, appended raw or base64; zlib blocks).

def vti_file(dims, type_name, payload, mode, zlib_blocks=0, big=False, u64=False, values=None):
    """A .vti of one point array over dims; payload is the array's bytes in the file's order."""
    word = (">" if big else "<") + ("Q" if u64 else "I")
    w = lambda v: struct.pack(word, v)
    if zlib_blocks:
        pieces = [payload[i:i + zlib_blocks] for i in range(0, len(payload), zlib_blocks)]
        packed = [zlib.compress(p) for p in pieces]
        head = w(len(pieces)) + w(zlib_blocks) + w(len(payload) % zlib_blocks) + b"".join(w(len(p)) for p in packed)
        runs = [head, b"".join(packed)]
    else:
        runs = [w(len(payload)) + payload]
    import base64
    ext = "0 %d 0 %d 0 %d" % (dims[0] - 1, dims[1] - 1, dims[2] - 1)
    text = ('<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" byte_order="%s" header_type="%s"%s>\n'
            '<ImageData WholeExtent="%s" Origin="-3 4.5 100" Spacing="0.5 2 1.25" Direction="1 0 0 0 1 0 0 0 1">\n'
            '<Piece Extent="%s">\n<PointData Scalars="s">\n'
            % ("BigEndian" if big else "LittleEndian", "UInt64" if u64 else "UInt32",
               ' compressor="vtkZLibDataCompressor"' if zlib_blocks else "", ext, ext))
    tail = "</PointData>\n</Piece>\n</ImageData>\n"
    a = '<DataArray type="%s" Name="s" NumberOfComponents="1" format="%%s"' % type_name
    if mode == "ascii":
        return (text + a % "ascii" + ">\n" + " ".join(values) + "\n</DataArray>\n" + tail + "</VTKFile>\n").encode()
    if mode == "binary":
        data = "".join(base64.b64encode(r).decode() for r in runs)
        return (text + a % "binary" + ">\n" + data + "\n</DataArray>\n" + tail + "</VTKFile>\n").encode()
    body = b"".join(runs) if mode == "raw" else "".join(base64.b64encode(r).decode() for r in runs).encode()
    return ((text + a % "appended" + ' offset="0"/>\n' + tail +
             '<AppendedData encoding="%s">\n_' % ("raw" if mode == "raw" else "base64")).encode()
            + body + b"\n</AppendedData>\n</VTKFile>\n")


def vti_seeds(out, crops):
    cube = bytes((x * 7 + y * 13 + z * 29) % 251 for z in range(4) for y in range(4) for x in range(4))
    put(out, "vti", "appended_raw_u8", vti_file((4, 4, 4), "UInt8", cube, "raw"))
    put(out, "vti", "appended_raw_zlib_u8", vti_file((4, 4, 4), "UInt8", cube, "raw", zlib_blocks=24))
    f32 = b"".join(struct.pack("<f", math.sin(i * 0.3)) for i in range(64))
    put(out, "vti", "binary_f32", vti_file((4, 4, 4), "Float32", f32, "binary"))
    put(out, "vti", "binary_zlib_f32_u64", vti_file((4, 4, 4), "Float32", f32, "binary", zlib_blocks=100, u64=True))
    i16 = b"".join(struct.pack(">h", v * 37 - 900) for v in range(64))
    put(out, "vti", "appended_base64_i16_big", vti_file((4, 4, 4), "Int16", i16, "base64", big=True))
    put(out, "vti", "appended_base64_zlib_i16_big", vti_file((4, 4, 4), "Int16", i16, "base64", zlib_blocks=32, big=True))
    put(out, "vti", "ascii_f64", vti_file((4, 4, 4), "Float64", b"", "ascii",
                                          values=["%g" % (v * 0.25 - 3) for v in range(64)]))
    # 32769³ doubles declared in a few hundred bytes, plain and in one block.
    big = vti_file((2, 2, 2), "Float64", b"", "raw", u64=True).replace(b"0 1 0 1 0 1", b"0 32768 0 32768 0 32768")
    declared = 32769 ** 3 * 8
    put(out, "vti", "declared_32769_cubed", big.replace(struct.pack("<Q", 0), struct.pack("<Q", declared), 1))
    for name, (dims, data) in crops.items():
        put(out, "vti", "shared_%s" % name, vti_file(dims, "UInt8", data, "raw", zlib_blocks=4096))

    # .pvti: the pieces p0.vti and p1.vti (the same bytes, after "\0DATA\0": both cover x 0..2).
    piece = vti_file((3, 4, 4), "UInt8", bytes((x * 7 + y * 13 + z * 29) % 251 for z in range(4) for y in range(4) for x in range(3)), "raw")
    pvti = ('<?xml version="1.0"?>\n<VTKFile type="PImageData" version="1.0" byte_order="LittleEndian" header_type="UInt32">\n'
            '<PImageData WholeExtent="%s" Origin="-3 4.5 100" Spacing="0.5 2 1.25">\n'
            '<PPointData Scalars="s"><PDataArray type="UInt8" Name="s"/></PPointData>\n'
            '<Piece Extent="0 2 0 3 0 3" Source="p0.vti"/>\n<Piece Extent="0 2 0 3 0 3" Source="p1.vti"/>\n'
            '</PImageData>\n</VTKFile>\n')
    put(out, "pvti", "two_pieces", (pvti % "0 2 0 3 0 3").encode() + b"\0DATA\0" + piece)
    put(out, "pvti", "gap", (pvti % "0 3 0 3 0 3").encode() + b"\0DATA\0" + piece)
    put(out, "pvti", "declared_2000x2000x1000", (pvti % "0 1999 0 1999 0 999").encode() + b"\0DATA\0" + piece)


# ---- jpeg: lossless JPEG streams (process 14), as the dicom harness's encapsulated frames hold.

# One Huffman table for every stream: categories 0-5 in 3 bits, 6-8 in 4, 9 in 5, then one code
# each of 6 to 12 bits (so that codes longer than the decoder's 9-bit lookup occur).
JPEG_COUNTS = [0, 0, 6, 3, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0]


def jpeg_codes():
    codes, code, sym = {}, 0, 0
    for length, count in enumerate(JPEG_COUNTS, start=1):
        for _ in range(count):
            codes[sym] = (code, length)
            code += 1
            sym += 1
        code <<= 1
    return codes


def jpeg_lossless(rows, cols, samples, precision=12, predictor=1, pt=0):
    """A lossless JPEG stream of `samples` (row by row) with the given predictor (1-7)."""
    codes = jpeg_codes()
    bits = precision - pt
    vals = [v >> pt for v in samples]
    out, acc, n = bytearray(), 0, 0

    def put_bits(v, k):
        nonlocal acc, n
        for i in range(k - 1, -1, -1):
            acc = (acc << 1) | ((v >> i) & 1)
            n += 1
            if n == 8:
                out.append(acc)
                if acc == 0xFF:
                    out.append(0)
                acc, n = 0, 0

    for y in range(rows):
        for x in range(cols):
            i = y * cols + x
            if y == 0:
                p = (1 << (bits - 1)) if x == 0 else vals[i - 1]
            elif x == 0:
                p = vals[i - cols]
            else:
                ra, rb, rc = vals[i - 1], vals[i - cols], vals[i - cols - 1]
                p = [ra, rb, rc, ra + rb - rc, ra + ((rb - rc) >> 1), rb + ((ra - rc) >> 1),
                     (ra + rb) >> 1][predictor - 1]
            d = (vals[i] - p) & 0xFFFF
            if d >= 0x8000:
                d -= 0x10000
            ssss = abs(d).bit_length()
            code, length = codes[ssss]
            put_bits(code, length)
            if 0 < ssss < 16:
                put_bits(d if d > 0 else d + (1 << ssss) - 1, ssss)
    while n:
        put_bits(1, 1)  # pad the last byte with ones
    dht = bytes([0x00]) + bytes(JPEG_COUNTS) + bytes(range(17))
    sof = bytes([precision]) + struct.pack(">HH", rows, cols) + bytes([1, 1, 0x11, 0])
    sos = bytes([1, 1, 0x00, predictor, 0, pt])
    seg = lambda m, body: b"\xff" + bytes([m]) + struct.pack(">H", len(body) + 2) + body
    return b"\xff\xd8" + seg(0xC4, dht) + seg(0xC3, sof) + seg(0xDA, sos) + bytes(out) + b"\xff\xd9"


def jpeg_seeds(out):
    for predictor in range(1, 8):
        samples = [(x * 37 + y * 101 + (x * y) % 13) % 4096 for y in range(6) for x in range(7)]
        put(out, "jpeg", "p%d_12bit" % predictor,
            bytes([5, 6, 1]) + jpeg_lossless(6, 7, samples, 12, predictor))
    samples = [(i * 7919) % 65536 for i in range(8 * 8)]  # large differences: long codes
    put(out, "jpeg", "16bit_wide", bytes([7, 7, 1]) + jpeg_lossless(8, 8, samples, 16, 4))
    put(out, "jpeg", "8bit_pt2", bytes([3, 4, 0]) + jpeg_lossless(4, 5, [i * 9 % 256 for i in range(20)], 8, 1, 2))


# ---- dicom: series of slice files "s0 \0NEXT\0 s1 \0NEXT\0 ...".

NEXT = b"\0NEXT\0"


def dicom_slice(ts, k, rows=4, cols=5, bits=16, signed=1, seq=True, pixels=None, frames=0, grid=None):
    """A slice file; with frames > 0 an enhanced image of that many frames (functional groups);
    with grid (offsets) an RT dose grid of one frame per offset; with the lossless JPEG
    (1.2.840.10008.1.2.4.70) or RLE (1.2.840.10008.1.2.5) transfer syntax, its frames
    encapsulated, one fragment each."""
    explicit = ts != "1.2.840.10008.1.2"
    big = ts == "1.2.840.10008.1.2.2"
    e16 = ">H" if big else "<H"
    e32 = ">I" if big else "<I"

    def pad(v, vr):
        v = v.encode() if isinstance(v, str) else v
        return v + (b"\0" if vr in ("UI", "OB") else b" ") if len(v) % 2 else v

    def el(g, e, vr, v, order=(e16, e32), force_explicit=None):
        v = pad(v, vr)
        ex = explicit if force_explicit is None else force_explicit
        out = struct.pack(order[0], g) + struct.pack(order[0], e)
        if ex:
            out += vr.encode()
            if vr in ("OB", "OW", "SQ", "UN", "UT"):
                out += b"\0\0" + struct.pack(order[1], len(v))
            else:
                out += struct.pack(order[0], len(v))
        else:
            out += struct.pack(order[1], len(v))
        return out + v

    le = ("<H", "<I")
    meta = el(2, 1, "OB", b"\0\1", le, True) + el(2, 2, "UI", "1.2.840.10008.5.1.4.1.1.2", le, True)
    meta += el(2, 3, "UI", "1.2.3.%d" % k, le, True) + el(2, 0x10, "UI", ts, le, True)
    head = b"\0" * 128 + b"DICM" + struct.pack("<HH", 2, 0) + b"UL" + struct.pack("<HI", 4, len(meta)) + meta
    us = lambda v: struct.pack(e16, v)
    d = el(8, 0x60, "CS", "CT")
    if seq:
        item = el(8, 0x1150, "UI", "1.2.3")
        items = struct.pack(e16, 0xfffe) + struct.pack(e16, 0xe000) + struct.pack(e32, 0xffffffff) + item
        items += struct.pack(e16, 0xfffe) + struct.pack(e16, 0xe00d) + struct.pack(e32, 0)
        d += struct.pack(e16, 8) + struct.pack(e16, 0x1140) + ((b"SQ\0\0") if explicit else b"") + struct.pack(e32, 0xffffffff)
        d += items + struct.pack(e16, 0xfffe) + struct.pack(e16, 0xe0dd) + struct.pack(e32, 0)
    def sq(g, e, items, undefined):
        out = struct.pack(e16, g) + struct.pack(e16, e) + (b"SQ\0\0" if explicit else b"")
        out += struct.pack(e32, 0xffffffff if undefined else len(items)) + items
        return out + (struct.pack(e16, 0xfffe) + struct.pack(e16, 0xe0dd) + struct.pack(e32, 0) if undefined else b"")

    def it(content, undefined):
        out = struct.pack(e16, 0xfffe) + struct.pack(e16, 0xe000)
        out += struct.pack(e32, 0xffffffff if undefined else len(content)) + content
        return out + (struct.pack(e16, 0xfffe) + struct.pack(e16, 0xe00d) + struct.pack(e32, 0) if undefined else b"")

    d += el(0x20, 0xe, "UI", "1.2.826.0.1.3680043.2.1125.1") + el(0x20, 0x13, "IS", str(k + 1))
    if not frames:
        d += el(0x20, 0x32, "DS", "-120.5\\33\\%g" % (7 + 1.25 * k)) + el(0x20, 0x37, "DS", "1\\0\\0\\0\\1\\0")
    d += el(0x28, 2, "US", us(1)) + el(0x28, 4, "CS", "MONOCHROME2")
    if frames:
        d += el(0x28, 8, "IS", str(frames))
    elif grid:
        d += el(0x28, 8, "IS", str(len(grid)))
    d += el(0x28, 0x10, "US", us(rows))
    d += el(0x28, 0x11, "US", us(cols)) + (b"" if frames else el(0x28, 0x30, "DS", "0.5\\0.75"))
    d += el(0x28, 0x100, "US", us(bits))
    d += el(0x28, 0x101, "US", us(bits if bits == 8 else 12)) + el(0x28, 0x103, "US", us(signed))
    if not frames:
        d += el(0x28, 0x1052, "DS", "-1024") + el(0x28, 0x1053, "DS", "1")
    else:
        shared = sq(0x20, 0x9116, it(el(0x20, 0x37, "DS", "1\\0\\0\\0\\1\\0"), True), True)
        shared += sq(0x28, 0x9110, it(el(0x28, 0x30, "DS", "0.5\\0.75"), True), True)
        shared += sq(0x28, 0x9145, it(el(0x28, 0x1052, "DS", "-1024") + el(0x28, 0x1053, "DS", "2"), False), False)
        d += sq(0x5200, 0x9229, it(shared, True), True)
        per = b""
        for f in range(frames):
            place = el(0x20, 0x32, "DS", "-120.5\\33\\%g" % (7 + 1.25 * ((f * 3) % frames)))
            per += it(sq(0x20, 0x9113, it(place, False), False), f % 2 == 0)
        d += sq(0x5200, 0x9230, per, False)
    if grid:
        d += el(0x3004, 0xc, "DS", "\\".join("%g" % g for g in grid)) + el(0x3004, 0xe, "DS", "0.001")
    n = rows * cols * max(frames, len(grid) if grid else 1)
    if ts == "1.2.840.10008.1.2.5":
        # RLE: per frame one fragment, a header of 16 words, one PackBits segment per byte,
        # most significant first: repeat runs of the high bytes, literal runs of the low.
        width = 1 if bits == 8 else 2
        item = lambda b: struct.pack("<HHI", 0xFFFE, 0xE000, len(b)) + b
        frags = item(b"")
        for f in range(max(frames, 1)):
            vals = [((i * 37 + (k + f) * 11) % 100) for i in range(rows * cols)]
            segs = []
            for byte in range(width - 1, -1, -1):
                lane = bytes((v >> (8 * byte)) & 0xFF for v in vals)
                seg = bytearray()
                for at in range(0, len(lane), 128):
                    chunk = lane[at:at + 128]
                    if len(set(chunk)) == 1 and len(chunk) > 1:
                        seg += bytes([(257 - len(chunk)) & 0xFF, chunk[0]])
                    else:
                        seg += bytes([len(chunk) - 1]) + chunk
                segs.append(bytes(seg))
            offs, at = [], 64
            for seg in segs:
                offs.append(at)
                at += len(seg)
            rle_head = struct.pack("<16I", len(segs), *(offs + [0] * (15 - len(offs))))
            body = rle_head + b"".join(segs)
            frags += item(body + (b"\0" if len(body) % 2 else b""))
        d += struct.pack("<HH", 0x7FE0, 0x10) + b"OB\0\0" + struct.pack("<I", 0xFFFFFFFF)
        return head + d + frags + struct.pack("<HHI", 0xFFFE, 0xE0DD, 0)
    if ts == "1.2.840.10008.1.2.4.70":
        stored = bits if bits == 8 else 12
        item = lambda b: struct.pack("<HHI", 0xFFFE, 0xE000, len(b)) + b
        frags = item(b"")  # an empty basic offset table
        for f in range(max(frames, 1)):
            vals = [((i * 37 + (k + f) * 11) % 100) % (1 << stored) for i in range(rows * cols)]
            stream = jpeg_lossless(rows, cols, vals, stored, 1)
            frags += item(stream + (b"\0" if len(stream) % 2 else b""))
        d += struct.pack("<HH", 0x7FE0, 0x10) + b"OB\0\0" + struct.pack("<I", 0xFFFFFFFF)
        return head + d + frags + struct.pack("<HHI", 0xFFFE, 0xE0DD, 0)
    if pixels is None:
        fmt = (">" if big else "<") + ("B" if bits == 8 else "h" if bits == 16 else "i") * n
        pixels = struct.pack(fmt, *[(i * 37 + k * 11) % 100 for i in range(n)])
    d += el(0x7fe0, 0x10, "OB" if bits == 8 else "OW", pixels)
    return head + d


def dicom_seeds(out):
    # The corpus's dicom/j2k_* seeds (JPEG 2000 frames) come from OpenJPEG through the tests'
    # support/jpeg2000_encode.hpp: Python here has no JPEG 2000 encoder.
    for name, ts in (("implicit", "1.2.840.10008.1.2"), ("explicit", "1.2.840.10008.1.2.1"),
                     ("big", "1.2.840.10008.1.2.2")):
        put(out, "dicom", "series_" + name, NEXT.join(dicom_slice(ts, k) for k in range(3)))
    put(out, "dicom", "series_u8", NEXT.join(dicom_slice("1.2.840.10008.1.2.1", k, bits=8, signed=0) for k in range(3)))
    put(out, "dicom", "series_i32", NEXT.join(dicom_slice("1.2.840.10008.1.2.1", k, bits=32) for k in range(3)))
    put(out, "dicom", "jpeg", NEXT.join(dicom_slice("1.2.840.10008.1.2.4.50", k) for k in range(2)))
    put(out, "dicom", "truncated", NEXT.join(dicom_slice("1.2.840.10008.1.2.1", k)[:200] for k in range(2)))
    put(out, "dicom", "short_pixels", NEXT.join(dicom_slice("1.2.840.10008.1.2.1", k, pixels=b"\1\2") for k in range(2)))
    for name, ts in (("implicit", "1.2.840.10008.1.2"), ("explicit", "1.2.840.10008.1.2.1"),
                     ("big", "1.2.840.10008.1.2.2")):
        put(out, "dicom", "enhanced_" + name, dicom_slice(ts, 0, frames=5))
    put(out, "dicom", "enhanced_concatenation", NEXT.join(dicom_slice("1.2.840.10008.1.2.1", k, frames=3) for k in range(2)))
    put(out, "dicom", "rtdose", dicom_slice("1.2.840.10008.1.2", 0, bits=32, signed=0, grid=[0, 2.5, 5, 7.5]))
    put(out, "dicom", "rtdose_absolute", dicom_slice("1.2.840.10008.1.2.1", 0, grid=[7, 9.5, 12, 14.5, 17]))
    put(out, "dicom", "enhanced_time_points", dicom_slice("1.2.840.10008.1.2.1", 0, frames=6))
    put(out, "dicom", "rle_series", NEXT.join(dicom_slice("1.2.840.10008.1.2.5", k) for k in range(3)))
    put(out, "dicom", "rle_enhanced", dicom_slice("1.2.840.10008.1.2.5", 0, bits=8, signed=0, frames=4))
    put(out, "dicom", "jpeg_series", NEXT.join(dicom_slice("1.2.840.10008.1.2.4.70", k) for k in range(3)))
    put(out, "dicom", "jpeg_enhanced", dicom_slice("1.2.840.10008.1.2.4.70", 0, bits=8, signed=0, frames=4))
    put(out, "dicom", "enhanced_short_pixels", dicom_slice("1.2.840.10008.1.2.1", 0, frames=4, pixels=b"\1\2"))
    put(out, "dicom", "declared_huge", NEXT.join(dicom_slice("1.2.840.10008.1.2.1", k, rows=65535, cols=65535,
                                                                pixels=b"\0" * 64) for k in range(2)))


def pgm(w, h, pixels, maxval=255):
    if maxval < 256:
        body = bytes(pixels)
    else:
        body = b"".join(struct.pack(">H", p) for p in pixels)
    return ("P5\n# seed\n%d %d\n%d\n" % (w, h, maxval)).encode() + body


def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)


def png(w, h, rows, depth=8, color=0):
    raw = b"".join(b"\0" + r for r in rows)
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, color, 0, 0, 0))
            + png_chunk(b"IDAT", zlib.compress(raw)) + png_chunk(b"IEND", b""))


def image_seeds(out, images):
    w, h = 24, 16
    px = [int(127.5 + 120 * math.sin(x * 0.4) * math.cos(y * 0.3)) for y in range(h) for x in range(w)]
    put(out, "pgm", "u8", pgm(w, h, px))
    put(out, "pgm", "u16", pgm(w, h, [p * 4 for p in px], 1023))
    put(out, "pgm", "wide_40000x2", "P5\n40000 2\n255\n".encode() + bytes(100))
    put(out, "pgm", "maxval_0", "P5\n2 2\n0\n".encode() + bytes(4))
    put(out, "pgm", "plain_p2", "P2\n2 2\n255\n1 2 3 4\n")
    rows8 = [bytes(px[y * w:(y + 1) * w]) for y in range(h)]
    put(out, "png", "gray8", png(w, h, rows8))
    rows16 = [b"".join(struct.pack(">H", p * 200) for p in px[y * w:(y + 1) * w]) for y in range(h)]
    put(out, "png", "gray16", png(w, h, rows16, 16))
    rows1 = [bytes([0b10110010, 0b01011100, 0b11110000]) for _ in range(h)]
    put(out, "png", "gray1", png(w, h, rows1, 1))
    rowsa = [b"".join(bytes([p, 255]) for p in px[y * w:(y + 1) * w]) for y in range(h)]
    put(out, "png", "gray_alpha", png(w, h, rowsa, 8, 4))
    put(out, "png", "huge_header", png(30000, 30000, [b""], 8)[:60])
    for name, (iw, ih, data) in images.items():
        put(out, "pgm", "shared_" + name, pgm(iw, ih, data))
        put(out, "png", "shared_" + name, png(iw, ih, [data[y * iw:(y + 1) * iw] for y in range(ih)]))


# ---- TIFF stacks.

def packbits(data):
    """PackBits: literal runs of up to 128 bytes, repeats of 3 to 128 as two bytes."""
    out, i = bytearray(), 0
    while i < len(data):
        j = i
        while j < len(data) and j - i < 128 and data[j] == data[i]:
            j += 1
        if j - i >= 3:
            out += bytes([257 - (j - i), data[i]])
            i = j
            continue
        j = i
        while j < len(data) and j - i < 128 and not (j + 2 < len(data) and data[j] == data[j + 1] == data[j + 2]):
            j += 1
        out += bytes([j - i - 1]) + data[i:j]
        i = j
    return bytes(out)


def tiff(pages, width, height, bits=8, fmt=1, compression=1, predictor=1, big=False,
         description=None, tile=None):
    """A classic TIFF: `pages` of raw sample bytes (already in the file's byte order), each in
    one strip (or in tiles of `tile` x `tile`), compressed by `compression` (1 none, 8 Deflate,
    32773 PackBits); ImageJ's description on the first page."""
    e = ">" if big else "<"
    head = (b"MM" if big else b"II") + struct.pack(e + "H", 42)
    body = b""
    offset = 8
    layouts = []
    for raw in pages:
        item = bits // 8
        chunks = []
        if tile:
            for y0 in range(0, height, tile):
                for x0 in range(0, width, tile):
                    t = bytearray(tile * tile * item)
                    for y in range(y0, min(height, y0 + tile)):
                        n = (min(width, x0 + tile) - x0) * item
                        t[(y - y0) * tile * item:(y - y0) * tile * item + n] = raw[(y * width + x0) * item:(y * width + x0) * item + n]
                    chunks.append(bytes(t))
        else:
            chunks.append(raw)
        coded = [zlib.compress(c) if compression == 8 else packbits(c) if compression == 32773 else c
                 for c in chunks]
        offsets = []
        for c in coded:
            offsets.append(offset + len(body))
            body += c
        layouts.append((offsets, [len(c) for c in coded]))
    ifd_at = offset + len(body)
    ifds = b""
    extra = b""
    for k, (offsets, counts) in enumerate(layouts):
        entries = [(256, 4, [width]), (257, 4, [height]), (258, 3, [bits]), (259, 3, [compression]),
                   (262, 3, [1])]
        if description and k == 0:
            entries.append((270, 2, description.encode() + b"\0"))
        if tile:
            entries += [(277, 3, [1]), (317, 3, [predictor]), (322, 3, [tile]), (323, 3, [tile]),
                        (324, 4, offsets), (325, 4, counts), (339, 3, [fmt])]
        else:
            entries += [(273, 4, offsets), (277, 3, [1]), (278, 4, [height]), (279, 4, counts),
                        (317, 3, [predictor]), (339, 3, [fmt])]
        entries.sort()
        size = 2 + 12 * len(entries) + 4
        here = ifd_at + len(ifds)
        data_at = here + size
        block, spill = struct.pack(e + "H", len(entries)), b""
        for tag, typ, values in entries:
            if typ == 2:
                payload, count = values, len(values)
            else:
                payload = b"".join(struct.pack(e + ("H" if typ == 3 else "I"), v) for v in values)
                count = len(values)
            if len(payload) <= 4:
                block += struct.pack(e + "HHI", tag, typ, count) + payload.ljust(4, b"\0")
            else:
                block += struct.pack(e + "HHII", tag, typ, count, data_at + len(spill))
                spill += payload + (b"\0" if len(payload) % 2 else b"")
        last = k == len(layouts) - 1
        block += struct.pack(e + "I", 0 if last else data_at + len(spill))
        ifds += block + spill
    return head + struct.pack(e + "I", ifd_at) + body + ifds


def tiff_seeds(out, crops):
    w, h = 9, 7
    u8 = [bytes((x * 7 + y * 13 + z * 29) % 251 for y in range(h) for x in range(w)) for z in range(3)]
    put(out, "tiff", "u8", tiff(u8, w, h))
    put(out, "tiff", "u8_deflate", tiff(u8, w, h, compression=8))
    put(out, "tiff", "u8_packbits", tiff(u8, w, h, compression=32773))
    put(out, "tiff", "u8_tiles", tiff(u8, w, h, tile=16))
    put(out, "tiff", "u8_tiles_deflate", tiff(u8, w, h, compression=8, tile=16))
    i16 = [b"".join(struct.pack(">h", (x * 300 + y * 77 - z * 999) % 30000 - 15000) for y in range(h) for x in range(w))
           for z in range(3)]
    put(out, "tiff", "i16_big", tiff(i16, w, h, bits=16, fmt=2, big=True))
    f32 = [b"".join(struct.pack("<f", math.sin(x * 0.5 + y * 0.3 + z)) for y in range(h) for x in range(w))
           for z in range(4)]
    put(out, "tiff", "f32_deflate", tiff(f32, w, h, bits=32, fmt=3, compression=8))
    put(out, "tiff", "imagej_frames", tiff(f32, w, h, bits=32, fmt=3,
                                           description="ImageJ=1.54f\nimages=4\nslices=2\nframes=2\nspacing=2.5\n"))
    ome = ('<?xml version="1.0"?><OME><Image ID="Image:0"><Pixels DimensionOrder="XYTZC" '
           'PhysicalSizeX="0.65" PhysicalSizeY="0.65" PhysicalSizeZ="2" PhysicalSizeZUnit="nm" SizeC="1" '
           'SizeT="2" SizeZ="2" SizeX="9" SizeY="7"/></Image></OME>')
    put(out, "tiff", "ome_xytzc", tiff(f32, w, h, bits=32, fmt=3, description=ome))
    put(out, "tiff", "imagej_channels", tiff(u8, w, h, description="ImageJ=1.54f\nimages=3\nchannels=3\n"))
    # 32769 x 32769 doubles declared over a few bytes of Deflate.
    put(out, "tiff", "huge", tiff([zlib.decompress(zlib.compress(b"\0" * 64))] * 2, 32769, 32769, bits=64, fmt=3,
                                  compression=8))
    for name, ((nx, ny, nz), crop) in sorted(crops.items()):
        slices = [crop[z * nx * ny:(z + 1) * nx * ny] for z in range(nz)]
        put(out, "tiff", name + "_deflate", tiff(slices, nx, ny, compression=8))


# ---- mrc: MRC2014 maps, field by field.

def mrc(n, mode, data, big=False, m=None, cell=None, angles=(90.0, 90.0, 90.0), axes=(1, 2, 3),
        start=(0, 0, 0), origin=(0.0, 0.0, 0.0), ispg=1, extended=b"", stamp=True, imod_unsigned=False):
    e = ">" if big else "<"
    m = m or n
    cell = cell or tuple(float(v) for v in m)
    h = bytearray(1024)
    struct.pack_into(e + "3ii3i3i", h, 0, *n, mode, *start, *m)
    struct.pack_into(e + "3f3f3i", h, 40, *cell, *angles, *axes)
    struct.pack_into(e + "ii", h, 88, ispg, len(extended))
    struct.pack_into(e + "i", h, 108, 20141)
    if imod_unsigned:
        struct.pack_into(e + "ii", h, 152, 1146047817, 0)
    struct.pack_into(e + "3f", h, 196, *origin)
    h[208:212] = b"MAP "
    if stamp:
        h[212:214] = b"\x11\x11" if big else b"\x44\x44"
    return bytes(h) + extended + data


def mrc_seeds(out, crops):
    n = (5, 4, 3)
    count = 60
    f32 = b"".join(struct.pack("<f", math.sin(i * 0.37) * 10) for i in range(count))
    put(out, "mrc", "f32", mrc(n, 2, f32, cell=(7.5, 6.0, 4.5), origin=(10.0, -5.0, 2.5)))
    put(out, "mrc", "f32_gzip", gzip.compress(mrc(n, 2, f32)))
    i16_big = b"".join(struct.pack(">h", (i * 997) % 4000 - 2000) for i in range(count))
    put(out, "mrc", "i16_big", mrc(n, 1, i16_big, big=True))
    u16 = b"".join(struct.pack("<H", (i * 1237) % 65536) for i in range(count))
    put(out, "mrc", "u16_permuted", mrc(n, 6, u16, axes=(3, 1, 2), m=(4, 3, 5), start=(-2, 3, 7)))
    half = b"".join(struct.pack("<e", math.cos(i * 0.21) * 100) for i in range(count))
    put(out, "mrc", "f16_no_stamp", mrc(n, 12, half, stamp=False))
    u8 = bytes((i * 37) % 251 for i in range(count))
    put(out, "mrc", "imod_u8_extended", mrc(n, 0, u8, imod_unsigned=True, extended=b"x" * 128))
    put(out, "mrc", "i8_oblique", mrc(n, 0, u8, angles=(70.0, 80.0, 100.0)))
    put(out, "mrc", "volume_stack", mrc((5, 4, 6), 0, u8 * 2, m=(5, 4, 3), ispg=401))
    put(out, "mrc", "declared_2000x2000x1000", mrc((2000, 2000, 1000), 2, f32))
    put(out, "mrc", "declared_gzip_floats", gzip.compress(mrc((2000, 2000, 1000), 2, bytes(1 << 16))))
    f32_nan = b"".join(struct.pack("<f", float("nan") if i % 2 else i) for i in range(count))
    put(out, "mrc", "f32_every_other_nan", mrc(n, 2, f32_nan))
    for name, (dims, data) in sorted(crops.items()):
        put(out, "mrc", "shared_%s_gzip" % name, gzip.compress(mrc(dims, 0, data, imod_unsigned=True)))


# ---- zarr: ".zarray \0DATA\0 chunk" (the harness writes the chunk as 0.0.0 and 0.1.0).

def zarray(shape, chunks, dtype, compressor, fill=0, order="C"):
    import json
    return json.dumps({"zarr_format": 2, "shape": shape, "chunks": chunks, "dtype": dtype,
                       "compressor": compressor, "fill_value": fill, "order": order,
                       "filters": None}).encode()


def zarr_seeds(out, crops):
    sep = b"\0DATA\0"
    u8 = bytes((i * 37) % 251 for i in range(4 * 4 * 4))
    put(out, "zarr", "u8_raw", zarray([4, 8, 4], [4, 4, 4], "|u1", None) + sep + u8)
    put(out, "zarr", "u8_zlib", zarray([4, 8, 4], [4, 4, 4], "|u1", {"id": "zlib", "level": 5}) +
        sep + zlib.compress(u8))
    i16 = b"".join(struct.pack(">h", (i * 997) % 4000 - 2000) for i in range(4 * 4 * 4))
    put(out, "zarr", "i16_big_gzip_fortran", zarray([4, 8, 4], [4, 4, 4], ">i2", {"id": "gzip"},
                                                   order="F") + sep + gzip.compress(i16))
    f32 = b"".join(struct.pack("<f", math.sin(i * 0.37)) for i in range(4 * 4 * 4))
    put(out, "zarr", "f32_fill_nan", zarray([4, 12, 4], [4, 4, 4], "<f4", None, fill="NaN") +
        sep + f32)
    put(out, "zarr", "declared_32769", zarray([32769, 32769, 32769], [4, 4, 4], "|u1", None) +
        sep + u8)
    put(out, "zarr", "series", zarray([2, 3, 4, 8, 4], [1, 1, 4, 4, 4], "<u2", None) + sep +
        u8 + u8)
    try:
        import numcodecs
        put(out, "zarr", "u8_blosc", zarray([4, 8, 4], [4, 4, 4], "|u1", {"id": "blosc"}) + sep +
            numcodecs.Blosc(cname="lz4").encode(u8))
        put(out, "zarr", "f32_zstd", zarray([4, 8, 4], [4, 4, 4], "<f4", {"id": "zstd"}) + sep +
            numcodecs.Zstd().encode(f32))
    except ImportError:
        pass
    for name, (dims, data) in sorted(crops.items()):
        shape = [dims[2], dims[1], dims[0]]
        put(out, "zarr", "shared_%s_zlib" % name,
            zarray(shape, [shape[0], (shape[1] + 1) // 2, shape[2]], "|u1", {"id": "zlib"}) +
            sep + zlib.compress(data[:shape[0] * ((shape[1] + 1) // 2) * shape[2]]))


# ---- mesh and contour files.

def ply(vertices, faces, normals=None):
    head = ("ply\nformat binary_little_endian 1.0\ncomment generated by progiso\nelement vertex %d\n"
            "property float x\nproperty float y\nproperty float z\n" % len(vertices))
    if normals:
        head += "property float nx\nproperty float ny\nproperty float nz\n"
    head += "element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(faces)
    body = b"".join(struct.pack("<fff", *v) + (struct.pack("<fff", *normals[i]) if normals else b"")
                    for i, v in enumerate(vertices))
    body += b"".join(struct.pack("<Biii", 3, *f) for f in faces)
    return head.encode() + body


def mesh_seeds(out):
    v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    f = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    put(out, "ply", "tetrahedron", ply(v, f))
    put(out, "ply", "bad_index", ply(v, [(0, 1, 7)]))
    put(out, "ply", "negative_index", ply(v, [(0, 1, -1)]))
    put(out, "ply", "truncated", ply(v, f)[:-5])
    n = [(-1, -1, -1), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    put(out, "ply", "normals", ply(v, f, n))
    put(out, "ply", "normals_short", ply(v, f, n)[:-20])
    put(out, "ply", "huge_count", ply(v, f).replace(b"element face 4", b"element face 4000000000"))
    put(out, "obj", "contours", "# generated by progiso: isocontours, 4 vertices, 2 polylines\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n# isovalue 64\nl 1 2 3 4 1\n# isovalue 127.5\nl 2 3\n")
    put(out, "obj", "streamed", "# generated by progiso: isocontours\nv 0 0 0\nv 1 0 0\n# isovalue 1\nl 1 2\n"
        "v 2 0 0\nv 3 1 0\n# isovalue 2\nl 3 4\n")
    put(out, "obj", "bad_index", "v 0 0 0\nl 1 2\n")
    put(out, "obj", "z_not_zero", "v 0 0 1\nl 1\n")
    put(out, "obj", "subnormal", "v 1e-320 0 0\nv 1 1 0\n# isovalue 1e-320\nl 1 2\n")
    put(out, "obj", "face", "v 0 0 0\nf 1 1 1\n")


# ---- command lines, NUL-separated.

def cli_seeds(out):
    cases = {
        "extract_raw": ["extract", "v.raw", "--dims", "64,64,93", "--type", "i16", "--spacing", "3.2,3.2,1.5",
                        "--iso", "500", "--max-triangles", "50000", "-o", "skin.ply"],
        "extract_nrrd": ["extract", "scan.nrrd", "--iso", "120", "--time-ms", "33", "-o", "q.obj",
                         "--stats-json", "s.json", "--threads", "2"],
        "demo": ["extract", "--demo", "-o", "demo.ply", "--stats-json", "demo.json"],
        "normals": ["extract", "--demo", "--normals", "-o", "demo.obj"],
        "time_overflow": ["extract", "v.nrrd", "--iso", "1", "--time-ms", "9.3e12", "-o", "o.ply"],
        "time_by_priority": ["extract", "v.nrrd", "--iso", "1", "--time-ms", "5", "--by-priority",
                             "-o", "o.ply"],
        "count_overflow": ["extract", "v.nrrd", "--iso", "1", "--max-triangles", "3e19", "-o", "o.ply"],
        "count_max": ["extract", "v.nrrd", "--iso", "1", "--max-triangles", "18446744073709551615", "-o", "o.ply"],
        "spacing_huge": ["extract", "v.raw", "--dims", "8,8,8", "--type", "u8", "--spacing", "1e40,1,1",
                         "--iso", "1", "-o", "o.ply"],
        "subnormal": ["extract", "v.nrrd", "--iso", "1e-320", "--error", "4.9e-324", "-o", "o.obj"],
        "hex_float": ["extract", "v.nrrd", "--iso", "0x1p-3", "-o", "o.obj"],
        "contour": ["contour", "coins.pgm", "--iso", "64,128,192", "-o", "coins.svg", "--frames", "f"],
        "contour_many": ["contour", "dem.pgm", "--iso", ",".join(str(300 + 50 * i) for i in range(15)),
                         "--error", "5", "-o", "dem.obj"],
        "contour_segments": ["contour", "a.png", "--iso", "10", "--max-segments", "1e6", "-o", "a.obj"],
        "help": ["extract", "--help"],
        "missing_value": ["extract", "v.nrrd", "--iso"],
    }
    for name, args in cases.items():
        put(out, "cli", name, "\0".join(args))


def shared_crops(data_dir):
    """16^3 crops of the 8-bit shared volumes and 48 x 32 crops of the shared images."""
    crops, images = {}, {}
    if not data_dir:
        return crops, images
    for name, (nx, ny, nz) in {"bucky_32x32x32_uint8.raw": (32, 32, 32),
                               "nucleon_41x41x41_uint8.raw": (41, 41, 41),
                               "hipip_68x68x68_uint8.raw": (68, 68, 68)}.items():
        path = os.path.join(data_dir, name)
        if not os.path.exists(path):
            continue
        with open(path, "rb") as f:
            vol = f.read()
        x0, y0, z0 = nx // 4, ny // 4, nz // 4
        crop = bytes(vol[(x0 + x) + nx * ((y0 + y) + ny * (z0 + z))]
                     for z in range(16) for y in range(16) for x in range(16))
        crops[name.split("_")[0]] = ((16, 16, 16), crop)
    for name in ("camera_512x512.pgm", "coins_384x303.pgm"):
        path = os.path.join(data_dir, name)
        if not os.path.exists(path):
            continue
        with open(path, "rb") as f:
            raw = f.read()
        w, h = (int(t) for t in name.split("_")[1].split(".")[0].split("x"))
        body = raw[len(raw) - w * h:]
        x0, y0 = w // 3, h // 3
        images[name.split("_")[0]] = (48, 32, bytes(body[(y0 + y) * w + x0 + x] for y in range(32) for x in range(48)))
    return crops, images


def hdf5_seeds(out):
    """Imaris and BigDataViewer files, written by h5py (Debian's python3-h5py) when it imports."""
    try:
        import h5py
        import numpy as np
    except ImportError:
        return
    import io

    def text(obj, name, value):
        obj.attrs.create(name, np.array(list(value), dtype="|S1"))

    def save(name, write):
        b = io.BytesIO()
        with h5py.File(b, "w") as f:
            write(f)
        put(out, "hdf5", name, b.getvalue())

    v = (np.arange(6 * 5 * 4).reshape(6, 5, 4) * 7 % 251).astype(np.uint8)

    def imaris(f, data, chunks=None, compression=None, size=(4, 5, 6)):
        text(f, "ImarisDataSet", "ImarisDataSet")
        info = f.create_group("DataSetInfo/Image")
        for q in range(3):
            text(info, "ExtMin%d" % q, "0")
            text(info, "ExtMax%d" % q, str(size[q]))
        for r, d in enumerate([data, data[::2, ::2, ::2]]):
            g = f.create_group("DataSet/ResolutionLevel %d/TimePoint 0/Channel 0" % r)
            for axis, n in zip("XYZ", reversed(d.shape)):
                text(g, "ImageSize" + axis, str(n))
            g.create_dataset("Data", data=d, chunks=chunks if r == 0 else None,
                             compression=compression if r == 0 else None)

    save("imaris_u8", lambda f: imaris(f, v))
    save("imaris_gzip", lambda f: imaris(f, v, chunks=(2, 5, 4), compression="gzip"))
    save("imaris_f32", lambda f: imaris(f, v.astype(np.float32) / 3))
    save("imaris_size_beyond", lambda f: imaris(f, v, size=(40, 5, 6)))

    def bdv(f, data):
        f.create_dataset("s00/resolutions", data=np.array([[1, 1, 1], [2, 2, 2]], dtype=float))
        f.create_dataset("s00/subdivisions", data=np.array([[4, 4, 4], [4, 4, 4]], dtype=np.int32))
        f.create_dataset("t00000/s00/0/cells", data=data, chunks=(2, 5, 4), compression="gzip")
        f.create_dataset("t00000/s00/1/cells", data=data[::2, ::2, ::2])

    save("bdv_i16", lambda f: bdv(f, v.astype(np.int16) - 100))

    def bomb(f):
        f.create_dataset("s00/resolutions", data=np.array([[1, 1, 1]], dtype=float))
        d = f.create_dataset("t00000/s00/0/cells", shape=(4096, 4096, 4096), dtype=np.uint8,
                             chunks=(64, 64, 64), compression="gzip")
        d[0:64, 0:64, 0:64] = 1

    save("bdv_bomb", bomb)


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    out = sys.argv[1]
    crops, images = shared_crops(sys.argv[2] if len(sys.argv) == 3 else None)
    raw_seeds(out, crops)
    nrrd_seeds(out, crops)
    nifti_seeds(out, crops)
    metaimage_seeds(out, crops)
    vtk_seeds(out, crops)
    vti_seeds(out, crops)
    jpeg_seeds(out)
    dicom_seeds(out)
    tiff_seeds(out, crops)
    mrc_seeds(out, crops)
    zarr_seeds(out, crops)
    hdf5_seeds(out)
    image_seeds(out, images)
    mesh_seeds(out)
    cli_seeds(out)


if __name__ == "__main__":
    main()
