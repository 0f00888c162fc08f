#!/usr/bin/env python3
"""progiso.marching_cubes from Python against scikit-image's marching_cubes and VTK's
vtkFlyingEdges3D through its Python wrappers: time (alternating pairs in one process), peak
memory (one fresh process per measurement) and the engine's first surface.

    PYTHONPATH=build/release/python /usr/bin/python3 bench/python_bench.py [--quick] [--reps N]

Inputs: the shared volumes (../shared/data, or $PROGISO_DATA_DIR) at their first suggested
isovalue, and 512^3 analytic fields (a sphere's distance as float32, a noisy Marschner-Lobb-like
field as uint8). Every tool makes normals (scikit-image always does; VTK with ComputeNormals on).
Prints one markdown table per measure (bench/README.md, "Python").
"""

import argparse
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent

SHARED = {
    "bucky": ("bucky_32x32x32_uint8.raw", (32, 32, 32), "u1", (1, 1, 1), 51),
    "nucleon": ("nucleon_41x41x41_uint8.raw", (41, 41, 41), "u1", (1, 1, 1), 60),
    "neghip": ("neghip_66x66x66_uint8.raw", (66, 66, 66), "u1", (1, 1, 1), 30),
    "hipip": ("hipip_68x68x68_uint8.raw", (68, 68, 68), "u1", (1, 1, 1), 128),
    "headsq": ("headsq_64x64x93_int16le.raw", (93, 64, 64), "<i2", (1.5, 3.2, 3.2), 500),
    "brainsmall": ("brainsmall_128x128x84_uint8.raw", (84, 128, 128), "u1", (1, 1, 1), 50),
}


def data_dir():
    env = os.environ.get("PROGISO_DATA_DIR")
    return pathlib.Path(env) if env else HERE.parent.parent / "shared" / "data"


def make_input(name, n=512):
    """(array, spacing, level) of a named input."""
    if name in SHARED:
        file, shape, dtype, spacing, level = SHARED[name]
        return np.fromfile(data_dir() / file, dtype=dtype).reshape(shape), spacing, level
    if name == "sphere512":
        z, y, x = np.ogrid[0:n, 0:n, 0:n]
        c = (n - 1) / 2 + 0.3
        vol = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2, dtype=np.float32)
        return vol.astype(np.float32), (1, 1, 1), n * 0.35
    if name == "waves512":
        z, y, x = np.ogrid[0:n, 0:n, 0:n]
        f = (np.sin(x * (12 / n)) * np.cos(y * (10 / n)) + np.sin(z * (14 / n)) * np.cos(x * (8 / n))
             + 0.02 * np.random.default_rng(5).standard_normal((n, n, n), dtype=np.float32))
        vol = ((f + 2.2) * (255 / 4.4)).clip(0, 255).astype(np.uint8)
        return vol, (1, 1, 1), 128
    raise ValueError(name)


# --- the three tools: each returns (triangles, seconds) for one call

def run_progiso(vol, spacing, level, threads):
    import progiso
    t = time.perf_counter()
    v, f, n, val = progiso.marching_cubes(vol, level, spacing=spacing, threads=threads)
    return len(f), time.perf_counter() - t


def run_skimage(vol, spacing, level, threads):
    from skimage.measure import marching_cubes
    t = time.perf_counter()
    v, f, n, val = marching_cubes(vol, level, spacing=spacing)
    return len(f), time.perf_counter() - t


_vtk_threads = None


def run_vtk(vol, spacing, level, threads):
    from vtkmodules.vtkCommonCore import vtkSMPTools
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D
    from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    global _vtk_threads
    if _vtk_threads != threads:
        vtkSMPTools.Initialize(threads)
        _vtk_threads = threads
    t = time.perf_counter()
    img = vtkImageData()
    img.SetDimensions(vol.shape[2], vol.shape[1], vol.shape[0])
    img.SetSpacing(spacing[2], spacing[1], spacing[0])
    scalars = numpy_to_vtk(vol.ravel(), deep=False)  # a view: no copy of the volume
    img.GetPointData().SetScalars(scalars)
    fe = vtkFlyingEdges3D()
    fe.SetInputData(img)
    fe.SetValue(0, level)
    fe.ComputeNormalsOn()
    fe.ComputeScalarsOff()
    fe.Update()
    out = fe.GetOutput()
    pts = vtk_to_numpy(out.GetPoints().GetData())
    tris = out.GetNumberOfCells()
    del pts
    return tris, time.perf_counter() - t


TOOLS = {"progiso": run_progiso, "skimage": run_skimage, "vtk": run_vtk}


def vtk_backend():
    try:
        from vtkmodules.vtkCommonCore import vtkSMPTools
        return vtkSMPTools.GetBackend()
    except Exception:  # noqa: BLE001
        return None


def times(inputs, threads_list, reps, tools):
    """Median seconds per (input, threads, tool), the tools called in turn, `reps` rounds."""
    rows = []
    for name in inputs:
        vol, spacing, level = make_input(name)
        for threads in threads_list:
            samples = {t: [] for t in tools}
            tris = {}
            for t in tools:  # warm-up round (imports, tables, pages)
                TOOLS[t](vol, spacing, level, threads)
            for _ in range(reps):
                for t in tools:
                    tris[t], s = TOOLS[t](vol, spacing, level, threads)
                    samples[t].append(s)
            med = {t: float(np.median(samples[t])) for t in tools}
            rows.append((name, vol.shape, vol.dtype, threads, med, tris))
            print("  %s %d thread(s): %s" % (name, threads, ", ".join(
                "%s %.1f ms" % (t, 1e3 * med[t]) for t in tools)), file=sys.stderr, flush=True)
    return rows


PEAK = r"""
import sys, numpy as np
sys.path.insert(0, sys.argv[4])
import python_bench as b
name, tool, threads = sys.argv[1], sys.argv[2], int(sys.argv[3])
vol, spacing, level = b.make_input(name)
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
small = np.arange(64, dtype=vol.dtype).reshape(4, 4, 4)
b.TOOLS[tool](small, (1, 1, 1), float(small.mean()) + 0.5, threads)  # imports, tables
open("/proc/self/clear_refs", "w").write("5")
before = status("VmRSS:")
tris, _ = b.TOOLS[tool](vol, spacing, level, threads)
print(status("VmHWM:") - before, tris, vol.nbytes, vol.size)
"""


def peak(name, tool, threads):
    out = subprocess.run([sys.executable, "-c", PEAK, name, tool, str(threads), str(HERE)],
                         capture_output=True, text=True, check=True).stdout.split()
    return tuple(int(x) for x in out)


def first_surface(inputs, reps):
    import progiso
    rows = []
    for name in inputs:
        vol, spacing, level = make_input(name)
        samples = []
        for _ in range(reps + 1):
            t = time.perf_counter()
            eng = progiso.Engine(vol, level, spacing=spacing)
            snap = eng.snapshot()
            samples.append(time.perf_counter() - t)
            tris = snap.triangle_count
            eng.close()
        rows.append((name, vol.shape, vol.dtype, float(np.median(samples[1:])), tris))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="the shared volumes only, 1 round")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--no-memory", action="store_true")
    args = ap.parse_args()
    import progiso
    tools = ["progiso", "skimage"]
    if vtk_backend() is not None:
        tools.append("vtk")
    inputs = list(SHARED)
    if not args.quick:
        inputs += ["sphere512", "waves512"]
    reps = 1 if args.quick else args.reps
    threads_list = [1, 2]
    print("VTK SMP backend: %s; cores: %d" % (vtk_backend(), progiso.default_threads()))

    rows = times(inputs, threads_list, reps, tools)
    print("\n### Time (median of %d alternating rounds)\n" % reps)
    head = "| input | threads | progiso ms | scikit-image ms | speed-up |"
    line = "|---|---:|---:|---:|---:|"
    if "vtk" in tools:
        head += " VTK FE ms | progiso / VTK |"
        line += "---:|---:|"
    print(head)
    print(line)
    for name, shape, dtype, threads, med, tris in rows:
        s = "| %s %s %s | %d | %.2f | %.2f | %.1f× |" % (
            name, "×".join(str(x) for x in shape[::-1]), dtype, threads, 1e3 * med["progiso"],
            1e3 * med["skimage"], med["skimage"] / med["progiso"])
        if "vtk" in tools:
            s += " %.2f | %.2f |" % (1e3 * med["vtk"], med["progiso"] / med["vtk"])
        print(s)

    if not args.no_memory:
        print("\n### Peak memory above the volume (MiB), one process per call\n")
        print("| input | volume MiB | progiso | its output | output + 1 B/voxel | scikit-image |"
              + (" VTK FE |" if "vtk" in tools else ""))
        print("|---|---:|---:|---:|---:|---:|" + ("---:|" if "vtk" in tools else ""))
        for name in inputs:
            p, tris, nbytes, voxels = peak(name, "progiso", 1)
            vol, spacing, level = make_input(name)
            out = progiso.marching_cubes(vol, level, spacing=spacing)
            output = sum(a.nbytes for a in out)
            del out, vol
            s = peak(name, "skimage", 1)[0]
            mib = 1 / 1048576
            row = "| %s | %.1f | %.1f | %.1f | %.1f | %.1f |" % (
                name, nbytes * mib, p * mib, output * mib, (output + voxels) * mib, s * mib)
            if "vtk" in tools:
                row += " %.1f |" % (peak(name, "vtk", 1)[0] * mib)
            print(row)

    print("\n### First surface from Python: Engine(volume, level) + snapshot()\n")
    print("| input | ms | triangles |")
    print("|---|---:|---:|")
    for name, shape, dtype, sec, tris in first_surface(inputs, 5 if not args.quick else 2):
        print("| %s %s %s | %.3f | %d |" % (name, "×".join(str(x) for x in shape[::-1]), dtype,
                                           1e3 * sec, tris))


if __name__ == "__main__":
    main()
