"""Scene files (TOML): what must pass, what must be blocked, and how to search.

Every key of a scene file is declared once, as a field of one of the dataclasses below: the field
carries its default, and its :class:`Spec` (made by :func:`setting`) carries its bounds or accepted
values, its unit and its one-line meaning. The reader (:func:`load_scene`) takes defaults and
validation from there, the class docstrings list them, and ``tests/test_scene.py`` checks that
``docs/scene-format.md`` says the same. Adding a key is one line in its class (and a row in the
docs, which the test asks for), e.g.::

    certify: bool = setting(False, "prove the winner exactly")

Paths are relative to the scene file. Every problem is reported as one
:class:`~sieve_mi.errors.SieveError` line naming the file and the key.

Settings given on the command line are declared the same way, in classes that are not tables of
a scene file (:class:`Check`, :class:`CheckInputs`; ``certify --budget`` is
:attr:`Verdict.certify_budget`): ``sieve_mi.cli`` builds each option (default, help, type) from
its field and checks the value with :func:`read_value`, so a bad option gets the one-line error a
bad key gets.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import re
import tomllib
import types
import typing
from dataclasses import MISSING, asdict, dataclass, field, fields

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.objectives import OBJECTIVES
from sieve_mi.optim import NLOPT_METHODS, PSO_COEFFICIENT

__all__ = [
    "DIGITS_MAX",
    "LENGTH_MAX",
    "NESTING_MAX",
    "SEED_MAX",
    "AXIS_NAMES",
    "Check",
    "CheckInputs",
    "Fabrication",
    "LAYOUT_MODES",
    "Layout",
    "OUTERS",
    "Reader",
    "Scene",
    "ShapeEntry",
    "Solver",
    "Spec",
    "UNITS",
    "UnknownSettingError",
    "Verdict",
    "NAME_MAX",
    "SCENE_FILE_MAX",
    "check_folder_name",
    "check_name",
    "describe",
    "documented",
    "field_of",
    "key_of",
    "key_text",
    "load_scene",
    "option_help",
    "parse_json",
    "parse_toml",
    "read_file",
    "read_shape",
    "read_tables",
    "read_value",
    "known_names",
    "refuse_unknown",
    "setting",
    "shown",
    "spec_of",
    "table_fields",
    "value_types",
]

#: Accepted ``units`` (a label for reports; meshes are not converted).
UNITS = ("mm", "cm", "m", "in", "um")
#: Accepted ``[solver] outer`` values: player A's optimiser (PSO or an nlopt global method).
OUTERS = ("pso", *NLOPT_METHODS)
#: Accepted ``[layout] mode`` values.
LAYOUT_MODES = ("merged", "separate")
#: Largest length a scene accepts (scales, tolerances, margins, plate sizes): a kilometre in mm.
#: Beyond it the polygon offsets and rasters overflow; nothing real is that large.
LENGTH_MAX = 1_000_000
#: Largest seed (nlopt's generator takes an unsigned 64-bit seed).
SEED_MAX = 2**64 - 1
#: Accepted ``check --axis`` and ``certify --axis`` values: the plate's axis a shape moves along.
AXIS_NAMES = ("x", "y", "z")


@dataclass(frozen=True)
class Spec:
    """How one scene key is checked and documented (the metadata of its dataclass field).

    Attributes
    ----------
    doc : str
        One-line meaning.
    unit : str or None
        Unit of a number (``"scene units"``, ``"s"``), None where it has none.
    minimum, maximum : int or float or None
        Inclusive bounds of a number (exclusive where ``exclusive_min``, ``exclusive_max``).
    exclusive_min : bool
        Whether the value must be strictly greater than ``minimum``.
    exclusive_max : bool
        Whether the value must be strictly less than ``maximum``.
    choices : tuple of str or None
        The accepted values of a string.
    default_doc : str or None
        The default in words, where it is not a fixed value (e.g. "the file's stem").
    key : str or None
        The TOML key, where it differs from the field name.
    """

    doc: str
    unit: str | None = None
    minimum: float | None = None
    maximum: float | None = None
    exclusive_min: bool = False
    exclusive_max: bool = False
    choices: tuple[str, ...] | None = None
    default_doc: str | None = None
    key: str | None = None


def setting(default=MISSING, doc: str = "", **spec):
    """A dataclass field for a scene key: its default and its :class:`Spec`.

    Parameters
    ----------
    default : bool, int, float, str or None
        The value used when the key is absent; leave it out for a required key.
    doc : str
        One-line meaning.
    **spec
        The other fields of :class:`Spec` (``unit``, ``minimum``, ``maximum``, ``exclusive_min``,
        ``exclusive_max``, ``choices``, ``default_doc``, ``key``).

    Returns
    -------
    dataclasses.Field
    """
    return field(default=default, metadata={"spec": Spec(doc, **spec)})


def spec_of(f: dataclasses.Field) -> Spec | None:
    """The :class:`Spec` of a dataclass field, or None for a field that is not a scene key."""
    return f.metadata.get("spec")


def field_of(cls: type, name: str) -> dataclasses.Field:
    """The field ``name`` of dataclass ``cls``."""
    return next(f for f in fields(cls) if f.name == name)


def _like(cls: type, name: str, **changes):
    """A field declared as ``cls``'s field ``name`` (its default and :class:`Spec`), with
    ``changes`` to the Spec: one setting's default and meaning, used by a second class."""
    f = field_of(cls, name)
    return field(default=f.default, metadata={"spec": dataclasses.replace(spec_of(f), **changes)})


def key_of(f: dataclasses.Field) -> str:
    """The TOML key of a dataclass field."""
    spec = spec_of(f)
    return spec.key if spec is not None and spec.key else f.name


@functools.cache
def value_types(cls: type) -> dict[str, type]:
    """The value type of each field of a dataclass, without ``| None``.

    Parameters
    ----------
    cls : type
        A dataclass of this module.

    Returns
    -------
    dict of str to type
        ``bool``, ``int``, ``float``, ``str``, ``list[float]`` (a quaternion),
        ``list[ShapeEntry]`` or a dataclass (a table); ``float | None`` gives ``float``.
    """
    out = {}
    for name, hint in typing.get_type_hints(cls).items():
        if isinstance(hint, types.UnionType):
            hint = next(a for a in typing.get_args(hint) if a is not type(None))
        out[name] = hint
    return out


def describe(cls: type, f: dataclasses.Field) -> str:
    """A field's type and bounds in words, e.g. ``"int 16–4096"`` or ``"number > 0"``.

    The form docs/scene-format.md uses in its type column.
    """
    spec, kind = spec_of(f), value_types(cls)[f.name]
    words = {bool: "bool", int: "int", float: "number", str: "string", list[float]: "[w, x, y, z]"}
    word = words.get(kind, "tables")
    exclusive = spec.exclusive_min or spec.exclusive_max
    if spec.minimum is not None and spec.maximum is not None and not exclusive:
        return f"{word} {spec.minimum}–{spec.maximum}"
    bounds = []
    if spec.minimum is not None:
        bounds.append(f"{'>' if spec.exclusive_min else '≥'} {spec.minimum}")
    if spec.maximum is not None:
        bounds.append(f"{'<' if spec.exclusive_max else '≤'} {spec.maximum}")
    text = " ".join([word, ", ".join(bounds)]) if bounds else word
    if spec.choices and kind is float:  # a number, or one of a few words
        text += " or " + " or ".join(f'"{c}"' for c in spec.choices)
    return text


def option_help(cls: type, f, default) -> str:
    """A command-line option's help from its field: meaning; accepted values (range, unit,
    default), with ``%`` escaped for argparse."""
    spec = spec_of(f)
    text = spec.doc + (f"; one of {', '.join(spec.choices)}" if spec.choices else "")
    shown = spec.default_doc if spec.default_doc is not None else default
    notes = [describe(cls, f)] if spec.minimum is not None or spec.maximum is not None else []
    notes += ([spec.unit] if spec.unit else []) + [f"default {shown}"]
    return f"{text} ({', '.join(notes)})".replace("%", "%%")


def documented(cls: type) -> type:
    """Class decorator: append a numpydoc ``Attributes`` section built from the fields'
    :class:`Spec` (type and bounds, default, meaning, unit) to the docstring."""
    lines = ["", "    Attributes", "    ----------"]
    for f in fields(cls):
        spec = spec_of(f)
        if spec is None:
            continue
        if spec.default_doc is not None:
            default = spec.default_doc
        elif f.default is MISSING:
            default = "required"
        else:
            default = repr(f.default)
        unit = f" ({spec.unit})" if spec.unit else ""
        lines += [
            f"    {f.name} : {describe(cls, f)}, default {default}",
            f"        {spec.doc[:1].upper()}{spec.doc[1:]}{unit}.",
        ]
        if spec.choices and value_types(cls)[f.name] is not float:
            lines.append(f"        One of: {', '.join(spec.choices)}.")
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n" + "\n".join(lines) + "\n"
    return cls


class UnknownSettingError(SieveError, AttributeError):
    """A setting's name that its settings class does not have (a typo): a one-line
    :class:`~sieve_mi.errors.SieveError` that is also the AttributeError Python raises for an
    attribute that cannot be set."""


def refuse_unknown(cls: type, name: str, where: str) -> None:
    """Raise :class:`UnknownSettingError` unless ``name`` is a field of dataclass ``cls``.

    Parameters
    ----------
    cls : type
        A settings dataclass.
    name : str
        The name given (an attribute set, a keyword argument).
    where : str
        What it is a setting of, for the message (``"solver"``, ``"check"``).
    """
    known = [f.name for f in fields(cls)]
    if name not in known:
        raise UnknownSettingError(
            f"{where}: {key_text(name)}: unknown setting; known: {', '.join(sorted(known))}"
        )


def known_names(where: str):
    """Class decorator: a dataclass whose constructor refuses a keyword that is not a field
    (:func:`refuse_unknown`: one line listing the known names) instead of Python's TypeError.

    For settings tables checked by their own ``__post_init__`` (``ShakeSettings``); the scene's
    tables get this and more from their checking decorator.
    """

    def decorate(cls: type) -> type:
        init = cls.__init__

        @functools.wraps(init)
        def __init__(self, *args, **kwargs):
            for name in kwargs:
                refuse_unknown(cls, name, where)
            init(self, *args, **kwargs)

        cls.__init__ = __init__
        return cls

    return decorate


def _checked(where: str):
    """Class decorator: a settings dataclass whose values are checked like a scene file's keys
    (:func:`read_value`), in code as in a file.

    Making an instance checks every value it is given (``Solver(particles=-5)``); assigning a
    field of a made instance checks the new value (``scene.solver.particles = -5``): either is
    the one-line :class:`~sieve_mi.errors.SieveError` that ``particles = -5`` in a scene file is,
    at once. A name that is not a field (``scene.solver.particle = 5``, ``Solver(particle=5)``)
    is refused (:class:`UnknownSettingError`), never silently kept.
    """

    def decorate(cls: type) -> type:
        checked = {f.name for f in fields(cls) if spec_of(f) is not None}
        optional = {f.name for f in fields(cls) if f.default is None}  # None: back to the default
        init = cls.__init__

        @functools.wraps(init)
        def __init__(self, *args, **kwargs):
            for name in kwargs:
                refuse_unknown(cls, name, where)
            init(self, *args, **kwargs)
            for f in fields(cls):  # in their order: the first bad one is named
                value = getattr(self, f.name)
                if f.name in checked and not (value is None and f.name in optional):
                    object.__setattr__(self, f.name, read_value(cls, f.name, value, where))

        def __setattr__(self, name, value):
            refuse_unknown(cls, name, where)
            if (
                name in checked
                and name in self.__dict__
                and not (value is None and name in optional)
            ):
                value = read_value(cls, name, value, where)
            object.__setattr__(self, name, value)

        cls.__init__, cls.__setattr__ = __init__, __setattr__
        return cls

    return decorate


@_checked("shape")
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
    data: object = field(default=None, repr=False, compare=False)


@_checked("fabrication")
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
        default_doc="the largest diameter of a B (the thinnest proved plate)",
    )
    border: float = setting(
        5.0,
        "plate material around the hole",
        unit="scene units",
        minimum=0,
        exclusive_min=True,
        maximum=LENGTH_MAX,
    )


@_checked("solver")
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
        0,
        "stop player A's swarm once its best has not improved (by 1 %, at least 0.001) for this "
        "many iterations in a row (0: run every iteration, as the paper)",
        minimum=0,
        maximum=100_000,
    )
    starts: int = setting(10, "random starts of each B per evaluation", minimum=1, maximum=10_000)
    steps: int = setting(100, "Adam steps per start", minimum=0, maximum=1_000_000)
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
    freeze: bool = setting(
        True,
        "record player B's Adam step once and replay it (drjit.freeze; same results)",
    )
    screen: bool = setting(
        True,
        "prove before the game that B holding a ball larger than any hole A can make are "
        "blocked; A then plays against the others only",
    )
    memory: float = setting(
        0.0,
        "memory one attack of player B may hold at once; more poses run in chunks (same "
        "results); 0: a quarter of the machine's available memory, in chunks of at most 0.25 GB "
        "on the CPU",
        unit="GB",
        minimum=0,
        maximum=1_000_000,
    )


@_checked("verdict")
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
    certify_budget: float = setting(
        30.0,
        "time budget of each proof, seconds",
        minimum=0,
        exclusive_min=True,
        maximum=86_400,
    )
    thin_budget: float = setting(
        10.0,
        "seconds of motion search (OMPL) per B thicker than the plate, searched in parallel",
        minimum=0,
        exclusive_min=True,
        maximum=86_400,
    )


@_checked("layout")
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
    restarts: int = setting(
        1,
        "when the merged hole still lets some B through, search every A again from another seed",
        minimum=0,
        maximum=100,
    )


@_checked("check")
@documented
@dataclass
class Check:
    """``sieve-mi check``'s search: player B's budget (the verdict's defaults) and the fit scale.

    Not a table of a scene file: the options ``--starts``, ``--steps``, ``--learning-rate``,
    ``--resolution``, ``--seed``, ``--no-fit`` and ``--fit-tolerance`` of ``sieve-mi check``, and
    :class:`sieve_mi.game.check.CheckSettings` (this class) in code, checked as the options are.
    """

    starts: int = _like(Verdict, "starts", doc="random starts of the fitting search")
    steps: int = _like(Verdict, "steps", minimum=1)
    learning_rate: float = _like(Solver, "learning_rate", maximum=1.0)
    resolution: int = _like(Verdict, "resolution", doc="raster side in pixels for --sieve")
    seed: int = _like(Solver, "seed", doc="random seed")
    thin_budget: float = _like(
        Verdict,
        "thin_budget",
        doc="seconds of motion search through a plate (--sieve) thinner than the part",
    )
    fit: bool = setting(True, "the fit-scale search (the largest scale that passes)")
    fit_tolerance: float = setting(
        0.01,
        "relative precision of the fit scale",
        minimum=1e-6,
        maximum=1,
        exclusive_max=True,
    )


@_checked("check")
@documented
@dataclass
class CheckInputs:
    """How ``sieve-mi check`` reads its part and its sieve (``certify``: ``scale`` and ``axis``).

    Not a table of a scene file: command-line options only.
    """

    scale: float = _like(ShapeEntry, "scale", maximum=1_000_000)
    axis: str = setting("z", "direction the shape moves through the plate", choices=AXIS_NAMES)
    pixel_size: float | None = setting(
        None,
        "size of one pixel of --hole",
        unit="scene units",
        minimum=0,
        exclusive_min=True,
        maximum=1_000_000,
        default_doc="the image's PNG pHYs; required with --hole where it has none",
    )
    units: str = setting("mm", "unit name for the report")


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
            (w, x, y, z).
        name : str
            The scene's name (output folder ``out/<name>``).
        directory : str, optional
            Folder that relative paths refer to (default: the working directory).

        An entry may also be a mesh file's path (relative to ``directory``). Everything is checked
        as in a scene file, with the same one-line :class:`~sieve_mi.errors.SieveError`; settings
        are attributes afterwards (``scene.fabrication.tolerance = 0.5``), checked when set.

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
        passes = [
            _entry(item, f"pass[{i}]", "pass") for i, item in enumerate(_items(passes, "passes"))
        ]
        blocks = [
            _entry(item, f"block[{i}]", "block") for i, item in enumerate(_items(blocks, "blocks"))
        ]
        return cls(path=path, name=name, passes=passes, blocks=blocks)

    def resolve(self, mesh: str) -> str:
        """A mesh path relative to the scene file, made absolute."""
        return mesh if os.path.isabs(mesh) else os.path.normpath(os.path.join(self.directory, mesh))

    def settings(self) -> dict:
        """The search and fabrication settings, as stored in ``report.json``."""
        return {"units": self.units, **{key: asdict(t) for key, t in self.tables().items()}}

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
    unknown = set(spec) - {"mesh", "name", "scale", "rotation"}
    if unknown or "mesh" not in spec:
        raise SieveError(f"{at}: expected 'mesh' and optional 'name', 'scale', 'rotation', got "
                         f"{sorted(map(str, spec))}")  # fmt: skip
    mesh = spec["mesh"]
    if role == "block" and spec.get("rotation") is not None:
        raise SieveError(f"{at}.rotation: shapes to block are tried in every orientation")
    values = {k: read_value(ShapeEntry, k, spec[k], at) for k in ("name", "scale", "rotation")
              if spec.get(k) is not None}  # fmt: skip
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


class Reader:
    """Type-checked access to one table of the scene file, with errors that name file and key."""

    def __init__(self, path: str, table: dict, where: str):
        self.path, self.table, self.where = path, table, where

    def error(self, key: str, what: str) -> SieveError:
        return SieveError(f"{self.path}: {self.where}{key_text(key)}: {what}")

    def check_keys(self, allowed) -> None:
        for key in self.table:
            if key not in allowed:
                raise self.error(key, f"unknown key; known keys here: {', '.join(sorted(allowed))}")

    def read(self, cls: type) -> dict:
        """The keys of ``cls`` present in this table, checked against their :class:`Spec`."""
        kinds = value_types(cls)
        values = {}
        for f in fields(cls):
            spec = spec_of(f)
            if spec is not None and key_of(f) in self.table and kinds[f.name] in _READERS:
                values[f.name] = _READERS[kinds[f.name]](self, key_of(f), spec)
        return values

    def value(self, cls: type, name: str, key: str):
        """The value under ``key`` of this table, checked as field ``name`` of ``cls``."""
        return _READERS[value_types(cls)[name]](self, key, spec_of(field_of(cls, name)))

    def number(self, key: str, spec: Spec, integer: bool = False):
        value = self.table[key]
        if isinstance(value, str) and spec.choices and not integer:
            if value in spec.choices:
                return value
            words = " or ".join(repr(c) for c in spec.choices)
            raise self.error(key, f"expected a number or {words}, got {shown(value)}")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(
                key, f"expected a {'whole number' if integer else 'number'}, got {shown(value)}"
            )
        if not (isinstance(value, int) or math.isfinite(value)):  # an int of any size is finite
            raise self.error(key, f"expected a finite number, got {shown(value)}")
        if integer and isinstance(value, float) and not value.is_integer():
            raise self.error(key, f"expected a whole number, got {shown(value)}")
        low, high = spec.minimum, spec.maximum
        if low is not None and (value <= low if spec.exclusive_min else value < low):
            raise self.error(
                key, f"must be {'>' if spec.exclusive_min else '>='} {low}, got {shown(value)}"
            )
        if high is not None and (value >= high if spec.exclusive_max else value > high):
            raise self.error(
                key, f"must be {'<' if spec.exclusive_max else '<='} {high}, got {shown(value)}"
            )
        if integer or abs(value) <= _FLOAT_MAX:
            return int(value) if integer else float(value)
        raise self.error(key, f"{shown(value)} is beyond a number's range (±1.8e308)")

    def integer(self, key: str, spec: Spec) -> int:
        return self.number(key, spec, integer=True)

    def boolean(self, key: str, spec: Spec) -> bool:
        value = self.table[key]
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {shown(value)}")
        return value

    def string(self, key: str, spec: Spec) -> str:
        value = self.table[key]
        if not isinstance(value, str) or not value:
            raise self.error(key, f"expected a non-empty string, got {shown(value)}")
        if spec.choices is not None and value not in spec.choices:
            raise self.error(key, f"{shown(value)} is not one of: {', '.join(spec.choices)}")
        return value

    def quaternion(self, key: str, spec: Spec) -> list[float]:
        """A rotation (w, x, y, z) of norm 1 (to 1e-3), returned normalised."""
        q = self.table[key]
        if not (
            isinstance(q, list)
            and len(q) == 4
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in q)
        ):
            raise self.error(key, f"expected a quaternion [w, x, y, z], got {shown(q)}")
        if any(abs(v) > _FLOAT_MAX for v in q if isinstance(v, int)):
            raise self.error(key, f"quaternion {shown(q)} has a number beyond ±1.8e308")
        qn = np.asarray(q, float)
        norm = float(np.linalg.norm(qn))
        if not np.all(np.isfinite(qn)) or norm < 1e-9:
            raise self.error(key, f"quaternion {shown(q)} has no direction")
        if abs(norm - 1.0) > 1e-3:
            raise self.error(
                key,
                f"quaternion {shown(q)} is not a unit quaternion (norm {norm:.4g}); divide it "
                "by its norm",
            )
        return [float(v) for v in qn / norm]


_READERS = {
    bool: Reader.boolean,
    int: Reader.integer,
    float: Reader.number,
    str: Reader.string,
    list[float]: Reader.quaternion,
}


def read_value(cls: type, name: str, value, where: str, key: str | None = None):
    """A value of field ``name`` of ``cls`` given outside a scene file, checked as a key of one.

    Parameters
    ----------
    cls : type
        A dataclass of this module (:class:`Check`, :class:`Verdict`, ...).
    name : str
        The field.
    value : bool, int, float, str or list
        The value as given; text that should have been a number is reported as such.
    where : str
        What gave it, for the message (e.g. ``"check"``, the command).
    key : str, optional
        The name it was given under (e.g. ``"--learning-rate"``); default its TOML key.

    Returns
    -------
    bool, int, float, str or list
        The value (a whole float for an int field as int, an int for a float field as float).

    Raises
    ------
    SieveError
        ``"{where}: {key}: {what}"``, the line a bad key of a scene file gets.

    Examples
    --------
    >>> read_value(Check, "learning_rate", 0.0, "check", "--learning-rate")
    Traceback (most recent call last):
    ...
    sieve_mi.errors.SieveError: check: --learning-rate: must be > 0, got 0.0
    """
    key = key or key_of(field_of(cls, name))
    return Reader(where, {key: value}, "").value(cls, name, key)


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
#: Longest name a scene or shape may have (names go into file and folder names, 255 bytes at most).
NAME_MAX = 100


def check_name(path: str, where: str, name: str) -> None:
    """Raise unless ``name`` is a usable label: at most :data:`NAME_MAX` characters, no control
    characters (newlines, tabs, NUL), not blank and not padded with spaces."""
    if len(name) > NAME_MAX:
        raise SieveError(f"{path}: {where}: {len(name)} characters; use at most {NAME_MAX}")
    if any(ord(c) < 32 or ord(c) == 127 for c in name) or name != name.strip() or not name:
        raise SieveError(
            f"{path}: {where}: {name[:40]!r} has control characters or blank space at its ends; "
            "use letters, digits, '-' and '_'"
        )


def check_folder_name(path: str, name: str, key: str = "name") -> None:
    """Raise unless ``name`` (given as ``key``) can be one folder's name: a usable label
    (:func:`check_name`) with no separators, NUL, '.' or '..'."""
    check_name(path, key, name)
    if any(c in name for c in "/\\\0") or name in (".", ".."):
        raise SieveError(
            f"{path}: {key}: {name!r} is used as a folder name; use letters, digits, '-' and '_'"
        )


#: Deepest nesting of arrays and tables a scene file or a configuration may have (a scene needs
#: three: a ``[[pass]]`` list, its table, a rotation); deeper is refused before Python's recursion
#: limit is reached.
NESTING_MAX = 32
#: Most digits of an integer a file may give (Python's own limit of text-to-int conversion; no
#: setting takes more than 20 digits, so only the message is at stake).
DIGITS_MAX = 4300
#: Bits of the largest integer of :data:`DIGITS_MAX` digits.
_BITS_MAX = int(DIGITS_MAX * math.log2(10))
#: The largest finite float (an int beyond it cannot be a float setting).
_FLOAT_MAX = 1.7976931348623157e308
#: Keys shown as they are in messages; any other key is quoted (``repr``).
_PLAIN_KEY = re.compile(r"[A-Za-z0-9_\-.]{1,40}")


def shown(value, limit: int = 60) -> str:
    """A value as a message shows it: its ``repr`` on one line, at most ``limit`` characters.

    Never fails: an integer too long to print is described by its number of digits, a value
    nested too deeply to ``repr`` by its type.

    Examples
    --------
    >>> shown("a" * 100, 10)
    "'aaaaaaaa…"
    >>> shown(10**5000)
    'an integer of 5,001 digits'
    """
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 256:
        return f"an integer of {_digits(value):,} digits"
    try:
        text = repr(value).replace("\n", " ")
    except (ValueError, RecursionError):
        text = f"<{type(value).__name__}>"
    return _cut(text, limit)


def _cut(text: str, limit: int = 20) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks a cut)."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _digits(value: int) -> int:
    """Decimal digits of ``abs(value)``, without converting it to text (Python refuses that for
    more than :data:`DIGITS_MAX` digits)."""
    n = int(abs(value).bit_length() * math.log10(2)) + 1
    return n - 1 if n > 1 and abs(value) < 10 ** (n - 1) else n


def key_text(key) -> str:
    """A key as a message names it: as it is when plain (``solver``, ``mesh_A_pso_iters``), else
    quoted and cut short (:func:`shown`), so a key with a newline stays on one line."""
    return key if isinstance(key, str) and _PLAIN_KEY.fullmatch(key) else shown(key, 40)


def _trail_text(trail: tuple) -> str:
    """A value's place in a parsed document, e.g. ``pass[0].rotation`` (at most 6 steps)."""
    text = ""
    for i, step in enumerate(trail):
        if i == 6:
            return text + ".…"
        text += f"[{step}]" if isinstance(step, int) else ("." if text else "") + key_text(step)
    return text or "(top level)"


class _Unreadable:
    """A number a file gives that Python cannot hold (an integer of more than
    :data:`DIGITS_MAX` digits, a float beyond ±1.8e308): a marker in the parsed document, so that
    :func:`_check_document` refuses it naming its key."""

    def __init__(self, what: str):
        self.what = what


def _parse_float(text: str):
    """A float literal of a TOML or JSON file: the float, or :class:`_Unreadable` where it is
    out of a float's range (Python would make it ``inf`` without a word)."""
    value = float(text)
    if math.isinf(value) and text.lstrip("+-")[:3].lower() != "inf":
        return _Unreadable(f"{_cut(text)} is beyond a number's range (±1.8e308)")
    return value


def _parse_int(text: str):
    """An integer literal of a JSON file: the int, or :class:`_Unreadable` beyond
    :data:`DIGITS_MAX` digits."""
    if len(text.lstrip("-")) > DIGITS_MAX:
        return _Unreadable(f"an integer of {len(text.lstrip('-')):,} digits")
    return int(text)


def _check_document(data, path: str, max_depth: int | None) -> None:
    """Refuse, naming the key, what a parsed document holds that no reader should meet: a number
    Python cannot hold (:class:`_Unreadable`, an integer of over :data:`DIGITS_MAX` digits) or,
    with ``max_depth``, arrays and tables nested deeper than that (walked without recursion)."""
    stack = [(data, (), 0)]
    while stack:
        value, trail, depth = stack.pop()
        if isinstance(value, _Unreadable):
            raise SieveError(f"{path}: {_trail_text(trail)}: {value.what}; give a smaller number")
        if (
            isinstance(value, int)
            and not isinstance(value, bool)
            and value.bit_length() > _BITS_MAX
        ):
            raise SieveError(f"{path}: {_trail_text(trail)}: {shown(value)}; give a smaller number")
        if isinstance(value, dict):
            children = value.items()
        elif isinstance(value, list):
            children = enumerate(value)
        else:
            continue
        if max_depth is not None and depth > max_depth:
            raise SieveError(
                f"{path}: {_trail_text(trail)}: arrays or tables nested more than {max_depth} "
                "deep; give numbers, strings and short lists"
            )
        stack.extend((v, (*trail, k), depth + 1) for k, v in children)


#: What a key, a table header, a string or a bracket of a TOML or JSON text looks like (for
#: :func:`_where_in_text`, which names the place of an error that the parser did not).
_TOKENS = re.compile(
    r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:\\.|[^"\\\n])*"|\'[^\'\n]*\'|#[^\n]*|[\[\]{}]'
)
_TOML_KEY = re.compile(r"(?m)^[ \t]*([^\s=#\[][^=\n]*?)[ \t]*=")
_TOML_TABLE = re.compile(r"(?m)^[ \t]*\[\[?[ \t]*([^\]\n]+?)[ \t]*\]")
_JSON_KEY = re.compile(r'"((?:\\.|[^"\\\n]){0,40})"\s*:')


def _where_in_text(text: str, pos: int, toml: bool) -> str:
    """The key and line at character ``pos`` of a TOML or JSON text, e.g. ``solver.particles
    (line 7)``: the last key given before it, under its table (a heuristic, for messages)."""
    head, line = text[:pos], text.count("\n", 0, pos) + 1
    if toml:
        keys, tables = list(_TOML_KEY.finditer(head)), list(_TOML_TABLE.finditer(head))
        key = keys[-1].group(1).strip() if keys else ""
        if tables and (not keys or tables[-1].start() < keys[-1].start()):
            key = f"{tables[-1].group(1).strip()}.{key}" if key else tables[-1].group(1).strip()
    else:
        keys = list(_JSON_KEY.finditer(head))
        key = keys[-1].group(1) if keys else ""
    return f"{key_text(key) if key else '(top level)'} (line {line})"


def _too_deep_at(text: str) -> int:
    """Where a TOML or JSON text first opens an array or table deeper than :data:`NESTING_MAX`
    (strings and comments skipped); 0 if nowhere."""
    depth = 0
    for m in _TOKENS.finditer(text):
        token = m.group()
        if token in "[{":
            depth += 1
            if depth > NESTING_MAX:
                return m.start()
        elif token in "]}":
            depth = max(depth - 1, 0)
    return 0


def _too_long_at(text: str) -> int:
    """Where a TOML text gives an integer of more than :data:`DIGITS_MAX` digits; 0 if nowhere."""
    for m in re.finditer(r"[0-9][0-9_]*", text):  # each run once: linear in the text
        if m.end() - m.start() > DIGITS_MAX and len(m.group().replace("_", "")) > DIGITS_MAX:
            return m.start()
    return 0


def parse_toml(text: str, path: str) -> dict:
    """A TOML document, every number and nesting checked: one line naming the file and key.

    Parameters
    ----------
    text : str
        The file's text (a leading byte-order mark is dropped).
    path : str
        The file, for messages.

    Returns
    -------
    dict

    Raises
    ------
    SieveError
        Invalid TOML; an integer of more than :data:`DIGITS_MAX` digits or a float beyond
        ±1.8e308; arrays or tables nested deeper than :data:`NESTING_MAX`.
    """
    text = text.removeprefix("\ufeff")  # a byte-order mark is not TOML's
    try:
        data = tomllib.loads(text, parse_float=_parse_float)
    except tomllib.TOMLDecodeError as exc:
        raise SieveError(f"{path}: not valid TOML ({exc})") from None
    except RecursionError:
        where = _where_in_text(text, _too_deep_at(text), toml=True)
        raise SieveError(f"{path}: {where}: arrays or tables nested more than {NESTING_MAX} "
                         "deep; give numbers, strings and short lists") from None  # fmt: skip
    except ValueError:  # int() of tomllib: more digits than Python converts
        where = _where_in_text(text, _too_long_at(text), toml=True)
        raise SieveError(f"{path}: {where}: an integer of more than {DIGITS_MAX:,} digits; "
                         "give a smaller number") from None  # fmt: skip
    _check_document(data, path, NESTING_MAX)
    return data


def parse_json(text: str, path: str, max_depth: int | None = NESTING_MAX):
    """A JSON document, every number, key and nesting checked: one line naming the file and key.

    The reader every JSON input of sieve-mi should use instead of ``json.load``: Python's reader
    lets a later duplicate key replace the earlier one silently, turns a float beyond ±1.8e308
    into ``inf``, and raises ValueError or RecursionError on a long integer or deep nesting.

    Parameters
    ----------
    text : str
        The file's text.
    path : str
        The file, for messages.
    max_depth : int or None
        Deepest nesting of arrays and objects accepted (None: any that Python parses, as a
        certificate's tree needs).

    Returns
    -------
    object
        The document (dict, list, str, int, float, bool or None).

    Raises
    ------
    SieveError
        Invalid JSON; a key given twice in one object; an integer of more than
        :data:`DIGITS_MAX` digits or a float beyond ±1.8e308; nesting deeper than ``max_depth``
        (or than Python can parse).

    Examples
    --------
    >>> parse_json('{"a": 1, "a": 2}', "c.json")
    Traceback (most recent call last):
    ...
    sieve_mi.errors.SieveError: c.json: a: given twice in one object; keep one
    """

    def unique(pairs):
        out = {}
        for key, value in pairs:
            if key in out:
                raise SieveError(f"{path}: {key_text(key)}: given twice in one object; keep one")
            out[key] = value
        return out

    try:
        data = json.loads(text, object_pairs_hook=unique, parse_int=_parse_int,
                          parse_float=_parse_float)  # fmt: skip
    except json.JSONDecodeError as exc:
        raise SieveError(f"{path}: not valid JSON ({exc})") from None
    except RecursionError:
        where = _where_in_text(text, _too_deep_at(text), toml=False)
        raise SieveError(f"{path}: {where}: arrays or objects nested too deeply; give numbers, "
                         "strings and short lists") from None  # fmt: skip
    _check_document(data, path, max_depth)
    return data


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
        if b.rotation is not None:
            raise SieveError(
                f"{path}: block[{i}].rotation: shapes to block are tried in every orientation; remove 'rotation'"
            )
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
        ``{"fabrication": Fabrication(...), "solver": Solver(...), ...}``, one per
        :func:`table_fields` entry (absent tables at their defaults).
    """
    out = {}
    for f in table_fields():
        cls = value_types(Scene)[f.name]
        r = Reader(path, _table(path, data, f.name), f.name + ".")
        r.check_keys({key_of(g) for g in fields(cls)})
        out[f.name] = cls(**r.read(cls))
    return out


def _table(path: str, data: dict, key: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise SieveError(f"{path}: {key}: expected a table [{key}]")
    return value
