"""The many-B game is not the pairwise game (paper Fig. 9), on a scene whose answers follow from geometry.

The scene
---------
A, a "wheel on an axle", every part of wire thickness d = 7 mm (all units mm):

* a ring (torus) whose centre line is a circle of diameter D = 34 around the z axis,
* a spoke along one diameter of the ring (it only makes A one piece), and
* an axle, a cylinder of length E = 60 along the ring's axis through its centre.

B1, a ball of diameter s = 20 (icosphere: vertices on the sphere, inscribed ball 19.91).
B2, a thin coin of diameter P = 50 and thickness t = 2 (64-gon: inscribed disk 49.94).
Tolerance 0, holes filled, a 70 mm plate (thicker than every shape: no thin-plate stage).
A's bounding radius is 30.2, so a pixel is 0.495 at the search resolution (128) and 0.325 at
the verdict resolution (192).

A's holes
---------
Each part of A is a skeleton (a circle, segments) thickened by a ball of radius d/2 (the meshes are
inscribed polygons, slightly inside that), so its projection is the projected skeleton thickened by
a disk of radius d/2. Let theta be the angle between the axle and the viewing direction z. Up to a
rotation in the plane (which B can copy) and the spoke (which always projects inside the ring's
filled ellipse), the hole depends on theta only. With y the direction of the projected axle,
H(theta) is the union of

* F = the filled ellipse with semi-axes D/2, (D/2) cos(theta), thickened by d/2 (ring and spoke), and
* S = a segment of length E sin(theta) along y, thickened by d/2 (axle).

Hence:

(i)   H lies in the disk of radius max(D + d, E sin(theta) + d) / 2 about its centre;
(ii)  H lies in the slab |y| <= (D cos(theta) + d) / 2 together with the strip |x| <= d/2;
(iii) F contains the ellipse with semi-axes (D + d)/2 and (D cos(theta) + d)/2, and S contains the
      axle's section through its axis, a 6.94 x E sin(theta) rectangle (24-gon axle).

The four facts (margins in parentheses; they are all several pixels)
-------------------------------------------------------------------
* Coin blocked for theta <= 40 deg. Every projection of the coin contains a segment of length 49.94
  (the diameter of its inscribed disk perpendicular to the view), but by (i) the hole's diameter is at
  most max(41, 60 sin 40 + 7 = 45.6) = 45.6 (4.3 too short in total; 8.9 face-on).
* Coin passes for theta >= 62 deg. Seen edge-on it is a 50 x 2 rectangle, which by (iii) fits in
  the axle's 6.94 x (60 sin 62 = 52.98) rectangle (2.98 spare in length, 4.94 in width).
* Ball passes for theta <= 62 deg. Its projection is a disk of diameter at most 20, and by (iii) F
  holds a disk of diameter min(41, 34 cos(theta) + 7) >= 34 cos 62 + 7 = 22.96 (2.96 spare).
* Ball blocked for theta >= 75 deg. Every projection of the ball holds a disk of diameter
  s' = 19.91 > d. Such a disk in the region of (ii) has its centre in the slab (otherwise the chord
  through its centre, 19.91 long, would lie outside the slab, in the 7 mm strip); the part beyond
  each edge of the slab lies in the strip, so the chord along that edge is at most d long and the
  edge is at least sqrt((s'/2)^2 - (d/2)^2) from the centre: the slab must be at least
  sqrt(s'^2 - d^2) = 18.64 wide. At theta >= 75 deg it is 34 cos 75 + 7 = 15.80 wide (2.84 short).

So A wins {A} vs {ball} (turn edge-on) and {A} vs {coin} (turn face-on), but in {A} vs
{ball, coin} every orientation lets one of them through: theta <= 62 deg admits the ball and
theta >= 62 deg admits the coin. Player A's orientations that block the ball all admit the coin and
vice versa.

A uniformly random rotation has cos(theta) uniform on [0, 1], so a random particle lands in the
argued winning sets with probability 1 - cos 40 = 0.23 (coin) and cos 75 = 0.26 (ball); the sets
where the coin and the ball are actually blocked (measured: theta below about 48 deg, above about
72 deg) hold about a third each, so a swarm of 12 particles starts inside them with probability
above 99%.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.api import solve
from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import from_axis_angle, to_matrix
from sieve_mi.scene import load_scene
from sieve_mi.testing.shapes import centred, from_manifold, sphere

D, WIRE, AXLE = 34.0, 7.0, 60.0  # A: ring centre-line diameter, wire thickness, axle length
BALL = 20.0  # B1: ball diameter
COIN, COIN_T = 50.0, 2.0  # B2: coin diameter and thickness

#: theta (degrees) up to which the coin is argued blocked, the crossover where both pass, and the
#: angle from which the ball is argued blocked.
COIN_BLOCKED, CROSSOVER, BALL_BLOCKED = 40.0, 62.0, 75.0

SETTINGS = """
[fabrication]
tolerance = 0.0
thickness = 70.0
[solver]
resolution = 128
particles = 12
iterations = 4
starts = 16
steps = 100
[verdict]
starts = 40
steps = 250
resolution = 192
"""


def wheel() -> trimesh.Trimesh:
    """A: ring + one spoke + axle, all of wire thickness WIRE, axle along z."""
    r = WIRE / 2
    ring = manifold3d.Manifold.revolve(
        manifold3d.CrossSection.circle(r, 24).translate((D / 2, 0.0)), 64
    )
    axle = manifold3d.Manifold.cylinder(AXLE, r, -1.0, 24, True)
    spoke = manifold3d.Manifold.cylinder(D, r, -1.0, 24, True).rotate((0.0, 90.0, 0.0))
    return centred(from_manifold(ring + axle + spoke))


def coin() -> trimesh.Trimesh:
    return centred(from_manifold(manifold3d.Manifold.cylinder(COIN_T, COIN / 2, -1.0, 64, True)))


def ball() -> trimesh.Trimesh:
    return sphere(BALL / 2, 3)


def tilt(theta_deg: float) -> list[float]:
    """The rotation tilting A's axle by theta from the viewing direction z (about x)."""
    return [float(v) for v in from_axis_angle([1.0, 0.0, 0.0], math.radians(theta_deg))]


def theta_of(q) -> float:
    """Angle (degrees, 0..90) between A's rotated axle and the viewing direction."""
    return math.degrees(math.acos(min(1.0, abs(float(to_matrix(np.asarray(q))[2, 2])))))


def _scene(write_scene, blocks: list[str], rotation=None, certify: bool = True):
    """The scene; ``certify=False`` where B wins whatever the proofs say (a proof can only turn
    a block into a passage): the attack's blocks are what is asserted. The A-wins games keep certify's search for a
    passage (which would overrule the attack) with a 4 s budget: the full exact proof of the
    blocked coin takes about 16 s on 2 cores, and an unfinished proof never changes a winner."""
    meshes = {"wheel.stl": wheel(), "ball.stl": ball(), "coin.stl": coin()}
    body = 'name = "many-b"\n[[pass]]\nmesh = "meshes/wheel.stl"\n'
    if rotation is not None:
        body += f"rotation = {rotation}\n"
    for b in blocks:
        body += f'[[block]]\nmesh = "meshes/{b}.stl"\n'
    scene = load_scene(write_scene(body + SETTINGS, meshes))
    scene.verdict.certify = certify
    scene.verdict.certify_budget = 4.0
    return scene


# ------------------------------------------------------------------------------------------------
# The premises, checked on the raster (no optimisation)
# ------------------------------------------------------------------------------------------------


def test_argument_numbers():
    a = wheel()
    assert a.is_volume and a.body_count == 1  # one solid piece
    assert shape_from_trimesh(a, name="wheel").radius == pytest.approx(30.2, abs=0.05)
    s_in = 2 * float(np.abs((ball().triangles_center * ball().face_normals).sum(1)).min())
    assert s_in == pytest.approx(19.91, abs=0.01)
    chord = COIN * math.cos(math.pi / 64)
    assert chord == pytest.approx(49.94, abs=0.01)
    c40, s62, c62, c75 = (
        f(math.radians(a))
        for f, a in (
            (math.sin, COIN_BLOCKED),
            (math.sin, CROSSOVER),
            (math.cos, CROSSOVER),
            (math.cos, BALL_BLOCKED),
        )
    )
    # coin blocked: its chord exceeds the hole's diameter
    assert chord - max(D + WIRE, AXLE * c40 + WIRE) >= 4.3
    # crossover: the coin fits the axle, the ball fits the ellipse, each with about 3 mm to spare
    assert AXLE * s62 - COIN >= 2.95 and WIRE * math.cos(math.pi / 24) - COIN_T >= 4.9
    assert D * c62 + WIRE - BALL >= 2.95
    # ball blocked: the slab is narrower than sqrt(s'^2 - d^2)
    assert math.sqrt(s_in**2 - WIRE**2) - (D * c75 + WIRE) >= 2.8


@pytest.mark.parametrize("theta", [0.0, 30.0, 45.0, 62.0, 75.0, 90.0])
def test_hole_lies_where_the_argument_puts_it(theta):
    # (i) and (ii) on the raster: every hole pixel lies in the disk and in slab-or-strip.
    a = shape_from_trimesh(wheel(), name="wheel")
    frame = Frame.covering(a.radius, 192)
    player = PlayerA(a, frame, tolerance=0.0)
    hole = player.holes(np.array([tilt(theta)]))[0]
    h = frame.pixel_size
    x, y = frame.centres()
    xx, yy = np.meshgrid(x, y)  # the axle projects along y (rotation about x)
    px, py = xx[hole.mask], yy[hole.mask]
    t = math.radians(theta)
    radius = max(D + WIRE, AXLE * math.sin(t) + WIRE) / 2
    assert np.hypot(px, py).max() <= radius + 1e-6
    in_slab = np.abs(py) <= (D * math.cos(t) + WIRE) / 2 + 1e-6
    in_strip = np.abs(px) <= WIRE / 2 + 1e-6
    assert np.all(in_slab | in_strip)
    # (iii): the hole holds the axle's rectangle and the thickened ellipse (up to a pixel)
    rect = (np.abs(xx) <= WIRE * math.cos(math.pi / 24) / 2 - h) & (
        np.abs(yy) <= AXLE * math.sin(t) / 2 - h
    )
    ell = (xx / ((D + WIRE) / 2 - h)) ** 2 + (yy / ((D * math.cos(t) + WIRE) / 2 - h)) ** 2 <= 1
    assert np.all(hole.mask[rect | ell])


# ------------------------------------------------------------------------------------------------
# The ingredients, with A's orientation fixed (only the verdict runs)
# ------------------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    "theta, ball_blocked, coin_blocked",
    [
        (0.0, False, True),  # face-on: a 41 mm disk, too small for the coin, roomy for the ball
        (COIN_BLOCKED, False, True),
        (CROSSOVER, False, False),  # both pass with about 3 mm to spare
        (BALL_BLOCKED, True, False),
        (90.0, True, False),  # edge-on: a 7 mm wide cross, the coin slides along the 60 mm axle
    ],
)
def test_fixed_orientation(write_scene, theta, ball_blocked, coin_blocked):
    scene = _scene(write_scene, ["ball", "coin"], rotation=tilt(theta), certify=False)
    r = solve(scene, seed=0, progress=False)
    assert theta_of(r.pass_quats[0]) == pytest.approx(theta, abs=1e-6)
    assert list(r.attack.blocked()[0]) == [ball_blocked, coin_blocked]
    assert r.winner == "B"  # never both blocked


# ------------------------------------------------------------------------------------------------
# The games, with player A searching
# ------------------------------------------------------------------------------------------------


def _other_passes(r, other: trimesh.Trimesh, name: str) -> bool:
    """Whether the shape *not* in the game fits through the hole A chose (verdict settings)."""
    shape = shape_from_trimesh(other, name=name)
    attack = PlayerB([shape], r.hole.frame).attack(
        [r.hole], 40, 250, 0.05, np.random.default_rng(1)
    )
    return bool(attack.beta[0, 0] == 0.0)


@pytest.mark.slow
def test_a_blocks_the_ball_alone_by_turning_edge_on(write_scene):
    r = solve(_scene(write_scene, ["ball"]), seed=0, progress=False)
    assert r.winner == "A"
    assert theta_of(r.pass_quats[0]) > CROSSOVER  # only near edge-on views block the ball ...
    assert _other_passes(r, coin(), "coin")  # ... and those let the coin through


@pytest.mark.slow
def test_a_blocks_the_coin_alone_by_turning_face_on(write_scene):
    r = solve(_scene(write_scene, ["coin"]), seed=0, progress=False)
    assert r.winner == "A"
    assert theta_of(r.pass_quats[0]) < CROSSOVER  # only near face-on views block the coin ...
    assert _other_passes(r, ball(), "ball")  # ... and those let the ball through


@pytest.mark.slow
def test_a_cannot_block_both(write_scene):
    r = solve(_scene(write_scene, ["ball", "coin"], certify=False), seed=0, progress=False)
    assert r.winner == "B"
    assert not r.attack.blocked()[0].all()
