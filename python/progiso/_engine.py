"""progiso.Engine: the progressive engine from Python."""

import time

from . import _progiso
from ._marching import _goal


class Snapshot:
    """One published cut of the engine's surface, as arrays that own their memory.

    ``vertices`` (n, 3) float32 and ``normals`` (n, 3) float32 (None when not asked for) in
    axis order and physical units (index times spacing); ``faces`` (t, 3) int32, wound as
    ``marching_cubes`` winds them. ``isovalue``, ``generation`` (isovalue changes before it),
    ``splits`` (refinements in the cut), ``uniform_stride`` (s > 0: the uniform cut of every
    s-th sample, made by streaming passes; 1 the finest cut; 0: a cut of refinements), and
    ``mark``, which ``Engine.changes(since=...)`` takes.
    """

    __slots__ = ("vertices", "faces", "normals", "isovalue", "generation", "splits",
                 "uniform_stride", "mark", "time")

    def __init__(self, vertices, faces, normals, info, mark):
        self.vertices = vertices
        self.faces = faces
        self.normals = normals
        self.isovalue = info["isovalue"]
        self.generation = info["generation"]
        self.splits = info["splits"]
        self.uniform_stride = info["uniform_stride"]
        self.mark = mark
        self.time = time.monotonic()

    @property
    def triangle_count(self):
        return len(self.faces)

    def area(self):
        """The surface's area (physical units squared)."""
        import numpy as np
        v = self.vertices.astype(np.float64)
        f = self.faces
        cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        return 0.5 * float(np.sqrt((cross * cross).sum(axis=1)).sum())

    def __repr__(self):
        return ("Snapshot(isovalue=%g, triangles=%d, splits=%d, uniform_stride=%d)"
                % (self.isovalue, len(self.faces), self.splits, self.uniform_stride))


class Change:
    """What changed from an earlier cut to a later one (a renderer applies it instead of
    replacing the whole surface).

    ``rebuilt``: the change is the whole later cut (another isovalue, or no earlier cut):
    drop everything first. ``gone``: ids (uint64) of the triangles no longer in the cut.
    ``added``: one id per added piece; ``positions`` (k, 3, 3) float32, three corners per
    piece in axis order, and ``normals`` likewise (or None). ``hidden``: ids added that lie
    wholly outside the data box (no piece). ``mark``: where the later cut stands, for the next
    call.
    """

    __slots__ = ("rebuilt", "gone", "added", "hidden", "positions", "normals", "mark")

    def __init__(self, rebuilt, gone, added, hidden, positions, normals, mark):
        self.rebuilt = rebuilt
        self.gone = gone
        self.added = added
        self.hidden = hidden
        self.positions = positions
        self.normals = normals
        self.mark = mark

    def __repr__(self):
        return ("Change(rebuilt=%s, gone=%d, added=%d)"
                % (self.rebuilt, len(self.gone), len(self.added)))


def _goal_args(goal, deadline, max_error, max_triangles):
    if goal is not None:
        if deadline is not None or max_error is not None or max_triangles is not None:
            raise ValueError("give a goal or keywords, not both")
        if goal == "full":
            return "full", 0.0
        raise ValueError("goal: expected 'full' (or use deadline=, max_error=, "
                         "max_triangles=), found %r" % (goal,))
    return _goal(deadline, max_error, max_triangles)


class Engine:
    """The progressive isosurface engine on a 3-D numpy array.

    ``Engine(volume, level)`` publishes the coarsest surface of ``level`` at once (no pass over
    the samples for integer arrays; floating-point samples are checked for NaN first). Runs
    refine it in the background on ``threads`` workers (default: all cores):

    - ``start(...)`` returns at once; ``refine(...)`` waits (Ctrl-C cancels the run and raises
      KeyboardInterrupt). Goals: none (full resolution), ``deadline=`` seconds, ``max_error=``,
      ``max_triangles=``.
    - ``cancel()`` stops a run within one refinement per worker; what was published stays.
    - ``set_isovalue(w)`` from any thread: the new isovalue's surface is published at once and
      the interrupted goal resumes.
    - ``snapshot()`` from any thread, at any moment: the last published cut (``Snapshot``).
    - ``changes(since=snapshot)``: what changed since an earlier cut (``Change``).
    - ``snapshots(interval=0.05, until=None)``: iterate over newer cuts as they come.

    The array is read in place (C-contiguous uint8, int8, uint16, int16, uint32, int32, float32,
    float64 or bool in native byte order; anything else is copied once, ``copied`` says so), and
    the engine keeps a reference to it while it lives. Do not write to it meanwhile: the engine
    reads it while refining. ``progress(dict)``, if given, is called on the thread waiting in
    ``refine()``/``wait()`` (never on a worker), about every 20 ms while a run makes progress;
    what it raises stops the run and is raised there. Errors are ValueError with progiso's
    message.

    ``uniform_cuts`` (default True): full and deadline runs on a fresh isovalue publish uniform
    cuts made by streaming passes (what buys the most surface per millisecond); False refines
    split by split from the start.
    """

    def __init__(self, volume, level, *, threads=None, spacing=(1., 1., 1.), smooth=None,
                 uniform_cuts=True, progress=None, normals=True):
        if len(spacing) != 3:
            raise ValueError("`spacing` must consist of three floats.")
        level = float(level)
        self._normals = bool(normals)
        self._impl = _progiso._Engine(volume, level, tuple(float(s) for s in spacing), threads,
                                      smooth, bool(uniform_cuts), progress)

    # -- runs
    def start(self, goal=None, *, deadline=None, max_error=None, max_triangles=None):
        """Start refining towards the goal in the background (cancels a run in progress)."""
        self._impl.start(*_goal_args(goal, deadline, max_error, max_triangles))

    def refine(self, goal=None, *, deadline=None, max_error=None, max_triangles=None):
        """Refine towards the goal and wait; True when it was reached (False: cancelled, or the
        deadline came first). The GIL is released meanwhile."""
        return self._impl.refine(*_goal_args(goal, deadline, max_error, max_triangles))

    def wait(self):
        """Wait until no run is active (Ctrl-C cancels it)."""
        self._impl.wait()

    def cancel(self):
        """Stop the run; what was published stays."""
        self._impl.cancel()

    def set_isovalue(self, w):
        """Switch to isovalue w (any thread): its coarsest surface is published at once."""
        self._impl.set_isovalue(float(w))

    # -- readers
    def snapshot(self, normals=None):
        """The last published cut as arrays (``Snapshot``)."""
        n = self._normals if normals is None else bool(normals)
        return Snapshot(*self._impl.snapshot(n))

    def changes(self, since=None, normals=None):
        """What changed from the cut ``since`` (a Snapshot, a Change, or its ``mark``; None: no
        cut, so everything) to the current one."""
        mark = getattr(since, "mark", since)
        n = self._normals if normals is None else bool(normals)
        return Change(*self._impl.changes(mark, n))

    def snapshots(self, interval=0.05, until=None, goal=None, *, deadline=None, max_error=None,
                  max_triangles=None):
        """Yield newer cuts as refinement makes them, at most one every ``interval`` seconds.

        With a goal (or its keywords), starts that run first. Without ``until``, stops once no
        run is active and the last cut was yielded; with it, follows the engine for ``until``
        seconds whatever runs come and go (a viewer's loop, while other threads start runs or
        move the isovalue). The first cut is yielded at once.
        Ctrl-C (KeyboardInterrupt) while iterating cancels the run. Between cuts the GIL is
        free (time.sleep), so other threads run.
        """
        if goal is not None or deadline is not None or max_error is not None \
                or max_triangles is not None:
            self.start(goal, deadline=deadline, max_error=max_error,
                       max_triangles=max_triangles)
        interval = max(0.0, float(interval))
        stop_at = None if until is None else time.monotonic() + float(until)
        last = None
        try:
            while True:
                running = self._impl.running
                mark = self._impl.mark()
                if last is None or not (mark == last):
                    snap = self.snapshot()
                    last = snap.mark
                    yield snap
                elif not running and stop_at is None:
                    return
                self._impl.deliver_progress()
                now = time.monotonic()
                if stop_at is not None and now >= stop_at:
                    return
                pause = interval if stop_at is None else min(interval, stop_at - now)
                time.sleep(max(pause, 0.0))
        except KeyboardInterrupt:
            self._impl.cancel()
            raise

    # -- state
    @property
    def isovalue(self):
        return self._impl.isovalue

    @property
    def running(self):
        return self._impl.running

    @property
    def done(self):
        """True when the cut is at full resolution."""
        return self._impl.done

    @property
    def threads(self):
        return self._impl.threads

    @property
    def copied(self):
        """Whether the array had to be copied (its layout or dtype is not read in place)."""
        return self._impl.copied

    @property
    def array(self):
        """The array the engine reads (the caller's own, unless ``copied``)."""
        return self._impl.array

    def statistics(self):
        return self._impl.statistics()

    def close(self):
        """Stop the engine and release the array now (otherwise when it is collected)."""
        self._impl = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
