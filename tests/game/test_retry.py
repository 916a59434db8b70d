"""``[solver] retries``: a lost search of a single A is searched again from another seed."""

import numpy as np
import pytest
import trimesh

from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT, settings_toml

LONG, SIDE, PLATE, THIN = 40.0, 20.0, 36.0, 4.0  # A: a 20 x 20 x 40 box; B: a 36 x 36 x 4 plate
SIDE_ON = np.array(
    [np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0]
)  # A's long axis (z) turned into the plane


def _extent(outline) -> np.ndarray:
    """The hole's width and height (its bounding box), scene units."""
    x0, y0, x1, y1 = outline.bounds()
    return np.array([x1 - x0, y1 - y0])


@pytest.mark.parametrize("retries", [0, 1])
def test_a_lost_search_is_searched_again_and_the_blocking_hole_kept(
    write_scene, monkeypatch, retries
):
    # The box end-on makes a 22 x 22 hole (tolerance 1) whose longest chord (20√2 + 2 = 30.3)
    # is shorter than the plate's side: every silhouette of the plate holds a 36 mm segment,
    # so the plate is blocked. Side-on the hole is 22 x 42: the plate passes edge-on (4 x 36).
    # The first search is forced side-on; the retry's real search finds a blocking hole.
    import sieve_mi.game.solver as solver
    from sieve_mi.scene import load_scene

    body = (
        '[[pass]]\nmesh = "meshes/a.stl"\n[[block]]\nmesh = "meshes/b.stl"\n'
        "[fabrication]\nthickness = 60.0\n"  # thicker than the plate is wide: no thin-plate search
        + settings_toml(
            solver={**TINY_SOLVER, "retries": retries, "polish": 2},
            verdict={**TINY_VERDICT, "certify": False},
        )  # fmt: skip
    )
    meshes = {"a.stl": trimesh.creation.box((SIDE, SIDE, LONG)),
              "b.stl": trimesh.creation.box((PLATE, PLATE, THIN))}  # fmt: skip
    scene = load_scene(write_scene(body, meshes))
    real, seeds = solver.search, []

    def first_side_on(scene, passes, blocks, rng, seed, progress):
        seeds.append(seed)
        if len(seeds) > 1:
            return real(scene, passes, blocks, rng, seed, progress)
        return solver.SearchOutcome(SIDE_ON[None], np.zeros((1, 2)), 0.5,
                                    solver.SwarmHistory(), [("rotate a", 1)], [0.5])  # fmt: skip

    monkeypatch.setattr(solver, "search", first_side_on)
    r = solver.solve(scene, seed=3, progress=False)
    tol = scene.fabrication.tolerance
    if retries == 0:  # the old behaviour: the side-on hole is the answer, and the plate passes it
        assert seeds == [3] and r.retries == []
        assert sorted(_extent(r.outline)) == pytest.approx(
            [SIDE + 2 * tol, LONG + 2 * tol], abs=0.5
        )
        assert min(_extent(r.outline)) > THIN and max(_extent(r.outline)) > PLATE
        assert not r.attack.blocked()[0, 0]
        return
    assert seeds == [3, 4]  # one retry, from seed + 1, and none after a hole that blocks
    assert r.attack.blocked()[0, 0] and r.attack.beta[0, 0] > 0
    # The kept hole's longest chord (at most its bounding box's diagonal) is below the plate's side.
    assert np.hypot(*_extent(r.outline)) < PLATE
    first, second = r.retries
    assert first["passed"] == ["b"] and not first["kept"] and first["seed"] == 3
    assert second["passed"] == [] and second["kept"] and second["seed"] == 4
    assert any("first search's hole let b through" in w and "seed 4 blocks every B" in w
               for w in r.warnings)  # fmt: skip
