"""The paper authors' JSON configurations, read as sieve-mi scenes.

*Computational Design of Shape-Aware Sieves* ships its examples as JSON files (GitHub
``David-Cha/shape-aware-sieves``, ``scripts/*.json``). ``sieve-mi solve config.json`` (and
:func:`sieve_mi.load_scene`) reads that format: every key maps to a scene setting
(:data:`SETTINGS`, :func:`load_authors_config`), is accepted without effect where sieve-mi has no
such knob (:data:`NO_EFFECT`), or is refused in one line; an unknown key is refused in one line
naming it. The mapping, key by key: ``docs/authors-config.md``.
"""

from __future__ import annotations

import math
import os

from sieve_mi.errors import SieveError
from sieve_mi.parsing import parse_json
from sieve_mi.scene import (
    SCENE_FILE_MAX,
    Fabrication,
    Layout,
    Scene,
    ShapeEntry,
    Solver,
    Verdict,
    check_folder_name,
)
from sieve_mi.settings import Reader, key_text, read_value, shown

__all__ = [
    "MESH_KEYS",
    "NO_EFFECT",
    "SETTINGS",
    "is_authors_config",
    "load_authors_config",
    "mesh_path",
]

#: JSON key -> (scene table, field): the value becomes that setting (checked as the scene's key).
SETTINGS = {
    "mesh_A_opt_num_posns": ("solver", "particles"),
    "mesh_A_pso_iters": ("solver", "iterations"),
    "mesh_A_pso_w": ("solver", "inertia"),
    "mesh_A_pso_c1": ("solver", "c_personal"),
    "mesh_A_pso_c2": ("solver", "c_global"),
    "mesh_B_opt_num_posns": ("solver", "starts"),
    "mesh_B_opt_iters": ("solver", "steps"),
    "mesh_B_opt_learning_rate": ("solver", "learning_rate"),
    "mesh_A_fill_soft_mask_holes": ("fabrication", "fill_holes"),
    "sieve_thickness": ("fabrication", "thickness"),
    "proj_A_pso_c1": ("layout", "c_personal"),
    "proj_A_pso_c2": ("layout", "c_global"),
}


def _number(low: float, integer: bool = False):
    """A check of a number >= ``low`` (a whole one where ``integer``: 3 or 3.0, as a scene's
    integer keys take)."""

    def ok(v) -> bool:
        if isinstance(v, bool) or not isinstance(v, int | float) or v < low:
            return False
        if isinstance(v, int):  # finite, of any size
            return True
        return math.isfinite(v) and (v.is_integer() or not integer)

    return ok


def _pair(item_ok):
    return lambda v: isinstance(v, list) and len(v) == 2 and all(item_ok(x) for x in v)


#: JSON key -> (check of its value, what it expects, why it has no effect in sieve-mi).
NO_EFFECT = {
    "simulation_scale": (
        _number(1e-12),
        "a number > 0",
        "sieve-mi sizes its raster frame to the shapes in scene units",
    ),
    "mesh_B_opt_posn_trans_bounds": (
        _pair(_number(-math.inf)),
        "two numbers",
        "player B's random starts span the hole",
    ),
    "mesh_B_opt_vtx_out_of_bounds_loss_weight": (
        _number(0),
        "a number >= 0",
        "B's loss has no raster border to stay inside",
    ),
    "proj_A_pso_w": (_number(0), "a number >= 0", "the placement swarm has no inertia setting"),
    "proj_A_pso_iters": (
        _number(0, integer=True),
        "a whole number >= 0",
        "the placement is searched in [layout] rounds",
    ),
    "pso_verbose": (lambda v: isinstance(v, bool), "true or false", "use --quiet"),
    "sieve_side_length": (
        _number(1e-12),
        "a number > 0",
        "the plate is the hole plus [fabrication] border",
    ),
    "sieve_resolution": (
        _pair(_number(1, integer=True)),
        "two whole numbers >= 1",
        "the plate is cut from the exact polygon, not a raster",
    ),
}

#: Keys of each entry of ``meshes_A`` and ``meshes_B``.
MESH_KEYS = ("filename", "fabrication_scale", "fabrication_offset")
#: Keys read by :func:`load_authors_config` itself.
_OWN = (
    "name",
    "meshes_A",
    "meshes_B",
    "meshes_A_winning_rot_vecs",
    "image_shape",
    "mesh_B_opt_use_area_proportion",
)


def is_authors_config(path: str) -> bool:
    """Whether ``path`` names a JSON configuration (by its ``.json`` suffix)."""
    return str(path).lower().endswith(".json")


def _read_json(path: str) -> dict:
    """The JSON object at ``path``; a missing, oversized or invalid file is a one-line error."""
    if not os.path.isfile(path):
        raise SieveError(f"{path}: scene file not found")
    if os.path.getsize(path) > SCENE_FILE_MAX:
        raise SieveError(f"{path}: {os.path.getsize(path):,} bytes; a configuration is short JSON")
    try:
        with open(path, encoding="utf-8-sig") as fh:
            text = fh.read(SCENE_FILE_MAX + 1)
    except (OSError, UnicodeDecodeError) as exc:
        raise SieveError(f"{path}: could not be read ({exc})") from None
    data = parse_json(text, path)  # numbers, nesting and duplicate keys checked
    if not isinstance(data, dict):
        raise SieveError(f"{path}: expected a JSON object of the paper authors' configuration")
    return data


def _check_keys(path: str, data: dict, known, where: str = "") -> None:
    for key in data:
        if key not in known:
            raise SieveError(
                f"{path}: {where}{key_text(key)}: unknown key of the paper authors' configuration format "
                f"(known: {', '.join(sorted(known))})"
            )


def mesh_path(path: str, filename, where: str) -> str:
    """Where a configuration's mesh ``filename`` is, relative to the configuration file.

    The configuration's folder first, then ``../data/`` from it (the authors' repository keeps
    the configurations in ``scripts/`` and the meshes in ``data/``).
    """
    if not isinstance(filename, str) or not filename:
        raise SieveError(f"{path}: {where}.filename: expected the mesh file's name")
    folder = os.path.dirname(os.path.abspath(path))
    for rel in (filename, os.path.join(os.pardir, "data", filename)):
        if os.path.isfile(os.path.join(folder, rel)):
            return rel
    name = filename if filename.isprintable() else shown(filename, spelling="json")
    raise SieveError(
        f"{path}: {where}.filename: {name}: mesh file not found (looked beside the "
        "configuration and in ../data/)"
    )


def _meshes(path: str, data: dict, key: str) -> tuple[list[ShapeEntry], list]:
    """The ``meshes_A`` or ``meshes_B`` entries, and each one's ``fabrication_offset``."""
    items = data.get(key)
    if not isinstance(items, list) or not items:
        raise SieveError(f"{path}: {key}: expected a list of one or more meshes")
    entries, offsets = [], []
    for i, item in enumerate(items):
        where = f"{key}[{i}]"
        if not isinstance(item, dict):
            raise SieveError(f"{path}: {where}: expected an object with 'filename'")
        _check_keys(path, item, MESH_KEYS, where + ".")
        reader = Reader(path, {"fabrication_scale": 1.0, **item}, f"{where}.", "json")
        scale = reader.value(ShapeEntry, "scale", "fabrication_scale")
        offset = item.get("fabrication_offset")
        if offset is not None:
            offset = reader.value(Fabrication, "tolerance", "fabrication_offset")
        entries.append(ShapeEntry(mesh=mesh_path(path, item.get("filename"), where), scale=scale))
        offsets.append(offset)
    return entries, offsets


def _tolerance(path: str, a_offsets: list, b_offsets: list) -> float:
    """``[fabrication] tolerance`` from the A offsets (all alike); B offsets must be null."""
    for j, off in enumerate(b_offsets):
        if off:
            raise SieveError(
                f"{path}: meshes_B[{j}].fabrication_offset: {off}: sieve-mi grows only A "
                "(by [fabrication] tolerance); give null"
            )
    values = {0.0 if off is None else off for off in a_offsets}
    if len(values) > 1:
        raise SieveError(
            f"{path}: meshes_A[*].fabrication_offset: {sorted(values)}: sieve-mi grows every A "
            "by one [fabrication] tolerance; give the same value (or null for 0) to each"
        )
    return values.pop()


def _settings(path: str, data: dict) -> dict:
    """``{"solver": {...}, "fabrication": {...}, ...}`` from the keys of :data:`SETTINGS`,
    ``image_shape`` and the keys without effect (checked, then dropped)."""
    tables = {"solver": {}, "verdict": {}, "fabrication": {}, "layout": {}}
    classes = {"solver": Solver, "verdict": Verdict, "fabrication": Fabrication, "layout": Layout}
    for key, (table, name) in SETTINGS.items():
        if key in data:
            tables[table][name] = read_value(
                classes[table], name, data[key], path, key, spelling="json"
            )
    for key, (ok, expected, why) in NO_EFFECT.items():
        if key in data and not ok(data[key]):
            raise SieveError(f"{path}: {key}: expected {expected} (no effect here: {why})")
    if "image_shape" in data:
        shape = data["image_shape"]
        if not (isinstance(shape, list) and len(shape) == 2 and shape[0] == shape[1]):
            raise SieveError(
                f"{path}: image_shape: {shown(shape, 40, 'json')}: sieve-mi's raster is square; "
                "give [N, N]"
            )
        for table, cls in (("solver", Solver), ("verdict", Verdict)):
            tables[table]["resolution"] = read_value(
                cls, "resolution", shape[0], path, "image_shape", spelling="json"
            )
    if data.get("mesh_B_opt_use_area_proportion", True) is not True:
        raise SieveError(
            f"{path}: mesh_B_opt_use_area_proportion: sieve-mi's beta is always the area "
            "proportion (eq. 12); give true"
        )
    if data.get("meshes_A_winning_rot_vecs") is not None:
        raise SieveError(
            f"{path}: meshes_A_winning_rot_vecs: fixed A rotations are not read from this format; "
            "give null, or write a TOML scene with [[pass]] rotation = [w, x, y, z]"
        )
    return tables


def load_authors_config(path: str) -> Scene:
    """Read a configuration of the paper authors' code as a :class:`~sieve_mi.scene.Scene`.

    Parameters
    ----------
    path : str
        The JSON file; meshes are looked up beside it, then in ``../data/`` (:func:`mesh_path`).

    Returns
    -------
    Scene
        In millimetres (the authors' fabricated size); every setting the file does not give at
        sieve-mi's default.

    Raises
    ------
    SieveError
        One line naming the file and the key: an unknown key, a wrong value, a missing mesh.
    """
    data = _read_json(path)
    _check_keys(path, data, (*SETTINGS, *NO_EFFECT, *_OWN))
    name = data.get("name", os.path.splitext(os.path.basename(path))[0])
    if not isinstance(name, str):
        raise SieveError(f"{path}: name: expected a string")
    check_folder_name(path, name)
    passes, a_offsets = _meshes(path, data, "meshes_A")
    blocks, b_offsets = _meshes(path, data, "meshes_B")
    tables = _settings(path, data)
    tables["fabrication"]["tolerance"] = _tolerance(path, a_offsets, b_offsets)
    return Scene(
        path=path,
        name=name,
        passes=passes,
        blocks=blocks,
        solver=Solver(**tables["solver"]),
        verdict=Verdict(**tables["verdict"]),
        fabrication=Fabrication(**tables["fabrication"]),
        layout=Layout(**tables["layout"]),
    )
