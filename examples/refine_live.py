#!/usr/bin/env python3
"""A surface refining while its isovalue moves, with its quality printed over time.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/refine_live.py [VOLUME [ISO ...]]

VOLUME is any file progiso reads (NRRD, NIfTI, DICOM directory, ...); without it, a 192^3
analytic field (three interlocked tori). The engine publishes its first surface at once, then
refines it in the background by error (largest first) while this script follows it with
engine.snapshots(); each isovalue given (or two chosen from the data) takes over from the last
after a while, from another thread, as a slider would. Each line: seconds since the start, the
isovalue, the triangles of the cut, its area as a share of the finest surface's and the share of
the finest surface's vertices within half a voxel of the cut (sampled), the cut's quality.
"""

import sys
import threading
import time

import numpy as np

import progiso


def tori(n=192):
    z, y, x = np.ogrid[0:n, 0:n, 0:n]
    x, y, z = (x / n - 0.5) * 3, (y / n - 0.5) * 3, (z / n - 0.5) * 3
    d = np.full((n, n, n), 9.0, dtype=np.float32)
    for (a, b, c) in ((x, y, z), (y, z, x), (z, x, y)):
        q = np.sqrt((a - 0.25) ** 2 + b ** 2) - 0.6
        d = np.minimum(d, np.sqrt(q ** 2 + c ** 2).astype(np.float32))
    return d, (1.0, 1.0, 1.0)


def main(argv):
    if len(argv) > 1:
        vol, spacing, _, _ = progiso.read_volume(argv[1])
        lo, hi = float(vol.min()), float(vol.max())
        isos = [float(w) for w in argv[2:]] or [lo + 0.3 * (hi - lo), lo + 0.5 * (hi - lo)]
    else:
        vol, spacing = tori()
        isos = [float(w) for w in argv[2:]] or [0.15, 0.25]
    voxel = max(spacing)
    # The finest surfaces, to measure the cuts against (the one-shot call: a fraction of a
    # second for a 192^3 field).
    finest = {}
    for w in isos:
        v, f, _, _ = progiso.marching_cubes(vol, w, spacing=spacing)
        probe = v[np.random.default_rng(1).choice(len(v), min(len(v), 4000), replace=False)]
        finest[w] = (progiso.Snapshot(v, f, None, {"isovalue": w, "generation": 0, "splits": 0,
                                                   "uniform_stride": 1}, None).area(), probe)

    start = time.monotonic()
    eng = progiso.Engine(vol, isos[0], spacing=spacing)
    first = eng.snapshot()
    print("first surface after %.2f ms: %d triangles"
          % (1e3 * (time.monotonic() - start), first.triangle_count))

    # The slider: each isovalue in turn, a moment after the last, while refinement goes on
    # (set_isovalue resumes the run's goal on the new isovalue; start() begins one if the last
    # had ended).
    def slider():
        for w in isos[1:]:
            time.sleep(0.15)
            eng.set_isovalue(w)
            if not eng.running:
                eng.start(max_error=0.0)

    mover = threading.Thread(target=slider)
    mover.start()
    from scipy.spatial import cKDTree  # noqa: E402 (optional: quality needs it)
    print("%8s %10s %10s %8s %10s" % ("t (s)", "isovalue", "triangles", "area", "near"))
    eng.start(max_error=0.0)
    for snap in eng.snapshots(interval=0.02, until=0.5 + 0.3 * len(isos)):
        area, probe = finest[snap.isovalue]
        near = 0.0
        if len(snap.vertices):
            near = float(np.mean(cKDTree(snap.vertices).query(probe)[0] <= 0.5 * voxel))
        print("%8.3f %10g %10d %7.1f%% %9.1f%%"
              % (snap.time - start, snap.isovalue, snap.triangle_count,
                 100 * snap.area() / area, 100 * near))
        if not eng.running and not mover.is_alive() and snap.isovalue == isos[-1]:
            break
    mover.join()
    eng.wait()
    print("done: %d triangles at isovalue %g" % (eng.snapshot().triangle_count, eng.isovalue))


if __name__ == "__main__":
    main(sys.argv)
