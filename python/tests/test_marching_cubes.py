"""progiso.marching_cubes against scikit-image's, the reference (Debian's python3-skimage)."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import progiso
from conftest import VOLUMES, area, load

skmeasure = pytest.importorskip("skimage.measure")


def sphere(shape=(40, 44, 48), centre=(19.3, 21.2, 23.1), dtype=np.float32):
    z, y, x = np.mgrid[0:shape[0], 0:shape[1], 0:shape[2]]
    return -np.sqrt((z - centre[0]) ** 2 + (y - centre[1]) ** 2 + (x - centre[2]) ** 2).astype(dtype)


def torus(shape=(48, 56, 64), R=16.0, r=6.0):
    z, y, x = np.mgrid[0:shape[0], 0:shape[1], 0:shape[2]].astype(np.float64)
    c = [(s - 1) / 2.0 for s in shape]
    q = np.sqrt((x - c[2]) ** 2 + (y - c[1]) ** 2) - R
    return np.sqrt(q ** 2 + (z - c[0]) ** 2), 4 * np.pi ** 2 * R * r, r


def test_sphere_area_is_within_one_percent_of_scikit_images_and_of_the_exact_area():
    f = sphere()
    v, fc, n, val = progiso.marching_cubes(f, -12.0)
    v2, f2, _, _ = skmeasure.marching_cubes(f, -12.0)
    a, a2 = area(v, fc), area(v2, f2)
    assert abs(a / a2 - 1) < 0.01
    assert abs(a / (4 * np.pi * 144) - 1) < 0.01


def test_torus_area_with_anisotropic_spacing_is_within_one_percent():
    f, exact, r = torus()
    spacing = (0.5, 1.0, 2.0)
    v, fc, _, _ = progiso.marching_cubes(f, r, spacing=spacing)
    v2, f2, _, _ = skmeasure.marching_cubes(f, r, spacing=spacing)
    assert abs(area(v, fc) / area(v2, f2) - 1) < 0.01
    # Spacing scales each axis: the same surface, unscaled, times the spacing.
    v1, f1, _, _ = progiso.marching_cubes(f, r)
    np.testing.assert_allclose(v, v1 * np.array(spacing, np.float32), rtol=1e-6)
    np.testing.assert_array_equal(fc, f1)


def test_dtypes_shapes_and_contiguity_are_scikit_images():
    f = sphere()
    out = progiso.marching_cubes(f, -10.0)
    ref = skmeasure.marching_cubes(f, -10.0)
    for mine, theirs in zip(out, ref):
        assert mine.dtype == theirs.dtype
        assert mine.shape[1:] == theirs.shape[1:]
        assert mine.flags["C_CONTIGUOUS"]
        assert mine.flags["OWNDATA"] or mine.base is not None
    v, fc, n, val = out
    assert len(v) == len(n) == len(val)
    assert fc.min() == 0 and fc.max() == len(v) - 1


def test_winding_and_normals_follow_gradient_direction_as_scikit_image():
    f = sphere()  # high inside
    c = np.array([19.3, 21.2, 23.1])
    for direction in ("descent", "ascent"):
        v, fc, n, _ = progiso.marching_cubes(f, -12.0, gradient_direction=direction)
        v2, f2, n2, _ = skmeasure.marching_cubes(f, -12.0, gradient_direction=direction)

        def outward_faces(v, fc):
            a, b, cc = v[fc[:, 0]], v[fc[:, 1]], v[fc[:, 2]]
            return np.mean(np.sum(np.cross(b - a, cc - a) * ((a + b + cc) / 3 - c), 1) > 0)

        assert outward_faces(v, fc) == outward_faces(v2, f2)
        assert outward_faces(v, fc) in (0.0, 1.0)
        # Normals: minus the gradient, outward for a field high inside, either direction.
        assert np.mean(np.sum(n * (v - c), 1) > 0) == 1.0
        assert np.mean(np.sum(n2 * (v2 - c), 1) > 0) == 1.0
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-5)


def test_vertices_on_grid_edges_match_scikit_images_with_their_normals_and_values():
    # Marching cubes and marching tetrahedra put the same vertex on every axis-aligned edge.
    rng = np.random.default_rng(7)
    f = sphere() + rng.normal(0, 0.05, (40, 44, 48)).astype(np.float32)
    v, _, n, val = progiso.marching_cubes(f, -12.0)
    v2, _, n2, val2 = skmeasure.marching_cubes(f, -12.0)
    d, i = cKDTree(v).query(v2)
    shared = d < 1e-5
    assert shared.mean() > 0.999  # every marching cubes vertex is one of ours
    # Ours: central differences (numpy.gradient) interpolated along the vertex's edge.
    inner = np.all((v2 > 1.5) & (v2 < np.array(f.shape) - 2.5), axis=1) & shared
    p = v2[inner].astype(np.float64)
    lo = np.floor(p + 1e-9).astype(int)
    t = p - lo
    axis = np.argmax(t > 1e-6, axis=1)
    hi = lo.copy()
    hi[np.arange(len(hi)), axis] += 1
    w = t[np.arange(len(t)), axis][:, None]
    grad = np.stack(np.gradient(f.astype(np.float64)), -1)
    g = (1 - w) * grad[tuple(lo.T)] + w * grad[tuple(hi.T)]
    expected = -g / np.linalg.norm(g, axis=1)[:, None]
    np.testing.assert_allclose(n[i[inner]], expected, atol=2e-4)
    np.testing.assert_allclose(val[i[inner]], np.abs(g).sum(axis=1), rtol=2e-4)
    # scikit-image's gradients are its own (Lewiner's), close to these.
    cos = np.sum(n[i[inner]] * n2[inner], axis=1)
    assert np.median(cos) > 0.999 and np.quantile(cos, 0.01) > 0.98
    rel = np.abs(val[i[inner]] / val2[inner] - 1)
    assert np.median(rel) < 0.1


@pytest.mark.parametrize("name", sorted(VOLUMES))
def test_every_shared_volume_matches_scikit_image_within_one_voxel(name, record_property):
    vol, spacing, isos = load(name)
    for iso in isos:
        v, fc, _, _ = progiso.marching_cubes(vol, iso, spacing=spacing)
        v2, f2, _, _ = skmeasure.marching_cubes(vol, iso, spacing=spacing)
        # Vertex to nearest vertex bounds vertex to surface from above; a voxel is the
        # largest spacing.
        voxel = max(spacing)
        d12 = cKDTree(v2).query(v)[0]
        d21 = cKDTree(v).query(v2)[0]
        assert np.mean(d12 <= voxel) >= 0.99, (name, iso, np.mean(d12 <= voxel))
        assert np.mean(d21 <= voxel) >= 0.99, (name, iso, np.mean(d21 <= voxel))
        ratio = area(v, fc) / area(v2, f2)
        record_property("area_ratio_%s_%s" % (name, iso), ratio)
        print("%s iso %s: area ratio %.4f, triangles %d vs %d, within a voxel %.4f / %.4f"
              % (name, iso, ratio, len(fc), len(f2), np.mean(d12 <= voxel),
                 np.mean(d21 <= voxel)))
        assert 0.9 < ratio < 1.3


def test_level_defaults_to_the_middle_of_the_range_and_is_checked():
    f = sphere()
    v, _, _, _ = progiso.marching_cubes(f)
    v2, _, _, _ = progiso.marching_cubes(f, 0.5 * (float(f.min()) + float(f.max())))
    np.testing.assert_array_equal(v, v2)
    for bad in (float(f.min()) - 1, float(f.max()) + 1):
        with pytest.raises(ValueError, match="within volume data range"):
            progiso.marching_cubes(f, bad)
        with pytest.raises(ValueError, match="within volume data range"):
            skmeasure.marching_cubes(f, bad)
    with pytest.raises(ValueError, match="nan"):
        progiso.marching_cubes(f, float("nan"))


def test_errors_are_scikit_images():
    f = sphere()
    cases = [
        ((np.zeros((3, 3)),), {}, "3D numpy array"),
        ((np.zeros((1, 3, 3)), 0.0), {}, "at least 2x2x2"),
        ((f, -10.0), {"spacing": (1, 1)}, "three floats"),
        ((f, -10.0), {"step_size": 0}, "at least one"),
        ((f, -10.0), {"gradient_direction": "up"}, "gradient_direction"),
        ((f, -10.0), {"method": "other"}, "method should be"),
        ((f, -10.0), {"mask": np.ones((2, 2, 2), bool)}, "same shape"),
    ]
    for args, kwargs, text in cases:
        with pytest.raises(ValueError, match=text):
            progiso.marching_cubes(*args, **kwargs)
        with pytest.raises(ValueError, match=text):
            skmeasure.marching_cubes(*args, **kwargs)
    flat = np.zeros((4, 4, 4), np.float32)
    flat[0, 0, 0] = 1
    with pytest.raises(RuntimeError, match="No surface"):
        progiso.marching_cubes(flat, 1.0)


def test_step_size_marches_every_step_size_th_sample():
    f = sphere()
    v, fc, _, _ = progiso.marching_cubes(f, -12.0, step_size=2)
    sub, sfc, _, _ = progiso.marching_cubes(np.ascontiguousarray(f[::2, ::2, ::2]), -12.0,
                                            spacing=(2, 2, 2))
    np.testing.assert_array_equal(v, sub)
    np.testing.assert_array_equal(fc, sfc)
    v2, f2, _, _ = skmeasure.marching_cubes(f, -12.0, step_size=2)
    assert abs(area(v, fc) / area(v2, f2) - 1) < 0.02
    assert len(fc) < len(progiso.marching_cubes(f, -12.0)[1]) / 3


def test_mask_keeps_the_cubes_scikit_image_marches():
    f = sphere()
    mask = np.zeros(f.shape, bool)
    mask[:20] = True
    v, fc, _, _ = progiso.marching_cubes(f, -12.0, mask=mask)
    v2, f2, _, _ = skmeasure.marching_cubes(f, -12.0, mask=mask)
    # Cubes whose upper corner has axis-0 index < 20: surface up to 19 on axis 0.
    assert v[:, 0].max() <= 19.0 + 1e-6 and v2[:, 0].max() <= 19.0 + 1e-6
    assert v[:, 0].max() > 18.0
    assert abs(area(v, fc) / area(v2, f2) - 1) < 0.02
    # Only used vertices remain.
    assert len(np.unique(fc)) == len(v)


def test_no_degenerate_triangles_where_scikit_image_makes_them():
    # Integer data with samples equal to the level: marching cubes collapses vertices onto
    # grid points; progiso keeps every vertex 1/4096 of an edge inside it.
    vol, _, _ = load("hipip")
    for fn in (skmeasure.marching_cubes, progiso.marching_cubes):
        v, fc, _, _ = fn(vol, 30)
        a, b, c = v[fc[:, 0]], v[fc[:, 1]], v[fc[:, 2]]
        zero = (np.linalg.norm(np.cross(b - a, c - a), axis=1) == 0).sum()
        if fn is progiso.marching_cubes:
            assert zero == 0
        else:
            assert zero > 0
    kept = progiso.marching_cubes(vol, 30, allow_degenerate=True)
    removed = progiso.marching_cubes(vol, 30, allow_degenerate=False)
    for x, y in zip(kept, removed):
        np.testing.assert_array_equal(x, y)


def test_goals_and_smoothing_options():
    f = sphere()
    full = progiso.marching_cubes(f, -12.0)
    coarse = progiso.marching_cubes(f, -12.0, max_error=0.5)
    budget = progiso.marching_cubes(f, -12.0, max_triangles=2000)
    assert len(coarse[1]) < len(full[1])
    assert len(budget[1]) <= 2000
    quick = progiso.marching_cubes(f, -12.0, deadline=0.0)
    assert 0 < len(quick[1]) <= len(full[1])
    smooth = progiso.marching_cubes(f, -12.0, smooth=1)
    assert len(smooth[1]) > 3 * len(full[1])
    assert abs(area(smooth[0], smooth[1]) / area(full[0], full[1]) - 1) < 0.01
    with pytest.raises(ValueError, match="at most one"):
        progiso.marching_cubes(f, -12.0, max_error=1, deadline=1)
    with pytest.raises(ValueError):
        progiso.marching_cubes(f, -12.0, smooth=9)
    with pytest.raises(ValueError, match="unknown key"):
        progiso.marching_cubes(f, -12.0, smooth={"level": 1})


def test_the_surface_is_the_same_for_every_thread_count():
    vol, spacing, _ = load("hipip")
    one = progiso.marching_cubes(vol, 128, threads=1)
    two = progiso.marching_cubes(vol, 128, threads=2)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)
