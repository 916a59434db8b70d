"""Scene files (TOML): what must pass, what must be blocked, and how to search.

Every key is declared once, as a field of a table's dataclass (:class:`ShapeEntry`,
:class:`Fabrication`, :class:`Solver`, :class:`Verdict`, :class:`Layout`,
:class:`~sieve_mi.shaker.Shake`, :class:`Scene`) made by :func:`sieve_mi.settings.setting`, with
its default, bounds or accepted values, unit and one-line meaning. :func:`load_scene` takes
defaults and validation from there; ``tests/test_scene.py`` checks that
``docs/scene-format.md`` has a row for each. Paths are relative to the scene file. Every problem
is one :class:`~sieve_mi.errors.SieveError` line naming the file and the key; a name that is not
a setting, set in code, is an :class:`UnknownSettingError` (:mod:`sieve_mi.settings`).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import asdict, dataclass, field, fields

from sieve_mi.errors import SieveError
from sieve_mi.geometry.pattern import PATTERNS, check_turns
from sieve_mi.geometry.stand_in import STAND_IN
from sieve_mi.objectives import OBJECTIVES
from sieve_mi.optim import NLOPT_METHODS, PSO_COEFFICIENT
from sieve_mi.parsing import parse_toml
from sieve_mi.settings import (
    ANGLES,
    LENGTH_MAX,
    NAME_MAX,
    SEED_MAX,
    SIZE,
    Reader,
    UnknownSettingError,
    check_folder_name,
    check_name,
    checked,
    documented,
    key_of,
    read_value,
    refuse_unknown,
    setting,
    shown,
    spec_of,
    value_types,
)
from sieve_mi.shaker import Shake

__all__ = [
    "LAYOUT_MODES",
    "NAME_MAX",
    "OUTERS",
    "PASS_ONLY",
    "SCENE_FILE_MAX",
    "UNITS",
    "Fabrication",
    "Layout",
    "Scene",
    "ShapeEntry",
    "Solver",
    "UnknownSettingError",
    "Verdict",
    "check_folder_name",
    "check_name",
    "load_scene",
    "read_file",
    "read_shape",
    "read_tables",
    "table_fields",
]

#: Accepted ``units`` (a label for reports; meshes are not converted).
UNITS = ("mm", "cm", "m", "in", "um")
#: Accepted ``[solver] outer`` values: player A's optimiser (PSO or an nlopt global method).
OUTERS = ("pso", *NLOPT_METHODS)
#: Accepted ``[layout] mode`` values.
LAYOUT_MODES = ("merged", "separate")
#: Bounds of a time budget in seconds (more than 0, at most a day).
_SECONDS = {"minimum": 0, "exclusive_min": True, "maximum": 86_400}


#: The bounds of a length that may be 0 (a tolerance).
_LENGTH0 = {"unit": "scene units", "minimum": 0, "maximum": LENGTH_MAX}
#: Keys only a ``[[pass]]`` table may have, and why a ``[[block]]`` has none.
PASS_ONLY = {"rotation": "shapes to block are tried in every orientation",
             "tolerance": "a shape to block has no hole of its own"}  # fmt: skip


@checked("shape")
@documented
@dataclass
class ShapeEntry:
    """One ``[[pass]]`` or ``[[block]]`` table, or a mesh given in code (:meth:`Scene.from_meshes`).

    Other Attributes
    ----------------
    data : trimesh.Trimesh or None
        The mesh itself for a scene built in code (``mesh`` is then only a label); None when the
        mesh is read from the file ``mesh``.
    """

    mesh: str = setting(doc="mesh file, relative to the scene file (anything trimesh reads)")
    scale: float = setting(
        1.0,
        "uniform scale from file units to scene units",
        minimum=0,
        exclusive_min=True,
        maximum=LENGTH_MAX,
    )
    rotation: list[float] | None = setting(
        None,
        "[[pass]] only: A's fixed orientation, a unit quaternion (w, x, y, z); no search",
        default_doc="none",
    )
    name: str | None = setting(None, "label in reports and file names", default_doc="file stem")
    tolerance: float | None = setting(None, "[[pass]] only: this A's own hole is its silhouette "
                                      'dilated by this much ([layout] mode = "separate")',
                                      default_doc="[fabrication] tolerance", **_LENGTH0)  # fmt: skip
    data: object = field(default=None, repr=False, compare=False)


#: The bounds of a positive length (a plate's size, border, web).
_LENGTH = {"unit": "scene units", "minimum": 0, "exclusive_min": True, "maximum": LENGTH_MAX}


@checked("fabrication")
@documented
@dataclass
class Fabrication:
    """``[fabrication]``: how the hole is made physical."""

    tolerance: float = setting(
        1.0,
        "A's silhouette is dilated by this much",
        unit="scene units",
        minimum=0,
        maximum=LENGTH_MAX,
    )
    fill_holes: bool = setting(True, "fill holes of the silhouette so H is simply connected")
    block_margin: float = setting(
        0.0,
        "B counts as blocked only if it also fails against H grown by this margin",
        unit="scene units",
        minimum=0,
        maximum=LENGTH_MAX,
    )
    thickness: float | str | None = setting(
        None,
        'sieve plate thickness; "thinnest" searches for the thinnest sheet where no B was '
        "found to pass (not proved; docs/fabrication.md)",
        unit="scene units",
        minimum=0,
        exclusive_min=True,
        maximum=LENGTH_MAX,
        choices=("thinnest",),
        default_doc="the thinnest proved plate (each blocked B's slab-section proof, bisected; "
        "its diameter where none holds), at least min_thickness",
    )
    min_thickness: float = setting(
        1.2, "the thinnest plate the default thickness may be (a printable sheet)", **_LENGTH
    )
    window: float | str = setting(
        0.0,
        "turns about the vertical (degrees, either way) over which every A passes the hole; "
        '"auto" bisects the widest that keeps every B blocked (docs/fabrication.md)',
        choices=("auto",),
        **{"unit": "degrees", "minimum": 0, "maximum": 90},
    )
    border: float = setting(5.0, "plate material around the hole", **_LENGTH)
    pattern: str = setting(
        "single",
        "one hole, or copies of it on a square or hexagonal lattice over plate_size",
        choices=PATTERNS,
    )
    plate_size: SIZE | None = setting(
        None,
        "the perforated sheet's width and height (a pattern only)",
        default_doc="a tray: 100 × 100 mm in the scene's units, larger when it would not hold "
        "3 × 3 holes",
        **_LENGTH,
    )
    web: float = setting(1.2, "least material between two holes of a pattern", **_LENGTH)
    turns: ANGLES | None = setting(None, "a pattern's copies turned by these angles in turn, one "
                                   "of them 0", unit="degrees", minimum=-360, maximum=360,
                                   default_doc="none (every copy as the hole)")  # fmt: skip
    mirror: bool = setting(False, "every other class of a pattern's copies mirrored, so a part "
                           "lying either side up finds its silhouette")  # fmt: skip


@checked("solver")
@documented
@dataclass
class Solver:
    """``[solver]``: the search (paper Sec. 6 defaults)."""

    objective: str = setting("clearance", "player B's loss", choices=OBJECTIVES)
    outer: str = setting("pso", "player A's optimiser", choices=OUTERS)
    resolution: int = setting(
        256, "raster side in pixels during the search", minimum=16, maximum=4096
    )
    particles: int = setting(10, "PSO particles", minimum=1, maximum=10_000)
    iterations: int = setting(10, "PSO iterations", minimum=0, maximum=100_000)
    patience: int = setting(
        5,
        "stop player A's swarm once its best has not improved (by 1 %, at least 0.001) for this "
        "many iterations in a row (0: run every iteration, as the paper)",
        minimum=0,
        maximum=100_000,
    )
    starts: int = setting(10, "random starts of each B per evaluation", minimum=1, maximum=10_000)
    steps: int = setting(100, "Adam steps per start", minimum=0, maximum=1_000_000)
    halving: float = setting(
        0.25,
        "successive halving of player B's starts in the search: after every this fraction of "
        "the steps, the worse half (by loss so far) of each candidate hole and B's starts stop "
        "(0: every start runs every step, as the paper; the verdict never halves)",
        minimum=0,
        maximum=1,
    )
    settle: bool = setting(
        True,
        "in the search's attacks, stop a hole's other B starts once one B fits it (the hole's "
        "value is 0 either way), and in the verdict stop each start that fits (false: every "
        "start runs every step, as the paper)",
    )
    learning_rate: float = setting(
        0.05, "Adam's learning rate", minimum=0, exclusive_min=True, maximum=1
    )
    seed: int = setting(0, "random seed (--seed overrides)", minimum=0, maximum=SEED_MAX)
    inertia: float = setting(PSO_COEFFICIENT, "PSO inertia", minimum=0)
    c_personal: float = setting(
        PSO_COEFFICIENT, "PSO acceleration towards a particle's best", minimum=0
    )
    c_global: float = setting(
        PSO_COEFFICIENT, "PSO acceleration towards the swarm's best", minimum=0
    )
    canonical: int = setting(
        20,
        "canonical views of each A evaluated before the swarm (0: none)",
        minimum=0,
        maximum=1000,
    )
    polish: int = setting(
        10,
        "rounds of the local polish of A's best rotation (0: none)",
        minimum=0,
        maximum=1000,
    )
    rest_poses: bool = setting(
        False,
        "player A also tries each A's likely resting poses on a flat plate and, among the "
        "rotations that block every B, prefers the one nearest a frequent resting pose (a "
        "shaken part already lies in it)",
    )
    retries: int = setting(
        1,
        "when the verdict on the exact hole finds some B passing, search A again from another "
        "seed (seed + 1, ...) and keep the better hole (more B blocked, then the higher least β); "
        "stops at a hole that blocks every B; a single A and separate holes (merged: "
        "[layout] restarts); 0: off",
        minimum=0,
        maximum=100,
    )
    freeze: bool = setting(
        True,
        "record player B's Adam step once and replay it (drjit.freeze; same results)",
    )
    screen: bool = setting(
        True,
        "prove before the game that B holding a ball larger than any hole A can make are "
        "blocked; A then plays against the others only",
    )
    stand_in: float | str = setting(
        0.0, STAND_IN, choices=("auto",), unit="scene units", minimum=0, maximum=LENGTH_MAX
    )
    memory: float = setting(
        0.0,
        "memory one attack of player B may hold at once; more poses run in chunks (same results); "
        "0: a quarter of the machine's available memory, in chunks of at most 0.25 GB on the CPU",
        unit="GB",
        minimum=0,
        maximum=1_000_000,
    )


@checked("verdict")
@documented
@dataclass
class Verdict:
    """``[verdict]``: the long re-run of player B that declares the winner."""

    starts: int = setting(100, "random starts per B", minimum=1, maximum=100_000)
    steps: int = setting(500, "Adam steps per start", minimum=0, maximum=1_000_000)
    resolution: int = setting(
        256, "raster side in pixels for the final hole and scores", minimum=16, maximum=4096
    )
    certify: bool = setting(
        True,
        "after the verdict, try to prove that each blocked B cannot pass the exact hole "
        "(in parallel over B; false turns it off)",
    )
    certify_budget: float = setting(30.0, "time budget of each proof, seconds", **_SECONDS)
    section_budget: float = setting(
        10.0,
        "seconds per blocked B for the slab-section proofs that bisect the thinnest proved plate "
        "(in parallel over B, after its proof)",
        **_SECONDS,
    )
    thin_budget: float = setting(
        10.0,
        "seconds of motion search (OMPL) per B thicker than the plate, searched in parallel",
        **_SECONDS,
    )


@checked("layout")
@documented
@dataclass
class Layout:
    """``[layout]``: how several pass shapes make one hole (paper Sec. 5.3, eq. 14)."""

    mode: str = setting("merged", "one merged hole, or one hole per A", choices=LAYOUT_MODES)
    tau: float = setting(
        10.0, "eq. 14 τ: weight of the blocking term", minimum=0, exclusive_min=True
    )
    rho: float = setting(
        200.0, "eq. 14 ρ: steepness of the tanh on β", minimum=0, exclusive_min=True
    )
    eta: float = setting(0.02, "eq. 14 η: β at which a block counts", minimum=0)
    alpha: float = setting(5.0, "eq. 14 α: weight of the hole-area penalty", minimum=0)
    c_personal: float = setting(0.05, "placement PSO acceleration ψ1", minimum=0)
    c_global: float = setting(0.05, "placement PSO acceleration ψ2", minimum=0)
    rounds: int = setting(
        3, "screening, swarm and re-ranking rounds per placement", minimum=1, maximum=100
    )
    alternatives: int = setting(
        2, "next-best rotations of a shape tried after that", minimum=0, maximum=100
    )
    mirrored: bool = setting(False, 'mode = "separate": each A that is not its own mirror image '
                             "also gets its mirrored hole (a flat part lying face up)")  # fmt: skip
    restarts: int = setting(
        1,
        "when the merged hole still lets some B through, search every A again from another seed",
        minimum=0,
        maximum=100,
    )


@documented
@dataclass
class Scene:
    """A parsed, validated scene (the top level of the file)."""

    path: str
    name: str = setting(
        doc="output folder out/<name>/ (unless --out)", default_doc="the file's stem"
    )
    passes: list[ShapeEntry] = setting(doc="set A: shapes that must pass", key="pass")
    blocks: list[ShapeEntry] = setting(doc="set B: shapes that must be blocked", key="block")
    units: str = setting("mm", "a label for reports; meshes are not converted", choices=UNITS)
    fabrication: Fabrication = field(default_factory=Fabrication)
    solver: Solver = field(default_factory=Solver)
    verdict: Verdict = field(default_factory=Verdict)
    layout: Layout = field(default_factory=Layout)
    shake: Shake = field(default_factory=Shake)
    #: The scene file's folder, absolute, fixed at load time (a later ``chdir`` does not move it).
    directory: str = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        self.directory = os.path.dirname(os.path.abspath(self.path))

    def __setattr__(self, name, value):
        """Set a field; a name that is not one is refused, and a new ``name``, ``units`` or
        table is checked as a scene file's would be (one-line SieveError)."""
        refuse_unknown(Scene, name, "scene")
        if name in self.__dict__:
            value = _scene_value(name, value)
        object.__setattr__(self, name, value)

    @classmethod
    def from_meshes(
        cls, passes: list, blocks: list, *, name: str = "scene", directory: str | None = None
    ) -> Scene:
        """A scene built in code from in-memory meshes, with every setting at its default.

        Parameters
        ----------
        passes, blocks : list
            One or more each: a ``trimesh.Trimesh``, a mesh file's path, or a dict with ``"mesh"``
            (either) and optional ``"name"``, ``"scale"`` and (``passes`` only) ``"rotation"``
            (w, x, y, z) and ``"tolerance"`` (scene units).
        name : str
            The scene's name (output folder ``out/<name>``).
        directory : str, optional
            Folder that relative paths refer to (default: the working directory).

        Everything is checked as in a scene file, with the same one-line SieveError; settings are
        attributes afterwards (``scene.fabrication.tolerance = 0.5``), checked when set.

        Examples
        --------
        >>> import trimesh
        >>> scene = Scene.from_meshes(
        ...     [trimesh.creation.box((20, 20, 20))],
        ...     [{"mesh": trimesh.creation.icosphere(3, 12.0), "name": "ball"}],
        ...     name="cube-vs-ball",
        ... )
        >>> [e.name for e in scene.passes + scene.blocks]
        ['pass_0', 'ball']
        """
        where = "Scene.from_meshes"
        if not isinstance(name, str):
            raise SieveError(f"{where}: name: expected a string, got {name!r:.40}")
        check_folder_name(where, name)
        path = os.path.join(os.path.abspath(directory or os.getcwd()), f"{name}.toml")
        passes = [_entry(x, f"pass[{i}]", "pass") for i, x in enumerate(_items(passes, "passes"))]
        blocks = [_entry(x, f"block[{i}]", "block") for i, x in enumerate(_items(blocks, "blocks"))]
        return cls(path=path, name=name, passes=passes, blocks=blocks)

    def resolve(self, mesh: str) -> str:
        """A mesh path relative to the scene file, made absolute."""
        return mesh if os.path.isabs(mesh) else os.path.normpath(os.path.join(self.directory, mesh))

    def settings(self) -> dict:
        """The settings as stored in ``report.json`` (``shake`` only where it is not the default)."""
        kept = {key: asdict(t) for key, t in self.tables().items() if t != Shake()}
        return {"units": self.units, **kept}

    def tables(self) -> dict:
        """The settings tables by TOML key: ``{"fabrication": Fabrication(...), ...}``."""
        return {f.name: getattr(self, f.name) for f in table_fields()}


def _scene_value(name: str, value):
    """A new value of :class:`Scene` field ``name``, checked: a table of its class, a usable
    folder name, one of the units."""
    kind = value_types(Scene)[name]
    if dataclasses.is_dataclass(kind) and not isinstance(value, kind):
        raise SieveError(f"scene: {name}: expected a {kind.__name__} table, got {shown(value)}")
    if name == "units":
        return read_value(Scene, name, value, "scene")
    if name == "name":
        if not isinstance(value, str):
            raise SieveError(f"scene: name: expected a string, got {shown(value)}")
        check_folder_name("scene", value)
    return value


def table_fields() -> list[dataclasses.Field]:
    """The fields of :class:`Scene` that are settings tables (``[fabrication]``, ``[solver]``, ...)."""
    kinds = value_types(Scene)
    return [f for f in fields(Scene) if dataclasses.is_dataclass(kinds[f.name])]


def _items(items, what: str) -> list:
    """``items`` as a non-empty list, or a one-line SieveError."""
    if isinstance(items, str | bytes | dict) or not hasattr(items, "__len__") or not len(items):
        raise SieveError(
            f"Scene.from_meshes: {what}: give a list of one or more meshes (trimesh.Trimesh, a "
            f"mesh file's path, or a dict with 'mesh'), got {items!r:.40}"
        )
    return list(items)


def _entry(item, where: str, role: str) -> ShapeEntry:
    """One shape of :meth:`Scene.from_meshes`, checked like a ``[[pass]]``/``[[block]]`` table."""
    import trimesh

    at = f"Scene.from_meshes: {where}"
    spec = dict(item) if isinstance(item, dict) else {"mesh": item}
    keys = ("name", "scale", "rotation", "tolerance")
    if set(spec) - {"mesh", *keys} or "mesh" not in spec:
        raise SieveError(f"{at}: expected 'mesh' and optional 'name', 'scale', 'rotation', "
                         f"'tolerance', got {sorted(map(str, spec))}")  # fmt: skip
    mesh = spec["mesh"]
    for key, why in PASS_ONLY.items() if role == "block" else ():
        if spec.get(key) is not None:
            raise SieveError(f"{at}.{key}: {why}")
    values = {k: read_value(ShapeEntry, k, spec[k], at) for k in keys if spec.get(k) is not None}
    if "name" in values:
        check_name(at, "name", values["name"])
    if isinstance(mesh, str | os.PathLike):
        return ShapeEntry(mesh=read_value(ShapeEntry, "mesh", os.fspath(mesh), at), **values)
    if not isinstance(mesh, trimesh.Trimesh):
        raise SieveError(f"{at}.mesh: expected a trimesh.Trimesh or a file path, got "
                         f"{type(mesh).__name__}")  # fmt: skip
    label = values.get("name") or where.replace("[", "_").rstrip("]")
    return ShapeEntry(mesh=f"<in memory: {label}>", name=label, data=mesh,
                      **{k: v for k, v in values.items() if k != "name"})  # fmt: skip


def read_shape(path: str, table, where: str) -> ShapeEntry:
    if not isinstance(table, dict):
        raise SieveError(f"{path}: {where}: expected a table like [[pass]] with a 'mesh' key")
    r = Reader(path, table, where + ".")
    r.check_keys({key_of(f) for f in fields(ShapeEntry)})
    if "mesh" not in table:
        raise r.error("mesh", "missing; give the path of a mesh file (relative to the scene file)")
    entry = ShapeEntry(**r.read(ShapeEntry))
    if entry.name is not None:
        check_name(path, f"{where}.name", entry.name)
    return entry


def _read_shapes(path: str, data: dict, key: str) -> list[ShapeEntry]:
    """The ``[[pass]]`` or ``[[block]]`` tables (one or more)."""
    if key not in data:
        raise SieveError(
            f"{path}: {key}: missing; add at least one [[{key}]] table with a 'mesh' key"
        )
    if not isinstance(data[key], list) or not data[key]:
        raise SieveError(f"{path}: {key}: expected one or more [[{key}]] tables")
    return [read_shape(path, t, f"{key}[{i}]") for i, t in enumerate(data[key])]


#: Largest scene file read, bytes (a scene is a few hundred bytes; meshes are separate files).
SCENE_FILE_MAX = 10 << 20


def read_file(path: str) -> dict:
    """The TOML document at ``path``; a missing, unreadable or invalid file is a SieveError."""
    if not os.path.exists(path):
        raise SieveError(f"{path}: scene file not found")
    if not os.path.isfile(path):
        raise SieveError(f"{path}: not a regular file; give a scene file (TOML)")
    if os.path.getsize(path) > SCENE_FILE_MAX:
        raise SieveError(
            f"{path}: {os.path.getsize(path):,} bytes; a scene file is a short TOML text"
        )
    try:
        with open(path, "rb") as fh:
            text = fh.read(SCENE_FILE_MAX + 1).decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SieveError(f"{path}: could not be read ({exc})") from None
    return parse_toml(text, path)


def load_scene(path: str) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str
        The TOML file.

    Returns
    -------
    Scene
        Every key absent from the file has its field's default.

    Raises
    ------
    SieveError
        On a missing file, bad TOML, unknown keys, wrong types or out-of-range values.
    """
    data = read_file(path)
    top = Reader(path, data, "")
    tables = table_fields()
    top.check_keys({key_of(f) for f in fields(Scene) if spec_of(f) is not None or f in tables})
    values = top.read(Scene)
    values.setdefault("name", os.path.splitext(os.path.basename(path))[0])
    check_folder_name(path, values["name"])
    passes, blocks = _read_shapes(path, data, "pass"), _read_shapes(path, data, "block")
    for i, b in enumerate(blocks):
        for key, why in PASS_ONLY.items():
            if getattr(b, key) is not None:
                raise SieveError(f"{path}: block[{i}].{key}: {why}; remove '{key}'")
    values.update(read_tables(path, data))
    return Scene(path=path, passes=passes, blocks=blocks, **values)


def read_tables(path: str, data: dict) -> dict:
    """The settings tables of a parsed TOML document, checked, with defaults filled in.

    Parameters
    ----------
    path : str
        The file, for error messages.
    data : dict
        The whole document.

    Returns
    -------
    dict
        ``{"fabrication": Fabrication(...), ...}``, every table (absent ones at their defaults).
    """
    out = {}
    for f in table_fields():
        cls = value_types(Scene)[f.name]
        r = Reader(path, _table(path, data, f.name), f.name + ".")
        r.check_keys({key_of(g) for g in fields(cls)})
        out[f.name] = cls(**r.read(cls))
    check_turns(out["fabrication"].turns, path)
    return out


def _table(path: str, data: dict, key: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise SieveError(f"{path}: {key}: expected a table [{key}]")
    return value
