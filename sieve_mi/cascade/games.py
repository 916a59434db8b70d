"""Games: one scene to solve, keyed by its content, run serially or as Ray tasks, and cached.

A :class:`GameSpec` is everything one solve needs (the scene with its meshes loaded, the seed,
the variant), so it travels to a Ray worker on another machine without shared files. The worker
(:func:`play`) solves it, writes the outputs as ``solve`` does into a scratch folder and sends
the files back; the driver writes them into the game cache (:class:`GameCache`) as each game
finishes, so an interrupted run keeps every finished game and the next run reuses it.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import shutil
import socket
import sys
import tempfile
import time
from dataclasses import dataclass, replace

from sieve_mi.backend import THREADS_ENV, default_variant
from sieve_mi.errors import SieveError
from sieve_mi.outputs import outdir
from sieve_mi.progress import Progress
from sieve_mi.scene import Scene

__all__ = [
    "RAY_CLIENT_PORT",
    "Engine",
    "EngineSettings",
    "FAULT_ENV",
    "GAME_FILE",
    "GameCache",
    "GameSpec",
    "Runner",
    "cache_folder",
    "check_address",
    "game_key",
    "game_line",
    "label_text",
    "play",
    "ray_module",
    "weakest",
]

#: Test hook: the first worker to see this path missing creates it and dies (Ray retries it).
FAULT_ENV = "SIEVE_MI_FAULT_ONCE"
#: The file in each cached game folder that holds its spec and summary.
GAME_FILE = "game.json"


@dataclass
class GameSpec:
    """One game to play.

    Attributes
    ----------
    key : str
        Folder name in the cache: readable label plus a content hash.
    scene : Scene
        With every shape's mesh loaded (``ShapeEntry.data``).
    seed : int
    variant : str
    label : dict
        What the game is, for tables and files (e.g. ``{"holds": [...], "passes": [...]}``).

    Every worker runs Dr.Jit on ``--threads N`` threads where the command was given it
    (``$SIEVE_MI_THREADS``, :func:`sieve_mi.backend.apply_threads`), else on its default pool.
    """

    key: str
    scene: Scene
    seed: int
    variant: str
    label: dict


def game_key(prefix: str, scene: Scene, seed: int, variant: str, digests: dict) -> str:
    """``<prefix>-<hash>``: the hash covers the shapes (mesh digests, scales, names, roles),
    every setting, the units, the seed and the variant, so an edited mixture plays again."""
    content = {
        "passes": [(e.name, digests[e.name], e.scale, e.rotation) for e in scene.passes],
        "blocks": [(e.name, digests[e.name], e.scale) for e in scene.blocks],
        "settings": scene.settings(),
        "seed": seed,
        "variant": variant,
    }
    h = hashlib.sha256(json.dumps(content, sort_keys=True, default=str).encode()).hexdigest()
    safe = "".join(c if c.isalnum() or c in "-_+" else "_" for c in prefix)[:80]
    return f"{safe}-{h[:12]}"


def weakest(summary: dict) -> dict:
    """The B of a game's summary that came closest to passing: one that passes, else the
    smallest β, then the smallest protrusion."""
    return min(summary["block"], key=lambda b: (b["blocked"], b["beta"], b["protrusion"]))


def play(spec: GameSpec) -> dict:
    """Solve one game (in a worker); returns its summary and its output files.

    Returns
    -------
    dict
        ``"summary"``: report.json's dict plus ``"outline"`` (the exact hole's polygons, lists
        of (x, y) in scene units); ``"files"``: relative path -> base64 of the bytes, everything
        ``solve`` writes.
    """
    flag = os.environ.get(FAULT_ENV)
    if flag and not os.path.exists(flag):
        open(flag, "w").close()
        os._exit(17)  # a worker dying mid-game
    from sieve_mi.api import solve
    from sieve_mi.backend import apply_threads

    apply_threads()
    t0 = time.perf_counter()
    result = solve(spec.scene, variant=spec.variant, seed=spec.seed, progress=False)
    with tempfile.TemporaryDirectory(prefix="sieve-mi-game-") as scratch:
        out = os.path.join(scratch, "out")
        report = result.save(out, figure=False, animation=False)
        files = {}
        for root, _, names in os.walk(out):
            for n in names:
                path = os.path.join(root, n)
                rel = os.path.relpath(path, out)
                if rel != outdir.MARKER:
                    with open(path, "rb") as fh:
                        files[rel] = base64.b64encode(fh.read()).decode()
    summary = dict(report)
    summary["outline"] = [p.tolist() for p in result.outline.to_polygons()]
    summary["game_s"] = round(time.perf_counter() - t0, 3)
    summary["worker"] = socket.gethostname()
    return {"summary": summary, "files": files}


class GameCache:
    """Finished games on disk: ``<folder>/<key>/`` as ``solve`` writes it, plus ``game.json``.

    Parameters
    ----------
    folder : str
        Where new games are written.
    also : list of str
        Folders searched too for finished games (e.g. a previous run's ``games/``).
    """

    def __init__(self, folder: str, also: tuple = ()):
        self.folder = folder
        self.search = [folder, *also]

    def find(self, key: str) -> str | None:
        """The folder of a finished game, or None."""
        for base in self.search:
            path = os.path.join(base, key)
            if os.path.isfile(os.path.join(path, GAME_FILE)) and outdir.is_replaceable(path):
                return path
        return None

    def load(self, key: str) -> dict | None:
        """A finished game's ``game.json`` (spec label and summary), or None (none there, or
        one that cannot be read: the game is played again)."""
        path = self.find(key)
        if path is None:
            return None
        try:
            with open(os.path.join(path, GAME_FILE)) as fh:
                record = json.load(fh)
        except (OSError, ValueError, RecursionError):
            return None
        return record if isinstance(record, dict) and "summary" in record else None

    def store(self, spec: GameSpec, outcome: dict) -> dict:
        """Write a finished game (atomically, see :func:`sieve_mi.outputs.outdir.writing`)."""
        record = {
            "key": spec.key,
            "label": spec.label,
            "seed": spec.seed,
            "variant": spec.variant,
            "summary": outcome["summary"],
        }
        target = os.path.join(self.folder, spec.key)
        with outdir.writing(target, command="game", option="game folder") as tmp:
            for rel, data in outcome["files"].items():
                path = os.path.join(tmp, rel)
                os.makedirs(os.path.dirname(path), exist_ok=True)
                with open(path, "wb") as fh:
                    fh.write(base64.b64decode(data))
            with open(os.path.join(tmp, GAME_FILE), "w") as fh:
                json.dump(record, fh, indent=1)
        return record


#: Port of a Ray client server (``ray://host`` without a port).
RAY_CLIENT_PORT = 10001
#: The HTTP/2 connection preface and an empty SETTINGS frame: Ray's GCS and client servers speak
#: gRPC, which answers with a SETTINGS frame of its own.
_HTTP2_HELLO = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])


def check_address(address: str, timeout: float = 3.0) -> None:
    """Raise a one-line SieveError unless a Ray cluster answers at ``address``.

    ``host:port`` (a head's GCS) or ``ray://host[:port]`` (a Ray client server): something must
    listen there and answer as gRPC (HTTP/2) within ``timeout`` seconds, so a port of some other
    service is refused at once instead of hanging in ``ray.init``. ``auto`` is checked when Ray
    starts (a one-line error where no cluster runs).
    """
    if address == "auto":
        return
    hostport = address[6:] if address.startswith("ray://") else address
    host, colon, port = hostport.rpartition(":")
    if address.startswith("ray://") and not colon:
        host, port = hostport, str(RAY_CLIENT_PORT)
    if not host or not port.isdigit() or not 0 < int(port) < 65536 or len(host) > 253:
        raise SieveError(
            f"--address {address[:80]}: expected host:port (e.g. 10.0.0.5:6379) or 'auto'"
        )
    try:
        with socket.create_connection((host, int(port)), timeout=timeout) as conn:
            conn.settimeout(timeout)
            conn.sendall(_HTTP2_HELLO)
            head = conn.recv(9)
    except (OSError, UnicodeError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise SieveError(
            f"--address {address[:80]}: nothing is listening there ({reason}); "
            "start a Ray head with 'ray start --head' or leave --address out"
        ) from None
    if len(head) < 9 or head[3] != 4:  # not an HTTP/2 SETTINGS frame: not gRPC, not Ray
        raise SieveError(
            f"--address {address[:80]}: something listens there but it is not a Ray cluster "
            "(no gRPC answer); give the head's GCS address (host:6379) or ray://host:10001"
        )


def ray_module():
    """The ``ray`` module, or None where it is not installed."""
    try:
        import ray
    except ImportError:
        return None
    return ray


class Runner:
    """Plays games, reusing cached ones; serially, or as Ray tasks.

    Parameters
    ----------
    cache : GameCache
    use_ray : bool
        Run the games as Ray tasks (``ray`` must be importable).
    address : str, optional
        An existing Ray cluster (``host:port``); default: a local Ray on this machine.
    workers : int, optional
        Local Ray: CPUs to give Ray (default: all).
    on_done : callable, optional
        Called as ``on_done(record, reused)`` after each game.
    """

    def __init__(self, cache, *, use_ray=False, address=None, workers=None, on_done=None):
        self.cache, self.use_ray, self.address, self.workers = cache, use_ray, address, workers
        self.on_done = on_done or (lambda record, reused: None)
        self.played, self.reused = 0, 0
        self._ray = None
        self._started = False

    def run(self, specs: list[GameSpec]) -> dict:
        """Play every spec not in the cache; returns ``{key: record}`` for all of them."""
        out, todo = {}, []
        for spec in {s.key: s for s in specs}.values():
            record = self.cache.load(spec.key)
            if record is None:
                todo.append(spec)
            else:
                out[spec.key] = record
                self.reused += 1
                self.on_done(record, True)
        if todo:
            runs = self._ray_games(todo) if self.use_ray else self._serial_games(todo)
            for spec, outcome in runs:
                record = self.cache.store(spec, outcome)
                out[spec.key] = record
                self.played += 1
                self.on_done(record, False)
        return out

    def _serial_games(self, todo):
        for spec in todo:
            yield spec, play(spec)

    def _ray_games(self, todo):
        ray = self._start()
        options = {"max_retries": 3, "num_cpus": 1}
        if todo[0].variant.startswith("cuda"):
            options["num_gpus"] = 1
        remote = ray.remote(**options)(play)
        pending = {remote.remote(spec): spec for spec in todo}
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                spec = pending.pop(done[0])
                try:
                    outcome = ray.get(done[0])
                except ray.exceptions.RayError as exc:
                    raise SieveError(f"game {spec.key} failed on Ray: {_first_line(exc)}") from None
                yield spec, outcome
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)

    def _start(self):
        if self._ray is not None:
            return self._ray
        ray = ray_module()
        if ray is None:
            raise SieveError(
                "Ray is not installed; pip install 'sieve-mi[cluster]' or use --serial"
            )
        if not ray.is_initialized():
            kwargs = {"include_dashboard": False, "log_to_driver": False, "logging_level": "error"}
            env = {THREADS_ENV: os.environ[THREADS_ENV]} if os.environ.get(THREADS_ENV) else {}
            if self.address:
                kwargs["address"] = self.address
            else:
                if self.workers:
                    kwargs["num_cpus"] = self.workers
                # local workers import sieve_mi from where the driver does
                env["PYTHONPATH"] = os.pathsep.join(sys.path)
            if env:
                kwargs["runtime_env"] = {"env_vars": env}
            try:
                ray.init(**kwargs)
            except Exception as exc:  # noqa: BLE001 - Ray raises many kinds; one line for all
                where = f"--address {self.address}" if self.address else "local Ray"
                raise SieveError(
                    f"{where}: Ray could not start or connect ({_first_line(exc)})"
                ) from None
            self._started = True
        self._ray = ray
        return ray

    def close(self) -> None:
        """Shut down the local Ray this runner started (a cluster is left running)."""
        if self._started and self._ray is not None:
            self._ray.shutdown()
        self._ray, self._started = None, False


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[-1] if text else type(exc).__name__


def cache_folder(out_dir: str) -> str:
    """Where finished games wait until the whole run is written: ``<out>.games`` beside it."""
    return os.path.normpath(out_dir) + ".games"


def label_text(label: dict) -> str:
    """A game's label for a progress line: ``hold X pass Y, Z`` (sort; ``screen hold ...`` or
    ``full hold ...`` where the label names its stage), ``seed 3 tolerance 0.5`` (sweep), each
    field padded so the lines align."""
    if "holds" in label or "passes" in label:
        stage = f"{label['stage']:<7}" if "stage" in label else ""
        return (
            f"{stage}hold {'+'.join(label.get('holds', [])) or '-':<20} pass "
            f"{'+'.join(label.get('passes', [])) or '-':<28}"
        )
    return " ".join(
        f"{k} {v:<6g}" if isinstance(v, float) else f"{k} {v:<4}" for k, v in label.items()
    )


def game_line(record: dict, reused: bool) -> str:
    """A finished game's progress line: its label, winner, weakest B, and its time or ``reused``."""
    s, label = record["summary"], record["label"]
    weak = weakest(s)
    return (
        f"  {label_text(label)} winner {s['winner']}  "
        f"weakest {weak['name']} beta {weak['beta']:.4f}  "
        + ("reused" if reused else f"{s.get('game_s', 0):.1f} s")
    )


def _clear_cache(folder: str, keys) -> None:
    """Remove the cached games that the written folder now holds; the cache folder if empty."""
    for key in keys:
        path = os.path.join(folder, key)
        if os.path.isdir(path) and outdir.is_replaceable(path):
            shutil.rmtree(path, ignore_errors=True)
    try:
        os.rmdir(folder)
    except OSError:
        pass


@dataclass(frozen=True)
class EngineSettings:
    """Where and how the games of ``sort`` and ``sweep`` run (their command-line options).

    Attributes
    ----------
    use_ray : bool, optional
        Run the games as Ray tasks; None: when Ray is installed (:meth:`resolved`).
    address : str, optional
        An existing Ray cluster (``host:port``); default: a local Ray on this machine.
    workers : int, optional
        Local Ray: CPUs to give Ray (default: all of this machine's).
    variant : str, optional
        The Mitsuba variant of every game; None: :func:`sieve_mi.backend.default_variant`.
    progress : bool
        A bar for the games and a line per finished game on stderr.
    """

    use_ray: bool | None = None
    address: str | None = None
    workers: int | None = None
    variant: str | None = None
    progress: bool = True

    def resolved(self) -> EngineSettings:
        """These settings with ``use_ray`` and ``variant`` decided (no None left in them)."""
        use_ray = (ray_module() is not None) if self.use_ray is None else self.use_ray
        return replace(self, use_ray=use_ray, variant=self.variant or default_variant())


class Engine:
    """The game engine of ``sort`` and ``sweep``: cache, runner and progress together.

    Use as a context manager (it shuts down a local Ray at the end). Finished games wait in
    :func:`cache_folder` (beside ``out_dir``) and in a previous run's ``out_dir/games``.

    Parameters
    ----------
    out_dir : str
        The command's output folder.
    settings : EngineSettings
        Resolved (:meth:`EngineSettings.resolved`): ``use_ray``, ``address``, ``workers`` as
        :class:`Runner` takes them, and ``progress``.
    """

    def __init__(self, out_dir: str, settings: EngineSettings):
        folder = cache_folder(out_dir)
        if os.path.lexists(folder) and not os.path.isdir(folder):  # found before any game
            raise SieveError(
                f"{folder}: exists and is not a folder; sieve-mi keeps finished games there "
                "until the output is written: move it or choose another --out"
            )
        self.cache = GameCache(folder, also=(os.path.join(out_dir, "games"),))
        # One bar for the games (done / known so far), a line per finished game; no "done in".
        self.bar = Progress(settings.progress, 0, "games", unit="game", done_line=False)
        self.runner = Runner(
            self.cache,
            use_ray=settings.use_ray,
            address=settings.address,
            workers=settings.workers,
            on_done=self.done,
        )
        self.records: dict = {}

    def play(self, specs: list) -> dict:
        """Play (or reuse) ``specs``; returns ``{key: record}``."""
        self.bar.grow(len({s.key for s in specs}))
        records = self.runner.run(specs)
        self.records.update(records)
        return records

    def done(self, record: dict, reused: bool) -> None:
        """A game is finished (played or ``reused``): its line (:func:`game_line`), a step."""
        self.bar.write(game_line(record, reused))
        self.bar.update(1)

    def info(self) -> dict:
        """How the games ran: mode, address, games played and reused."""
        r = self.runner
        mode = "ray" if r.use_ray else "serial"
        return {"mode": mode, "address": r.address, "played": r.played, "reused": r.reused}

    def folders(self) -> dict:
        """``{key: folder}`` of every game played or reused."""
        return {k: self.cache.find(k) for k in self.records}

    def clear_cache(self) -> None:
        """Remove the waiting games (after the output folder that copies them is written)."""
        _clear_cache(self.cache.folder, self.records)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.bar.close()
        self.runner.close()
        return False
