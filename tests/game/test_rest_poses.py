"""Rest poses (:mod:`sieve_mi.game.rest`): known shares, and player A's preference.

Shares on paper: trimesh's quasi-static share of a hull face is about the solid angle it
subtends from the centre of mass, over 4π (a random drop direction topples onto the face its
ray leaves through). A rectangle a x b seen from distance d on its axis subtends
Ω = 4 arcsin(ab / sqrt((a² + 4d²)(b² + 4d²))).

* A cube: six equal faces at equal distance, 1/6 each.
* A 1 x 2 brick's body, 15.8 x 7.8 x 9.6 mm (the studs add 1.7 mm on top): its long sides
  (15.8 x 9.6 at 3.9 mm) subtend 24.5 % each, its top and bottom (15.8 x 7.8 at 4.8 mm) 18 %, its
  ends (7.8 x 9.6 at 7.9 mm) 7.4 %: most of the mass on the two large faces.
* The preference scene: A a 16 x 8 x 11 mm box (x, y, z), B a 12 x 9.5 x 9.5 mm box, tolerance
  0.2 mm. A's rests: y down (16 x 11 face at 4 mm) 25.7 % each, z down (16 x 8 at 5.5 mm) 16.1 %,
  x down (8 x 11 at 8 mm) 8.2 %. The y-down hole (16.4 x 11.4 mm) lets B's 12 x 9.5 face through;
  the z-down (16.4 x 8.4) and x-down (8.4 x 11.4) holes are 8.4 mm wide, less than B's least
  width 9.5 mm, so both block B. Of the two, z down costs (0 + 1°) / 16 % = 6°, x down 12°:
  the preference must choose z down (the part lying on its large 16 x 8 face), whatever the
  search's own rotation.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sieve_mi.game.rest import LIKELY_SHARE, Rests, likely_rests, nearest_rest, prefer
from sieve_mi.game.solver import load_shapes, search
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.scene import Scene
from sieve_mi.testing.catalogue import brick
from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT


def _box(x, y, z):
    return shape_from_trimesh(trimesh.creation.box((x, y, z)), name="box")


def test_a_cube_rests_on_its_six_faces_equally():
    rests = Rests.of(_box(20, 20, 20))
    assert len(rests.shares) == 6
    np.testing.assert_allclose(rests.shares, 1 / 6, atol=1e-6)
    axes = np.abs(np.rint(rests.normals)).argmax(axis=1) * 2 + (rests.normals.sum(axis=1) > 0)
    assert sorted(axes) == list(range(6))  # +-x, +-y, +-z once each
    assert len(rests.likely()) == 6


def test_a_brick_rests_mostly_on_its_large_faces():
    rests = Rests.of(shape_from_trimesh(brick(2, 1), name="1x2"))
    down = {tuple(np.rint(n).astype(int)): p for n, p in zip(rests.normals, rests.shares)}
    sides = down[(0, 1, 0)] + down[(0, -1, 0)]
    assert sides > 0.5
    assert min(down[(0, 1, 0)], down[(0, -1, 0)]) > max(
        p for n, p in down.items() if n not in ((0, 1, 0), (0, -1, 0))
    )
    assert down[(1, 0, 0)] < 0.1 and down[(-1, 0, 0)] < 0.1  # standing on an end
    assert len(rests.likely()) == 6  # the tilted rests on a stud's edge are not likely
    assert rests.shares[rests.likely()].min() >= LIKELY_SHARE


def test_nearest_rest_measures_the_tilt_only():
    box = _box(16, 8, 11)
    turned = np.array([np.cos(0.6), 0, 0, np.sin(0.6)])  # any turn about z: still resting
    got = nearest_rest(box, turned)
    assert got["down"] == [0.0, 0.0, -1.0] and got["angle_deg"] < 1e-6
    tilted = np.array([np.cos(np.radians(5)), np.sin(np.radians(5)), 0, 0])  # 10° about x
    assert nearest_rest(box, tilted)["angle_deg"] == pytest.approx(10.0, abs=1e-6)


def test_prefer_skips_a_rest_pose_the_strong_attack_lets_through():
    box = _box(16, 8, 11)
    rests, quats = likely_rests(box)
    downs = [tuple(np.rint(rests.normals[rests.likely()][k]).astype(int)) for k in range(6)]
    values = np.full(6, 0.3)  # the search's short attack: every rest pose blocks

    def verify(q):  # the verdict-strength attack: B fits the y-down holes
        k = int(np.argmin(rests.angles(q)))
        return -0.1 if abs(rests.normals[k][1]) > 0.5 else 0.2

    search = (np.array([np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0]), 0.5)  # x down (end on)
    q, value, record = prefer(rests, search, quats, values, verify)
    assert downs[0][1] != 0  # the likeliest rest is y down ...
    assert record["chosen"] == "rest pose" and value == 0.2
    assert [t["verified"] for t in record["tried"]][:2] == [-0.1, -0.1]  # ... both y faces fail
    assert abs(nearest_rest(box, q)["down"][2]) == 1.0  # z down taken over the search's x down
    assert record["search"]["position"] == "end on"


@pytest.mark.slow
def test_the_preference_lays_the_box_on_its_large_blocking_face():
    scene = Scene.from_meshes(
        [trimesh.creation.box((16, 8, 11))], [trimesh.creation.box((12, 9.5, 9.5))], name="rest"
    )
    scene.fabrication.tolerance = 0.2
    for key, value in {**TINY_SOLVER, "canonical": 4, "polish": 0, "rest_poses": True}.items():
        setattr(scene.solver, key, value)
    for key, value in TINY_VERDICT.items():
        setattr(scene.verdict, key, value)
    passes, blocks = load_shapes(scene)
    out = search(scene, passes, blocks, np.random.default_rng(0), 0, False)
    rest = nearest_rest(passes[0], out.quats[0])
    assert abs(rest["down"][2]) == 1.0 and rest["angle_deg"] < 1.0  # lying on its 16 x 8 face
    assert rest["share"] == pytest.approx(0.16, abs=0.03)
    assert out.rest_choice[0]["cost"] == pytest.approx(1 / rest["share"], rel=1e-6)


def test_the_console_names_the_rest_pose_chosen():
    from sieve_mi.outputs.console import rest_lines

    search = {"position": "end on", "angle_deg": 0.0, "share": 0.074, "value": 0.42, "cost": 13.5}
    rest = {"position": "on its side", "angle_deg": 0.0, "share": 0.171,
            "preferred": {"chosen": "rest pose", "cost": 5.8, "search": search, "tried": []}}  # fmt: skip
    report = {"pass": [{"name": "1x2", "rest": rest}, {"name": "fixed", "rest": None}]}
    assert rest_lines(report) == [
        "1x2: passes on its side, 0.0° from a resting pose (17 % of drops settle on that face), "
        "chosen over the search's end on, 0.0° from resting (7 %) by [solver] rest_poses"
    ]
    rest["preferred"]["chosen"] = "search"
    assert rest_lines(report)[0].endswith(
        "the search's own; no likelier resting pose blocks every B"
    )
    assert rest_lines({"pass": [{"name": "1x2"}]}) == []  # no rest_poses: no line


def test_the_search_keeps_its_own_exact_rest_pose():
    cube = _box(20, 20, 20)
    rests, quats = likely_rests(cube)

    def verify(q):  # a tie (every face 1/6, the search face-on) needs no strong attack
        raise AssertionError("verified a rest pose no better than the search's own")

    q, value, record = prefer(
        rests, (np.array([1.0, 0, 0, 0]), 0.05), quats, np.full(6, 0.06), verify
    )
    assert record["chosen"] == "search" and value == 0.05 and np.allclose(q, [1, 0, 0, 0])
