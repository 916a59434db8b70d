"""The paper authors' JSON configurations (docs/authors-config.md): mapping, refusals, a solve."""

from __future__ import annotations

import json
import os
import shutil

import pytest
from helpers import REPO, cli_run

import sieve_mi as sm
from sieve_mi.authors_config import NO_EFFECT, SETTINGS, load_authors_config

MESHES = os.path.join(REPO, "scenes", "meshes")


def _config(**changes) -> dict:
    """A configuration as the authors' scripts write it (their default values), one A, one B."""
    data = {
        "name": "cube_vs_sphere",
        "simulation_scale": 0.01,
        "meshes_A": [{"filename": "cube.stl", "fabrication_scale": 1.0, "fabrication_offset": 1.0}],
        "meshes_B": [
            {"filename": "sphere.stl", "fabrication_scale": 1.2, "fabrication_offset": None}
        ],
        "meshes_A_winning_rot_vecs": None,
        "mesh_A_opt_num_posns": 7,
        "mesh_A_fill_soft_mask_holes": False,
        "mesh_B_opt_num_posns": 5,
        "mesh_B_opt_posn_trans_bounds": [-0.1, 0.1],
        "mesh_B_opt_use_area_proportion": True,
        "mesh_B_opt_vtx_out_of_bounds_loss_weight": 0,
        "mesh_B_opt_iters": 40,
        "mesh_B_opt_learning_rate": 0.02,
        "mesh_A_pso_c1": 0.3,
        "mesh_A_pso_c2": 0.35,
        "mesh_A_pso_w": 0.5,
        "mesh_A_pso_iters": 3,
        "proj_A_pso_c1": 0.06,
        "proj_A_pso_c2": 0.07,
        "proj_A_pso_w": 0.5,
        "proj_A_pso_iters": 10,
        "pso_verbose": True,
        "image_shape": [96, 96],
        "sieve_side_length": 80.0,
        "sieve_thickness": 45.0,
        "sieve_resolution": [1024, 1024],
    }
    data.update(changes)
    return data


@pytest.fixture
def authors_repo(tmp_path):
    """The authors' layout: configurations in scripts/, meshes in data/."""
    (tmp_path / "scripts").mkdir()
    (tmp_path / "data").mkdir()
    for name in ("cube.stl", "sphere.stl"):
        shutil.copy(os.path.join(MESHES, name), tmp_path / "data" / name)

    def write(**changes) -> str:
        path = tmp_path / "scripts" / "config.json"
        path.write_text(json.dumps(_config(**changes), indent=2))
        return str(path)

    return write


def test_every_key_maps_to_the_scene(authors_repo):
    scene = sm.load_scene(authors_repo())
    assert scene.name == "cube_vs_sphere" and scene.units == "mm"
    assert [(e.mesh, e.scale) for e in scene.passes] == [
        (os.path.join("..", "data", "cube.stl"), 1.0)
    ]
    assert [(e.mesh, e.scale) for e in scene.blocks] == [
        (os.path.join("..", "data", "sphere.stl"), 1.2)
    ]
    assert os.path.isfile(scene.resolve(scene.passes[0].mesh))
    s, f, v, lay = scene.solver, scene.fabrication, scene.verdict, scene.layout
    assert (s.particles, s.iterations, s.inertia, s.c_personal, s.c_global) == (
        7,
        3,
        0.5,
        0.3,
        0.35,
    )
    assert (s.starts, s.steps, s.learning_rate, s.resolution) == (5, 40, 0.02, 96)
    assert (f.tolerance, f.fill_holes, f.thickness) == (1.0, False, 45.0)
    assert (lay.c_personal, lay.c_global, v.resolution) == (0.06, 0.07, 96)
    # every key of the authors' format is either mapped, without effect, or read as above
    assert set(_config()) <= set(SETTINGS) | set(NO_EFFECT) | {
        "name", "meshes_A", "meshes_B", "meshes_A_winning_rot_vecs", "image_shape",
        "mesh_B_opt_use_area_proportion",
    }  # fmt: skip
    unset = sm.load_scene(
        authors_repo(meshes_A=[{"filename": "cube.stl", "fabrication_offset": None}])
    )
    assert unset.fabrication.tolerance == 0.0 and unset.passes[0].scale == 1.0


def test_the_bundled_example_reads():
    scene = sm.load_scene(os.path.join(REPO, "scenes", "cube-vs-sphere.json"))
    assert [e.mesh for e in scene.passes + scene.blocks] == ["meshes/cube.stl", "meshes/sphere.stl"]
    assert scene.fabrication.tolerance == 1.0 and scene.solver.particles == 10


@pytest.mark.parametrize(
    "changes, needle",
    [
        ({"mesh_A_opt_num_particles": 3}, "mesh_A_opt_num_particles: unknown key"),
        ({"meshes_A": [{"filename": "cube.stl", "scale": 2}]}, "meshes_A[0].scale: unknown key"),
        ({"mesh_A_opt_num_posns": 0}, "mesh_A_opt_num_posns: must be >= 1"),
        ({"mesh_B_opt_learning_rate": "fast"}, "mesh_B_opt_learning_rate: "),
        ({"meshes_B": [{"filename": "nope.stl"}]}, "meshes_B[0].filename: nope.stl: mesh file not found"),
        ({"meshes_A": []}, "meshes_A: expected a list of one or more meshes"),
        ({"meshes_B": [{"filename": "sphere.stl", "fabrication_offset": 0.5}]}, "meshes_B[0].fabrication_offset"),
        ({"image_shape": [256, 128]}, "image_shape: [256, 128]: sieve-mi's raster is square"),
        ({"meshes_A_winning_rot_vecs": [[1, 0, 0, 0, 1, 0]]}, "meshes_A_winning_rot_vecs: fixed A rotations"),
        ({"mesh_B_opt_use_area_proportion": False}, "mesh_B_opt_use_area_proportion"),
        ({"simulation_scale": -1}, "simulation_scale: expected a number > 0"),
        ({"sieve_resolution": [1024]}, "sieve_resolution: expected two whole numbers"),
        ({"name": "a/b"}, "name: 'a/b' is used as a folder name"),
    ],
)  # fmt: skip
def test_bad_keys_are_one_line_naming_the_key(authors_repo, changes, needle):
    path = authors_repo(**changes)
    with pytest.raises(sm.SieveError) as e:
        load_authors_config(path)
    message = str(e.value)
    assert "\n" not in message and message.startswith(f"{path}: ") and needle in message, message


#: (changes, how the line goes on after "<path>: "): values shown as JSON writes them.
JSON_SPELLING = [
    ({"sieve_thickness": None}, "sieve_thickness: expected a number, got null"),
    ({"mesh_A_pso_iters": True}, "mesh_A_pso_iters: expected a whole number, got true"),
    ({"mesh_B_opt_learning_rate": False}, "mesh_B_opt_learning_rate: expected a number, got false"),
    ({"mesh_B_opt_num_posns": "ten"}, 'mesh_B_opt_num_posns: expected a whole number, got "ten"'),
    ({"image_shape": [None, None]}, "image_shape: expected a whole number, got null"),
    ({"image_shape": [None, 3]}, "image_shape: [null, 3]: sieve-mi's raster is square; give [N, N]"),
    ({"meshes_A": [{"filename": "cube.stl", "fabrication_scale": None}]},
     "meshes_A[0].fabrication_scale: expected a number, got null"),
]  # fmt: skip


@pytest.mark.parametrize("changes, words", JSON_SPELLING, ids=range(len(JSON_SPELLING)))
def test_values_are_shown_in_json_spelling(authors_repo, capsys, tmp_path, changes, words):
    # Were Python's spellings: "got None", "got True", "got 'ten'".
    import hashlib

    from sieve_mi.cli import main

    path = authors_repo(**changes)
    before = hashlib.sha256(open(path, "rb").read()).hexdigest()
    code, err = main(["solve", path, "--out", str(tmp_path / "o")]), capsys.readouterr().err
    assert code == 2 and err == f"sieve-mi: error: {path}: {words}\n", err
    assert hashlib.sha256(open(path, "rb").read()).hexdigest() == before
    assert not (tmp_path / "o").exists()


def test_two_a_offsets_must_agree(authors_repo):
    meshes = [
        {"filename": "cube.stl", "fabrication_offset": 1.0},
        {"filename": "cube.stl", "fabrication_offset": 0.5},
    ]
    with pytest.raises(sm.SieveError, match=r"meshes_A\[\*\].fabrication_offset: \[0.5, 1.0\]"):
        load_authors_config(authors_repo(meshes_A=meshes))


def test_cli_refuses_an_unknown_key_in_one_line(authors_repo, tmp_path, capsys):
    from sieve_mi.cli import main  # in this process: any other exception fails the test

    code = main(["solve", authors_repo(sieve_colour="red"), "--out", str(tmp_path / "o")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert lines[0].startswith("sieve-mi: error: ") and "sieve_colour: unknown key" in lines[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_solve_reads_a_configuration(authors_repo, tmp_path, capsys):
    out = tmp_path / "o"
    config = authors_repo(mesh_A_opt_num_posns=4, mesh_A_pso_iters=1, mesh_B_opt_num_posns=4)
    run = cli_run(  # in this process: the reading is the subject, not the process
        capsys,
        "solve",
        config,
        "--out",
        str(out),
        "--quiet",
        "--json",
        "--no-figure",
        "--no-animation",
    )
    report = json.loads(run.stdout)
    assert run.returncode == (0 if report["winner"] == "A" else 3), run.stderr
    assert report["name"] == "cube_vs_sphere" and [p["name"] for p in report["pass"]] == ["cube"]
    settings = report["settings"]
    assert settings["solver"]["particles"] == 4 and settings["solver"]["resolution"] == 96
    assert (
        settings["fabrication"]["tolerance"] == 1.0 and settings["fabrication"]["thickness"] == 45.0
    )
    assert report["winner"] == "A"  # a 20 mm cube's hole blocks a 28.8 mm ball


# --- numbers, nesting and keys no reader should meet (issue 40, rows 11 and 18) -----------------


def _raw(authors_repo, key: str, text: str) -> str:
    """A configuration whose ``key`` holds the raw JSON ``text`` (written as it is)."""
    path = authors_repo(**{key: 1})
    with open(path, encoding="utf-8") as fh:
        doc = fh.read()
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(doc.replace(f'"{key}": 1', f'"{key}": {text}', 1))
    return path


#: (key, raw JSON value, words of the message after "<path>: <key>...").
HOSTILE = [
    ("mesh_A_pso_iters", "9" * 5000, "mesh_A_pso_iters: an integer of 5,000 digits"),
    ("mesh_B_opt_learning_rate", "9" * 400 + ".0", "mesh_B_opt_learning_rate: 9999999999999999999… is beyond"),
    ("mesh_B_opt_learning_rate", "1e400", "mesh_B_opt_learning_rate: 1e400 is beyond a number's range"),
    ("mesh_A_pso_w", "9" * 400, "mesh_A_pso_w: an integer of 400 digits is beyond a number's range"),
    ("image_shape", f"[{'9' * 400}, {'9' * 400}]", "image_shape: must be <= 4096, got an integer of 400 digits"),
    ("simulation_scale", "[" * 50_000 + "]" * 50_000, "simulation_scale (line "),
    ("simulation_scale", "[" * 40 + "]" * 40, "simulation_scale[0][0][0][0][0].…: arrays or tables nested"),
    ("mesh_B_opt_num_posns", "2.5", "mesh_B_opt_num_posns: expected a whole number, got 2.5"),
    ("mesh_A_pso_iters", '3, "mesh_A_pso_iters": 30', "mesh_A_pso_iters: given twice in one object"),
    ("meshes_B", '[{"filename": "sphere.stl", "filename": "cube.stl"}]', "filename: given twice"),
]  # fmt: skip


@pytest.mark.parametrize("key, text, words", HOSTILE, ids=range(len(HOSTILE)))
def test_hostile_numbers_nesting_and_duplicate_keys_are_one_line(
    authors_repo, capsys, tmp_path, key, text, words
):
    # Were ValueError, OverflowError and RecursionError tracebacks, or (a duplicate key) the
    # last value silently; now one line naming the file and the key, exit 2, nothing touched.
    import hashlib

    from sieve_mi.cli import main

    path = _raw(authors_repo, key, text)
    before = hashlib.sha256(open(path, "rb").read()).hexdigest()
    code, err = main(["solve", path, "--out", str(tmp_path / "o")]), capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"sieve-mi: error: {path}: ") and words in lines[0], lines[0]
    assert hashlib.sha256(open(path, "rb").read()).hexdigest() == before
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("key", [*SETTINGS, *NO_EFFECT])
def test_every_key_takes_extreme_numbers_or_refuses_them_in_one_line(authors_repo, key):
    for text in ["9" * 5000, "9" * 400, "-" + "9" * 400 + ".5", "1e-400", "NaN", "-Infinity",
                 "2.0", "[[[[1]]]]", "{}", '"x"', "true", "null"]:  # fmt: skip
        path = _raw(authors_repo, key, text)
        try:
            load_authors_config(path)
        except sm.SieveError as e:
            assert "\n" not in str(e) and str(e).startswith(f"{path}: "), (key, text, str(e))


def test_a_whole_float_is_an_integer_for_every_integer_key(authors_repo):
    # 10.0 is 10 for the keys that become settings and for those without effect alike.
    scene = load_authors_config(authors_repo(mesh_A_pso_iters=3.0, proj_A_pso_iters=10.0))
    assert scene.solver.iterations == 3 and type(scene.solver.iterations) is int
    with pytest.raises(sm.SieveError, match=r"proj_A_pso_iters: expected a whole number >= 0"):
        load_authors_config(authors_repo(proj_A_pso_iters=10.5))
