"""Safe output folders: sieve-mi never deletes what it did not write.

Every command that writes a folder (``solve``, ``check --out``) goes through :func:`writing`:

* The destination is checked first (:func:`validate`). It may be missing, an empty folder, or
  an earlier sieve-mi output: a folder with the marker file ``.sieve-mi``, a ``report.json`` and
  nothing that the marker does not list. Anything else (a file, a folder of the user's files,
  the working directory, the home folder, a filesystem root, a folder holding an input) is
  refused with one :class:`~sieve_mi.errors.SieveError` line, and nothing is touched.
* The outputs are written into a temporary folder ``.sieve-mi-tmp-<pid>-<host>-<random>``
  beside the destination. At the end the marker is written, the destination is checked again,
  and the new folder is swapped in atomically (``renameat2(RENAME_EXCHANGE)`` on Linux; else
  rename the old aside, rename the new in, restore the old on failure); the old one is removed
  last. SIGINT, SIGTERM and SIGHUP are held back during the swap and the clean-up.
* Any exception, KeyboardInterrupt included, removes the temporary folder (and the parent
  folders the run created, if they are empty), unless the writer salvages an interrupted
  folder (``salvage``: a solve stopped after its verdict keeps report.json and the plate,
  and its report names the missing files). Temporary folders
  of runs that were killed outright (their pid is gone) are removed by the next run that writes
  into the same parent folder.

A command that adds files to an earlier output (``shake DIR``) goes through :func:`add_files`: the
folder must carry the marker and hold nothing the marker does not list (:func:`check_addition`,
run before the work too); each file is written beside its name and renamed over it, and the
marker lists it.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import os
import secrets
import shutil
import socket
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator

from sieve_mi.errors import SieveError, deferred_signals, raise_if_signalled

__all__ = [
    "MARKER",
    "TMP_PREFIX",
    "add_files",
    "check_addition",
    "deferred_signals",
    "is_replaceable",
    "read_marker",
    "remove_stale",
    "stale_additions",
    "swap_in",
    "validate",
    "write_marker",
    "writing",
]

MARKER = ".sieve-mi"
"""Name of the marker file in every sieve-mi output folder."""

TMP_PREFIX = ".sieve-mi-tmp-"
"""Prefix of the temporary folders written beside a destination."""


# ------------------------------------------------------------------------------------------------
# Checking a destination
# ------------------------------------------------------------------------------------------------


def _can_create(folder: str) -> bool:
    """Whether a folder can really be made in ``folder`` (a probe, removed at once).

    ``os.access`` says yes for root everywhere, also in /proc and /sys, where nothing can be
    written; so the refusal would come only after the whole solve.
    """
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".sieve-mi-probe-", dir=folder))
    except OSError:
        return False
    return True


def validate(out_dir: str, *, inputs: Iterable[str] = (), option: str = "--out") -> str:
    """Check that ``out_dir`` may be written (or replaced) by sieve-mi; touch nothing.

    Parameters
    ----------
    out_dir : str
        The destination folder as the user gave it.
    inputs : iterable of str
        Input files of the command (scene, meshes, plate, image): a folder that holds one of
        them is refused.
    option : str
        The option name used in messages.

    Returns
    -------
    str
        The destination with symbolic links resolved (absolute).

    Raises
    ------
    SieveError
        One line saying why the folder is refused.
    """
    say = f"{option} {out_dir}"
    if os.path.islink(out_dir) and not os.path.exists(out_dir):
        raise SieveError(f"{say} is a broken symbolic link; choose another folder")
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise SieveError(f"{say} exists and is not a folder; choose another path")
    dest = os.path.realpath(out_dir)
    _refuse_protected(dest, say, inputs)
    base = os.path.dirname(dest)
    while not os.path.lexists(base):
        base = os.path.dirname(base)
    if not os.path.isdir(base) or not os.access(base, os.W_OK | os.X_OK) or not _can_create(base):
        raise SieveError(f"{say}: cannot write into {base}; choose another folder")
    if os.path.isdir(dest) and os.listdir(dest) and not is_replaceable(dest):
        raise SieveError(
            f"{say} exists and holds files that sieve-mi did not write; choose another folder"
        )
    return dest


def _contains(folder: str, path: str) -> bool:
    """Whether ``path`` is ``folder`` or lies inside it (both resolved, absolute)."""
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def _refuse_protected(dest: str, say: str, inputs: Iterable[str]) -> None:
    """Raise if ``dest`` (resolved) is a root, or is or contains the cwd, home or an input."""
    if os.path.dirname(dest) == dest or os.path.ismount(dest):
        raise SieveError(f"{say} is a filesystem root; choose another folder")
    cwd = os.path.realpath(os.getcwd())
    if dest == cwd:
        raise SieveError(f"{say} is the working directory; choose another folder")
    if _contains(dest, cwd):
        raise SieveError(f"{say} contains the working directory; choose another folder")
    home = os.path.realpath(os.path.expanduser("~"))
    if _contains(dest, home):
        raise SieveError(f"{say} is or contains your home folder; choose another folder")
    for path in inputs:
        if path and _contains(dest, os.path.realpath(path)):
            raise SieveError(f"{say} holds the input file {path}; choose another folder")


def _entries(root: str) -> tuple[set[str], set[str]]:
    """Files and folders under ``root`` as relative paths with ``/`` (symlinks count as files)."""
    files, folders = set(), set()
    stack = [""]
    while stack:
        rel = stack.pop()
        with os.scandir(os.path.join(root, rel)) as it:
            for entry in it:
                name = f"{rel}/{entry.name}" if rel else entry.name
                if entry.is_dir(follow_symlinks=False):
                    folders.add(name)
                    stack.append(name)
                else:
                    files.add(name)
    return files, folders


def read_marker(folder: str) -> dict | None:
    """The marker of a sieve-mi output folder, or None if it has none or it is unreadable."""
    try:
        with open(os.path.join(folder, MARKER)) as fh:
            marker = json.load(fh)
    except (OSError, ValueError, RecursionError):  # a damaged or hostile marker: none
        return None
    ok = isinstance(marker, dict) and all(
        isinstance(marker.get(k), list) and all(isinstance(x, str) for x in marker[k])
        for k in ("files", "folders")
    )
    return marker if ok else None


def is_replaceable(folder: str) -> bool:
    """Whether ``folder`` is a sieve-mi output holding only what its marker lists.

    It needs the marker, a ``report.json``, and no file or folder that the marker does not
    name (a user's ``notes.txt`` added to an old output makes it irreplaceable).
    """
    marker = read_marker(folder)
    if marker is None or not os.path.isfile(os.path.join(folder, "report.json")):
        return False
    files, folders = _entries(folder)
    return files - {MARKER} <= set(marker["files"]) and folders <= set(marker["folders"])


def check_addition(folder: str, names: Iterable[str], *, hint: str = "") -> dict:
    """Check that sieve-mi may write the files ``names`` into its output ``folder``; touch nothing.

    The folder needs a readable marker and must hold nothing that the marker does not list (a
    user's file there, even one named like an output, makes the folder refused); each of
    ``names`` may be missing or a listed file, not a folder.

    Parameters
    ----------
    folder : str
        An existing sieve-mi output folder.
    names : iterable of str
        The files to add or replace (plain names in ``folder``).
    hint : str
        What to do instead when the folder has no marker (ends that message).

    Returns
    -------
    dict
        The folder's marker.

    Raises
    ------
    SieveError
        One line saying why the folder is refused.
    """
    marker = read_marker(folder) if os.path.isdir(folder) else None
    if marker is None:
        raise SieveError(
            f"{folder}: has no readable {MARKER} marker, so sieve-mi did not write it; "
            f"{hint or 'choose a sieve-mi output folder'}"
        )
    files, folders = _entries(folder)
    files -= set(stale_additions(folder, files))  # sieve-mi's own, of a run killed outright
    unlisted = sorted(
        (files - {MARKER} - set(marker["files"])) | (folders - set(marker["folders"]))
    )
    if unlisted:
        more = f" (and {len(unlisted) - 1} more)" if len(unlisted) > 1 else ""
        raise SieveError(
            f"{folder}: holds {unlisted[0]}{more}, which its {MARKER} marker does not list "
            "(sieve-mi did not write it); move it out of the folder or choose another folder"
        )
    for name in names:
        path = os.path.join(folder, name)
        if os.path.isdir(path) and not os.path.islink(path):
            raise SieveError(f"{path}: is a folder where sieve-mi writes a file; move it away")
    if not os.access(folder, os.W_OK | os.X_OK) or not _can_create(folder):
        raise SieveError(f"{folder}: cannot write into it; check its permissions")
    return marker


def stale_additions(folder: str, files: Iterable[str]) -> list[str]:
    """The temporary files of :func:`add_files` in ``folder`` left by runs killed outright.

    :func:`add_files` writes ``.<name>.sieve-mi-tmp-<pid>`` beside each file; one whose process
    is gone (SIGKILL, a power cut) is sieve-mi's own leftover, not a user's file.

    Parameters
    ----------
    folder : str
    files : iterable of str
        Names in ``folder`` (relative, as :func:`_entries` gives them).

    Returns
    -------
    list of str
    """
    out = []
    for name in files:
        head, sep, pid = name.rpartition(".sieve-mi-tmp-")
        if not (sep and "/" not in name and head.startswith(".") and pid.isdigit()):
            continue
        if int(pid) != os.getpid() and not _pid_alive(int(pid)):
            if not os.path.islink(os.path.join(folder, name)):
                out.append(name)
    return out


def add_files(
    folder: str, contents: dict[str, bytes], *, hint: str = "", drop: tuple[str, ...] = ()
) -> None:
    """Add (or replace) files in sieve-mi's output ``folder`` and list them in its marker.

    The folder is checked as by :func:`check_addition` (again, right before writing). The files
    of ``drop`` that the marker lists and ``contents`` does not replace are removed first (an
    earlier run's output that this run did not make must not stand beside this run's report),
    then the marker is rewritten (listing a file that is not there yet is harmless; a written
    file that it does not list would make the folder refused), then each file is written to a
    temporary file beside it and renamed over it, with SIGINT, SIGTERM and SIGHUP held back.

    Parameters
    ----------
    folder : str
    contents : dict of str to bytes
        File name in ``folder`` to its new content.
    hint : str
        As for :func:`check_addition`.
    drop : tuple of str
        Names of this command's outputs that this run did not make (a file the marker does not
        list is the user's and is never removed).

    Raises
    ------
    SieveError
        The folder is refused, or a file could not be written (one line).
    """
    marker = check_addition(folder, contents, hint=hint)
    raise_if_signalled()  # a run told to stop adds nothing
    gone = [n for n in drop if n in marker["files"] and n not in contents]
    marker["files"] = sorted((set(marker["files"]) - set(gone)) | set(contents))
    text = json.dumps(marker, indent=1).encode()
    with deferred_signals():
        for name in [*stale_additions(folder, os.listdir(folder)), *gone]:
            with contextlib.suppress(OSError):
                os.remove(os.path.join(folder, name))
        for name, data in ((MARKER, text), *contents.items()):
            tmp = os.path.join(folder, f".{name}.sieve-mi-tmp-{os.getpid()}")
            try:
                with open(tmp, "wb") as fh:
                    fh.write(data)
                os.replace(tmp, os.path.join(folder, name))
            except OSError as exc:
                raise SieveError(f"{folder}: could not write {name} ({exc})") from None
            finally:
                if os.path.lexists(tmp):
                    os.remove(tmp)


# ------------------------------------------------------------------------------------------------
# Writing and swapping
# ------------------------------------------------------------------------------------------------


def _host() -> str:
    """This machine's name, reduced to letters, digits and ``_`` (no ``-``: it separates)."""
    return "".join(c if c.isalnum() else "_" for c in socket.gethostname())[:40] or "host"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale(parent: str) -> list[str]:
    """Remove the temporary folders in ``parent`` left by killed runs on this machine.

    A folder ``.sieve-mi-tmp-<pid>-<host>-...`` is removed when ``<host>`` is this machine and
    no process ``<pid>`` is alive. Returns the names removed.
    """
    removed = []
    try:
        names = os.listdir(parent)
    except OSError:
        return removed
    for name in names:
        pid, _, rest = name[len(TMP_PREFIX) :].partition("-")
        if not (name.startswith(TMP_PREFIX) and pid.isdigit() and rest.startswith(_host() + "-")):
            continue
        path = os.path.join(parent, name)
        if int(pid) == os.getpid() or _pid_alive(int(pid)) or os.path.islink(path):
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed.append(name)
    return removed


def write_marker(folder: str, command: str) -> None:
    """Write ``.sieve-mi`` into ``folder``: version, command and every file and folder in it."""
    from sieve_mi._version import VERSION

    files, folders = _entries(folder)
    marker = {
        "sieve_mi": VERSION,
        "command": command,
        "files": sorted(files - {MARKER}),
        "folders": sorted(folders),
    }
    with open(os.path.join(folder, MARKER), "w") as fh:
        json.dump(marker, fh, indent=1)


def _exchange(a: str, b: str) -> bool:
    """Swap two existing paths atomically (Linux ``renameat2``); False where not supported."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    if fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.EXDEV):
        return False
    raise OSError(err, os.strerror(err), b)


def swap_in(tmp: str, dest: str) -> None:
    """Put the finished folder ``tmp`` at ``dest``; an old ``dest`` is removed last.

    On failure the old ``dest`` is left (or put back) in place and ``tmp`` is left to the
    caller. Call with signals deferred.
    """
    if not os.path.lexists(dest):
        os.rename(tmp, dest)
        return
    if _exchange(tmp, dest):
        shutil.rmtree(tmp, ignore_errors=True)  # now the old output
        return
    aside = tmp + "-old"  # a kill between the two renames leaves it to remove_stale
    os.rename(dest, aside)
    try:
        os.rename(tmp, dest)
    except BaseException:
        os.rename(aside, dest)
        raise
    shutil.rmtree(aside, ignore_errors=True)


@contextlib.contextmanager
def writing(
    out_dir: str,
    *,
    command: str,
    inputs: Iterable[str] = (),
    option: str = "--out",
    salvage: Callable[[str], str | None] | None = None,
) -> Iterator[str]:
    """Yield a fresh temporary folder; when the block ends without error, make it ``out_dir``.

    Parameters
    ----------
    out_dir : str
        The destination folder (see :func:`validate` for what is accepted).
    command : str
        The command writing it (``"solve"``, ``"check"``), recorded in the marker.
    inputs : iterable of str
        Input files of the command; a destination that holds one is refused.
    option : str
        The option name used in messages.
    salvage : callable, optional
        Called with the temporary folder when the block is interrupted (KeyboardInterrupt,
        which SIGTERM and SIGHUP become); if it returns a note (one line: what was kept and
        what is missing), the folder, as it stands, is finished and swapped in as for a
        completed run, the note is printed on stderr, and the interrupt goes on (a solve
        stopped after its verdict keeps report.json and the plate). Signals are held meanwhile.

    Yields
    ------
    str
        The temporary folder to write into (beside the destination).

    Raises
    ------
    SieveError
        The destination is refused (before anything is written, or again just before the swap),
        or the swap failed; the old destination is then unchanged.
    """
    inputs = list(inputs)
    dest = validate(out_dir, inputs=inputs, option=option)
    parent = os.path.dirname(dest)
    created = _first_missing(parent)
    tmp = None
    try:
        with deferred_signals():
            try:
                os.makedirs(parent, exist_ok=True)
            except OSError as exc:
                raise SieveError(f"{option} {out_dir}: cannot create its folder ({exc})") from None
            remove_stale(parent)
            tmp = _make_temp(parent)
        yield tmp
        raise_if_signalled()  # told to stop while writing: the interrupt's path below
        _finish(tmp, dest, out_dir, command, inputs, option)
    except KeyboardInterrupt:
        with deferred_signals():
            try:
                note = _salvaged(tmp, salvage) if tmp is not None and salvage else None
                if note:
                    _finish(tmp, dest, out_dir, command, inputs, option)
                    print(f"sieve-mi: {note}", file=sys.stderr)
            except BaseException:  # noqa: BLE001 - nothing kept; the interrupt goes on below
                pass
            finally:
                _clean_up(tmp, parent, created)
        raise
    except BaseException:
        with deferred_signals():
            _clean_up(tmp, parent, created)
        raise


def _finish(tmp: str, dest: str, out_dir: str, command: str, inputs: list, option: str) -> None:
    """Write the marker into ``tmp``, check the destination again and swap ``tmp`` in."""
    write_marker(tmp, command)
    with deferred_signals():
        validate(out_dir, inputs=inputs, option=option)
        try:
            swap_in(tmp, dest)
        except OSError as exc:
            raise SieveError(f"{option} {out_dir}: could not be replaced ({exc})") from None


def _salvaged(tmp: str, salvage: Callable[[str], str | None]) -> str | None:
    """``salvage(tmp)``: what it kept of the interrupted folder, or None (also on an error)."""
    try:
        return salvage(tmp)
    except Exception:  # noqa: BLE001 - salvaging is best effort; the interrupt is what matters
        return None


def _clean_up(tmp: str | None, parent: str, created: str | None) -> None:
    """Remove the temporary folder (if still there) and the parent folders the run made."""
    if tmp is not None and os.path.lexists(tmp):
        shutil.rmtree(tmp, ignore_errors=True)
    _remove_created(parent, created)


def _first_missing(path: str) -> str | None:
    """The outermost folder that ``os.makedirs(path)`` would create, or None if it exists."""
    missing = None
    while not os.path.lexists(path):
        missing, path = path, os.path.dirname(path)
    return missing


def _remove_created(parent: str, created: str | None) -> None:
    """Remove the folders from ``parent`` up to ``created`` that a failed run made, if empty."""
    while created is not None and _contains(created, parent):
        try:
            os.rmdir(parent)
        except OSError:
            return
        parent = os.path.dirname(parent)


def _make_temp(parent: str) -> str:
    """Create an empty temporary folder in ``parent`` named after this process and machine."""
    for _ in range(100):
        path = os.path.join(parent, f"{TMP_PREFIX}{os.getpid()}-{_host()}-{secrets.token_hex(4)}")
        try:
            os.mkdir(path, 0o755)
        except FileExistsError:
            continue
        except OSError as exc:
            raise SieveError(f"{parent}: cannot write an output folder here ({exc})") from None
        return path
    raise SieveError(f"{parent}: cannot create a temporary output folder")
