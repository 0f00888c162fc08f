"""Arrays are read in place: no copy of the volume, checked by address and by peak memory."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import progiso
from progiso import _progiso

DTYPES = ["uint8", "int8", "uint16", "int16", "uint32", "int32", "float32", "float64", "bool"]


@pytest.mark.parametrize("dtype", DTYPES)
def test_c_contiguous_native_arrays_are_read_in_place(dtype):
    a = (np.arange(4 * 5 * 6) % 7).reshape(4, 5, 6).astype(dtype)
    address, copied = _progiso._view_address(a)
    assert not copied
    assert address == a.__array_interface__["data"][0]
    eng = progiso.Engine(a, 0.5 if dtype == "bool" else 3.5)
    assert not eng.copied
    assert eng.array is a


def test_read_only_arrays_are_read_in_place():
    a = np.linspace(0, 1, 6 * 6 * 6, dtype=np.float32).reshape(6, 6, 6)
    a.flags.writeable = False
    assert not _progiso._view_address(a)[1]
    v, fc, _, _ = progiso.marching_cubes(a, 0.5)
    assert len(fc) > 0


@pytest.mark.parametrize("make", [
    lambda a: a[:, :, ::2],                       # strided
    lambda a: np.asfortranarray(a),               # Fortran order
    lambda a: a.astype(">f4"),                    # big-endian
    lambda a: a.astype(np.int64),                 # 64-bit integers
    lambda a: a.astype(np.float16),               # half floats
])
def test_other_layouts_are_copied_once_and_give_the_same_surface(make):
    a = np.sin(np.arange(8 * 9 * 10, dtype=np.float64) * 0.37).reshape(8, 9, 10) * 100
    b = make(a)
    address, copied = _progiso._view_address(b)
    assert copied
    v, fc, _, _ = progiso.marching_cubes(b, 10.0)
    ref = np.ascontiguousarray(b).astype(np.float64)
    v2, f2, _, _ = progiso.marching_cubes(ref, 10.0)
    np.testing.assert_array_equal(v, v2)
    np.testing.assert_array_equal(fc, f2)


PEAK = textwrap.dedent("""
    import sys, numpy as np, progiso
    n = int(sys.argv[1]); dtype = sys.argv[2]
    z, y, x = np.ogrid[0:n, 0:n, 0:n]
    r = np.sqrt((x - n / 2 + .3) ** 2 + (y - n / 2 + .2) ** 2 + (z - n / 2 + .1) ** 2)
    vol = (255 - r * (200 / n)).clip(0, 255).astype(dtype)
    del r
    def status(key):
        for line in open("/proc/self/status"):
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    progiso.marching_cubes(np.ones((3, 3, 3), np.float32) * np.arange(3), 1.0)  # warm up
    open("/proc/self/clear_refs", "w").write("5")   # reset the peak
    before = status("VmRSS:")
    out = progiso.marching_cubes(vol, 128.0)
    peak = status("VmHWM:") - before
    output = sum(a.nbytes for a in out)
    print(peak, output, vol.nbytes)
""")


def test_peak_memory_is_below_the_output_plus_one_byte_per_voxel():
    n = 160
    res = subprocess.run([sys.executable, "-c", PEAK, str(n), "float32"], capture_output=True,
                         text=True, check=True)
    peak, output, volume = (int(x) for x in res.stdout.split())
    voxels = n ** 3
    print("peak above the volume: %d bytes; output %d; volume %d" % (peak, output, volume))
    # A float32 copy of the volume alone would be `volume` bytes more.
    assert peak <= output + voxels + (8 << 20)
    assert peak < volume
