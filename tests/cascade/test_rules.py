"""Cascades that plan before they play: exact rules, the size guesses, screening, re-planning.

Every case is argued on paper in its comment. The planner tests play no real game: a fake
``play_games`` decides each game by the coins' official sizes (a coin is held only by a hole for
coins narrower by more than twice the tolerance), so they check which games the planner asks for.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import pytest
import trimesh
from shapely.geometry import MultiPoint

from sieve_mi.cascade.games import EngineSettings, label_text
from sieve_mi.cascade.mixture import load_mixture
from sieve_mi.cascade.plan import plan_cascade
from sieve_mi.cascade.rules import Rules, body, end_first, fits_inside
from sieve_mi.cascade.sort import sort_mixture
from sieve_mi.cascade.stages import screening_tables, worth_screening
from sieve_mi.geometry.meshes import load_trimesh, shape_from_trimesh
from sieve_mi.geometry.rotations import to_matrix
from sieve_mi.geometry.size import (
    canonical_extents,
    enclosing_circle,
    end_first_radius,
    predicted_margin,
    rectangle_fits,
)
from sieve_mi.scene import Layout, Solver, Verdict
from sieve_mi.testing import shapes
from sieve_mi.testing.settings import CASCADE_SOLVER, TINY_LAYOUT, TINY_VERDICT, settings_toml

MESHES = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "meshes")
#: Official diameter and thickness, mm.
COINS = {
    "2eur": (25.75, 2.20),
    "50c": (24.25, 2.38),
    "1eur": (23.25, 2.33),
    "20c": (22.25, 2.14),
    "5c": (21.25, 1.67),
    "10c": (19.75, 1.93),
    "2c": (18.75, 1.67),
    "1c": (16.25, 1.67),
}
TOL = 0.1


def _coin_body(name: str, as_name: str | None = None):
    mesh = load_trimesh(os.path.join(MESHES, f"coin_{name}.stl"))
    return body(shape_from_trimesh(mesh, name=as_name or name))


def _mesh_body(mesh, name: str):
    return body(shape_from_trimesh(mesh, name=name))


def test_rectangles_and_the_predicted_margin_on_paper():
    # A 20 x 1.5 strip does not fit a 15 x 15 square (Carver: (30/21.5)^2 = 1.95 < 2), a
    # 20 x 1 strip does (30/21)^2 = 2.04; axis-parallel cases are plain comparisons.
    assert not rectangle_fits(20.0, 1.5, 15.0, 15.0) and rectangle_fits(20.0, 1.0, 15.0, 15.0)
    assert rectangle_fits(10.0, 4.0, 10.0, 4.0) and not rectangle_fits(10.0, 4.1, 12.0, 4.0)
    assert not rectangle_fits(5.0, 5.0, 4.9, 4.9)
    # Brute force over turns agrees.
    rng = np.random.default_rng(0)
    for _ in range(300):
        a, b = sorted(rng.uniform(1, 10, 2))[::-1]
        p, q = sorted(rng.uniform(0.1, 12, 2))[::-1]
        turns = np.linspace(0.0, np.pi / 2, 4001)
        w, h = p * np.cos(turns) + q * np.sin(turns), p * np.sin(turns) + q * np.cos(turns)
        brute = bool(np.any((w <= a + 1e-9) & (h <= b + 1e-9)))
        if abs(((a + b) / (p + q)) ** 2 + ((a - b) / (max(p - q, 1e-9))) ** 2 - 2) > 1e-3:
            assert rectangle_fits(p, q, a, b) == brute
    # The 5 c coin over a 10 c coin's slot: 1.5 mm wider, so (21.25 - 19.95) / 2 = 0.65 mm, a
    # little less turned (0.63); the other way 0.03 mm: (1.93 - 1.87) / 2, the thicknesses.
    e5, e10 = np.array([21.25, 21.25, 1.67]), np.array([19.75, 19.75, 1.93])
    assert predicted_margin(e5, e10, TOL) == pytest.approx(0.63, abs=0.01)
    assert predicted_margin(e10, e5, TOL) == pytest.approx(0.03, abs=1e-6)
    assert predicted_margin(e10, e10, TOL) == pytest.approx(-TOL, abs=1e-6)  # fits with 0.1
    cube = shape_from_trimesh(trimesh.creation.box((30.0, 10.0, 4.0)), name="bar")
    assert canonical_extents(cube) == pytest.approx([30.0, 10.0, 4.0])


def test_enclosing_circles_and_end_first_radii():
    assert enclosing_circle(np.array([[0.0, 0], [4, 0], [4, 3], [0, 3]]))[1] == pytest.approx(2.5)
    assert enclosing_circle(np.array([[0.0, 0], [2, 0], [1, 0]]))[1] == pytest.approx(1.0)
    pts = np.random.default_rng(1).normal(size=(200, 2))
    c, r = enclosing_circle(pts)
    assert np.linalg.norm(pts - c, axis=1).max() <= r + 1e-12
    # Two farthest points of a disk sample bound the smallest circle from below.
    assert r <= 1.0001 * np.linalg.norm(pts - pts.mean(0), axis=1).max()
    pencil = shape_from_trimesh(trimesh.creation.cylinder(1.5, 40.0, sections=48), name="p")
    assert end_first_radius(pencil)[0] == pytest.approx(1.5, rel=1e-9)  # seen end-on
    coin = shape_from_trimesh(shapes.coin(16.25, 1.67), name="1c")
    assert end_first_radius(coin)[0] == pytest.approx(16.25 / 2, rel=1e-9)  # face-on


def test_a_coin_inside_a_wider_coin_of_the_same_thickness_is_ruled_out_with_a_certificate():
    # The 1 cent coin (16.25 x 1.67) lies inside the 2 cent coin (18.75 x 1.67) grown by the
    # 0.1 mm tolerance: as thick, 2.5 mm narrower. So every hole that passes the 2 cent coin
    # passes the 1 cent coin (turned the same way): holding it over the 2 cent is hopeless.
    # The 10 cent coin (19.75 x 1.93) fits inside neither the 5 cent (1.67 + 0.2 < 1.93) nor
    # does the 5 cent (21.25 wide) fit inside it: both holds are left to the games.
    c1, c2, c5, c10 = (_coin_body(n) for n in ("1c", "2c", "5c", "10c"))
    assert all(b.convex for b in (c1, c2, c5, c10))
    assert c10.ball == pytest.approx(1.93 / 2, rel=1e-6)
    ruling = fits_inside(c1, c2, TOL)
    assert ruling is not None and ruling.rule == "fits-inside"
    assert ruling.margin == pytest.approx(TOL, abs=1e-6)  # the faces: 0.1 mm to spare
    assert "1c passes every hole that passes 2c" in ruling.reason
    assert fits_inside(c2, c1, TOL) is None
    assert fits_inside(c10, c5, TOL) is None and fits_inside(c5, c10, TOL) is None
    assert fits_inside(c1, c2, 0.0) is None  # as thick: no room to spare without the tolerance
    # The certificate, replayed: in random views the placed 1 cent coin's silhouette lies in the
    # 2 cent coin's grown by the tolerance.
    rot = to_matrix(np.array(ruling.certificate["rotation"]))
    placed = c1.points @ rot.T + np.array(ruling.certificate["translation"])
    rng = np.random.default_rng(2)
    for _ in range(50):
        q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        hole = MultiPoint((c2.points @ q.T)[:, :2]).convex_hull.buffer(TOL, quad_segs=32)
        assert MultiPoint((placed @ q.T)[:, :2]).convex_hull.difference(hole).area == 0.0


def test_a_pencil_goes_through_any_hole_a_larger_ball_passes_end_first():
    # A 3 mm pencil, 40 mm long, over a 10 mm ball: every hole that passes the ball holds a
    # disk of radius 5 (+0.1), the pencil seen end-on fits in one of radius 1.5. It fits inside
    # no ball (too long), so only the end-first rule sees it. The ball over the pencil: no rule.
    pencil = _mesh_body(trimesh.creation.cylinder(1.5, 40.0, sections=48), "pencil")
    ball = _mesh_body(trimesh.creation.icosphere(2, 5.0), "ball")
    ruling = end_first(pencil, ball, TOL)
    assert ruling is not None and ruling.rule == "end-first"
    assert ruling.margin == pytest.approx(ball.ball + TOL - 1.5, rel=1e-9)
    assert 4.7 < ball.ball < 5.0  # the icosphere's faces lie inside the sphere
    assert fits_inside(pencil, ball, TOL) is None and end_first(ball, pencil, TOL) is None
    # A shape that is not convex rules nothing out (its hull is not its solid): an L of two
    # 2 mm bars holds the 1 mm ball nowhere near its hull's inscribed ball.
    ell = _mesh_body(shapes.l_rod(arm=20.0, side=2.0), "ell")
    small = _mesh_body(trimesh.creation.icosphere(2, 0.5), "small")
    assert not ell.convex and ell.ball == 0.0
    assert fits_inside(small, ell, TOL) is None and end_first(small, ell, TOL) is None


def test_the_eight_euro_coins_leave_one_candidate_at_every_sieve_but_one():
    # Coin x fits inside coin a grown by 0.1 mm when D_x <= D_a + 0.2 and t_x <= t_a + 0.2:
    # 27 of the 56 ordered pairs (e.g. the 50 c inside the 2 euro: 24.25 < 25.75 and
    # 2.38 <= 2.20 + 0.2). Then at every sieve only the widest coin left can be held, but at
    # {5c, 10c, 2c, 1c} where neither the 5 c nor the 10 c coin fits inside the other.
    rules = Rules([_coin_body(n) for n in COINS], TOL)
    expected = {
        (x, a)
        for x, (dx, tx) in COINS.items()
        for a, (da, ta) in COINS.items()
        if x != a and dx <= da + 2 * TOL and tx <= ta + 2 * TOL + 1e-9
    }
    assert set(rules.pairs) == expected and len(expected) == 27
    assert rules.hopeless(["10c"], ["20c", "1c"])["passing"] == "20c"
    assert rules.hopeless(["5c"], ["10c", "2c", "1c"]) is None
    assert rules.margin(["5c"], ["10c", "2c", "1c"]) > rules.margin(["10c"], ["5c", "2c", "1c"])


@dataclass
class _Spec:
    key: str
    label: dict


def _coin_games(calls: list, lose=frozenset(), win=frozenset()):
    """A fake ``play_games``: a hold wins iff the held coins are wider, by more than twice the
    tolerance, than every passing coin (the diameters decide; ``1c_twin`` is a 1 cent coin);
    the games whose keys are in ``lose`` lose and those in ``win`` win anyway. Every spec asked
    for is appended to ``calls``."""

    def diameter(name):
        return COINS[name.split("_")[0]][0]

    def play(specs):
        out = {}
        for s in specs:
            calls.append(s)
            held, passing = s.label["holds"], s.label["passes"]
            wins = min(map(diameter, held)) > max(map(diameter, passing)) + 2 * TOL
            wins = (wins or s.key in win) and s.key not in lose
            block = [
                {"name": h, "blocked": wins, "beta": 0.1 if wins else 0.0, "protrusion": 0.5}
                for h in held
            ]
            out[s.key] = {
                "key": s.key,
                "label": s.label,
                "summary": {"winner": "AB"[not wins], "block": block},
            }
        return out

    return play


def _maker(stage: str):
    def make(holds, passes):
        label = {"holds": list(holds), "passes": list(passes), "stage": stage}
        return _Spec(f"{stage}-{'+'.join(holds)}-over-{'+'.join(passes)}", label)

    return make


def _plan(names, calls, *, lose=frozenset(), win=frozenset(), parallel=False):
    rules = Rules([_coin_body(n) for n in names], TOL)
    return plan_cascade(
        names,
        _coin_games(calls, lose, win),
        _maker("full"),
        parallel=parallel,
        screen_spec=_maker("screen"),
        hopeless=rules.hopeless,
        margin=rules.margin,
    )


@pytest.mark.parametrize("parallel", [False, True])
def test_three_coins_the_hopeless_hold_is_never_played(parallel):
    # 10c, 1c, 5c: the 1 cent coin fits inside both others, so no sieve may hold it above them
    # (ruled out, no game). At the top the 5 c and the 10 c coins are candidates; the 5 c coin
    # is ranked first (0.63 mm predicted against 0.03), screened, wins, and is played in full;
    # then the 10 c coin is the only candidate over the 1 cent coin.
    calls = []
    plan = _plan(["10c", "1c", "5c"], calls, parallel=parallel)
    assert plan.trays == [["5c"], ["10c"], ["1c"]]
    assert not any("1c" in s.label["holds"] for s in calls)
    played = [(s.label["stage"], s.label["holds"][0]) for s in calls]
    assert played == [("screen", "5c"), ("full", "5c"), ("full", "10c")] or (
        parallel
        and played == [("screen", "5c"), ("screen", "10c"), ("full", "5c"), ("full", "10c")]
    )
    top, below = plan.levels
    assert [r["held"] for r in top["ruled_out"]] == ["1c"] and top["ruled_out"][0][
        "rule"
    ] == "fits-inside"
    assert [c["holds"] for c in top["candidates"]] == [["5c"], ["10c"]]
    assert top["by"] == "won its screening game" and top["full"]["winner"] == "A"
    assert below["by"] == "only candidate" and "screening" not in below


def test_eight_coins_are_planned_by_diameter_with_one_screening_game():
    # The order: 2 eur, 50 c, 1 eur, 20 c, 5 c, 10 c, 2 c, 1 c. Seven full games, one
    # screening game (5 c before 10 c), and no game holding a coin that fits inside another.
    calls = []
    plan = _plan(list(COINS), calls)
    assert plan.trays == [[n] for n in ("2eur", "50c", "1eur", "20c", "5c", "10c", "2c", "1c")]
    assert [s.label["stage"] for s in calls].count("screen") == 1
    assert len(calls) == 8 and not plan.inseparable


def test_a_lost_full_game_is_replanned_from_its_sieve():
    # The 5 c coin wins its screening game but (here) loses its full game: that hold is marked
    # lost at the top and the cascade is planned again from there. The 10 c coin is then the
    # only candidate (and, in this fake, wins over the 5 c and 1 c coins), then 5 c over 1 c.
    calls = []
    plan = _plan(
        ["10c", "1c", "5c"],
        calls,
        lose={"full-5c-over-10c+1c"},
        win={"full-10c-over-1c+5c"},
    )
    assert plan.trays == [["10c"], ["5c"], ["1c"]]
    first, unplayed, again, last = plan.levels
    assert first["chosen"] == ["5c"] and first["full"]["winner"] == "B"
    assert unplayed["chosen"] == ["10c"] and unplayed["full"].startswith("not played")
    assert again["lost"] == [{"holds": ["5c"], "game": "full-5c-over-10c+1c"}]
    assert again["chosen"] == ["10c"] and again["by"] == "only candidate"
    assert last["chosen"] == ["5c"] and last["full"]["winner"] == "A"
    assert [s.key for s in calls if s.label["stage"] == "screen"] == ["screen-5c-over-10c+1c"]


def test_twins_are_inseparable_by_the_rules_without_a_game():
    # A 1 cent coin and its twin fit inside each other: neither can be held over the other, so
    # they share a tray; the 2 euro coin above them is the only game.
    calls = []
    bodies = [_coin_body("2eur"), _coin_body("1c"), _coin_body("1c", "1c_twin")]
    rules = Rules(bodies, TOL)
    plan = plan_cascade(
        ["2eur", "1c", "1c_twin"],
        _coin_games(calls),
        _maker("full"),
        parallel=False,
        hopeless=rules.hopeless,
        margin=rules.margin,
    )
    assert plan.trays == [["2eur"], ["1c", "1c_twin"]] and len(calls) == 1
    (pair,) = plan.inseparable
    assert pair.keys == [] and "1c passes every hole that passes 1c_twin" in pair.reason
    assert "1c_twin passes every hole that passes 1c" in pair.reason


def test_screening_settings_only_lower_and_skip_the_proof():
    t = screening_tables(
        {"solver": Solver(particles=2, steps=200), "verdict": Verdict(), "layout": Layout()}
    )
    assert (t["solver"].particles, t["solver"].steps, t["solver"].canonical) == (2, 40, 20)
    assert (t["verdict"].starts, t["verdict"].certify) == (16, False)
    assert (t["layout"].rounds, t["layout"].restarts) == (1, 0)
    # Worth it only when the full search is at least twice the screening one: 6 x 5 x 6 x 60 =
    # 10,800 Adam steps against 4 x 3 x 4 x 40 = 1,920; the tiny cascade's 720 against 720.
    full = {
        "solver": Solver(particles=6, iterations=4, starts=6, steps=60),
        "verdict": Verdict(),
        "layout": Layout(),
    }
    assert worth_screening(full, screening_tables(full))
    tiny = {"solver": Solver(**CASCADE_SOLVER), "verdict": Verdict(), "layout": Layout()}
    assert not worth_screening(tiny, screening_tables(tiny))
    assert label_text({"holds": ["a"], "passes": ["b"], "stage": "screen"}).split() == [
        "screen",
        "hold",
        "a",
        "pass",
        "b",
    ]


@pytest.mark.slow
def test_three_coins_sort_by_diameter_with_two_games(tmp_path):
    # 2 euro, 5 cent, 1 cent: each smaller coin fits inside each larger one grown by 0.1 mm
    # (no thicker by more than 0.2 mm), so every hold but the widest coin's is ruled out before
    # any game, and the plan is the diameters' order: two full games, no screening game.
    text = 'name = "three"\n'
    for name in ("1c", "5c", "2eur"):
        path = os.path.abspath(os.path.join(MESHES, f"coin_{name}.stl"))
        text += f'[[shape]]\nmesh = "{path}"\nname = "{name}"\n'
    text += settings_toml(
        fabrication={"tolerance": TOL},
        solver=CASCADE_SOLVER,
        verdict={**TINY_VERDICT, "certify": False},
        layout=TINY_LAYOUT,
    )
    (tmp_path / "three.toml").write_text(text)
    report = sort_mixture(
        load_mixture(str(tmp_path / "three.toml")),
        str(tmp_path / "out"),
        engine=EngineSettings(use_ray=False, progress=False),
    )
    assert report["trays"] == [["2eur"], ["5c"], ["1c"]]
    assert [(g["stage"], g["holds"]) for g in report["games"]] == [
        ("full", ["2eur"]),
        ("full", ["5c"]),
    ]
    ruled = {(r["held"], r["passing"]) for r in report["rules"]["ruled_out"]}
    assert ruled == {("1c", "5c"), ("1c", "2eur"), ("5c", "2eur")}
    assert [lv["by"] for lv in report["levels"]] == ["only candidate", "only candidate"]
    assert report["screening"] is None  # tiny full games: screening would not pay
    assert all(s["winner"] == "A" and s["margins"]["protrusion"] > 1.5 for s in report["sieves"])
    assert all(r["convex"] for r in report["shapes"])


@pytest.mark.parametrize(
    "text", ["{not json", "[" * 50_000 + "]" * 50_000, "[1, 2]", '{"label": "no summary"}']
)
def test_a_damaged_game_record_is_played_again_not_a_traceback(tmp_path, text):
    from sieve_mi.cascade.games import GAME_FILE, GameCache
    from sieve_mi.outputs import outdir

    game = tmp_path / "k1"
    game.mkdir()
    (game / "report.json").write_text("{}")
    (game / GAME_FILE).write_text(text)
    outdir.write_marker(str(game), "game")
    cache = GameCache(str(tmp_path))
    assert cache.find("k1") == str(game)  # a finished game's folder ...
    assert cache.load("k1") is None  # ... whose record cannot be read: the game is played again
