"""The raster frame shared by holes and silhouettes.

A :class:`Frame` is an N x N grid of square pixels centred on the origin of the xy-plane. Pixel
(row j, column i) has its centre at ``x = -R + (i + 0.5) h``, ``y = R - (j + 0.5) h`` where ``R`` is
the half extent and ``h = 2R/N`` the pixel size (scene units), so images show +y up. Masks are
sampled at pixel centres. The same infinite pixel lattice extends beyond the frame, which lets a
shape's silhouette be rasterised in a window anywhere in the plane and compared with the hole
pixel for pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Frame", "crop_window"]

#: Orthographic sensors by (resolution, half extent): :meth:`Frame.sensor`.
_SENSORS: dict = {}


@dataclass(frozen=True)
class Frame:
    """Square raster frame centred on the origin.

    Parameters
    ----------
    resolution : int
        Pixels per side, N.
    half_extent : float
        Half the side length R of the covered square, in scene units.
    """

    resolution: int
    half_extent: float

    @property
    def pixel_size(self) -> float:
        """Side length h of one pixel, in scene units."""
        return 2.0 * self.half_extent / self.resolution

    def sensor(self):
        """Mitsuba's orthographic sensor that frames this raster (cached per frame).

        It looks down the z-axis (from +z, so +x is to the image's right and +y up, row 0 at
        the top) and its N x N film covers the frame: ``sensor.sample_ray`` at film position
        ((i + 0.5) / N, (j + 0.5) / N) gives the ray through pixel (row j, column i)'s centre,
        also for indices beyond the frame (the lattice extends). The silhouettes' rays come
        from it (:meth:`sieve_mi.geometry.silhouettes.SilhouetteRenderer.trace`), and ``mi.render``
        under it gives the written masks (:meth:`~sieve_mi.geometry.silhouettes.SilhouetteRenderer.render`).
        The cache is keyed by Mitsuba's variant too: a sensor built under ``llvm_ad_mono`` takes
        only LLVM arrays, so a run that switches to ``cuda_ad_mono`` needs its own.
        """
        import mitsuba as mi

        key = (mi.variant(), self.resolution, self.half_extent)
        if key not in _SENSORS:
            _SENSORS[key] = self.window_sensor(0, 0, self.resolution)
        return _SENSORS[key]

    def window_sensor(self, row0: int, col0: int, size: int):
        """The orthographic sensor whose size x size film is the lattice window at (row0, col0).

        Its pixel centres are the lattice's: film pixel (j, i) is lattice pixel (row0 + j,
        col0 + i). The sensor sits at z = 1 looking down -z; whatever is rendered under it
        must lie below z = 0 (and above z = -1e7, in scene units). Its sampler takes each pixel's one
        sample at the centre (stratified, no jitter), so ``mi.render(..., spp=1)`` samples
        exactly the pixel centres. Not cached (windows differ from pose to pose; the whole
        frame's sensor is, by :meth:`sensor`).
        """
        import mitsuba as mi

        h = self.pixel_size
        half = 0.5 * size * h
        cx = -self.half_extent + col0 * h + half
        cy = self.half_extent - row0 * h - half
        t = mi.ScalarTransform4f()
        to_world = t.look_at(origin=[cx, cy, 1.0], target=[cx, cy, 0.0], up=[0, 1, 0]) @ t.scale(
            [half, half, 1.0]
        )
        return mi.load_dict(
            {
                "type": "orthographic",
                "to_world": to_world,
                "near_clip": 1e-3,
                "far_clip": 1e7,
                "sampler": {"type": "stratified", "sample_count": 1, "jitter": False},
                "film": {
                    "type": "hdrfilm",
                    "width": size,
                    "height": size,
                    "pixel_format": "luminance",
                    "rfilter": {"type": "box"},
                },
            }
        )

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Pixel-centre coordinates: x per column (N,) and y per row (N,), scene units."""
        i = np.arange(self.resolution) + 0.5
        return -self.half_extent + i * self.pixel_size, self.half_extent - i * self.pixel_size

    def to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """Continuous (column, row) coordinates of points ``xy`` (..., 2); pixel centres are integers."""
        xy = np.asarray(xy, dtype=np.float64)
        h = self.pixel_size
        return np.stack(
            [(xy[..., 0] + self.half_extent) / h - 0.5, (self.half_extent - xy[..., 1]) / h - 0.5],
            -1,
        )

    def window_centres(
        self, row0: np.ndarray, col0: np.ndarray, size: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pixel-centre coordinates of size x size windows whose top-left lattice pixel is (row0, col0).

        Returns
        -------
        x, y : (K, size) ndarrays
            x per window column and y per window row, scene units.
        """
        h = self.pixel_size
        k = np.arange(size) + 0.5
        x = -self.half_extent + (np.asarray(col0)[:, None] + k[None, :]) * h
        y = self.half_extent - (np.asarray(row0)[:, None] + k[None, :]) * h
        return x, y

    @staticmethod
    def covering(radius: float, resolution: int, margin_px: float = 3.0) -> Frame:
        """The frame of given resolution whose inscribed disk holds a disk of ``radius`` plus a margin.

        Parameters
        ----------
        radius : float
            Radius in scene units that must lie inside the frame.
        resolution : int
            Pixels per side.
        margin_px : float
            Extra margin in pixels on each side, so the hole never touches the frame's border.
        """
        if radius <= 0:
            raise ValueError("radius must be positive")
        return Frame(resolution, radius * resolution / (resolution - 2.0 * margin_px))


def crop_window(image: np.ndarray, row0: int, col0: int, size: int, fill=0) -> np.ndarray:
    """The size x size window of ``image`` at lattice offset (row0, col0), padded with ``fill`` outside."""
    n_rows, n_cols = image.shape
    out = np.full((size, size), fill, dtype=image.dtype)
    r0, c0 = max(row0, 0), max(col0, 0)
    r1, c1 = min(row0 + size, n_rows), min(col0 + size, n_cols)
    if r1 > r0 and c1 > c0:
        out[r0 - row0 : r1 - row0, c0 - col0 : c1 - col0] = image[r0:r1, c0:c1]
    return out
