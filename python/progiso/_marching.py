"""progiso.marching_cubes: scikit-image's marching_cubes call, answered by progiso."""

import numbers

import numpy as np

from . import _progiso


def _goal(deadline, max_error, max_triangles):
    given = [(k, v) for k, v in (("deadline", deadline), ("error", max_error),
                                 ("triangles", max_triangles)) if v is not None]
    if len(given) > 1:
        raise ValueError("give at most one of deadline, max_error and max_triangles, found "
                         + ", ".join(k for k, _ in given))
    if not given:
        return "full", 0.0
    kind, value = given[0]
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError("%s: expected a number, found %r" % (kind, value)) from None
    return kind, value


def marching_cubes(volume, level=None, *, spacing=(1., 1., 1.), gradient_direction='descent',
                   step_size=1, allow_degenerate=True, method='lewiner', mask=None,
                   threads=None, deadline=None, max_error=None, max_triangles=None,
                   smooth=None):
    """The isosurface of ``volume`` at ``level``, as ``skimage.measure.marching_cubes`` gives it:
    ``(verts, faces, normals, values)``.

    A drop-in replacement: the arguments and return values are scikit-image's, with the same
    meanings, dtypes (float32 vertices, normals and values; int32 faces) and errors (ValueError
    for a level outside the data range, a volume that is not 3-D or smaller than 2x2x2, a bad
    spacing, step_size, gradient_direction, method or mask; RuntimeError when no surface is
    found).

    Parameters beyond scikit-image's:

    threads : int, optional
        Worker threads (default: all cores). The surface is the same for every count.
    deadline : float, optional
        Seconds: return the finest surface made by then (uniform cuts of the hierarchy, coarse
        to fine; the coarsest is always made).
    max_error : float, optional
        Refine the hierarchy until no split left would move the surface by more than this
        (in the data's units of length before spacing): a coarser, adaptive surface.
    max_triangles : int, optional
        Refine, largest error first, as far as this many triangles allow.
    smooth : int or dict, optional
        Refine the field of the paper's 4-point subdivision rule instead of the data: an int
        is the number of levels below the data (1 to 3, each halving the spacing), a dict may
        give ``levels``, ``from_level`` (use the data on every 2**K-th sample only), ``alpha``
        and ``region`` ((lo0, lo1, lo2, hi0, hi1, hi2) in index units, axis order).

    How the output differs from scikit-image's, and why:

    - The surface is marching tetrahedra on six tetrahedra per cube (the finest cut of the
      bisection hierarchy), not marching cubes: every vertex on a grid edge is where linear
      interpolation puts it, as in marching cubes, but cubes are cut along diagonals too, so
      there are vertices on face and body diagonals, and about 1.5 to 2 times the triangles.
      The surface is topologically consistent everywhere (no ambiguous case to resolve) and
      closed inside the volume.
    - ``normals`` are minus the gradient in physical units (spacing applied), normalised:
      with a spacing other than (1, 1, 1) they are perpendicular to the scaled surface, where
      scikit-image's ignore the spacing.
    - ``values`` are scikit-image's measure, the L1 norm of the data's gradient (central
      differences, index units) at the vertex, interpolated there from the cube's corners
      (scikit-image averages the vertex's edge ends).
    - ``verts`` are float32 for every spacing (scikit-image returns float64 when the spacing is
      not (1, 1, 1)).
    - ``method`` is accepted ('lewiner', 'lorensen') and ignored: there is one method.
    - ``mask`` keeps the triangles of the cubes whose upper corner the mask marks, the cubes
      scikit-image marches.

    Memory: a C-contiguous array of uint8, int8, uint16, int16, uint32, int32, float32, float64
    or bool in native byte order is read in place, without a copy. Any other layout or dtype is
    copied once into one of those (64-bit integers to float64). ``step_size`` > 1 reads every
    step_size-th sample into a copy 1/step_size**3 the size. Floating-point samples must be
    finite. The output arrays own their memory (no further copy).

    Ctrl-C stops the extraction and raises KeyboardInterrupt.
    """
    if not isinstance(volume, np.ndarray) or volume.ndim != 3:
        raise ValueError('Input volume should be a 3D numpy array.')
    if volume.shape[0] < 2 or volume.shape[1] < 2 or volume.shape[2] < 2:
        raise ValueError("Input array must be at least 2x2x2.")
    if method not in ('lewiner', 'lorensen', '_lorensen'):
        raise ValueError("method should be one of 'lewiner', 'lorensen' or '_lorensen'.")
    if gradient_direction not in ('descent', 'ascent'):
        raise ValueError("Incorrect input %s in `gradient_direction`, see docstring."
                         % (gradient_direction,))
    if len(spacing) != 3:
        raise ValueError("`spacing` must consist of three floats.")
    spacing = tuple(float(s) for s in spacing)
    if not all(np.isfinite(s) and s > 0 for s in spacing):
        raise ValueError("`spacing` must be finite and positive, found %r" % (spacing,))
    step_size = int(step_size)
    if step_size < 1:
        raise ValueError('step_size must be at least one.')
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != volume.shape:
            raise ValueError('volume and mask must have the same shape.')
        if mask.dtype != np.bool_:
            mask = mask.astype(bool)
    if threads is not None and (not isinstance(threads, numbers.Integral) or threads < 1):
        raise ValueError("threads: expected a positive integer, found %r" % (threads,))
    goal, goal_value = _goal(deadline, max_error, max_triangles)
    if step_size > 1:
        volume = volume[::step_size, ::step_size, ::step_size]
        if mask is not None:
            mask = mask[::step_size, ::step_size, ::step_size]
        spacing = tuple(s * step_size for s in spacing)
        if min(volume.shape) < 2:
            raise ValueError("step_size %d leaves fewer than 2 samples along an axis"
                             % step_size)
    if volume.dtype.kind not in "biuf":
        raise ValueError("Input volume should hold real numbers, found dtype %s" % volume.dtype)
    if level is not None:
        level = float(level)
        if np.isnan(level):
            raise ValueError("Surface level must be a number, found nan.")
    # The level is checked against the data's range (or made from it) by _extract, from the
    # range found while the samples are checked: no pass of numpy's min() and max() besides.
    verts, faces, normals, values, info = _progiso._extract(
        volume, level, spacing, threads, goal, goal_value, smooth, mask,
        bool(allow_degenerate), gradient_direction == 'ascent')
    if len(verts) == 0:
        raise RuntimeError('No surface found at the given iso value.')
    return verts, faces, normals, values
