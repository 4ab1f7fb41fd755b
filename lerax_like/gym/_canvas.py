"""`Canvas`: a picture drawn in world coordinates with NumPy alone (no pygame for an array).

Shapes are painted by their signed distance (in pixels) from each pixel centre, over the
pixels of their bounding box only: a pixel is covered by `clip(0.5 - distance, 0, 1)`,
which antialiases every edge by one pixel, as pygame's `gfxdraw.aapolygon` outlines do
for Gymnasium's pictures. Positions are in world units (metres, `y` up); widths and
radii are in pixels, so that a rod looks the same at every zoom.
"""

import functools
from collections.abc import Sequence

import numpy as np


Colour = tuple[int, int, int]
Point = tuple[float, float]


@functools.lru_cache(maxsize=8)
def _blank(height: int, width: int, background: Colour) -> np.ndarray:
    """An empty picture, made once per size and colour (filling one costs more than copying it)."""
    blank = np.empty((height, width, 3), dtype=np.uint8)
    blank[...] = np.asarray(background, dtype=np.uint8)
    blank.flags.writeable = False
    return blank


class Canvas:
    """A `height` by `width` RGB picture of the world box `xlim` by `ylim` (world units, `y` up).

    The box is scaled to fit the picture and centred; `scale` is pixels per world unit.
    `image()` returns the picture as Gymnasium's renderers do: `(height, width, 3)` uint8.
    """

    def __init__(
        self,
        xlim: tuple[float, float],
        ylim: tuple[float, float],
        width: int = 600,
        height: int = 400,
        background: Colour = (255, 255, 255),
    ):
        if not (xlim[1] > xlim[0] and ylim[1] > ylim[0]):
            raise ValueError(f"a canvas needs xlim and ylim with low < high, got {xlim} and {ylim}")
        self.width, self.height = width, height
        self.scale = min(width / (xlim[1] - xlim[0]), height / (ylim[1] - ylim[0]))
        self._centre = ((xlim[0] + xlim[1]) / 2, (ylim[0] + ylim[1]) / 2)
        # uint8 throughout: each shape blends in floats over its own pixels only.
        self._pixels = _blank(height, width, background).copy()

    def pixel(self, point: Point) -> np.ndarray:
        """Where the world point `(x, y)` lies in the picture: `(column, row)` as floats."""
        x, y = point
        return np.array(
            [(x - self._centre[0]) * self.scale + self.width / 2, self.height / 2 - (y - self._centre[1]) * self.scale],
            dtype=np.float64,
        )

    def _paint(self, low: np.ndarray, high: np.ndarray, distance, colour: Colour) -> None:
        """Blend `colour` over the pixels whose centres lie within `distance` (pixels, a
        function of the centres' columns and rows; negative inside), within the box `low`-`high`."""
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
            return  # a shape at an infinite or undefined place is not in the picture
        column_0, row_0 = np.maximum(np.floor(low - 1), 0).astype(int)
        column_1 = int(min(np.ceil(high[0] + 1), self.width))
        row_1 = int(min(np.ceil(high[1] + 1), self.height))
        if column_0 >= column_1 or row_0 >= row_1:
            return
        columns = np.arange(column_0, column_1, dtype=np.float32)[None, :] + 0.5
        rows = np.arange(row_0, row_1, dtype=np.float32)[:, None] + 0.5
        coverage = np.clip(0.5 - distance(columns, rows), 0.0, 1.0)
        region = self._pixels[row_0:row_1, column_0:column_1]
        # Most of a box is outside the shape or wholly inside it: only the edge is blended.
        region[coverage >= 1.0] = colour
        edge = (coverage > 0.0) & (coverage < 1.0)
        below = region[edge].astype(np.float32)
        region[edge] = np.rint(below + (np.asarray(colour, dtype=np.float32) - below) * coverage[edge][:, None])

    def disc(self, centre: Point, radius: float, colour: Colour) -> None:
        """A filled disc of `radius` pixels."""
        c = self.pixel(centre).astype(np.float32)
        self._paint(c - radius, c + radius, lambda x, y: np.hypot(x - c[0], y - c[1]) - radius, colour)

    def ring(self, centre: Point, radius: float, width: float, colour: Colour) -> None:
        """A circle of `radius` pixels drawn `width` pixels wide."""
        c = self.pixel(centre).astype(np.float32)
        reach = radius + width / 2
        self._paint(
            c - reach, c + reach, lambda x, y: np.abs(np.hypot(x - c[0], y - c[1]) - radius) - width / 2, colour
        )

    def segment(self, start: Point, end: Point, width: float, colour: Colour) -> None:
        """A straight stroke `width` pixels wide with round ends (a rod, a line)."""
        a, b = self.pixel(start).astype(np.float32), self.pixel(end).astype(np.float32)
        along = b - a
        length_squared = max(float(along @ along), 1e-12)
        half = width / 2

        def distance(x, y):
            t = np.clip(((x - a[0]) * along[0] + (y - a[1]) * along[1]) / length_squared, 0.0, 1.0)
            return np.hypot(x - a[0] - t * along[0], y - a[1] - t * along[1]) - half

        # Only the part within the picture is painted: a line drawn to beyond the picture's
        # edges (a floor, a slope) would otherwise be measured over its whole box.
        margin = half + 1
        low_t, high_t = 0.0, 1.0
        for origin, step, limit in ((a[0], along[0], self.width), (a[1], along[1], self.height)):
            if abs(step) < 1e-12:
                if not -margin <= origin <= limit + margin:
                    return
                continue
            t_0, t_1 = sorted(((-margin - origin) / step, (limit + margin - origin) / step))
            low_t, high_t = max(low_t, t_0), min(high_t, t_1)
        if low_t > high_t:
            return
        first, last = a + low_t * along, a + high_t * along
        self._paint(np.minimum(first, last) - half, np.maximum(first, last) + half, distance, colour)

    def rectangle(self, low: Point, high: Point, colour: Colour) -> None:
        """A filled rectangle with sides along the axes, between the corners `low` and `high`."""
        a, b = self.pixel(low).astype(np.float32), self.pixel(high).astype(np.float32)
        low_pixel, high_pixel = np.minimum(a, b), np.maximum(a, b)

        def distance(x, y):
            return np.maximum(
                np.maximum(low_pixel[0] - x, x - high_pixel[0]), np.maximum(low_pixel[1] - y, y - high_pixel[1])
            )

        if not (np.all(np.isfinite(low_pixel)) and np.all(np.isfinite(high_pixel))):
            return
        # The pixels wholly inside are set at once (a wall or the floor fills much of the
        # picture); only the four edges are blended.
        column_0, row_0 = np.clip(np.ceil(low_pixel), 0, [self.width, self.height]).astype(int)
        column_1, row_1 = np.clip(np.floor(high_pixel), 0, [self.width, self.height]).astype(int)
        self._pixels[row_0:row_1, column_0:column_1] = colour
        for start, end in (
            ((low_pixel[0], low_pixel[1]), (low_pixel[0], high_pixel[1])),
            ((high_pixel[0], low_pixel[1]), (high_pixel[0], high_pixel[1])),
            ((low_pixel[0], low_pixel[1]), (high_pixel[0], low_pixel[1])),
            ((low_pixel[0], high_pixel[1]), (high_pixel[0], high_pixel[1])),
        ):
            self._paint(np.array(start), np.array(end), distance, colour)

    def below(self, point: Point, direction: Point, colour: Colour) -> None:
        """Fill the side of the line through `point` along `direction` (world) that lies
        below it (ground under a slope), to the picture's edges."""
        p = self.pixel(point).astype(np.float32)
        d = np.array([direction[0], -direction[1]], dtype=np.float32)  # y down in the picture
        d /= max(float(np.hypot(*d)), 1e-12)
        normal = np.array([-d[1], d[0]]) if d[0] >= 0 else np.array([d[1], -d[0]])  # pointing down (+row)
        if abs(d[0]) < 1e-6:
            return  # a vertical line has no side below it
        # The line's highest row within the picture bounds the box from above.
        rows = p[1] + d[1] / d[0] * (np.array([0.0, self.width]) - p[0])
        low = np.array([0.0, max(float(rows.min()), 0.0)])
        high = np.array([float(self.width), float(self.height)])
        self._paint(low, high, lambda x, y: -((x - p[0]) * normal[0] + (y - p[1]) * normal[1]), colour)

    def polygon(self, points: Sequence[Point], colour: Colour) -> None:
        """A filled convex polygon with these corners (world points, either winding)."""
        corners = np.array([self.pixel(point) for point in points], dtype=np.float32)
        edges = np.roll(corners, -1, axis=0) - corners
        # Outward unit normals whichever the winding: the sign of the polygon's area.
        area = float(np.sum(corners[:, 0] * np.roll(corners[:, 1], -1) - np.roll(corners[:, 0], -1) * corners[:, 1]))
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) * (1.0 if area >= 0 else -1.0)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        offsets = np.sum(normals * corners, axis=1)

        def distance(x, y):
            # Inside, the distance to the nearest edge; outside, a bound of it (exact off the corners).
            return np.max(normals[:, 0, None, None] * x + normals[:, 1, None, None] * y - offsets[:, None, None], axis=0)

        self._paint(corners.min(axis=0), corners.max(axis=0), distance, colour)

    def image(self) -> np.ndarray:
        """The picture: `(height, width, 3)` uint8."""
        return self._pixels.copy()
