"""The Python API refuses bad arguments with the CLI's one-line SieveError, before any work."""

from __future__ import annotations

import os

import pytest
import trimesh
from helpers import REPO

import sieve_mi as sm
from sieve_mi.cascade.commands import parse_seeds

DEFAULT = os.path.join(REPO, "scenes", "default.toml")


@pytest.fixture(scope="module")
def scene():
    return sm.load_scene(DEFAULT)


def _cli(capsys, *args) -> tuple[int, str]:
    """``sieve-mi ARGS`` in this process (``sieve_mi.cli.main``): its exit code and stderr (an
    exception other than the one-line error fails the test as a traceback would)."""
    from sieve_mi.cli import main

    code = main(list(args))
    return code, capsys.readouterr().err


def _one_line(exc: pytest.ExceptionInfo, needle: str) -> None:
    text = str(exc.value)
    assert "\n" not in text and needle in text, text


@pytest.mark.parametrize("bad", [None, 123, b"x", ""])
def test_load_scene_and_load_shape_want_a_path(bad):
    with pytest.raises(sm.SieveError) as e:
        sm.load_scene(bad)
    _one_line(e, "load_scene: expected a file path")
    with pytest.raises(sm.SieveError) as e:
        sm.load_shape(bad)
    _one_line(e, "load_shape: expected a file path")


@pytest.mark.parametrize(
    "bad, needle",
    [(None, "expected a Scene"), ("t.toml", "sieve_mi.load_scene(path)"), (3, "expected a Scene")],
)
def test_solve_wants_a_scene(bad, needle):
    with pytest.raises(sm.SieveError) as e:
        sm.solve(bad)
    _one_line(e, needle)


def _must_not_run(monkeypatch, target):
    """Make the function at dotted path ``target`` fail the test if it is called."""

    def called(*args, **kwargs):
        raise AssertionError(f"{target} must not be called")

    monkeypatch.setattr(target, called, raising=False)


@pytest.mark.parametrize("seed", [-1, "3", 1.5, True, 2**64, float("nan")])
def test_solve_refuses_bad_seeds_at_once(scene, seed, monkeypatch):
    _must_not_run(monkeypatch, "sieve_mi.game.solver.solve")  # refused before any work
    with pytest.raises(sm.SieveError) as e:
        sm.solve(scene, seed=seed, progress=False)
    _one_line(e, "seed")


@pytest.mark.parametrize("bad", [None, 123, b"x", ""])
def test_result_save_wants_a_folder_path(bad):
    with pytest.raises(sm.SieveError) as e:
        sm.Result.save(object(), bad)  # refused before the result is looked at
    _one_line(e, "Result.save: expected a file path")


@pytest.mark.parametrize(
    "args, kwargs, needle",
    [
        ((None,), {"sieve": "plate.stl"}, "check: expected a mesh"),
        (("part.stl",), {}, "give sieve=PLATE"),
        (("part.stl",), {"image": "hole.png"}, "needs pixel_size"),
    ],
)
def test_check_refuses_missing_pieces_in_words_of_the_api(
    args, kwargs, needle, tmp_path, monkeypatch
):
    from PIL import Image

    monkeypatch.chdir(tmp_path)
    Image.new("L", (8, 8)).save("hole.png")  # an image that records no pixel size
    with pytest.raises(sm.SieveError) as e:
        sm.check(*args, **kwargs)
    _one_line(e, needle)
    assert "--" not in str(e.value)  # not the CLI's option names


@pytest.mark.parametrize("text", ["0-1000000000", "0-100000", f"{2**64}", "5-2", "-3", "x"])
def test_sweep_seeds_are_bounded_before_any_list_is_built(text, monkeypatch):
    _must_not_run(monkeypatch, "sieve_mi.cascade.commands.range")  # no seed is listed
    with pytest.raises(sm.SieveError) as e:
        parse_seeds(text)
    _one_line(e, "--seeds")


def test_seed_two_to_the_64_is_one_line_from_the_cli(tmp_path, capsys):
    code, err = _cli(capsys, "solve", DEFAULT, "--seed", str(2**64), "--out", str(tmp_path / "o"))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "--seed" in lines[0] and "2**64" in lines[0], err
    assert not (tmp_path / "o").exists()


def test_report_settings_record_the_seed_that_ran():
    # --seed 7 (or solve(seed=7)) overrides [solver] seed: report.json's settings say 7, as its
    # provenance does, so the settings replay the run.
    from sieve_mi.outputs.report import report_dict

    rupert = os.path.join(os.path.dirname(DEFAULT), "rupert.toml")
    scene = sm.load_scene(rupert)
    assert scene.solver.seed != 7
    rep = report_dict(sm.solve(scene, seed=7, progress=False))
    assert rep["settings"]["solver"]["seed"] == 7 == rep["provenance"]["seed"]
    assert scene.solver.seed != 7  # the scene itself is not changed


@pytest.mark.parametrize(
    "table, key, value, needle",
    [
        ("solver", "particles", -5, "solver: particles: must be >= 1, got -5"),
        ("solver", "particles", "ten", "solver: particles: expected a whole number, got 'ten'"),
        ("solver", "objective", "bogus", "solver: objective: 'bogus' is not one of"),
        ("solver", "learning_rate", float("nan"), "solver: learning_rate: expected a finite"),
        ("verdict", "steps", "10", "verdict: steps: expected a whole number, got '10'"),
        ("fabrication", "tolerance", 1e300, "fabrication: tolerance: must be <= 1000000"),
        ("layout", "mode", "stacked", "layout: mode: 'stacked' is not one of"),
    ],
)
def test_settings_are_checked_when_set(scene, table, key, value, needle):
    # The same Spec and one-line error as the TOML path, at the assignment (not deep in a solve).
    settings = getattr(scene, table)
    before = getattr(settings, key)
    with pytest.raises(sm.SieveError) as e:
        setattr(settings, key, value)
    _one_line(e, needle)
    assert getattr(settings, key) == before  # unchanged


def test_good_settings_are_set_and_converted(scene):
    scene.solver.particles = 3.0  # a whole float is an int, as in a scene file
    assert scene.solver.particles == 3 and isinstance(scene.solver.particles, int)
    scene.fabrication.tolerance = 1  # an int is a float
    assert scene.fabrication.tolerance == 1.0 and isinstance(scene.fabrication.tolerance, float)


@pytest.mark.parametrize(
    "passes, blocks, needle",
    [
        ([], ["B"], "passes: give a list of one or more meshes"),
        (["A"], [], "blocks: give a list of one or more meshes"),
        ("x", ["B"], "passes: give a list"),
        ([None], ["B"], "pass[0].mesh: expected a trimesh.Trimesh or a file path"),
        ([{"mesh": "A", "scale": -1}], ["B"], "pass[0]: scale: must be > 0, got -1"),
        ([{"mesh": "A", "colour": 1}], ["B"], "pass[0]: expected 'mesh' and optional"),
        (["A"], [{"mesh": "B", "rotation": [1, 0, 0, 0]}], "block[0].rotation: shapes to block"),
        ([{"mesh": "A", "name": "a\nb"}], ["B"], "pass[0]: name: 'a\\nb' has control characters"),
    ],
)
def test_scenes_built_in_code_are_checked_like_files(passes, blocks, needle):
    box, ball = trimesh.creation.box((20, 20, 20)), trimesh.creation.icosphere(3, 12.0)

    def real(x):
        if isinstance(x, dict):
            return {k: real(v) for k, v in x.items()}
        return {"A": box, "B": ball}.get(x, x) if isinstance(x, str) else x

    args = [real(x) for x in passes] if isinstance(passes, list) else passes
    with pytest.raises(sm.SieveError) as e:
        sm.Scene.from_meshes(args, [real(x) for x in blocks])
    _one_line(e, "Scene.from_meshes: " + needle)


def test_a_scene_built_in_code_takes_mesh_files_too():
    meshes = os.path.join(os.path.dirname(DEFAULT), "meshes")
    scene = sm.Scene.from_meshes(["cube.stl"], ["sphere.stl"], directory=meshes)
    assert scene.resolve(scene.passes[0].mesh) == os.path.join(meshes, "cube.stl")
    from sieve_mi.game.solver import load_shapes

    passes, blocks = load_shapes(scene)
    assert passes[0].face_count == 12 and passes[0].radius == pytest.approx(10 * 3**0.5, rel=1e-6)


@pytest.mark.parametrize(
    "text, needle",
    [("1e300", "must be <= 1000000"), ("-1", "must be >= 0"), ("nan", "finite number"),
     ("0.5,x", "expected numbers"), (",".join(["1"] * 101), "more than 100 tolerances")],
)  # fmt: skip
def test_sweep_tolerances_are_checked_like_the_scene_key(text, needle):
    from sieve_mi.cascade.commands import parse_tolerances

    with pytest.raises(sm.SieveError) as e:
        parse_tolerances(text)
    _one_line(e, needle)
    assert parse_tolerances("0.5,1") == [0.5, 1.0]


def test_sweep_seed_and_seeds_are_one_option(tmp_path, capsys):
    from sieve_mi.cascade.commands import parse_seeds
    from sieve_mi.cli import _parser

    for flag in ("--seed", "--seeds"):
        assert _parser().parse_args(["sweep", DEFAULT, flag, "7"]).seeds == "7"
    assert parse_seeds("7") == [7]
    code, err = _cli(capsys, "sweep", DEFAULT, "--seed", "5-2", "--out", str(tmp_path / "o"))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "--seeds 5-2" in lines[0], err


def test_a_missing_mesh_names_the_scene_file_and_key(tmp_path, capsys):
    scene = tmp_path / "l.toml"
    cube = os.path.join(os.path.dirname(DEFAULT), "meshes", "cube.stl")
    scene.write_text(f'[[pass]]\nmesh = "{cube}"\n[[block]]\nmesh = "nope.stl"\n')
    code, err = _cli(capsys, "solve", str(scene), "--out", str(tmp_path / "o"))
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert f"{scene}: block[0].mesh: " in lines[0] and "nope.stl: mesh file not found" in lines[0]


def test_a_mixture_shape_name_is_reported_under_its_key(tmp_path):
    from sieve_mi.cascade.mixture import load_mixture

    path = tmp_path / "m.toml"
    path.write_text('[[shape]]\nmesh = "a.stl"\nname = "../x"\n[[shape]]\nmesh = "a.stl"\n')
    with pytest.raises(sm.SieveError) as e:
        load_mixture(str(path))
    _one_line(e, "shape[0].name: '../x' is used as a folder name")


# --- the API validates like the CLI (issue 40, rows 12, 13, 16 and 17) --------------------------

CUBE = os.path.join(os.path.dirname(DEFAULT), "meshes", "cube.stl")


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"sieve": CUBE, "axis": "w"}, "check: axis: 'w' is not one of: x, y, z"),
        ({"sieve": CUBE, "axis": None}, "check: axis: expected a non-empty string, got None"),
        ({"sieve": CUBE, "settings": {}}, "check: settings: expected a CheckSettings"),
        ({"sieve": CUBE, "settings": {"starts": 3}}, "got {'starts': 3}"),
        ({"sieve": CUBE, "image": "hole.png"}, "check: give sieve=PLATE (a plate mesh) or image=HOLE (a hole image), not both"),
        ({"sieve": 123}, "check: sieve: expected a file path (str), got 123"),
        ({"image": b"hole.png"}, "check: image: expected a file path (str), got b'hole.png'"),
        ({"sieve": CUBE, "units": 5}, "check: units: expected a non-empty string, got 5"),
        ({"image": "hole.png", "pixel_size": -1}, "check: pixel_size: must be > 0, got -1"),
        ({"image": "hole.png", "pixel_size": float("nan")}, "check: pixel_size: expected a finite number"),
        ({"sieve": CUBE, "progress": 3}, "check: progress: expected a function or None, got 3"),
    ],
)  # fmt: skip
def test_check_refuses_bad_arguments_in_one_line_before_any_work(kwargs, needle, monkeypatch):
    # Were KeyError ('w'), AttributeError (a dict for settings), or image= silently ignored.
    _must_not_run(monkeypatch, "sieve_mi.game.check.as_shape")  # the part is not even read
    with pytest.raises(sm.SieveError) as e:
        sm.check(CUBE, **kwargs)
    _one_line(e, needle)
    assert "--" not in str(e.value)


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"thin_budget": 0}, "check: thin_budget: must be > 0, got 0"),
        ({"thin_budget": float("nan")}, "check: thin_budget: expected a finite number, got nan"),
        ({"starts": 0}, "check: starts: must be >= 1, got 0"),
        ({"starts": 2.5}, "check: starts: expected a whole number, got 2.5"),
        ({"fit_tolerance": 1}, "check: fit_tolerance: must be < 1, got 1"),
        ({"strats": 4}, "check: strats: unknown setting; known: fit, fit_tolerance, learning_rate"),
    ],
)
def test_check_settings_are_checked_when_made(kwargs, needle):
    from sieve_mi.game.check import CheckSettings

    with pytest.raises(sm.SieveError) as e:
        CheckSettings(**kwargs)
    _one_line(e, needle)
    assert CheckSettings(starts=4.0, thin_budget=1).starts == 4  # whole floats are integers


@pytest.mark.parametrize(
    "table, make, needle",
    [
        ("solver", {"particles": 0}, "solver: particles: must be >= 1, got 0"),
        ("verdict", {"thin_budget": -1.0}, "verdict: thin_budget: must be > 0, got -1.0"),
        ("layout", {"mode": "stacked"}, "layout: mode: 'stacked' is not one of"),
        ("fabrication", {"thickness": "thin"}, "fabrication: thickness: expected a number or 'thinnest'"),
    ],
)  # fmt: skip
def test_settings_tables_are_checked_when_made(scene, table, make, needle):
    cls = type(getattr(scene, table))
    with pytest.raises(sm.SieveError) as e:
        cls(**make)
    _one_line(e, needle)


@pytest.mark.parametrize(
    "target, name, needle",
    [
        ("solver", "nosuchkey", "solver: nosuchkey: unknown setting; known: c_global, c_personal"),
        ("verdict", "start", "verdict: start: unknown setting; known: certify, certify_budget"),
        ("fabrication", "tolerence", "fabrication: tolerence: unknown setting"),
        ("layout", "a\nb", "layout: 'a\\nb': unknown setting"),
        (None, "unit", "scene: unit: unknown setting; known: blocks, directory, fabrication"),
    ],
)
def test_an_unknown_setting_name_is_refused_not_ignored(scene, target, name, needle):
    # A typo in a setting was silently kept as a new attribute, and the run used the default.
    obj = scene if target is None else getattr(scene, target)
    with pytest.raises(AttributeError) as e:  # what Python raises for a name it cannot set
        setattr(obj, name, 1)
    assert isinstance(e.value, sm.SieveError)  # and the CLI's one line
    _one_line(e, needle)
    assert not hasattr(obj, name)


@pytest.mark.parametrize(
    "name, value, needle",
    [
        ("units", "furlong", "scene: units: 'furlong' is not one of: mm, cm, m, in, um"),
        ("name", "../x", "scene: name: '../x' is used as a folder name"),
        ("name", 3, "scene: name: expected a string, got 3"),
        ("solver", {}, "scene: solver: expected a Solver table, got {}"),
    ],
)
def test_scene_fields_are_checked_when_set(name, value, needle):
    scene = sm.load_scene(DEFAULT)
    before = getattr(scene, name)
    with pytest.raises(sm.SieveError) as e:
        setattr(scene, name, value)
    _one_line(e, needle)
    assert getattr(scene, name) == before


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"scale": -1}, "load_shape: scale: must be > 0, got -1"),
        ({"scale": "x"}, "load_shape: scale: expected a number, got 'x'"),
        ({"name": "a\nb"}, "load_shape: name: 'a\\nb' has control characters"),
        ({"name": 3}, "load_shape: name: expected a string, got 3"),
    ],
)
def test_load_shape_checks_its_arguments(kwargs, needle):
    with pytest.raises(sm.SieveError) as e:
        sm.load_shape(CUBE, **kwargs)
    _one_line(e, needle)
    assert sm.load_shape(CUBE, scale=2, name="c").radius == pytest.approx(20 * 3**0.5, rel=1e-6)


def _garbage(tmp_path) -> dict:
    """Files that are not meshes, by name."""
    import numpy as np

    files = {
        "random.stl": np.random.default_rng(0).bytes(3000),
        "text.stl": b"hello\nthis is not a mesh\n",
        "empty.stl": b"",
        "random.obj": np.random.default_rng(1).bytes(500),
    }
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    return files


@pytest.mark.parametrize("name", ["random.stl", "text.stl", "empty.stl", "random.obj"])
def test_a_file_that_is_not_a_mesh_says_so(tmp_path, capsys, name):
    # Was "holds no triangles (a point cloud or empty scene?)", or "a truncated binary STL"
    # for random bytes.
    import hashlib

    from sieve_mi.cli import main

    data = _garbage(tmp_path)[name]
    path = str(tmp_path / name)
    with pytest.raises(sm.SieveError) as e:
        sm.load_shape(path)
    _one_line(e, f"{path}: could not be read as a mesh")
    assert "check that it is a triangle mesh file (STL, OBJ, PLY" in str(e.value)
    assert "point cloud" not in str(e.value) and "truncated" not in str(e.value)
    code = main(["check", path, "--sieve", CUBE, "--out", str(tmp_path / "o")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and lines == [f"sieve-mi: error: {e.value}"]
    assert hashlib.sha256(open(path, "rb").read()).digest() == hashlib.sha256(data).digest()
    assert not (tmp_path / "o").exists()


def test_a_point_cloud_is_named_as_one(tmp_path):
    path = tmp_path / "points.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(sm.SieveError) as e:
        sm.load_shape(str(path))
    _one_line(e, "holds points (a point cloud) but no triangles; give a triangle mesh")


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"budget_s": 0}, "certify settings: budget_s: expected a number > 0, got 0"),
        ({"min_angle": float("nan")}, "certify settings: min_angle: expected a number > 0, got nan"),
        ({"max_points": 2.5}, "certify settings: max_points: expected a whole number >= 1, got 2.5"),
        ({"kappa": 10**400}, "certify settings: kappa: expected a number >= 0, got an integer of 401 digits"),
    ],
)  # fmt: skip
def test_certify_settings_are_checked_and_typos_refused(kwargs, needle):
    from sieve_mi.certify.search import Settings

    with pytest.raises(sm.SieveError) as e:
        Settings(**kwargs)
    _one_line(e, needle)
    settings = Settings(edge_spacing=0, bound="isotropic")
    with pytest.raises(AttributeError) as e:
        settings.kapa = 0.1
    _one_line(e, "certify settings: kapa: unknown setting; known: bound, budget_s")
