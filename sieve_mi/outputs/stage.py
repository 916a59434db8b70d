"""The Mitsuba stage shared by ``figure.png`` and ``passage.gif``: variant, view, lights, materials.

One idea: what the two Mitsuba pictures (:mod:`sieve_mi.outputs.figure`,
:mod:`sieve_mi.outputs.animation`, and through it ``shake.gif``) build alike, built once here:

* :func:`rgb_variant`: Mitsuba switched to an RGB variant for a colour picture, the caller's
  variant restored afterwards (also on error);
* :func:`view_axes`, :func:`box_corners`, :func:`perspective`, :func:`film`: a camera that looks
  from an azimuth and elevation (+z up) at a box, and the film it exposes;
* :func:`scene`, :func:`sun_direction`: a constant sky and a directional sun;
* :data:`COLOURS`, :func:`colour_name`, :func:`diffuse`, :func:`mesh`: two-sided diffuse
  materials in the palette's colours (:mod:`sieve_mi.outputs.palette`) on triangle meshes (the
  plate with its hole, the shapes);
* :func:`srgb8`: linear radiance to 8-bit sRGB.

Each picture keeps its own settings (view angles, lights, integrator, sampler, picture size):
only the way they are put on the stage is shared. Directions are unit vectors in scene
coordinates; lengths are scene units (mm).
"""

from __future__ import annotations

import contextlib
import math

import numpy as np

from sieve_mi.backend import select_rgb_variant
from sieve_mi.outputs.palette import block_colour, linear

__all__ = [
    "COLOURS",
    "box_corners",
    "colour_name",
    "diffuse",
    "direction",
    "film",
    "mesh",
    "perspective",
    "rgb_variant",
    "scene",
    "spectrum",
    "srgb8",
    "sun_direction",
    "view_axes",
]

#: Diffuse reflectances of the plate and the shapes in RGB variants: the palette's colours in
#: linear RGB (:func:`sieve_mi.outputs.palette.linear`).
COLOURS = {k: linear(k) for k in ("plate", "pass", "blocked", "escaped")}


@contextlib.contextmanager
def rgb_variant(mi):
    """Switch Mitsuba to an RGB variant for the ``with`` block; restore the caller's after it.

    Parameters
    ----------
    mi : module
        The ``mitsuba`` module.

    Yields
    ------
    str
        The variant in effect in the block: the first usable RGB one
        (:func:`sieve_mi.backend.select_rgb_variant`), else the caller's monochrome variant.

    Notes
    -----
    The caller's variant is set again on leaving the block, also on error. Where none was set
    before, the chosen one stays selected (Mitsuba cannot unset a variant).
    """
    before = mi.variant()
    try:
        yield select_rgb_variant(mi, before)
    finally:
        if before is not None and mi.variant() != before:
            mi.set_variant(before)


def direction(azimuth: float, elevation: float) -> np.ndarray:
    """The unit vector at ``azimuth`` (from +x towards +y) and ``elevation`` (above the xy plane).

    Parameters
    ----------
    azimuth, elevation : float
        Degrees.

    Returns
    -------
    (3,) ndarray
    """
    az, el = math.radians(azimuth), math.radians(elevation)
    return np.array([math.cos(az) * math.cos(el), math.sin(az) * math.cos(el), math.sin(el)])


def view_axes(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The axes of a camera seen from the scene at ``azimuth``, ``elevation`` (degrees), +z up.

    Returns
    -------
    back, right, up : (3,) ndarrays
        Unit vectors: from the scene towards the camera (:func:`direction`), the picture's
        right and its up.
    """
    back = direction(azimuth, elevation)
    right = np.cross(-back, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return back, right, np.cross(right, -back)


def box_corners(boxes) -> np.ndarray:
    """The corners of axis-aligned boxes.

    Parameters
    ----------
    boxes : sequence of (2, 3) ndarrays, or one (2, 3) ndarray
        Lower and upper corners, scene units.

    Returns
    -------
    (8 * len(boxes), 3) ndarray
        Eight corners per box, box after box, scene units.
    """
    boxes = [boxes] if np.ndim(boxes) == 2 else boxes
    return np.array(
        [[b[i, 0], b[j, 1], b[k, 2]] for b in boxes for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    )


def sun_direction(azimuth: float, elevation: float) -> np.ndarray:
    """The direction sunlight travels when the sun stands at ``azimuth``, ``elevation`` (degrees).

    Returns
    -------
    (3,) ndarray
        Unit vector, pointing down from the sun.
    """
    return -direction(azimuth, elevation)


def spectrum(value) -> dict:
    """A Mitsuba spectrum: an RGB triple (linear) as ``rgb``, a number as a flat ``spectrum``.

    A grey light in an RGB variant is given as a triple of equal values: a flat spectrum would
    be tinted pink in sRGB.
    """
    if np.ndim(value):
        return {"type": "rgb", "value": [float(c) for c in value]}
    return {"type": "spectrum", "value": float(value)}


def diffuse(value) -> dict:
    """A two-sided diffuse material (a dict for ``mi.load_dict``) of reflectance ``value``
    (:func:`spectrum`): open and inconsistently wound meshes shade from both sides."""
    return {"type": "twosided", "material": {"type": "diffuse", "reflectance": spectrum(value)}}


def colour_name(role: str, passes: bool) -> str:
    """The palette name of a shape: ``"pass"`` for an A, else ``"escaped"`` or ``"blocked"``.

    Parameters
    ----------
    role : {"pass", "block"}
    passes : bool
        Whether a B gets through the hole (ignored for an A).
    """
    return "pass" if role == "pass" else block_colour(not passes)


def mesh(mi, name: str, vertices: np.ndarray, faces: np.ndarray, value, normals=None):
    """A Mitsuba triangle mesh with a :func:`diffuse` material (world coordinates).

    Parameters
    ----------
    mi : module
        The ``mitsuba`` module (its variant set).
    name : str
    vertices : (V, 3) array_like
        Scene units.
    faces : (F, 3) array_like of int
        Vertex indices.
    value : float or (3,) sequence
        The reflectance (:func:`spectrum`).
    normals : (V, 3) array_like, optional
        Shading normals per vertex (default: flat shading).

    Returns
    -------
    mitsuba.Mesh
    """
    vertices, faces = np.asarray(vertices).reshape(-1, 3), np.asarray(faces).reshape(-1, 3)
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(diffuse(value))
    m = mi.Mesh(
        name, len(vertices), len(faces), props=props, has_vertex_normals=normals is not None
    )
    params = mi.traverse(m)
    # The buffers' own types: Dr.Jit arrays in JIT variants, dynamic arrays in scalar ones.
    params["vertex_positions"] = type(params["vertex_positions"])(
        vertices.astype(np.float32).ravel()
    )
    params["faces"] = type(params["faces"])(faces.astype(np.uint32).ravel())
    if normals is not None:
        params["vertex_normals"] = type(params["vertex_normals"])(
            np.asarray(normals).astype(np.float32).ravel()
        )
    params.update()
    return m


def scene(integrator: dict, sky, sun, sun_dir: np.ndarray) -> dict:
    """A scene (a dict for ``mi.load_dict``) lit by a constant sky and a directional sun.

    Parameters
    ----------
    integrator : dict
        Mitsuba's integrator.
    sky, sun : float or (3,) sequence
        The sky's radiance and the sun's irradiance (:func:`spectrum`).
    sun_dir : (3,) ndarray
        The direction sunlight travels (:func:`sun_direction`).

    Returns
    -------
    dict
        ``type``, ``integrator``, ``sky`` and ``sun``; the caller adds the shapes.
    """
    return {
        "type": "scene",
        "integrator": integrator,
        "sky": {"type": "constant", "radiance": spectrum(sky)},
        "sun": {"type": "directional", "direction": sun_dir.tolist(), "irradiance": spectrum(sun)},
    }


def film(mi, width: int, height: int, rfilter: str | None = None) -> dict:
    """An ``hdrfilm`` of ``width`` x ``height`` pixels, luminance in a monochrome variant, else RGB.

    Parameters
    ----------
    mi : module
        The ``mitsuba`` module (its variant set).
    width, height : int
        Pixels.
    rfilter : str, optional
        Mitsuba's reconstruction filter (default: Mitsuba's own).
    """
    out = {"type": "hdrfilm", "width": width, "height": height}
    if rfilter is not None:
        out["rfilter"] = {"type": rfilter}
    out["pixel_format"] = "luminance" if "mono" in mi.variant() else "rgb"
    return out


def perspective(mi, eye, fov: float, size: float, far: float) -> dict:
    """A perspective camera (a dict for ``mi.load_dict``); the caller adds its film and sampler.

    Parameters
    ----------
    mi : module
        The ``mitsuba`` module.
    eye : (origin, target, up)
        Three (3,) array_likes: where the camera stands and what it looks at (scene units), and
        the picture's up direction.
    fov : float
        Horizontal field of view, degrees.
    size : float
        The scene's size, scene units: the near clip plane lies at ``1e-3 * size``.
    far : float
        The far clip plane, in scene sizes.
    """
    origin, target, up = (np.asarray(v, dtype=np.float64).tolist() for v in eye)
    return {
        "type": "perspective",
        "fov": fov,
        "fov_axis": "x",
        "near_clip": 1e-3 * size,
        "far_clip": far * size,
        "to_world": mi.ScalarTransform4f().look_at(origin=origin, target=target, up=up),
    }


def srgb8(linear_radiance: np.ndarray, white: float = 1.0) -> np.ndarray:
    """Linear radiance to 8-bit sRGB (any shape): ``white`` and above become 255.

    Parameters
    ----------
    linear_radiance : ndarray
    white : float
        The radiance shown white (the exposure).

    Returns
    -------
    ndarray of uint8
        The same shape; NaN becomes 0 and infinity 255.
    """
    # The same arithmetic as ``np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) -
    # 0.055)`` on the clipped input (NaN 0), in place: a third of the time on a GIF's frames,
    # and two arrays of the input's size instead of four (the same bytes; a fresh process's
    # first touch of new memory is slow: 0.06-0.24 -> 0.05-0.15 CPU s on the default scene's
    # 20 frames, 2026-12-07).
    shape = np.shape(linear_radiance)
    x = np.divide(np.reshape(linear_radiance, -1), white)
    np.clip(x, 0.0, 1.0, out=x)  # infinities to 0, 1; NaN stays
    x[np.isnan(x)] = 0.0
    srgb = np.power(x, 1 / 2.4)
    srgb *= 1.055
    srgb -= 0.055
    low = x <= 0.0031308
    np.copyto(srgb, np.multiply(x, 12.92, out=x, where=low), where=low)
    srgb *= 255
    return np.rint(srgb, out=srgb).astype(np.uint8).reshape(shape)
