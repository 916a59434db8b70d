"""Output folders (issue 18): sieve-mi never deletes what it did not write.

Refusals leave every byte in place; an earlier sieve-mi output is replaced whole; an interrupt
at any point leaves the old complete output (or the new complete one), never a mix, and no
``.sieve-mi-tmp-*`` folder.
"""

from __future__ import annotations

import filecmp
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import trimesh
from helpers import REPO, cli_run
from PIL import Image

from sieve_mi import cli
from sieve_mi.errors import SieveError
from sieve_mi.outputs import outdir

SMALL = """
[solver]
particles = 2
iterations = 1
starts = 2
steps = 5
resolution = 32
[verdict]
starts = 2
steps = 5
resolution = 32
"""
SCENE = (
    'name = "tiny"\n[[pass]]\nmesh = "meshes/cube.stl"\n[[block]]\nmesh = "meshes/sphere.stl"\n'
    + SMALL
)
CHECK_SMALL = ["--starts", "2", "--steps", "5", "--no-fit"]
REFUSED = "exists and holds files that sieve-mi did not write; choose another folder"


ROOT = REPO


def _env(env=None) -> dict:
    """The environment with this checkout first on the path (subprocesses run in other folders)."""
    env = dict(os.environ if env is None else env)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (ROOT, env.get("PYTHONPATH")) if p)
    return env


def run_cli(*args, cwd=None, env=None):
    return subprocess.run(
        [sys.executable, "-m", "sieve_mi", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=_env(env),
        timeout=600,
    )


def snapshot(root) -> dict:
    """Every file and folder under ``root``: relative path -> bytes (None for a folder)."""
    snap = {}
    for dirpath, _dirnames, filenames in os.walk(root):
        rel = os.path.relpath(dirpath, root)
        snap[rel] = None
        for f in filenames:
            with open(os.path.join(dirpath, f), "rb") as fh:
                snap[os.path.join(rel, f)] = fh.read()
    return snap


def temp_folders(parent) -> list[str]:
    return [f for f in os.listdir(parent) if f.startswith(outdir.TMP_PREFIX)]


def assert_complete(folder) -> dict:
    """``folder`` is one whole sieve-mi output: the marker lists exactly what is there."""
    marker = outdir.read_marker(str(folder))
    assert marker is not None
    files, folders = outdir._entries(str(folder))
    assert files - {outdir.MARKER} == set(marker["files"])
    assert folders == set(marker["folders"])
    return json.loads((folder / "report.json").read_text())


def assert_one_line_error(p, needle):
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert lines[0].startswith("sieve-mi: error: ") and needle in lines[0], lines[0]


@pytest.fixture
def scene_dir(write_scene, tmp_path):
    """A folder with scene.toml, meshes/cube.stl (20 mm), meshes/sphere.stl (r 12) and notes."""
    path = write_scene(
        SCENE,
        {
            "cube.stl": trimesh.creation.box((20.0, 20.0, 20.0)),
            "sphere.stl": trimesh.creation.icosphere(2, 12.0),
        },
    )
    (tmp_path / "mywork.txt").write_text("my own notes\n")
    return path


@pytest.fixture
def precious(tmp_path):
    """A folder of the user's files (one in a sub-folder)."""
    d = tmp_path / "precious"
    (d / "sub").mkdir(parents=True)
    (d / "thesis.tex").write_text("important\n")
    (d / "sub" / "data.csv").write_bytes(b"x,1\n")
    return d


def fake_output(folder, text="old") -> None:
    """An earlier sieve-mi output in ``folder`` written through outdir (report and a mask)."""
    with outdir.writing(str(folder), command="solve") as tmp:
        os.mkdir(os.path.join(tmp, "masks"))
        with open(os.path.join(tmp, "report.json"), "w") as fh:
            json.dump({"run": text}, fh)
        with open(os.path.join(tmp, "masks", "m.exr"), "w") as fh:
            fh.write(text)


# ------------------------------------------------------------------------------------------------
# Which folders may be written (no solve needed)
# ------------------------------------------------------------------------------------------------


def test_missing_empty_and_earlier_outputs_are_accepted(tmp_path):
    assert outdir.validate(str(tmp_path / "new" / "deeper")) == str(tmp_path / "new" / "deeper")
    (tmp_path / "empty").mkdir()
    fake_output(tmp_path / "empty")
    assert json.loads((tmp_path / "empty" / "report.json").read_text()) == {"run": "old"}
    fake_output(tmp_path / "empty", "new")  # an earlier output is replaced whole
    assert assert_complete(tmp_path / "empty") == {"run": "new"}
    assert (tmp_path / "empty" / "masks" / "m.exr").read_text() == "new"
    assert temp_folders(tmp_path) == []


@pytest.mark.parametrize(
    "added", ["notes.txt", "masks/notes.txt", "extra/", "masks/extra/", "link"]
)
def test_an_earlier_output_with_a_user_file_added_is_refused(tmp_path, added):
    out = tmp_path / "out"
    fake_output(out)
    if added == "link":
        os.symlink(tmp_path, out / "link")
    elif added.endswith("/"):
        (out / added).mkdir()
    else:
        (out / added).write_text("mine")
    before = snapshot(out)
    with pytest.raises(SieveError, match="did not write"):
        with outdir.writing(str(out), command="solve") as tmp:
            open(os.path.join(tmp, "report.json"), "w").close()
    assert snapshot(out) == before and temp_folders(tmp_path) == []


@pytest.mark.parametrize("damage", ["no marker", "bad marker", "no report"])
def test_a_folder_without_a_valid_marker_and_report_is_foreign(tmp_path, damage):
    out = tmp_path / "out"
    fake_output(out)
    if damage == "no marker":
        (out / outdir.MARKER).unlink()
    elif damage == "bad marker":
        (out / outdir.MARKER).write_text('{"files": "report.json"}')
    else:
        (out / "report.json").unlink()
    assert not outdir.is_replaceable(str(out))
    with pytest.raises(SieveError, match="did not write"):
        outdir.validate(str(out))


def test_protected_folders_are_refused_even_when_empty(tmp_path, monkeypatch):
    home, work = tmp_path / "home", tmp_path / "work"
    home.mkdir()
    work.mkdir()
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "shape.stl").write_text("solid")
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(work)
    cases = {
        ".": "is the working directory",
        "..": "contains the working directory",
        str(home): "is or contains your home folder",
        "/": "is a filesystem root",
        str(tmp_path / "in"): "holds the input file",
    }
    for out, needle in cases.items():
        with pytest.raises(SieveError, match=needle):
            outdir.validate(out, inputs=[str(tmp_path / "in" / "shape.stl")])
    assert os.listdir(work) == [] and os.listdir(home) == []
    assert os.listdir(tmp_path / "in") == ["shape.stl"]


def test_a_symlink_to_an_earlier_output_replaces_its_target(tmp_path):
    fake_output(tmp_path / "real")
    os.symlink(tmp_path / "real", tmp_path / "link")
    fake_output(tmp_path / "link", "new")
    assert os.path.islink(tmp_path / "link")
    assert assert_complete(tmp_path / "real") == {"run": "new"}
    (tmp_path / "file").write_text("x")
    with pytest.raises(SieveError, match="cannot write into"):
        outdir.validate(str(tmp_path / "file" / "sub" / "out"))
    os.symlink(tmp_path / "nowhere", tmp_path / "dangling")
    with pytest.raises(SieveError, match="broken symbolic link"):
        outdir.validate(str(tmp_path / "dangling"))


def test_stale_temp_folders_of_dead_runs_are_removed(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = outdir._host()
    names = {
        "dead": f"{outdir.TMP_PREFIX}{dead.pid}-{host}-0001",
        "dead_aside": f"{outdir.TMP_PREFIX}{dead.pid}-{host}-0002-old",
        "alive": f"{outdir.TMP_PREFIX}{os.getppid()}-{host}-0003",
        "other_host": f"{outdir.TMP_PREFIX}{dead.pid}-elsewhere-0004",
        "not_ours": ".sieve-mi-tmpfoo",
    }
    for name in names.values():
        (tmp_path / name).mkdir()
        (tmp_path / name / "f").write_text("x")
    fake_output(tmp_path / "out")
    left = set(os.listdir(tmp_path))
    assert names["dead"] not in left and names["dead_aside"] not in left
    assert {names["alive"], names["other_host"], names["not_ours"], "out"} <= left


def test_the_fallback_swap_restores_the_old_output_when_the_rename_fails(tmp_path, monkeypatch):
    out = tmp_path / "out"
    fake_output(out)
    before = snapshot(out)
    monkeypatch.setattr(outdir, "_exchange", lambda a, b: False)
    rename = os.rename

    def failing_rename(src, dst):
        if os.path.basename(src).startswith(outdir.TMP_PREFIX) and not src.endswith("-old"):
            raise KeyboardInterrupt  # between moving the old aside and moving the new in
        rename(src, dst)

    monkeypatch.setattr(os, "rename", failing_rename)
    with pytest.raises(KeyboardInterrupt):
        fake_output(out, "new")
    assert snapshot(out) == before and temp_folders(tmp_path) == []
    monkeypatch.setattr(os, "rename", rename)
    fake_output(out, "new")  # without renameat2 the swap still works
    assert assert_complete(out) == {"run": "new"} and temp_folders(tmp_path) == []


# ------------------------------------------------------------------------------------------------
# solve: refusals through the command line (stopped before the search)
# ------------------------------------------------------------------------------------------------


def test_solve_refuses_a_folder_of_foreign_files(scene_dir, precious, tmp_path):
    before = snapshot(tmp_path)
    p = run_cli("solve", scene_dir, "--out", str(precious), "--quiet", "--no-figure")
    assert_one_line_error(p, f"--out {precious} {REFUSED}")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "out, needle",
    [
        (".", "is the working directory"),
        ("..", "contains the working directory"),
        ("{scene}", "holds the input file"),
        ("{scene}/meshes", "holds the input file"),
        ("{home}", "your home folder"),
        ("/", "filesystem root"),
        ("/proc/x", "cannot write into /proc"),  # root may "access" it; refused before the solve
        ("/sys/x", "cannot write into /sys"),
    ],
)
def test_solve_refuses_protected_folders(scene_dir, tmp_path, tmp_path_factory, out, needle):
    home, elsewhere = tmp_path_factory.mktemp("home"), tmp_path_factory.mktemp("elsewhere")
    (home / ".bashrc").write_text("# mine\n")
    env = dict(os.environ, HOME=str(home))
    out = out.format(scene=os.path.dirname(scene_dir), home=home)
    cwd = tmp_path if out in (".", "..") else elsewhere  # tmp_path holds the scene
    before = snapshot(tmp_path), snapshot(home)
    p = run_cli("solve", scene_dir, "--out", out, "--quiet", "--no-figure", cwd=cwd, env=env)
    assert_one_line_error(p, needle)
    assert (snapshot(tmp_path), snapshot(home)) == before and os.listdir(elsewhere) == []


# ------------------------------------------------------------------------------------------------
# solve: replacing and interrupting (one tiny solve, written several times)
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_result(tmp_path_factory):
    from sieve_mi.api import solve
    from sieve_mi.scene import load_scene

    d = tmp_path_factory.mktemp("tiny")
    (d / "meshes").mkdir()
    trimesh.creation.box((20.0, 20.0, 20.0)).export(str(d / "meshes" / "cube.stl"))
    trimesh.creation.icosphere(2, 12.0).export(str(d / "meshes" / "sphere.stl"))
    (d / "scene.toml").write_text(SCENE)
    return solve(load_scene(str(d / "scene.toml")), progress=False)


def _write(result, out):
    """Write ``result``'s outputs into ``out`` as solve does, but for the two renders: the
    folder's rules do not depend on which files it holds (the signal tests below interrupt a
    real solve, passage.gif and all)."""
    from sieve_mi.outputs.report import write_outputs

    return write_outputs(result, str(out), figure=False, animation=False)


@pytest.mark.slow
def test_solve_output_replaces_an_earlier_output_but_not_a_user_file(tiny_result, tmp_path):
    out = tmp_path / "out"
    _write(tiny_result, out)
    report = assert_complete(out)
    assert {"sieve.stl", "hole.svg", "report.json"} <= set(os.listdir(out))
    assert report["name"] == "tiny" and outdir.read_marker(str(out))["command"] == "solve"
    (out / "hole.svg").write_text("stale")  # a file sieve-mi wrote, edited: still replaceable
    _write(tiny_result, out)
    assert (out / "hole.svg").read_text().startswith("<")
    (out / "masks" / "notes.txt").write_text("mine")
    before = snapshot(out)
    with pytest.raises(SieveError, match="did not write"):
        _write(tiny_result, out)
    assert snapshot(out) == before and temp_folders(tmp_path) == []


def _raise_interrupt(*args, **kwargs):
    raise KeyboardInterrupt


@pytest.mark.slow
@pytest.mark.parametrize(
    "module, name",
    [
        ("sieve_mi.outputs.fabrication", "write_svg"),  # the plate's files: sieve.stl is written
        ("sieve_mi.outputs.outdir", "write_marker"),  # every output written, the marker fails
        ("sieve_mi.outputs.outdir", "_exchange"),  # at the swap itself
    ],
)
def test_an_interrupted_solve_leaves_the_old_output(
    tiny_result, tmp_path, monkeypatch, module, name
):
    out = tmp_path / "out"
    _write(tiny_result, out)
    (out / "hole.svg").write_text("old")  # tells the old output from a new one
    before = snapshot(out)
    monkeypatch.setattr(sys.modules[module], name, _raise_interrupt)
    with pytest.raises(KeyboardInterrupt):
        _write(tiny_result, out)
    assert snapshot(out) == before and temp_folders(tmp_path) == []
    if name == "_exchange":
        return  # a first run renames its folder in: no exchange
    with pytest.raises(KeyboardInterrupt):
        _write(tiny_result, tmp_path / "new" / "fresh")  # a first run leaves nothing at all
    assert not (tmp_path / "new").exists() and temp_folders(tmp_path) == []


@pytest.mark.slow
@pytest.mark.parametrize(
    "module, name, missing",
    [
        ("sieve_mi.outputs.plots", "overlay_figure", ["hole.png", "masks", "overlay.png"]),
        ("sieve_mi.outputs.viewer", "write_page", ["report.html"]),
    ],
)
def test_a_solve_stopped_after_its_verdict_keeps_the_verdict_and_the_plate(
    tiny_result, tmp_path, monkeypatch, capsys, module, name, missing
):
    whole = _write(tiny_result, tmp_path / "whole")
    out = tmp_path / "out"
    _write(tiny_result, out)
    (out / "hole.svg").write_text("old")  # tells the old output from the new one
    monkeypatch.setattr(sys.modules[module], name, _raise_interrupt)
    with pytest.raises(KeyboardInterrupt):
        _write(tiny_result, out)
    assert temp_folders(tmp_path) == []
    assert_complete(out)  # the marker lists exactly what is there: a later solve replaces it
    report = json.loads((out / "report.json").read_text())
    assert set(missing) <= set(report["incomplete"]["missing"])
    assert not any((out / f).exists() for f in report["incomplete"]["missing"])
    assert report["block"][0]["blocked"] == whole["block"][0]["blocked"]
    assert report["fabrication"]["thickness"] == whole["fabrication"]["thickness"]
    for f in ("sieve.stl", "hole.svg", "pass_0.stl", "block_0.stl"):
        assert filecmp.cmp(out / f, tmp_path / "whole" / f, shallow=False), f
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "kept report.json and the plate; missing:" in err[0]
    monkeypatch.undo()
    _write(tiny_result, out)  # the next solve completes it
    assert "incomplete" not in json.loads((out / "report.json").read_text())


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_while_writing_leaves_the_old_output(scene_dir, tiny_result, tmp_path, sig, code):
    out = tmp_path / "out"
    _write(tiny_result, out)
    (out / "hole.svg").write_text("old")
    before = snapshot(out)
    args = ["solve", scene_dir, "--out", str(out), "--quiet", "--no-figure"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "sieve_mi", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )
    deadline = time.monotonic() + 300
    while not temp_folders(tmp_path) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.002)
    proc.send_signal(sig)  # the outputs are being written into the temporary folder
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == code, err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("sieve-mi: ")
    assert temp_folders(tmp_path) == []
    if snapshot(out) != before:  # the signal came after the verdict's files: those are kept
        assert "kept report.json and the plate" in err
        assert_complete(out)
        assert json.loads((out / "report.json").read_text())["incomplete"]["missing"]


# ------------------------------------------------------------------------------------------------
# check --out
# ------------------------------------------------------------------------------------------------


@pytest.fixture
def check_files(tmp_path):
    """A 10 mm cube and a 16 mm square hole image (pixel 1 mm) in tmp_path/in."""
    d = tmp_path / "in"
    d.mkdir()
    trimesh.creation.box((10.0, 10.0, 10.0)).export(str(d / "cube.stl"))
    img = np.zeros((24, 24), np.uint8)
    img[4:20, 4:20] = 255
    Image.fromarray(img).save(d / "hole.png")
    return str(d / "cube.stl"), ["--hole", str(d / "hole.png"), "--pixel-size", "1"]


@pytest.mark.slow
def test_check_out_writes_and_replaces_its_report(check_files, precious, tmp_path, capsys):
    shape, hole = check_files
    out = tmp_path / "checked"
    p = cli_run(capsys, "check", shape, *hole, *CHECK_SMALL, "--json", "--out", str(out))
    assert p.returncode == 0, p.stderr
    report = assert_complete(out)
    assert report == json.loads(p.stdout) and report["passes"] is True
    assert outdir.read_marker(str(out))["command"] == "check"
    p = cli_run(
        capsys, "check", shape, *hole, *CHECK_SMALL, "--scale", "2", "--json", "--out", str(out)
    )
    assert p.returncode == 3, p.stderr  # blocked
    assert assert_complete(out)["passes"] is False  # 20 mm cube, 16 mm hole: replaced
    before = snapshot(tmp_path)
    for target, needle in ((precious, REFUSED), (tmp_path / "in", "holds the input file")):
        p = cli_run(capsys, "check", shape, *hole, *CHECK_SMALL, "--out", str(target))
        assert_one_line_error(p, needle)
    assert snapshot(tmp_path) == before


@pytest.mark.slow
def test_an_interrupted_check_leaves_the_old_output(check_files, tmp_path, monkeypatch, capsys):
    shape, hole = check_files
    out = tmp_path / "checked"
    assert cli.main(["check", shape, *hole, *CHECK_SMALL, "--out", str(out)]) == 0
    before = snapshot(out)
    monkeypatch.setattr(outdir, "write_marker", _raise_interrupt)
    code = cli.main(["check", shape, *hole, *CHECK_SMALL, "--scale", "2", "--out", str(out)])
    assert code == 130 and "interrupted" in capsys.readouterr().err
    assert snapshot(out) == before and temp_folders(tmp_path) == []


def test_signals_sent_from_another_thread_wait_for_the_block_to_end():
    # A signal sent to the process may be delivered to any thread (Dr.Jit has workers); the
    # deferral must hold it back all the same, and raise it once the block ends.
    import threading

    reached = []
    with pytest.raises(KeyboardInterrupt):
        with outdir.deferred_signals():
            sender = threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGINT))
            sender.start()
            sender.join()
            for _ in range(100):  # many chances for Python to run a pending handler
                time.sleep(0.001)
            reached.append(True)
    assert reached == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_deferred_signals_arrive_even_when_the_thread_blocks_them():
    # A process may inherit a mask that blocks SIGINT (launchers do that); the signal must not
    # stay pending past the block, and the caller's mask comes back afterwards.
    import time

    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        with pytest.raises(KeyboardInterrupt):
            with outdir.deferred_signals():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)
        assert signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])
        assert signal.SIGINT not in signal.sigpending()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def test_a_leftover_of_a_killed_addition_is_removed_but_a_live_one_or_a_users_file_is_not(
    tmp_path,
):
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "report.json").write_text("{}")
    outdir.write_marker(str(folder), "solve")
    proc = subprocess.Popen(["true"])  # a process that has ended: its pid is free
    proc.wait()
    dead = proc.pid
    (folder / f".shake.json.sieve-mi-tmp-{dead}").write_text("half")
    outdir.add_files(str(folder), {"shake.json": b"{}"})
    assert sorted(os.listdir(folder)) == [outdir.MARKER, "report.json", "shake.json"]
    (folder / f".shake.json.sieve-mi-tmp-{os.getppid()}").write_text("a live run's")
    with pytest.raises(SieveError, match="marker does not list"):
        outdir.check_addition(str(folder), ["shake.json"])
    os.remove(folder / f".shake.json.sieve-mi-tmp-{os.getppid()}")
    (folder / f"shake.json.sieve-mi-tmp-{dead}").write_text("mine: no leading dot")
    with pytest.raises(SieveError, match="marker does not list"):
        outdir.check_addition(str(folder), ["shake.json"])


def test_an_output_this_run_did_not_make_is_dropped_but_a_users_file_stays(tmp_path):
    # shake DIR without a clip after a shake with one: the earlier shake.gif showed other
    # trials, so it goes (and leaves the marker); a file the marker does not list is the user's.
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "report.json").write_text("{}")
    outdir.write_marker(str(folder), "solve")
    outdir.add_files(str(folder), {"shake.json": b"{}", "shake.gif": b"GIF89a"})
    assert "shake.gif" in outdir.read_marker(str(folder))["files"]
    outdir.add_files(str(folder), {"shake.json": b'{"n": 2}'}, drop=("shake.gif", "notes.txt"))
    assert sorted(os.listdir(folder)) == [outdir.MARKER, "report.json", "shake.json"]
    assert "shake.gif" not in outdir.read_marker(str(folder))["files"]
    assert (folder / "shake.json").read_bytes() == b'{"n": 2}'
    outdir.write_marker(str(folder), "solve")  # lists report.json and shake.json only
    (folder / "shake.gif").write_bytes(b"the user's")
    with pytest.raises(SieveError, match="marker does not list"):
        outdir.add_files(str(folder), {"report.json": b"{}"}, drop=("shake.gif",))
    assert (folder / "shake.gif").read_bytes() == b"the user's"
