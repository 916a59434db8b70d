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
