"""Bad input: one clear Python exception, never a crash; the array outlives every use."""

import gc
import weakref

import numpy as np
import pytest

import progiso


def field(n=24, dtype=np.float32):
    z, y, x = np.mgrid[0:n, 0:n, 0:n]
    return np.sqrt((x - n / 2 + .3) ** 2 + (y - n / 2 + .2) ** 2 + (z - n / 2 + .1) ** 2).astype(dtype)


@pytest.mark.parametrize("bad,text", [
    (np.zeros((4, 4, 4), np.complex64), "real numbers"),
    (np.array([[["a"] * 3] * 3] * 3), "real numbers"),
    (np.zeros((4, 4, 4), object), "real numbers"),
])
def test_wrong_dtypes_are_value_errors(bad, text):
    with pytest.raises(ValueError, match=text):
        progiso.marching_cubes(bad, 0.5)
    with pytest.raises(ValueError, match=text):
        progiso.Engine(bad, 0.5)


def test_wrong_rank_empty_and_non_arrays_are_value_errors():
    for bad in (np.zeros((4, 4)), np.zeros((2, 2, 2, 2)), np.zeros((0, 4, 4))):
        with pytest.raises(ValueError):
            progiso.marching_cubes(bad, 0.5)
        with pytest.raises(ValueError):
            progiso.Engine(bad, 0.5)
    with pytest.raises(ValueError, match="3D numpy array"):
        progiso.marching_cubes([[[0, 1], [0, 1]], [[0, 1], [0, 1]]], 0.5)
    with pytest.raises(ValueError, match="expected a 3-D array"):
        progiso.Engine(np.zeros((4, 4)), 0.5)
    with pytest.raises(ValueError, match="dims must be at least"):
        progiso.Engine(np.zeros((4, 1, 4)), 0.5)


def test_nan_levels_and_samples_are_value_errors():
    f = field()
    with pytest.raises(ValueError, match="nan"):
        progiso.marching_cubes(f, float("nan"))
    with pytest.raises(ValueError, match="finite"):
        progiso.Engine(f, float("nan"))
    g = f.copy()
    g[3, 4, 5] = np.nan
    with pytest.raises(ValueError, match=r"expected finite samples, found nan .*x 5, y 4, z 3"):
        progiso.marching_cubes(g, 5.0)
    g[3, 4, 5] = np.inf
    with pytest.raises(ValueError, match="expected finite samples"):
        progiso.Engine(g, 5.0)


def test_bad_spacing_threads_and_goals_are_value_errors():
    f = field()
    with pytest.raises(ValueError, match="spacing"):
        progiso.marching_cubes(f, 5.0, spacing=(1, 0, 1))
    with pytest.raises(ValueError, match="spacing"):
        progiso.Engine(f, 5.0, spacing=(1, -1, 1))
    with pytest.raises(ValueError, match="threads"):
        progiso.marching_cubes(f, 5.0, threads=0)
    with pytest.raises(ValueError, match="threads"):
        progiso.Engine(f, 5.0, threads=0)
    eng = progiso.Engine(f, 5.0)
    with pytest.raises(ValueError, match="max_error"):
        eng.refine(max_error=-1)
    with pytest.raises(ValueError, match="goal"):
        eng.start("sometime")
    with pytest.raises(ValueError, match="finite"):
        eng.set_isovalue(float("inf"))


def test_the_array_outlives_the_callers_reference_while_the_engine_runs():
    f = field(48)
    expected = progiso.marching_cubes(f.copy(), 9.0)
    watch = weakref.ref(f)
    eng = progiso.Engine(f, 9.0, threads=2, uniform_cuts=False)
    eng.start()
    del f
    gc.collect()
    assert watch() is not None  # the engine holds it
    eng.wait()
    snap = eng.snapshot()
    from conftest import triangle_set
    assert triangle_set(snap.vertices, snap.faces) == triangle_set(expected[0], expected[1])
    eng.close()
    del eng, snap
    gc.collect()
    assert watch() is None  # and lets it go


def test_an_exception_raised_by_the_progress_callback_stops_the_run_and_is_raised():
    calls = []

    def progress(p):
        calls.append(p)
        raise RuntimeError("stop here")

    f = field(96)
    eng = progiso.Engine(f, 9.0, threads=2, progress=progress, uniform_cuts=False)
    with pytest.raises(RuntimeError, match="stop here"):
        # Raised while the run goes on (progress is delivered every 20 ms) or, for a run
        # shorter than that, once it ends.
        eng.refine()
    assert len(calls) == 1 and {"splits", "triangles", "next_error", "depth"} <= set(calls[0])
    assert not eng.running
    # The engine stays usable.
    assert eng.refine(max_triangles=100)


def test_mask_of_another_shape_and_a_bad_smooth_are_value_errors():
    f = field()
    with pytest.raises(ValueError, match="same shape"):
        progiso.marching_cubes(f, 5.0, mask=np.ones((3, 3, 3), bool))
    with pytest.raises(ValueError, match="smooth"):
        progiso.marching_cubes(f, 5.0, smooth="lots")
    with pytest.raises(ValueError, match="smoothing"):
        progiso.Engine(f, 5.0, smooth={"levels": 7})
