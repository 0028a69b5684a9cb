"""Ray paths from a source to a sensor on a rectangular plate: direct and edge reflections.

Image sources: the plate is [0, L] x [0, W]; a ray reflected by the edge x = 0 comes
from the image (-xs, ys), by x = L from (2L - xs, ys), by y = 0 from (xs, -ys), by
y = W from (xs, 2W - ys). In general the images are (sx xs + 2 m L, sy ys + 2 n W),
sx, sy = +-1, with |2m| (sx = +1) or |2m - 1| (sx = -1) reflections on the x edges
and likewise on the y edges; order 1 gives the four edges, order 2 adds the four
corners (one reflection on an x edge and one on a y edge) and the four double
reflections between opposite edges. Each path is the straight line from its image to
the sensor: its length, and its direction (deg from the x axis) as seen along that
line, which for a reflection off an edge parallel to a symmetry axis of an
orthotropic plate has the same group velocity as every segment of the real ray.

Units: m, degrees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .wavelet import WaveError

__all__ = ["RayPath", "ray_paths"]


@dataclass(frozen=True)
class RayPath:
    """One source-to-sensor ray: ``name`` ('direct', 'x=0', 'x=L', 'y=0', 'y=W',
    'corner x=0,y=W', 'x=0,x=L', ...), number of reflections, length (m) and direction
    (deg from the x axis, from the image source to the sensor)."""

    name: str
    order: int
    length_m: float
    direction_deg: float


def _axis(s: float, size: float, sign: int, m: int) -> tuple[float, int]:
    """Image coordinate along one axis and its number of reflections."""
    return sign * s + 2 * m * size, abs(2 * m) if sign > 0 else abs(2 * m - 1)


def ray_paths(source_xy: tuple[float, float], sensor_xy: tuple[float, float], length: float, width: float,
              order: int = 1) -> tuple[RayPath, ...]:
    """Direct path and every edge reflection up to ``order`` reflections (0, 1 or 2),
    shortest first."""
    if order not in (0, 1, 2):
        raise WaveError(f"reflection order {order!r}: expected 0, 1 or 2")
    if not (length > 0 and width > 0):
        raise WaveError(f"plate {length!r} x {width!r} m: expected positive sizes")
    xs, ys = source_xy
    xr, yr = sensor_xy
    names_x = {(1, 0): "", (-1, 0): "x=0", (-1, 1): "x=L", (1, -1): "x=L,x=0", (1, 1): "x=0,x=L"}
    names_y = {(1, 0): "", (-1, 0): "y=0", (-1, 1): "y=W", (1, -1): "y=W,y=0", (1, 1): "y=0,y=W"}
    out = []
    for (sx, mx), nx_name in names_x.items():
        X, nx = _axis(xs, length, sx, mx)
        for (sy, my), ny_name in names_y.items():
            Y, ny = _axis(ys, width, sy, my)
            n = nx + ny
            if n > order:
                continue
            r = math.hypot(xr - X, yr - Y)
            if r <= 0:
                raise WaveError(f"sensor at {sensor_xy} coincides with the source or an image of it")
            if n == 0:
                name = "direct"
            elif nx and ny:
                name = f"corner {nx_name},{ny_name}"
            else:
                name = nx_name or ny_name
            out.append(RayPath(name, n, r, math.degrees(math.atan2(yr - Y, xr - X))))
    return tuple(sorted(out, key=lambda p: p.length_m))
