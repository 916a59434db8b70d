"""Trust in certificates (issue 40, rows 1, 4, 12c, 15): a file is a certificate only when it
parses as one, a certificate is written atomically, and the replay re-derives every claim.

Known answers: the hole is a 22 mm square (its largest disk has radius 11). The 24 mm sphere
(inscribed ball radius ~11.9) is proved blocked at the root; a 15 mm cube passes face-on; a
40 x 40 x 4 mm plate is proved blocked by the cell tree (every projection is at least 40 mm long,
the square's diagonal 31.1 mm); a 31.5 x 31.5 x 4 mm slab is left undecided in 0.05 s.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import re

import manifold3d
import pytest

from sieve_mi import cli
from sieve_mi.certify import certificate, certify, replay
from sieve_mi.certify.certificate import FORMAT
from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.testing import shapes

SQUARE = manifold3d.CrossSection.square([22.0, 22.0], center=True)


@pytest.fixture(scope="module")
def certs() -> dict:
    """Certificates of each kind against the 22 mm square: the status and the dict."""
    made = {
        "ball": (shapes.sphere(12.0), 5.0),
        "tree": (shapes.box(40.0, 40.0, 4.0), 5.0),
        "passage": (shapes.cube(15.0), 5.0),
        "undecided": (shapes.box(31.5, 31.5, 4.0), 0.05),
    }
    out = {}
    for name, (mesh, budget) in made.items():
        c = certify(shape_from_trimesh(mesh, name=name), [SQUARE], budget_s=budget)
        out[name] = c
    assert {k: c.status for k, c in out.items()} == {
        "ball": "proved",
        "tree": "proved",
        "passage": "passage",
        "undecided": "undecided",
    }
    assert out["ball"].method == "ball" and out["tree"].method == "cells"
    return {k: c.certificate for k, c in out.items()}


@pytest.fixture
def run(tmp_path):
    """A 24 mm ball and a 60 x 60 x 3 mm plate with a 22 mm round hole in ``tmp_path``; returns
    a function running ``sieve-mi certify ball24.stl --sieve plate22.stl ARGS`` in-process."""
    shapes.sphere(12.0).export(str(tmp_path / "ball24.stl"))
    plate = manifold3d.Manifold.cube([60.0, 60.0, 3.0], center=True) - manifold3d.Manifold.cylinder(
        10.0, 11.0, 11.0, 96, center=True
    )
    shapes.from_manifold(plate).export(str(tmp_path / "plate22.stl"))

    def go(*args: str) -> int:
        return cli.main(
            ["certify", str(tmp_path / "ball24.stl"), "--sieve", str(tmp_path / "plate22.stl"),
             *args]
        )  # fmt: skip

    return go


def _tree_state(folder) -> dict:
    """Every entry under ``folder``: a file's SHA-256, a link's target, or "dir"."""
    state = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = os.path.join(root, name)
            if os.path.islink(p):
                state[p] = "link -> " + os.readlink(p)
            elif os.path.isdir(p):
                state[p] = "dir"
            else:
                with open(p, "rb") as fh:
                    state[p] = hashlib.sha256(fh.read()).hexdigest()
    return state


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sieve-mi: error: "), err
    return err[0]


# ------------------------------------------------------------------------------------------------
# Row 1: --certificate overwrites only a file that parses as a certificate
# ------------------------------------------------------------------------------------------------


def _full_cert_text(certs) -> str:
    return json.dumps(certs["ball"])


NOT_CERTIFICATES = {
    # the reproduction: the format line quoted in a note
    "doc.md": lambda c: f'notes\n"format": "{FORMAT}"\n',
    # a JSON collection with the key nested, and one holding a whole certificate
    "nested.json": lambda c: json.dumps({"items": [{"format": FORMAT}]}),
    "list.json": lambda c: "[" + _full_cert_text(c) + "]",
    # the top-level format but not a certificate's structure
    "partial.json": lambda c: json.dumps({"format": FORMAT, "notes": "mine"}),
    "wrapped.json": lambda c: json.dumps(
        {"format": FORMAT, "backup": json.loads(_full_cert_text(c))}
    ),
    # not JSON at all
    "binary.json": lambda c: "\x00\x01solid ball\n" + f'"format": "{FORMAT}"',
}


@pytest.mark.parametrize("name", sorted(NOT_CERTIFICATES))
def test_a_file_that_only_mentions_the_format_is_refused_byte_identical(
    tmp_path, run, certs, capsys, monkeypatch, name
):
    target = tmp_path / name
    target.write_text(NOT_CERTIFICATES[name](certs))
    before = _tree_state(tmp_path)
    import sieve_mi.geometry.meshes as meshes

    def no_work(*a, **k):
        raise AssertionError("the run started work before refusing --certificate")

    monkeypatch.setattr(meshes, "load_shape", no_work)
    assert run("--certificate", str(target)) == 2
    line = _one_error_line(capsys)
    assert f"--certificate {target}: exists and is not a sieve-mi certificate" in line
    assert _tree_state(tmp_path) == before


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda t: (t / "sub").mkdir() or t / "sub", "is a folder"),
        (lambda t: str(t / "new") + "/", "is a folder"),
        (lambda t: t / "missing" / "c.json", "does not exist"),
        (lambda t: (t / "l.json").symlink_to(t / "real.json") or t / "l.json", "symbolic link"),
        (lambda t: (t / "d.json").symlink_to(t / "nowhere") or t / "d.json", "symbolic link"),
        (lambda t: t / "ball24.stl", "is an input of this run"),
    ],
    ids=["folder", "trailing-slash", "missing-folder", "link-to-cert", "dangling-link", "input"],
)
def test_certificate_paths_that_would_lose_data_are_refused(tmp_path, run, capsys, make, message):
    assert run("--certificate", str(tmp_path / "real.json")) == 0  # a real certificate
    capsys.readouterr()
    target = make(tmp_path)
    before = _tree_state(tmp_path)
    assert run("--certificate", str(target)) == 2
    assert message in _one_error_line(capsys)
    assert _tree_state(tmp_path) == before


def test_an_empty_certificate_path_is_refused_not_ignored(tmp_path, run, capsys):
    before = _tree_state(tmp_path)
    assert run("--certificate", "") == 2
    assert "--certificate '': name a file" in _one_error_line(capsys)
    assert _tree_state(tmp_path) == before


def test_an_unwritable_folder_is_refused_before_the_work(tmp_path, run, capsys, monkeypatch):
    # root may write anywhere, so the folder's permission is what os.access reports here
    real = os.access
    monkeypatch.setattr(
        os, "access", lambda p, mode: False if str(p) == str(tmp_path) else real(p, mode)
    )
    before = _tree_state(tmp_path)
    assert run("--certificate", str(tmp_path / "c.json")) == 2
    assert "is not writable" in _one_error_line(capsys)
    assert _tree_state(tmp_path) == before


def test_own_certificate_is_replaced_and_no_temporary_file_is_left(tmp_path, run, capsys):
    cert = tmp_path / "c.json"
    assert run("--certificate", str(cert)) == 0
    first = cert.read_bytes()
    assert run("--certificate", str(cert)) == 0  # it is sieve-mi's own: replaced
    data = json.loads(cert.read_text())
    assert certificate.is_certificate(data) and data["status"] == "proved"
    assert cert.read_bytes() == first  # deterministic
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ball24.stl", "c.json", "plate22.stl"]
    assert oct(cert.stat().st_mode & 0o777) != "0o600"  # not the temporary file's private mode


@pytest.mark.parametrize("failure", [KeyboardInterrupt, OSError])
def test_an_interrupted_or_failed_write_keeps_the_old_certificate(
    tmp_path, run, capsys, monkeypatch, failure
):
    cert = tmp_path / "c.json"
    assert run("--certificate", str(cert)) == 0
    capsys.readouterr()
    before = _tree_state(tmp_path)
    real_dump = json.dump

    def half_then_fail(obj, fh, **kw):  # half the JSON is on disk in the temporary file
        text = json.dumps(obj)
        fh.write(text[: len(text) // 2])
        fh.flush()
        raise failure(28, "No space left on device") if failure is OSError else failure()

    monkeypatch.setattr(certificate.json, "dump", half_then_fail)
    code = run("--certificate", str(cert))
    monkeypatch.setattr(certificate.json, "dump", real_dump)
    err = capsys.readouterr().err.strip().splitlines()
    if failure is OSError:
        assert code == 2 and len(err) == 1 and "cannot write the certificate" in err[0]
    else:
        assert code == 130 and err == ["sieve-mi: interrupted"]
    assert _tree_state(tmp_path) == before  # the old certificate intact, no temporary file


# ------------------------------------------------------------------------------------------------
# Rows 4 and 15: the replay re-derives the status; a rejection always says why
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kind, claim, shown",
    [
        ("ball", "passage", "proved"),  # row 4
        ("ball", "undecided", "proved"),
        ("tree", "passage", "proved"),
        ("tree", "undecided", "proved"),
        ("passage", "proved", "passage"),  # row 15
        ("passage", "undecided", "passage"),
        ("undecided", "proved", "undecided"),
        ("undecided", "passage", "undecided"),
    ],
)
def test_replay_rejects_a_relabelled_status_naming_the_field(
    tmp_path, certs, capsys, kind, claim, shown
):
    assert replay(certs[kind])["valid"]  # the certificate as written holds
    forged = copy.deepcopy(certs[kind])
    forged["status"] = claim
    path = tmp_path / "forged.json"
    path.write_text(json.dumps(forged))
    before = _tree_state(tmp_path)
    assert cli.main(["certify", "--replay", str(path)]) == 3
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"certificate INVALID: claims {claim}")
    assert out[1].strip().startswith(f"status: claims {claim}, but the evidence shows {shown}")
    rep = replay(str(path))
    assert not rep["valid"] and not rep["proved"] and rep["errors"]
    assert _tree_state(tmp_path) == before


@pytest.mark.parametrize(
    "kind, tamper, field",
    [
        ("ball", lambda c, o: c.__setitem__("passage", o["passage"]["passage"]), "passage:"),
        ("ball", lambda c, o: c.__setitem__("tree", o["tree"]["tree"]), "tree:"),
        ("passage", lambda c, o: c.__setitem__("passage", None), "status:"),
        ("passage", lambda c, o: c.__setitem__("status", "maybe"), "status:"),
        ("tree", lambda c, o: c.__setitem__("passage", o["passage"]["passage"]), "passage:"),
        ("tree", lambda c, o: c["tree"][0].__setitem__("c", c["tree"][0]["c"][:7]), "tree:"),
        ("ball", lambda c, o: c["root"].__setitem__("radius", 10.5), "root.radius:"),
        ("ball", lambda c, o: c["shape"].__setitem__("sha256", "0" * 64), "shape.sha256:"),
        ("tree", lambda c, o: c.__setitem__("symmetry", "octahedral"), "symmetry:"),
        ("tree", lambda c, o: c["settings"].__setitem__("bound", "magic"), "settings.bound:"),
    ],
    ids=[
        "ball+passage", "ball+tree", "passage-removed", "unknown-status", "proof+passage",
        "split-of-7", "ball-radius", "hash", "symmetry", "bound",
    ],
)  # fmt: skip
def test_every_rejection_lists_why(certs, kind, tamper, field):
    forged = copy.deepcopy(certs[kind])
    tamper(forged, {k: copy.deepcopy(v) for k, v in certs.items()})
    rep = replay(forged)
    assert not rep["valid"] and rep["errors"], rep
    assert any(e.startswith(field) for e in rep["errors"]), rep["errors"]


# ------------------------------------------------------------------------------------------------
# Row 12c: the API and malformed certificates give one line, never a traceback
# ------------------------------------------------------------------------------------------------


def _set(path: str, value):
    def tamper(c):
        *keys, last = path.split(".")
        node = c
        for k in keys:
            node = node[int(k)] if k.isdigit() else node[k]
        node[int(last) if last.isdigit() else last] = value

    return tamper


MALFORMED = [
    ("root.radius", float("nan"), "root.radius must be a positive finite number"),
    ("root.radius", 10**400, "root.radius must be a positive finite number"),
    ("root.centre", [float("inf"), 0, 0], "root.centre holds a number that is not finite"),
    ("shape.vertices.0.0", float("nan"), "shape.vertices holds a number that is not finite"),
    ("shape.vertices.0.0", 1e300, "shape.vertices holds a number that is not finite or exceeds"),
    ("shape.faces.0.0", 10**30, "shape.faces must be an array"),
    ("shape.faces.0.0", -1, "shape.faces: an index is outside"),
    ("settings.kappa", float("nan"), "settings.kappa must be a positive finite number"),
    ("settings.directions", 10**12, "settings.directions must be an integer in 1..100000"),
    ("status", 3, "status must be a string"),
    ("hole", [[[0, 0], [1, 1]]], "hole[0]: a contour needs at least 3 points"),
    ("root", "ball", "root must be null or an object"),
    ("shape", [], "not a sieve-mi certificate (shape is not an object)"),
]


@pytest.mark.parametrize(
    "key, value, message", MALFORMED, ids=[m[0] + "-" + m[2][-12:] for m in MALFORMED]
)
def test_malformed_certificate_is_one_line(tmp_path, certs, capsys, key, value, message):
    forged = copy.deepcopy(certs["ball"])
    _set(key, value)(forged)
    with pytest.raises(SieveError, match=re.escape(message)) as e:
        replay(forged)
    assert "\n" not in str(e.value)
    path = tmp_path / "forged.json"
    path.write_text(json.dumps(forged))  # NaN and Infinity as Python's json writes them
    before = _tree_state(tmp_path)
    assert cli.main(["certify", "--replay", str(path)]) == 2
    assert message in _one_error_line(capsys)
    assert _tree_state(tmp_path) == before


@pytest.mark.parametrize(
    "source, message",
    [
        (None, "expected a file path or a dict, got NoneType"),
        ([1, 2], "expected a file path or a dict, got list"),
        (5, "expected a file path or a dict, got int"),
        ({}, "not a sieve-mi certificate"),
        ("LIST", "not a sieve-mi certificate"),
        ("DEEP", "nested too deeply"),
        ("DIGITS", "an integer with too many digits"),
        ("FOLDER", "is not a regular file"),
        ("MISSING", "certificate not found"),
    ],
)
def test_replay_api_refuses_what_is_not_a_certificate(tmp_path, source, message):
    files = {
        "LIST": ("list.json", json.dumps([{"format": FORMAT}])),
        "DEEP": ("deep.json", "[" * 50_000 + "]" * 50_000),
        "DIGITS": ("digits.json", '{"format": ' + "9" * 5000 + "}"),
    }
    if isinstance(source, str) and source in files:
        name, text = files[source]
        (tmp_path / name).write_text(text)
        source = str(tmp_path / name)
    elif source == "FOLDER":
        source = str(tmp_path)
    elif source == "MISSING":
        source = str(tmp_path / "none.json")
    with pytest.raises(SieveError, match=message) as e:
        replay(source)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(
    "args, message",
    [
        ((None, [SQUARE]), "shape must be a Shape"),
        (("BALL", None), "holes must be a list"),
        (("BALL", [SQUARE], "5"), "budget '5'"),
        (("BALL", [SQUARE], float("nan")), "budget nan"),
        (("BALL", [SQUARE], 5.0, {"bound": "isotropic"}), "settings must be a"),
    ],
)
def test_certify_api_refuses_arguments_of_the_wrong_kind(args, message):
    ball = shape_from_trimesh(shapes.sphere(12.0), name="ball")
    shape, holes, *rest = (ball if a == "BALL" else a for a in args)
    kwargs = dict(zip(("budget_s", "settings"), rest))
    with pytest.raises(SieveError, match=message):
        certify(shape, holes, **kwargs)


@pytest.mark.parametrize(
    "d, message",
    [
        ("M 0 0 L 1e308 0 L 1e308 1e308 Z", "a coordinate exceeds 1e+09 scene units"),
        ("M 0 0 L 1" + "0" * 400 + " 0 L 10 10 Z", "no polygon with finite coordinates"),
    ],
    ids=["beyond-the-polygon-range", "400-digit-number"],
)
def test_svg_hole_with_huge_coordinates_is_one_line(tmp_path, run, capsys, d, message):
    svg = tmp_path / "h.svg"
    svg.write_text(f'<svg><path d="{d}"/></svg>')
    before = _tree_state(tmp_path)
    code = cli.main(["certify", str(tmp_path / "ball24.stl"), "--hole", str(svg)])
    assert code == 2 and message in _one_error_line(capsys)
    assert _tree_state(tmp_path) == before


def test_a_file_larger_than_any_certificate_is_not_read_and_not_replaced(
    tmp_path, run, capsys, monkeypatch
):
    cert = tmp_path / "c.json"
    assert run("--certificate", str(cert)) == 0
    capsys.readouterr()
    monkeypatch.setattr(certificate, "MAX_CERTIFICATE_BYTES", cert.stat().st_size - 1)
    before = _tree_state(tmp_path)
    assert run("--certificate", str(cert)) == 2
    assert "is not a sieve-mi certificate" in _one_error_line(capsys)
    assert _tree_state(tmp_path) == before


# ------------------------------------------------------------------------------------------------
# Hostile pass F1: a straight proof is no proof on a plate thinner than the part
# ------------------------------------------------------------------------------------------------
# Known answers: the L-rod (two 20 mm arms of 2 mm section) is 28.35 mm across
# (sqrt(20² + 20² + 2²)). Every straight pose projects one arm at least 20 sin 45° = 14.1 mm long,
# so no pose fits a 6 mm round hole: certify proves that in ~0.2 s. On a 2 mm plate the rod
# threads through tilted (tests/game/test_sheet.py finds and verifies the motion), so the proof
# holds only on plates at least 28.35 mm thick (the thick-plate argument). The 24 mm ball holds a
# ball wider than the hole: proved on any plate.

ROD_DIAMETER = math.sqrt(20.0**2 + 20.0**2 + 2.0**2)


@pytest.fixture(scope="module")
def rod_files(tmp_path_factory) -> dict:
    """The L-rod, a 24 mm ball, 60 x 60 mm plates with a 6 mm round hole (2 and 30 mm thick, and
    an open mesh of the 2 mm one) and a 6 mm square hole as SVG."""
    folder = tmp_path_factory.mktemp("rod")
    files = {"rod": folder / "rod.stl", "ball": folder / "ball.stl", "svg": folder / "sq6.svg"}
    shapes.l_rod().export(str(files["rod"]))
    shapes.sphere(12.0).export(str(files["ball"]))
    for t in (2.0, 30.0):
        plate = manifold3d.Manifold.cube([60.0, 60.0, t], center=True)
        plate -= manifold3d.Manifold.cylinder(t + 2.0, 3.0, 3.0, 64, center=True)
        files[f"plate{t:g}"] = folder / f"plate{t:g}.stl"
        shapes.from_manifold(plate).export(str(files[f"plate{t:g}"]))
    thin = shapes.from_manifold(
        manifold3d.Manifold.cube([60.0, 60.0, 2.0], center=True)
        - manifold3d.Manifold.cylinder(4.0, 3.0, 3.0, 64, center=True)
    )
    top = thin.triangles_center[:, 2] > 0.99
    files["open"] = folder / "open.stl"
    thin.update_faces(~top)
    thin.export(str(files["open"]))
    files["svg"].write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="12mm" height="12mm" '
        'viewBox="-6 -6 12 12"><path d="M -3 -3 H 3 V 3 H -3 Z"/></svg>'
    )
    return files


def _hashes(files: dict) -> dict:
    return {k: hashlib.sha256(p.read_bytes()).hexdigest() for k, p in files.items()}


PLATE_ANSWERS = [
    # shape, source, exit code, the line (undecided: all of it, {s} and {n} numbers; proved: the
    # second line's start), holds_for, thickness
    ("rod", "plate2", 4,
     "rod: undecided (cells) in {s} s: proved that no pose passes straight through, but the plate "
     "is 2 mm thick and the part 28.35 mm across: a tilted passage is not excluded (see "
     "`sieve-mi check --sieve` for a motion search)", "plates at least the diameter thick", 2.0),
    ("rod", "plate30", 0, "holds on this plate: 30 mm thick, the part 28.35 mm across",
     "plates at least the diameter thick", 30.0),
    ("rod", "open", 4,
     "rod: undecided (cells) in {s} s: proved that no pose passes straight through, but the plate "
     "mesh is not a closed solid ({n} edges not shared by two faces), so its thickness cannot be "
     "measured (the part is 28.35 mm across): a tilted passage is not excluded (see "
     "`sieve-mi check --sieve` for a motion search)", "plates at least the diameter thick", None),
    ("rod", "svg", 0,
     "proved for straight passage, or plates at least the part's 28.35 mm diameter thick (an "
     "outline has no thickness", "plates at least the diameter thick", None),
    ("ball", "plate2", 0, "holds on a plate of any thickness (a ball inside the part is wider",
     "any plate", 2.0),
]  # fmt: skip


@pytest.mark.parametrize(
    "shape, source, code, line, holds, thickness",
    PLATE_ANSWERS,
    ids=["rod-2mm", "rod-30mm", "rod-open-plate", "rod-svg", "ball-2mm"],
)
def test_certify_says_proved_only_where_the_proof_covers_the_plate(
    tmp_path, rod_files, capsys, shape, source, code, line, holds, thickness
):
    before = _hashes(rod_files)
    flag = "--hole" if source == "svg" else "--sieve"
    cert = tmp_path / "c.json"
    # 4 s: the rod's straight proof takes under a second (0.4 s at load 10, 2026-12-07); on the
    # 2 mm plate, where it threads, the slab-section proof gets the rest and fails (twice here)
    args = ["certify", str(rod_files[shape]), flag, str(rod_files[source]), "--budget", "4"]
    assert cli.main([*args, "--certificate", str(cert)]) == code
    out, err = capsys.readouterr()
    assert err == ""
    lines = out.strip().splitlines()
    if line.startswith(shape + ": undecided"):  # the single line says why it is not proved
        assert len(lines) == 1
        pattern = re.escape(line).replace(r"\{s\}", r"[0-9.]+").replace(r"\{n\}", r"\d+")
        assert re.fullmatch(pattern, lines[0]), lines[0]
    else:
        assert lines[0].startswith(f"{shape}: proved") and lines[1].startswith(line)
    assert cli.main([*args, "--json"]) == code
    data = json.loads(capsys.readouterr().out)
    assert data["straight"] == "proved" and data["holds_for"] == holds
    assert data["status"] == ("proved" if code == 0 else "undecided")
    assert data["thickness"] == thickness
    assert data["diameter"] == pytest.approx(ROD_DIAMETER if shape == "rod" else 24.0, rel=2e-3)
    # the certificate records the scope; the replay re-derives it and says whether it covers
    stored = json.loads(cert.read_text())
    assert stored["status"] == "proved" and stored["plate"]["holds_for"] == holds
    assert stored["plate"]["thickness"] == thickness
    rep = replay(str(cert))
    assert rep["valid"] and rep["holds_for"] == holds
    assert rep["covers_plate"] == (None if thickness is None else code == 0)
    assert _hashes(rod_files) == before
    if (shape, source) == ("rod", "plate2"):  # the command's replay says so, in one line
        _replay_says_the_thin_plate_is_not_covered(cert, capsys)


def _replay_says_the_thin_plate_is_not_covered(cert, capsys) -> None:
    """``certify --replay`` of the rod's certificate on the 2 mm plate (written by the test
    above: one 8 s proof for both) says it is valid and does not cover that plate, and leaves
    the file as it was."""
    before = cert.read_bytes()
    assert cli.main(["certify", "--replay", str(cert)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and out[0].startswith(
        "certificate valid: claims proved (holds for plates at least the diameter thick: "
        "28.35 mm; the recorded plate, 2 mm, is NOT covered)"
    )
    assert cert.read_bytes() == before


def test_on_sheet_keeps_solve_from_calling_a_cell_proof_on_a_thin_plate_proved(rod_files):
    """solve: a plate thinner than B's diameter ([fabrication] thickness, "thinnest") turns a
    cell-tree proof into "undecided" in report.json and the console; a ball proof stays."""
    from sieve_mi.certify.blocks import on_sheet
    from sieve_mi.geometry.meshes import load_shape
    from sieve_mi.outputs.console import _certified_cell

    hole = manifold3d.CrossSection.circle(3.0, 64)
    rod = certify(load_shape(str(rod_files["rod"])), [hole], budget_s=20.0)
    ball = certify(load_shape(str(rod_files["ball"])), [hole], budget_s=5.0)
    assert (rod.status, rod.method, ball.method) == ("proved", "cells", "ball")
    thin = on_sheet([rod, None, ball], 2.0)
    assert thin[1] is None and rod.status == "proved"  # a copy: the straight answer is kept
    assert (thin[0].status, thin[0].straight, thin[0].covers_plate) == (
        "undecided",
        "proved",
        False,
    )
    assert (thin[2].status, thin[2].covers_plate) == ("proved", True)
    row = thin[0].to_dict()
    assert row["status"] == "undecided" and row["thickness"] == 2.0
    assert _certified_cell({"certification": row}).startswith("straight only")
    assert thin[0].certificate["plate"]["thickness"] == 2.0 and replay(thin[0].certificate)["valid"]
    thick = on_sheet([rod], 28.4)[0]  # solve's default plate: the diameter, rounded up
    assert thick.status == "proved" and thick.covers_plate


PLATE_TAMPERING = [
    ("tree", "holds_for", "any plate", "plate.holds_for: claims 'any plate', but a cell-tree"),
    ("ball", "holds_for", "plates at least the diameter thick", "plate.holds_for:"),
    ("undecided", "holds_for", "any plate", "plate.holds_for:"),
    ("passage", "holds_for", None, "plate.holds_for:"),
    ("tree", "diameter", 30.0, "plate.diameter: claims 30.0"),
]


@pytest.mark.parametrize(
    "kind, key, value, error", PLATE_TAMPERING, ids=[f"{t[0]}-{t[1]}" for t in PLATE_TAMPERING]
)
def test_replay_rejects_a_scope_the_evidence_does_not_give(tmp_path, certs, capsys, kind, key,
                                                           value, error):  # fmt: skip
    assert replay(certs[kind])["valid"]
    forged = copy.deepcopy(certs[kind])
    forged["plate"][key] = value
    path = tmp_path / "forged.json"
    path.write_text(json.dumps(forged))
    before = _tree_state(tmp_path)
    assert cli.main(["certify", "--replay", str(path)]) == 3
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("certificate INVALID") and out[1].strip().startswith(error)
    assert _tree_state(tmp_path) == before


def test_certificates_written_before_the_plate_scope_still_replay(certs):
    for kind, holds in [("ball", "any plate"), ("tree", "plates at least the diameter thick"),
                        ("passage", "any plate"), ("undecided", None)]:  # fmt: skip
        old = copy.deepcopy(certs[kind])
        del old["plate"]
        rep = replay(old)
        assert rep["valid"] and rep["holds_for"] == holds and rep["thickness"] is None


@pytest.mark.parametrize(
    "value, message",
    [
        ({"thickness": float("nan"), "diameter": 40.0, "holds_for": None}, "plate.thickness"),
        ({"thickness": -1, "diameter": 40.0, "holds_for": None}, "plate.thickness"),
        ({"thickness": None, "diameter": 0, "holds_for": None}, "plate.diameter must be"),
        ({"thickness": None, "diameter": 40.0, "holds_for": 3}, "plate.holds_for must be"),
        ([], "plate must be an object"),
    ],
)
def test_a_malformed_plate_entry_is_one_line(certs, value, message):
    forged = copy.deepcopy(certs["tree"])
    forged["plate"] = value
    with pytest.raises(SieveError, match=re.escape(message)) as e:
        replay(forged)
    assert "\n" not in str(e.value)


# ------------------------------------------------------------------------------------------------
# Hostile pass F2: an SVG hole is read exactly, or refused in one line
# ------------------------------------------------------------------------------------------------
# Known answer: a 20 mm cube passes a 22 mm square face-on (exit 3), however the square is drawn.

_SVG = '<svg xmlns="http://www.w3.org/2000/svg"{attrs}>{body}</svg>'
_SQUARE_L = '<path d="M -11 -11 L 11 -11 L 11 11 L -11 11 Z"/>'

SQUARES = {
    "H-V": ("", '<path d="M -11 -11 H 11 V 11 L -11 11 Z"/>'),
    "relative": ("", '<path d="m -11 -11 h 22 v 22 l -22 0 z"/>'),
    "implicit-lines": ("", '<path d="M -11,-11 11,-11 11,11 -11,11z"/>'),
    "relative-implicit": ("", '<path d="m-11-11 22 0 0 22-22 0z"/>'),
    "rect+tiny-path": ("", '<rect x="-11" y="-11" width="22" height="22"/>'
                           '<path d="M 0 0 L 0.1 0 L 0.1 0.1 Z"/>'),
    "polygon": ("", '<polygon points="-11,-11 11,-11 11,11 -11,11"/>'),
    "polyline": ("", '<g><polyline points="-11 -11 11 -11 11 11 -11 11"/></g>'),
    "solve-mm": (' width="30mm" height="30mm" viewBox="-15 -15 30 30"', _SQUARE_L),
    "solve-cm": (' width="30cm" height="30cm" viewBox="-15 -15 30 30"', _SQUARE_L),
    "editor": (' xmlns:i="urn:x" width="30" height="30"',
               '<defs><path d="M 0 0 L 99 0 L 99 99 Z"/></defs><i:namedview/><title>t</title>'
               + _SQUARE_L),
}  # fmt: skip

REFUSED = {
    "arc": ("", '<path d="M -20 0 A 20 20 0 1 0 20 0 A 20 20 0 1 0 -20 0 Z"/>',
            "<path> command A (an elliptical arc) is not read"),
    "cubic": ("", '<path d="M 0 0 C 1 1 2 2 3 0 Z"/>', "<path> command C (a cubic Bézier"),
    "quadratic": ("", '<path d="M 0 0 q 1 1 2 0 z"/>', "<path> command q (a quadratic Bézier"),
    "group-transform": ("", '<g transform="scale(2)"><path d="M -5.5 -5.5 L 5.5 -5.5 L 5.5 5.5 '
                        'L -5.5 5.5 Z"/></g>', "<g> has a transform (not read"),
    "style-transform": ("", '<path style="transform: scale(2)" d="M 0 0 L 1 0 L 1 1 Z"/>',
                        "<path> has a transform"),
    "root-transform": (' transform="scale(2)"', _SQUARE_L, "<svg> has a transform"),
    "circle": ("", '<circle r="20"/>', "<circle> (a circle) is not read"),
    "ellipse": ("", '<ellipse rx="20" ry="10"/>', "<ellipse> (an ellipse) is not read"),
    "rounded-rect": ("", '<rect x="-11" y="-11" width="22" height="22" rx="2"/>',
                     "<rect> with rounded corners (rx) is not read"),
    "rect-units": ("", '<rect x="-11" y="-11" width="22mm" height="22"/>',
                   "<rect width> '22mm' is not read"),
    "viewbox-scales": (' width="60mm" height="60mm" viewBox="-15 -15 30 30"', _SQUARE_L,
                       "scales the drawing by 2"),
    "mm-without-viewbox": (' width="30mm" height="30mm"', _SQUARE_L, "without a viewBox"),
    "points-unit": (' width="30pt" height="30pt" viewBox="-15 -15 30 30"', _SQUARE_L,
                    "<svg width='30pt'> is not read"),
    "use": ("", '<use href="#a"/>', "<use> (a reference to other elements) is not read"),
    "style-sheet": ("", '<style>path {transform: scale(2)}</style>' + _SQUARE_L,
                    "<style> (a style sheet"),
    "clip-path": ("", '<path clip-path="url(#c)" d="M 0 0 L 1 0 L 1 1 Z"/>',
                  "<path> has a clip-path"),
    "stray-text": ("", '<path d="M 0 0 L 1 0 # 1 1 Z"/>', "unexpected '#' in the path"),
    "no-moveto": ("", '<path d="L 0 0 L 1 0 L 1 1 Z"/>', "must start with M"),
    "odd-coordinates": ("", '<path d="M 0 0 L 1 0 1 Z"/>', "command L needs x y pairs"),
    "not-svg": (None, "<html/>", "not an SVG file"),
}  # fmt: skip


@pytest.fixture(scope="module")
def cube20(tmp_path_factory):
    path = tmp_path_factory.mktemp("cube") / "cube20.stl"
    shapes.cube(20.0).export(str(path))
    return path


@pytest.mark.parametrize("name", sorted(SQUARES))
def test_an_svg_square_drawn_any_readable_way_lets_the_cube_through(tmp_path, cube20, capsys, name):
    attrs, body = SQUARES[name]
    svg = tmp_path / "h.svg"
    svg.write_text(_SVG.format(attrs=attrs, body=body))
    before = _tree_state(tmp_path)
    assert cli.main(["certify", str(cube20), "--hole", str(svg), "--budget", "5"]) == 3
    out, err = capsys.readouterr()
    assert out.startswith("cube20: passage") and err == ""
    assert _tree_state(tmp_path) == before


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_an_svg_the_reader_cannot_take_exactly_is_refused_in_one_line(
    tmp_path, cube20, capsys, name
):
    attrs, body, message = REFUSED[name]
    svg = tmp_path / "h.svg"
    svg.write_text(body if attrs is None else _SVG.format(attrs=attrs, body=body))
    before = _tree_state(tmp_path)
    assert cli.main(["certify", str(cube20), "--hole", str(svg), "--budget", "5"]) == 2
    line = _one_error_line(capsys)
    assert line.startswith(f"sieve-mi: error: {svg}: ") and message in line, line
    assert _tree_state(tmp_path) == before


def test_svg_path_commands_give_the_exact_polygons():
    from sieve_mi.certify.svg import parse_path

    got = parse_path("m 1 1 l 2 0 0 2 z l 0 -1 -1 0 z M 10 10 H 12 V 12 h -2 v -1", "p.svg")
    want = [
        [(1, 1), (3, 1), (3, 3)],
        [(1, 1), (1, 0), (0, 0)],  # a line after z starts at the closed subpath's start
        [(10, 10), (12, 10), (12, 12), (10, 12), (10, 11)],  # an open subpath is filled closed
    ]
    assert [c.tolist() for c in got] == [[[x, -y] for x, y in w] for w in want]


def test_svg_fill_rule_is_read_per_element():
    """Two nested squares in one path: a ring with evenodd, a square with nonzero (SVG's
    default); separate elements are unioned."""
    import tempfile

    from sieve_mi.certify import read_svg_hole

    nested = "M 0 0 L 10 0 L 10 10 L 0 10 Z M 2 2 L 8 2 L 8 8 L 2 8 Z"
    areas = {}
    for rule in ("evenodd", "nonzero"):
        with tempfile.NamedTemporaryFile("w", suffix=".svg", delete=False) as fh:
            fh.write(_SVG.format(attrs="", body=f'<path fill-rule="{rule}" d="{nested}"/>'))
        areas[rule] = read_svg_hole(fh.name).area()
        os.remove(fh.name)
    assert areas == {"evenodd": pytest.approx(64.0), "nonzero": pytest.approx(100.0)}


# ------------------------------------------------------------------------------------------------
# Hostile pass F3: an undecided run never reads "100.00 %"
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "fraction, complete, digits, shown",
    [
        (0.9999977312982082, False, 2, "99.99"),  # the hostile pass's brick: was "100.00"
        (1.0, False, 2, "99.99"),
        (0.99996, False, 1, "99.9"),
        (0.29, False, 2, "29.00"),
        (0.0, False, 2, "0.00"),
        (0.9999999999, True, 2, "100.00"),
    ],
)
def test_excluded_percent_is_never_rounded_up_to_100(fraction, complete, digits, shown):
    from sieve_mi.certify.certificate import excluded_percent

    assert excluded_percent(fraction, complete, digits) == shown


def test_undecided_summary_and_solve_cell_do_not_say_100(capsys):
    from sieve_mi.certify.certificate import Certification
    from sieve_mi.outputs.console import _certified_cell

    r = Certification(
        "undecided", 3.5, "cells", 20841, 15800, 19488, 0.9999977, straight="undecided"
    )
    assert "excluded 99.99 %" in cli._certify_summary("brick", r)
    cell = _certified_cell({"certification": r.to_dict()})
    assert cell.startswith("undecided (99.9 % excluded")
