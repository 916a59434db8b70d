"""Choosing the Dr.Jit/Mitsuba backend.

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
    "MIN_LLVM",
    "RGB_VARIANTS",
    "THREADS_ENV",
    "VARIANTS",
    "VARIANT_ENV",
    "apply_threads",
    "bitmap_threads",
    "configure_llvm",
    "default_variant",
    "find_llvm",
    "gpu_available",
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


def set_threads(count) -> None:
    """Run Dr.Jit's CPU kernels on ``count`` threads (``--threads N``; Mitsuba's ``-t``).

    The count is kept in ``$SIEVE_MI_THREADS`` too, so processes started later (Ray workers of
    ``sort`` and ``sweep``) use it as well (:func:`apply_threads`).

    Parameters
    ----------
    count : int
        At least 1.

    Raises
    ------
    SieveError
        If ``count`` is not a whole number of at least 1.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise SieveError(f"--threads {count}: must be a whole number of at least 1")
    os.environ[THREADS_ENV] = str(count)
    apply_threads()


def apply_threads() -> int | None:
    """Apply ``$SIEVE_MI_THREADS`` (set by :func:`set_threads`) to Dr.Jit; return it (None: unset)."""
    text = os.environ.get(THREADS_ENV)
    if not text:
        return None
    try:
        count = int(text)
    except ValueError:
        raise SieveError(f"{THREADS_ENV}={text}: must be a whole number of at least 1") from None
    if count < 1:
        raise SieveError(f"{THREADS_ENV}={text}: must be a whole number of at least 1")
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
