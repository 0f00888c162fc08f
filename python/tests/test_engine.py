"""progiso.Engine from Python: cuts that refine, changes, threads, interruption."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import progiso
from conftest import area, load, triangle_set


def blob(n=96):
    z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float32) / n
    return (np.sin(7 * x) * np.cos(5 * y) + np.sin(6 * z) * np.cos(4 * x) + 2 * x).astype(np.float32)


def test_the_first_surface_is_there_at_once_and_refinement_makes_it_finer():
    vol, _, _ = load("brainsmall")
    eng = progiso.Engine(vol, 60, threads=2)
    first = eng.snapshot()
    assert first.triangle_count > 0 and first.isovalue == 60
    assert eng.refine(max_error=2.0)
    mid = eng.snapshot()
    assert mid.triangle_count > first.triangle_count and mid.splits > 0
    assert eng.refine()
    last = eng.snapshot()
    assert eng.done and last.uniform_stride == 1
    full = progiso.marching_cubes(vol, 60)
    assert triangle_set(last.vertices, last.faces) == triangle_set(full[0], full[1])
    assert abs(area(mid.vertices, mid.faces) / area(full[0], full[1]) - 1) < 0.15


def test_snapshots_iterator_yields_newer_cuts_until_the_run_ends():
    vol, _, _ = load("brainsmall")
    eng = progiso.Engine(vol, 60, threads=2, uniform_cuts=False)
    cuts = list(eng.snapshots(interval=0.001, max_error=0.5))
    assert len(cuts) >= 2
    splits = [c.splits for c in cuts]
    assert splits == sorted(splits) and len(set(splits)) == len(splits)  # each one newer
    assert not eng.running
    assert cuts[-1].splits == eng.snapshot().splits  # the last cut was yielded
    # until= bounds the iteration.
    eng.set_isovalue(30)
    t0 = time.monotonic()
    for _ in eng.snapshots(interval=0.01, until=0.05):
        pass
    assert time.monotonic() - t0 < 2.0


def test_changes_applied_in_order_rebuild_each_snapshot():
    vol, _, _ = load("hipip")
    eng = progiso.Engine(vol, 128, threads=2, uniform_cuts=False)
    pieces = {}  # id -> list of pieces
    change = eng.changes()  # everything
    assert change.rebuilt
    mark = change
    eng.start(max_error=0.0)
    steps = 0
    while True:
        running = eng.running
        if change.rebuilt:
            pieces.clear()
        for gone in change.gone:
            del pieces[int(gone)]
        for k, ident in enumerate(change.added):
            pieces.setdefault(int(ident), []).append(change.positions[k].tobytes())
        snap = eng.snapshot(normals=False)
        steps += 1
        if not running and change.mark == snap.mark:
            break
        change = eng.changes(since=mark)
        mark = change
    held = sorted(p for v in pieces.values() for p in v)
    # The pieces equal the current cut's triangles (as positions, corner order as given).
    corners = snap.vertices[snap.faces]
    want = sorted(c.tobytes() for c in corners)
    assert len(held) == len(want)
    assert held == want
    assert steps >= 2


def test_snapshots_from_several_threads_and_isovalue_changes_from_another():
    vol = blob(96)
    eng = progiso.Engine(vol, 1.0, threads=2, uniform_cuts=False)
    errors = []
    seen = []
    stop = threading.Event()

    def reader():
        try:
            while not stop.is_set():
                s = eng.snapshot(normals=False)
                # Every cut is of one isovalue, and valid indices.
                if len(s.faces):
                    assert s.faces.max() < len(s.vertices)
                seen.append(s.isovalue)
        except Exception as e:  # noqa: BLE001
            errors.append(e)

    def changer():
        try:
            for w in (0.5, 1.5, 0.8, 1.2):
                time.sleep(0.01)
                eng.set_isovalue(w)
        except Exception as e:  # noqa: BLE001
            errors.append(e)

    threads = [threading.Thread(target=reader) for _ in range(3)] + [threading.Thread(target=changer)]
    eng.start(max_error=0.0)
    for t in threads:
        t.start()
    threads[-1].join()
    eng.wait()
    stop.set()
    for t in threads:
        t.join()
    assert not errors
    assert eng.isovalue == 1.2
    assert len(seen) > 10 and set(seen) <= {1.0, 0.5, 1.5, 0.8, 1.2}
    final = eng.snapshot()
    full = progiso.marching_cubes(vol, 1.2)
    assert triangle_set(final.vertices, final.faces) == triangle_set(full[0], full[1])


def test_ctrl_c_cancels_a_blocking_refine_cleanly():
    vol = blob(160)
    eng = progiso.Engine(vol, 1.0, threads=2, uniform_cuts=False)
    main = threading.get_ident()
    timer = threading.Timer(0.05, lambda: signal.pthread_kill(main, signal.SIGINT))
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        eng.refine(max_error=0.0)
        # A fast machine may finish first: refine again until the signal lands.
        while True:
            eng.set_isovalue(eng.isovalue + 0.01)
            eng.refine(max_error=0.0)
    timer.join()
    assert time.monotonic() - t0 < 30
    assert not eng.running
    snap = eng.snapshot()
    assert snap.triangle_count > 0
    assert eng.refine(max_triangles=1000)


def test_ctrl_c_stops_a_one_shot_extraction():
    vol = blob(200)
    main = threading.get_ident()
    timer = threading.Timer(0.02, lambda: signal.pthread_kill(main, signal.SIGINT))
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        for _ in range(1000):
            progiso.marching_cubes(vol, 1.0, threads=1)
    timer.join()


def test_deadline_runs_publish_uniform_cuts_coarse_to_fine():
    vol = blob(128)
    eng = progiso.Engine(vol, 1.0, threads=2)
    strides = [s.uniform_stride for s in eng.snapshots(interval=0.0005, deadline=5.0)]
    strides = [s for s in strides if s > 0]
    assert strides and strides == sorted(strides, reverse=True)
    assert strides[-1] == 1


def test_statistics_and_properties():
    eng = progiso.Engine(blob(32), 1.0, threads=1)
    assert eng.threads == 1 and not eng.running and eng.isovalue == 1.0
    eng.refine()
    st = eng.statistics()
    assert st["triangles"] > 0 and st["runs"] == 1
    assert eng.done
