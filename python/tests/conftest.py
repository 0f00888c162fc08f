"""Shared helpers of the Python tests: the shared volumes, surface measures, the command."""

import os
import pathlib

import numpy as np
import pytest

SOURCE = pathlib.Path(os.environ.get("PROGISO_SOURCE_DIR",
                                     pathlib.Path(__file__).resolve().parents[2]))


def data_dir():
    env = os.environ.get("PROGISO_DATA_DIR")
    if env:
        return pathlib.Path(env)
    return SOURCE.parent / "shared" / "data"


# name: (file, shape in axis order (z, y, x), dtype, spacing per axis, isovalues)
VOLUMES = {
    "bucky": ("bucky_32x32x32_uint8.raw", (32, 32, 32), np.uint8, (1, 1, 1), (51, 128)),
    "nucleon": ("nucleon_41x41x41_uint8.raw", (41, 41, 41), np.uint8, (1, 1, 1), (60, 140)),
    "neghip": ("neghip_66x66x66_uint8.raw", (66, 66, 66), np.uint8, (1, 1, 1), (30, 128)),
    "hipip": ("hipip_68x68x68_uint8.raw", (68, 68, 68), np.uint8, (1, 1, 1), (128, 30)),
    "headsq": ("headsq_64x64x93_int16le.raw", (93, 64, 64), np.dtype("<i2"), (1.5, 3.2, 3.2),
               (500, 1150)),
    "brainsmall": ("brainsmall_128x128x84_uint8.raw", (84, 128, 128), np.uint8, (1, 1, 1),
                   (30, 60)),
}


def load(name):
    """(array, spacing, isovalues) of a shared volume; skips when the data is absent."""
    file, shape, dtype, spacing, isos = VOLUMES[name]
    path = data_dir() / file
    if not path.exists():
        pytest.skip("shared data not found: %s (set PROGISO_DATA_DIR)" % path)
    return np.fromfile(path, dtype=dtype).reshape(shape), spacing, isos


def area(verts, faces):
    v = np.asarray(verts, dtype=np.float64)
    f = np.asarray(faces)
    c = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return 0.5 * float(np.sqrt((c * c).sum(axis=1)).sum())


def triangle_set(verts, faces):
    """The triangles as a set of corner triples (positions as bytes), rotated so the smallest
    corner comes first: equal sets are equal surfaces, numbering and start corner aside."""
    v = np.asarray(verts)
    out = set()
    for f in np.asarray(faces):
        corners = [v[i].tobytes() for i in f]
        k = corners.index(min(corners))
        out.add(tuple(corners[k:] + corners[:k]))
    return out


def progiso_exe():
    exe = os.environ.get("PROGISO_EXE")
    if not exe or not os.path.exists(exe):
        pytest.skip("the progiso command is not built (PROGISO_EXE)")
    return exe


def read_ply(path):
    """(verts (n, 3) float32 in x, y, z order, faces (t, 3)) of progiso's binary PLY."""
    data = pathlib.Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    nv = nt = 0
    props = 0
    for line in header:
        if line.startswith("element vertex"):
            nv = int(line.split()[2])
        elif line.startswith("element face"):
            nt = int(line.split()[2])
        elif line.startswith("property float"):
            props += 1
    verts = np.frombuffer(data, dtype="<f4", count=nv * props, offset=end).reshape(nv, props)
    faces_raw = np.frombuffer(data, dtype=np.dtype([("n", "u1"), ("i", "<i4", 3)]), count=nt,
                              offset=end + nv * props * 4)
    assert (faces_raw["n"] == 3).all()
    return verts[:, :3].copy(), faces_raw["i"].copy()
