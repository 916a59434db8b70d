"""``figure.png`` and ``passage.gif`` rendered in a worker process while the save writes the rest.

One idea: the two Mitsuba pictures of a solve (:mod:`sieve_mi.outputs.figure`,
:mod:`sieve_mi.outputs.animation`) need nothing that the images, the plots and the page make, and
they cost most of a small solve's save (2.8 + 1.8 s of the default scene's 9.7 s on 2 cores,
2026-12-04). :func:`start` forks one worker (:func:`sieve_mi.workers.worker_pool`) that switches
Mitsuba to an RGB variant once, renders the GIF, then the figure, into the save's temporary
folder (in that order: the GIF's one-thread parts, about a third of it, run beside the save's
own work, and the figure's rendering, on every core, is what the save waits for last);
:meth:`Pictures.wait` collects what report.json records of them. Where a fork is unsafe
(a CUDA variant: its context does not survive a fork; a system without ``fork``) both are
rendered in this process, one after the other, as before. The pictures are the same either way:
the same scene, sampler seed and settings give the same pixels.

The command line forks that worker once it has read the scene and accepted ``--out``, before
it imports Dr.Jit (:func:`first`), so the worker's start (Dr.Jit, Mitsuba's RGB variant,
matplotlib for the figure's title, PIL and the pictures' modules: :func:`_rgb_fresh` and
:func:`_ready`) runs beside the command's own one-thread start (its remaining imports, Dr.Jit's
variant, the screen) instead of beside the search, whose pace main's Python thread sets while
Dr.Jit's threads keep the other core busy; :func:`start` then hands the pictures to it. Where
the command has imported Dr.Jit before (a solve run in a process that rendered already) or uses
a CUDA variant, :func:`ahead` forks it when the solve's ``screen`` stage ends, as before
2026-12-07. The command line
also hands the solver :meth:`_Ahead.prerender`, which the solver calls before its ``margins``
stage: the worker then renders the GIF and the figure while the margins are measured and the
rest of the save is written, into a folder of its own, and :func:`start` takes them over (the
same plate, so the same pictures). A solve from Python forks its worker in the save, as before.

Times: the worker's rendering overlaps the rest of the save, so ``figure_s`` and
``animation_s`` in report.json are the seconds the save *waited* for each (the part of its
wall time they account for: the stages still add up to ``total_s``); the seconds each took in
the worker are in :attr:`Pictures.rendered`.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import tempfile
import time
from typing import NamedTuple

__all__ = ["Pictures", "ahead", "built", "first", "render", "start"]

#: The worker forked ahead of the save (:func:`ahead`), while its block runs; else None.
_AHEAD = None


def render(tmp: str, figure_args: tuple | None, passage) -> dict:
    """Render ``passage.gif`` (with ``passage``), then ``figure.png`` (with ``figure_args``),
    into ``tmp``.

    The GIF comes first: a third of its time is one thread's (the scene's tracing, the frames'
    sRGB, palettes and file), which the save's own work fills beside it, while the figure's
    rendering, last, keeps both cores busy up to its last rows (see the module docstring).

    Parameters
    ----------
    tmp : str
        The save's temporary folder.
    figure_args : tuple or None
        ``(plate, passes, blocks, blocked, title)`` for
        :func:`sieve_mi.outputs.figure.render_figure`; None: no figure.
    passage : Passage or None
        The GIF's motion (:func:`sieve_mi.outputs.passage.build`); None: no GIF.

    Returns
    -------
    dict
        ``figure_end`` and ``animation_end`` (the ``time.perf_counter()`` at which each file was
        written, None without it), ``figure_s`` and ``animation_s`` (seconds each took),
        ``animation`` (what :func:`~sieve_mi.outputs.animation.write_gif` returns, or None) and
        ``peak_gb`` (this process's peak resident memory, GB).
    """
    from sieve_mi.backend import MemoryWatch

    out = {"figure_end": None, "animation_end": None, "figure_s": 0.0, "animation_s": 0.0,
           "animation": None}  # fmt: skip
    if passage is not None:
        from sieve_mi.outputs.animation import write_gif

        t0 = time.perf_counter()
        out["animation"] = write_gif(os.path.join(tmp, "passage.gif"), passage)
        out["animation_end"] = time.perf_counter()
        out["animation_s"] = out["animation_end"] - t0
    if figure_args is not None:
        from sieve_mi.outputs.figure import render_figure

        t0 = time.perf_counter()
        plate, passes, blocks, blocked, title = figure_args
        render_figure(os.path.join(tmp, "figure.png"), plate, passes, blocks, blocked, title=title)
        out["figure_end"] = time.perf_counter()
        out["figure_s"] = out["figure_end"] - t0
    watch = MemoryWatch()
    out["peak_gb"] = watch.peak
    watch.stop()
    return out


def _rgb_once() -> None:
    """The worker's first step: Dr.Jit's CPU threads brought back, then Mitsuba in an RGB
    variant for good (the worker renders only colour pictures, so
    :func:`sieve_mi.outputs.stage.rgb_variant` switches no more).

    A fork keeps only the forking thread: Dr.Jit's pool still counts the parent's workers, but
    none of them runs in the child, so every kernel would run on one thread. Raising the count
    by the missing workers starts that many new ones (Dr.Jit starts the difference), so the
    worker renders on as many threads as the parent had.
    """
    import drjit as dr
    import mitsuba as mi

    from sieve_mi.backend import select_rgb_variant

    wanted = dr.thread_count()
    running = len(os.listdir("/proc/self/task")) - 1  # threads beside this one (Linux)
    if running < wanted:
        dr.set_thread_count(2 * wanted - running)
    select_rgb_variant(mi, mi.variant())


def _rgb_fresh(variant: str, threads: int | None) -> None:
    """The first step of a worker forked before this process imported Dr.Jit (:func:`first`):
    Dr.Jit imported afresh (its own pool: every thread runs), on the command's thread count
    (``--threads``, else ``$SIEVE_MI_THREADS``: the parent checks and applies them as well,
    and says what is wrong with them), then Mitsuba in the RGB variant that :func:`_rgb_once`
    picks after ``variant`` (the solve's)."""
    from sieve_mi.backend import apply_threads, configure_llvm, select_rgb_variant, set_threads
    from sieve_mi.errors import SieveError

    configure_llvm()
    import mitsuba as mi

    with contextlib.suppress(SieveError):  # the parent stops with the same error
        if threads is not None:
            set_threads(threads)
        else:
            apply_threads()
    select_rgb_variant(mi, variant)


def _ready() -> None:
    """The early worker's first job (:func:`ahead`): the pictures' modules imported, so the
    save's job starts rendering at once; matplotlib's too, for the figure's title (imported
    at the title, it cost the save 0.3-0.5 s after the figure's rendering; here it runs
    beside the search, which leaves part of a core idle on 2 cores)."""
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401
    import PIL.Image  # noqa: F401

    import sieve_mi.outputs.animation  # noqa: F401
    import sieve_mi.outputs.figure  # noqa: F401


def _forkable(variant: str | None) -> bool:
    """Whether the pictures may be rendered in a forked worker: Linux, and not a CUDA variant."""
    return sys.platform.startswith("linux") and not str(variant or "").startswith("cuda")


class Pictures:
    """The figure and the GIF of one save, being rendered (see the module docstring).

    Made by :func:`start`; :meth:`wait` returns their record. Leaving the ``with`` block of
    :func:`start` by an exception stops the worker at once (nothing is kept of its files).

    Attributes
    ----------
    rendered : dict
        After :meth:`wait`: :func:`render`'s answer (the seconds each picture took).
    """

    def __init__(self, job: tuple, future=None, folder: str | None = None):
        self._job, self._future, self._folder, self.rendered = job, future, folder, {}

    def wait(self) -> dict:
        """Wait for both pictures; return the seconds the save waited for each.

        Returns
        -------
        dict
            ``animation_s`` and ``figure_s``: the caller's wall time from this call until the
            GIF, then the figure, was written (in this process: the time each took), and
            ``animation`` (:func:`~sieve_mi.outputs.animation.write_gif`'s record or None) and
            ``peak_gb`` (the rendering process's peak memory, GB).
        """
        t_wait = time.perf_counter()
        if self._future is None:
            self.rendered = render(*self._job)
            return {
                k: self.rendered[k] for k in ("figure_s", "animation_s", "animation", "peak_gb")
            }
        self.rendered = self._future.result()
        if self._folder is not None:  # rendered before the save began (:meth:`_Ahead.prerender`)
            for name in ("figure.png", "passage.gif"):
                if os.path.exists(os.path.join(self._folder, name)):
                    shutil.move(os.path.join(self._folder, name), os.path.join(self._job[0], name))
        waited = time.perf_counter() - t_wait
        # the picture written first accounts for the wait up to its end, the other for the rest
        first = "animation" if self.rendered.get("animation_end") is not None else "figure"
        end = self.rendered.get(f"{first}_end")
        first_s = 0.0 if end is None else min(max(end - t_wait, 0.0), waited)
        second = {"animation": "figure", "figure": "animation"}[first]
        return {
            f"{first}_s": first_s,
            f"{second}_s": waited - first_s,
            "animation": self.rendered["animation"],
            "peak_gb": self.rendered["peak_gb"],
        }


def start(tmp: str, figure_args: tuple | None, passage, variant: str | None):
    """A context manager yielding :class:`Pictures`: the figure and GIF rendering into ``tmp``.

    Parameters
    ----------
    tmp : str
        The save's temporary folder.
    figure_args, passage
        As :func:`render`; both None: nothing to render (no worker).
    variant : str or None
        The solve's Mitsuba variant: with a CUDA one (or without ``fork``) the pictures are
        rendered in this process by :meth:`Pictures.wait`.
    """
    from sieve_mi.workers import worker_pool

    job = (tmp, figure_args, passage)

    @contextlib.contextmanager
    def pictures():
        if (figure_args is None and passage is None) or not _forkable(variant):
            yield Pictures(job)
            return
        early = _AHEAD.take() if _AHEAD is not None else None
        if early is not None:  # forked ahead (:func:`ahead`): stopped at once on an exception
            wanted = (figure_args is not None, passage is not None)
            folder, future = _AHEAD.prerendered(wanted)
            try:
                yield Pictures(job, future or early.submit(render, *job), folder)
            except BaseException:
                _AHEAD.stop()
                raise
            return
        with worker_pool(1, initializer=_rgb_once, what="figure and GIF rendering") as pool:
            yield Pictures(job, pool.submit(render, *job))

    return pictures()


def built(result) -> tuple | None:
    """The plate meshes that the worker forked ahead rendered ``result``'s pictures from
    (:meth:`_Ahead.built`), for the save to write instead of building them again; else None."""
    return _AHEAD.built(result) if _AHEAD is not None else None


class _Early(NamedTuple):
    """What :meth:`_Ahead.prerender` started: the pictures rendered before the save.

    Attributes
    ----------
    folder : str
        The folder of their own the worker renders them into (removed once the worker stops).
    wanted : tuple of bool
        ``(figure, gif)``: which of figure.png and passage.gif were asked for; the save takes
        them over only where it wants the same (:meth:`_Ahead.prerendered`).
    future : concurrent.futures.Future or None
        The worker's :func:`render` job; None where building the plate failed (the save
        renders them itself).
    """

    folder: str
    wanted: tuple
    future: object = None


class _Ahead:
    """The worker of :func:`ahead`: forked by :meth:`fork`, taken by :func:`start`."""

    def __init__(self, stack):
        self._stack, self._pool, self._early, self._built = stack, None, None, None

    def fork(self) -> None:
        """Fork the worker now (once; not with a CUDA variant or without ``fork``). Where the
        fork fails (an ``OSError``: no memory, too many processes) the save forks its own."""
        import drjit as dr
        import mitsuba as mi

        if self._pool is not None or not _forkable(mi.variant()):
            return
        dr.sync_thread()  # no kernel of this thread runs while the process is copied
        self._start(_rgb_once)

    def fork_fresh(self, variant: str, threads: int | None) -> None:
        """Fork the worker now, before this process imports Dr.Jit (:func:`first`): it imports
        Dr.Jit, Mitsuba and the pictures' modules itself (:func:`_rgb_fresh`, :func:`_ready`).
        Where the fork fails the save forks its own, as in :meth:`fork`."""
        self._start(_rgb_fresh, (variant, threads))

    def _start(self, initializer, initargs: tuple = ()) -> None:
        """The worker's pool, started now with ``initializer(*initargs)`` and :func:`_ready` as
        its first job (the process starts at once); nothing where the fork fails."""
        from sieve_mi.workers import worker_pool

        self._stack.callback(self._forget)  # after the worker stops (callbacks run last first)
        try:
            pool = self._stack.enter_context(
                worker_pool(
                    1, initializer=initializer, initargs=initargs, what="figure and GIF rendering"
                )
            )
            pool.submit(_ready)  # the process starts now
        except OSError:
            self._stack.close()
            return
        self._pool = pool

    def take(self):
        """The forked worker's pool (None where none was forked)."""
        return self._pool

    def prerender(self, result, figure: bool, animation: bool) -> None:
        """Start ``result``'s figure (with ``figure``) and GIF (with ``animation``) in the worker
        now, into a folder of their own, before the save (the solver calls this before its
        ``margins`` stage, which the pictures do not show: 0.4 s of the default scene that the
        worker renders beside). The plate is built as the save builds it
        (:func:`~sieve_mi.outputs.fabrication.plate_files`), so the pictures are the save's;
        :func:`start` takes them over (:meth:`prerendered`). Nothing happens without a forked
        worker; where building the plate fails, the save builds it again and says why.

        Parameters
        ----------
        result : sieve_mi.game.result.Result
            The game's result without its margins (:func:`sieve_mi.game.solver.solve`'s
            ``early``).
        figure, animation : bool
            Whether the save writes figure.png and passage.gif.
        """
        from sieve_mi.outputs.fabrication import figure_args, plate_meshes
        from sieve_mi.outputs.passage import build

        if self._pool is None or self._early is not None or not (figure or animation):
            return
        folder = tempfile.mkdtemp(prefix=".sieve-mi-pictures-")
        self._early = _Early(folder, (figure, animation))
        try:
            built = plate_meshes(result)
            meshes = built[3]
            job = (folder, figure_args(result, meshes) if figure else None,
                   build(result, meshes[0]) if animation else None)  # fmt: skip
        except Exception:  # noqa: BLE001 - the save builds the plate again and reports it
            return
        self._early = self._early._replace(future=self._pool.submit(render, *job))
        self._built = (result.outline, getattr(result, "sheet", None), built)

    def built(self, result) -> tuple | None:
        """:func:`~sieve_mi.outputs.fabrication.plate_meshes`' answer that :meth:`prerender`
        made, where ``result`` has the same hole and sheet (the save's result: the same game
        with its margins), else None."""
        got = self._built
        if (
            got is None
            or got[0] is not result.outline
            or got[1] is not getattr(result, "sheet", None)
        ):
            return None
        return got[2]

    def prerendered(self, wanted: tuple) -> tuple:
        """``(folder, future)`` of :meth:`prerender`'s pictures where they are the ones
        ``wanted`` (``(figure, gif)``: the save's), else ``(None, None)``."""
        early = self._early
        if early is None or early.future is None or early.wanted != wanted:
            return None, None
        return early.folder, early.future

    def _forget(self) -> None:
        """Remove :meth:`prerender`'s folder (once the worker has stopped)."""
        if self._early is not None:
            shutil.rmtree(self._early.folder, ignore_errors=True)
            self._early = None

    def stop(self) -> None:
        """Stop the worker at once (the save was left by an exception)."""
        self._pool = None
        self._stack.__exit__(*sys.exc_info())

    def drop(self) -> None:
        """End the worker where the block it was forked for ends: at once where it rendered
        nothing (the command ended before its verdict), rather than wait for its imports; else
        once its jobs are done (the save waited for them)."""
        from sieve_mi.workers import stop_workers

        if self._pool is not None and self._early is None:
            stop_workers(self._pool)
        self._pool = None
        self._stack.close()


@contextlib.contextmanager
def _ending(early: _Ahead):
    """Yield ``early``; then end its worker: at once on an exception (:meth:`_Ahead.stop`), else
    by :meth:`_Ahead.drop`."""
    try:
        yield early
    except BaseException:
        early.stop()
        raise
    early.drop()


@contextlib.contextmanager
def ahead(run, stage: str = "screen"):
    """A context manager in which the pictures' worker is forked when ``run``'s stage ``stage``
    ends (:meth:`sieve_mi.telemetry.Run.after`), for the save in the block to use.

    Parameters
    ----------
    run : sieve_mi.telemetry.Run
        The solve's record.
    stage : str
        The stage after which the worker is forked: the Dr.Jit variant is set by then (the
        worker switches to its RGB sibling) and the search, the longest stage, follows.
    """
    global _AHEAD
    if _AHEAD is not None:  # forked at the command's start (:func:`first`): ends with the block
        with _ending(_AHEAD) as early:
            yield early
        return
    with contextlib.ExitStack() as stack:
        _AHEAD = _Ahead(stack)
        run.after(stage, _AHEAD.fork)
        try:
            yield _AHEAD
        finally:
            _AHEAD = None


@contextlib.contextmanager
def first(variant: str | None, threads: int | None = None):
    """A context manager in which the pictures' worker is forked at once, for :func:`ahead`
    (and the save) in the block to use: ``sieve-mi solve`` with pictures enters it once the
    scene and ``--out`` are accepted (a refused run imports no Dr.Jit and makes none of its
    files, such as its kernel cache in the home folder), so the worker's imports (Dr.Jit,
    Mitsuba's RGB variant, matplotlib, PIL and the pictures' modules) run beside the command's
    own start, one thread's work (its imports, Dr.Jit's variant, the screen), instead of beside
    the search, which keeps both cores busy.

    Nothing is forked where this process has imported Dr.Jit already (a fork would copy its
    running pool: a solve run in a process that rendered before, such as a test's) or with a
    CUDA ``variant`` (:func:`_forkable`): :func:`ahead` forks then, as before.

    Parameters
    ----------
    variant : str or None
        The solve's variant (``--variant``; None: :func:`sieve_mi.backend.default_variant`).
    threads : int, optional
        ``--threads``: Dr.Jit's thread count in the worker (default: ``$SIEVE_MI_THREADS``,
        else one per core).
    """
    global _AHEAD
    from sieve_mi.backend import default_variant

    variant = variant or default_variant()
    if _AHEAD is not None or "drjit" in sys.modules or not _forkable(variant):
        yield None
        return
    with contextlib.ExitStack() as stack:
        _AHEAD = _Ahead(stack)
        _AHEAD.fork_fresh(variant, threads)
        try:
            with _ending(_AHEAD) as early:
                yield early
        finally:
            _AHEAD = None
