"""Choosing the Dr.Jit/Mitsuba backend, and the process's share of the machine (threads, memory).

Dr.Jit 1.5's LLVM backend needs libLLVM >= 17 (with 14-16 every kernel dies with
``Cannot select: ... fminimum``). :func:`configure_llvm` finds a suitable library and sets
``DRJIT_LIBLLVM_PATH`` before Dr.Jit is imported; :func:`use_variant` selects the Mitsuba variant
and turns a missing backend into a one-line :class:`~sieve_mi.errors.SieveError`.
"""

from __future__ import annotations

import contextlib
import glob
import os
import re
import sys

from sieve_mi.errors import SieveError

__all__ = [
    "BYTES_PER_PAIR",
    "CPU_MEMORY_CAP_GB",
    "MEMORY_SHARE",
    "MIN_LLVM",
    "MemoryWatch",
    "RGB_VARIANTS",
    "THREADS_ENV",
    "VARIANTS",
    "VARIANT_ENV",
    "ALIGNMENT",
    "aligned",
    "apply_threads",
    "available_memory",
    "bitmap_threads",
    "configure_llvm",
    "default_variant",
    "ensure_variant",
    "find_llvm",
    "gpu_available",
    "max_threads",
    "pair_budget",
    "process_age",
    "release_cached_memory",
    "select_rgb_variant",
    "set_threads",
    "use_variant",
]

#: Variants sieve-mi supports: CPU (LLVM) and GPU (CUDA), both monochrome with autodiff.
VARIANTS = ("llvm_ad_mono", "cuda_ad_mono")
MIN_LLVM = 17
#: Environment variable that changes the default variant (e.g. ``SIEVE_MI_VARIANT=cuda_ad_mono``).
VARIANT_ENV = "SIEVE_MI_VARIANT"
#: Environment variable holding ``--threads N`` for every process of a run (Ray workers too).
THREADS_ENV = "SIEVE_MI_THREADS"

_PATTERNS = (
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib/*-linux-gnu/libLLVM-*.so*",
    "/usr/lib/*-linux-gnu/libLLVM.so.*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm*/lib/libLLVM.dylib",
    "/usr/local/opt/llvm*/lib/libLLVM.dylib",
)


def _llvm_major(path: str) -> int | None:
    """Major LLVM version encoded in a library path, or None if it cannot be told."""
    m = re.search(r"llvm[-@]?(\d+)", path, re.IGNORECASE) or re.search(
        r"libLLVM[-.]?(?:so\.)?(\d+)", path
    )
    return int(m.group(1)) if m else None


def find_llvm() -> str | None:
    """Path of the newest libLLVM with major version >= 17 on this machine, or None.

    Returns
    -------
    str or None
        An existing shared library path.
    """
    best: tuple[int, str] | None = None
    for pattern in _PATTERNS:
        for path in glob.glob(pattern):
            major = _llvm_major(path)
            if major is not None and major >= MIN_LLVM and (best is None or major > best[0]):
                best = (major, path)
    return best[1] if best else None


def configure_llvm() -> str | None:
    """Point Dr.Jit at a usable libLLVM unless the user already chose one.

    Must run before ``drjit`` is imported; has no effect afterwards.

    Returns
    -------
    str or None
        The library Dr.Jit will use, or None if none was found.
    """
    chosen = os.environ.get("DRJIT_LIBLLVM_PATH")
    if chosen and os.path.exists(chosen):
        return chosen
    found = find_llvm()
    if found and "drjit" not in sys.modules:
        os.environ["DRJIT_LIBLLVM_PATH"] = found
    return found


def default_variant() -> str:
    """The variant used when none is named: ``$SIEVE_MI_VARIANT`` if set, else ``"llvm_ad_mono"`` (CPU)."""
    return os.environ.get(VARIANT_ENV) or "llvm_ad_mono"


def use_variant(variant: str | None = None):
    """Select a Mitsuba variant and return the ``mitsuba`` module.

    Parameters
    ----------
    variant : str, optional
        ``"llvm_ad_mono"`` (CPU) or ``"cuda_ad_mono"`` (NVIDIA GPU); default :func:`default_variant`.

    Raises
    ------
    SieveError
        If the variant is unknown or its backend is not available on this machine.
    """
    if variant is None:
        variant = default_variant()
        if variant not in VARIANTS:
            raise SieveError(
                f"{VARIANT_ENV}={variant}: not a supported variant; use one of: {', '.join(VARIANTS)}"
            )
    if variant not in VARIANTS:
        raise SieveError(f"variant '{variant}' is not supported; use one of: {', '.join(VARIANTS)}")
    if variant.startswith("llvm") and configure_llvm() is None:
        raise SieveError(
            "no libLLVM >= 17 found for Dr.Jit's CPU backend: run 'apt-get install libllvm19' "
            "(or 'make setup'), or set DRJIT_LIBLLVM_PATH to a libLLVM 17+ library"
        )
    import drjit as dr
    import mitsuba as mi

    if variant.startswith("cuda") and not dr.has_backend(dr.JitBackend.CUDA):
        raise SieveError(
            "variant 'cuda_ad_mono' needs an NVIDIA GPU with a CUDA driver; none was found (use --variant llvm_ad_mono)"
        )
    if variant.startswith("llvm") and not dr.has_backend(dr.JitBackend.LLVM):
        raise SieveError(
            "Dr.Jit could not load libLLVM; set DRJIT_LIBLLVM_PATH to a libLLVM 17+ library (e.g. Debian's libllvm19)"
        )
    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


def ensure_variant():
    """The ``mitsuba`` module with a variant selected: the one in effect (a caller's
    :func:`use_variant`, ``--variant``), else :func:`default_variant` (``$SIEVE_MI_VARIANT`` or
    ``llvm_ad_mono``). For entry points such as :func:`sieve_mi.check` that render but leave the
    choice of variant to their caller.

    Raises
    ------
    SieveError
        As :func:`use_variant`.
    """
    configure_llvm()
    import mitsuba as mi

    return mi if mi.variant() else use_variant(None)


def gpu_available() -> bool:
    """Whether Dr.Jit can use a CUDA device here."""
    import drjit as dr

    return bool(dr.has_backend(dr.JitBackend.CUDA))


#: RGB variants to try, in order (``cuda_ad_rgb`` moves to the front when a CUDA variant is active).
RGB_VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb", "scalar_rgb")


def select_rgb_variant(mi, before: str | None) -> str:
    """Switch Mitsuba to the first usable RGB variant (for colour pictures); return the one chosen.

    The current backend's RGB variant comes first (``cuda_ad_rgb`` while a CUDA variant is
    active); where none can be used, the current variant ``before`` is kept (or, with none,
    ``llvm_ad_mono``). The caller restores ``before`` when done.
    """
    import drjit as dr

    backends = {"llvm": dr.JitBackend.LLVM, "cuda": dr.JitBackend.CUDA}
    order = list(RGB_VARIANTS)
    if before and before.startswith("cuda") and "cuda_ad_rgb" in order:  # stay on the GPU
        order.insert(0, order.pop(order.index("cuda_ad_rgb")))
    available = set(mi.variants())
    for v in order:
        kind = v.split("_")[0]
        if v not in available or (kind in backends and not dr.has_backend(backends[kind])):
            continue
        try:
            mi.set_variant(v)
            return v
        except Exception:  # noqa: BLE001 - a variant that fails to load: try the next one
            continue
    if before is None:
        return use_variant("llvm_ad_mono").variant()
    mi.set_variant(before)
    return before


def max_threads() -> int:
    """The most CPU threads sieve-mi gives Dr.Jit: this machine's cores times four.

    More threads than that only slow the kernels down, and a count in the millions makes the
    thread pool spend minutes creating threads (during which the process cannot stop).

    Examples
    --------
    >>> max_threads() == 4 * (os.cpu_count() or 1)
    True
    """
    return 4 * (os.cpu_count() or 1)


def _thread_count(value, say: str) -> int:
    """``value`` as a thread count in [1, :func:`max_threads`]; ``say`` names it in the error."""
    top = max_threads()
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
        raise SieveError(
            f"{say}: must be a whole number from 1 to {top} (four per core on this machine's "
            f"{os.cpu_count() or 1} cores)"
        )
    return value


def set_threads(count) -> None:
    """Run Dr.Jit's CPU kernels on ``count`` threads (``--threads N``; Mitsuba's ``-t``).

    The count is kept in ``$SIEVE_MI_THREADS`` too, so processes started later (Ray workers of
    ``sort`` and ``sweep``) use it as well (:func:`apply_threads`).

    Parameters
    ----------
    count : int
        From 1 to :func:`max_threads`.

    Raises
    ------
    SieveError
        If ``count`` is not a whole number in that range.
    """
    count = _thread_count(count, f"--threads {str(count)[:40]}")
    os.environ[THREADS_ENV] = str(count)
    apply_threads()


def apply_threads() -> int | None:
    """Apply ``$SIEVE_MI_THREADS`` (set by :func:`set_threads`) to Dr.Jit; return it (None: unset).

    Raises
    ------
    SieveError
        If the variable is not a whole number from 1 to :func:`max_threads`.
    """
    text = os.environ.get(THREADS_ENV)
    if not text:
        return None
    digits = text.strip()
    count = int(digits) if digits.isdigit() and len(digits) <= 18 else None
    count = _thread_count(count, f"{THREADS_ENV}={text[:40]}")
    configure_llvm()
    import drjit as dr

    dr.set_thread_count(count)
    return count


@contextlib.contextmanager
def bitmap_threads():
    """Give Dr.Jit's thread pool at least two threads inside the block.

    Mitsuba 3.9 reads and writes OpenEXR files (``mi.Bitmap``) on Dr.Jit's pool, and with one
    thread (``--threads 1``) that never returns; the count is restored afterwards.
    """
    import drjit as dr

    before = dr.thread_count()
    if before < 2:
        dr.set_thread_count(2)
    try:
        yield
    finally:
        if before < 2:
            dr.set_thread_count(before)


def release_cached_memory() -> None:
    """Give Dr.Jit's cached allocations back to the system, on the CPU only.

    Dr.Jit keeps freed arrays in a cache for reuse, so after one attack of player B the process
    holds that attack's peak whether it is used again or not: on cow-bunny 0.5 GB of the 0.95 GB
    peak was this cache (benchmarks/notes/performance-history.md, "Memory"). Called between attacks; on a GPU the
    cache is kept (allocating device memory synchronises, and the device has the room).
    """
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant() or ""
    if variant.startswith("llvm"):
        dr.flush_malloc_cache()


def _resident_gb() -> float | None:
    """The process's resident memory now, GB (None where /proc is not there)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**30
    except (OSError, ValueError, IndexError):
        return None


def _peak_gb() -> float:
    """The process's peak resident memory so far (``getrusage``), GB."""
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**30 if sys.platform == "darwin" else peak / 2**20


def process_age() -> float | None:
    """Seconds since this process started (Python's start-up and imports included), or None
    where the system does not say (it is read from Linux's ``/proc``, to 1/100 s).

    Examples
    --------
    >>> age = process_age()
    >>> age is None or age >= 0.0
    True
    """
    try:
        with open("/proc/self/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        with open("/proc/uptime") as fh:
            uptime = float(fh.read().split()[0])
        # field 22 of stat (the 20th after the command's closing bracket): start, clock ticks
        return max(0.0, uptime - int(fields[19]) / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None


class MemoryWatch:
    """Peak resident memory of each stage of a run, GB.

    A daemon thread samples the resident set every ``interval`` seconds while the watch runs.
    A stage's peak is exact where the process's peak (``getrusage``) rose during the stage,
    since the new peak was then reached inside it; otherwise it is the largest sample (a spike
    shorter than the interval can be missed). Nothing is reset, so ``getrusage`` and external
    tools still see the process's true peak.

    Parameters
    ----------
    interval : float
        Seconds between samples.

    Examples
    --------
    >>> watch = MemoryWatch()
    >>> data = bytearray(50 * 2**20)  # 50 MB touched in this stage
    >>> watch.mark("build") >= 0.05
    True
    >>> watch.stop()
    """

    def __init__(self, interval: float = 0.01):
        import threading

        #: Stage name -> peak GB, in the order marked.
        self.peaks: dict[str, float] = {}
        self.interval = float(interval)
        self._lock = threading.Lock()
        self._process_peak = _peak_gb()
        self._max = _resident_gb() or 0.0
        self._thread = None
        self.start()

    def start(self) -> None:
        """(Re)start sampling; a stage counts from the last mark or from here."""
        import threading

        if self._thread is not None:
            return
        self._running = True
        self._thread = threading.Thread(target=self._sample, name="sieve-mi-memory", daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        import time

        while self._running:
            now = _resident_gb()
            if now is None:
                return
            with self._lock:
                self._max = max(self._max, now)
            time.sleep(self.interval)

    def mark(self, stage: str) -> float:
        """End ``stage`` here: record and return its peak, GB; the next stage starts now."""
        now = _resident_gb() or 0.0
        peak = _peak_gb()
        with self._lock:
            sampled, self._max = max(self._max, now), now
        rose, self._process_peak = peak > self._process_peak, max(peak, self._process_peak)
        self.peaks[stage] = round(peak if rose else sampled, 4)
        return self.peaks[stage]

    def stop(self) -> None:
        """Stop sampling (:meth:`start` resumes)."""
        self._running = False
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    @property
    def peak(self) -> float:
        """The process's peak resident memory so far, GB."""
        return round(max(_peak_gb(), *self.peaks.values(), 0.0), 4)


# Player B's memory budget: how many (pose, segment) pairs one descent may bind at once.

#: Memory one (pose, segment) pair of a descent holds, bytes: 32 measured on the CPU at 5M pairs
#: (traced or frozen, benchmarks/notes/performance-history.md), doubled for the AD graph, buffers and allocator slack.
BYTES_PER_PAIR = 64
#: Share of the machine's available memory player B's descents use by default (``[solver] memory
#: = 0``) ...
MEMORY_SHARE = 0.25
#: ... at most this many GB on the CPU: chunks of 4M pairs keep both cores busy, and a larger
#: budget only raises the peak (cow-bunny's verdict, one run: 0.125 / 0.25 / 0.5 GB / a quarter
#: of 23 GB gave peaks of 0.94 / 1.05 / 1.15 / 1.73 GB in the same time, benchmarks/notes/performance-history.md).
#: Not on a GPU, where fewer, larger launches pay.
CPU_MEMORY_CAP_GB = 0.25


def available_memory() -> int:
    """Bytes of memory available to new allocations (Linux's MemAvailable; else physical memory)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 8 << 30


def _on_gpu() -> bool:
    """Whether the active Mitsuba variant runs on CUDA."""
    import mitsuba as mi

    return bool((mi.variant() or "").startswith("cuda"))


def pair_budget(memory_gb: float = 0.0, *, cap: bool = True) -> int:
    """(pose, segment) pairs one descent may bind at once, for a memory budget in GB.

    ``0`` means :data:`MEMORY_SHARE` of :func:`available_memory`, as measured now, and with
    ``cap`` at most :data:`CPU_MEMORY_CAP_GB` unless a CUDA variant is active (the cap sizes
    chunks; the uncapped share decides whether a scene fits at all).
    """
    budget = memory_gb * 2**30 if memory_gb > 0 else MEMORY_SHARE * available_memory()
    if cap and memory_gb <= 0 and not _on_gpu():
        budget = min(budget, CPU_MEMORY_CAP_GB * 2**30)
    return max(1, int(budget // BYTES_PER_PAIR))


#: The alignment, bytes, that Dr.Jit's LLVM kernels assume of memory they load as packets.
ALIGNMENT = 64


def aligned(values, dtype):
    """``values`` as a C-contiguous NumPy array of ``dtype`` that starts on a 64-byte boundary.

    Dr.Jit's CPU backend reads a NumPy array in place (``mi.Float(a)`` copies nothing), and a
    kernel that reads one is compiled for the array's alignment: one that starts on a 64-byte
    boundary only by chance (NumPy's small arrays: one time in four) gives its kernels another
    source, which the kernel cache has not seen when several such inputs meet (one descent's
    seven pose columns: 2^7 sources). On 2 cores the authors' arch compiled 8-15 such kernels
    afresh in every solve, 20-25 ms each (2026-12-07). Arrays made with this helper always read
    as aligned; the values are the same.

    Parameters
    ----------
    values : array_like
    dtype : numpy dtype

    Returns
    -------
    ndarray
        ``values`` itself where it already is such an array, else an aligned copy (same shape).
    """
    import numpy as np

    a = np.asarray(values, dtype=dtype)
    if a.flags.c_contiguous and a.ctypes.data % ALIGNMENT == 0:
        return a
    size = max(a.size, 1)
    buf = np.empty(size + ALIGNMENT // a.itemsize, dtype=a.dtype)
    skip = (-buf.ctypes.data % ALIGNMENT) // a.itemsize
    out = buf[skip : skip + a.size].reshape(a.shape)
    out[...] = a
    return out
