"""The scene's geometry: arrows and their copies, boxes, squares, flat text, axes, taxel numbers. No Qt.

Plain pyvista meshes (and the numpy arrays they are made of) that
:class:`~tactile_viewer.render.scene.Scene` places as actors; nothing here
touches a plotter. Coordinates are millimetres.

Text that belongs to the skin (axis ticks, the direction convention, taxel
numbers) is flat vector text lying on the surface's plane: it costs a few
hundred triangles instead of a texture per label, reads the same in the Top
view and in larger screenshots, and turns with the skin.
"""

from __future__ import annotations

import math

import numpy as np
import pyvista as pv
from vtkmodules.vtkRenderingFreeType import vtkVectorText

from solver import SensorGrid

__all__ = ["solid_arrow", "flat_arrow", "glyphs", "squares", "box_faces", "axes_mesh", "taxel_numbers",
           "MM", "LIFT_MAP", "LIFT_TEXT", "LIFT_FLAT", "MAX_TAXEL_IDS"]

MM = 1e3  # metres -> millimetres
# heights above the surface, in pitches: the map covers the layer's top, the taxel numbers the
# map, flat arrows the numbers (far below anything a viewer could see as a gap)
LIFT_MAP, LIFT_TEXT, LIFT_FLAT = 0.002, 0.004, 0.006
MAX_TAXEL_IDS = 4096  # more numbers than a 64x64 skin's are unreadable and cost seconds to build
DIGIT_ADVANCE = 0.8  # vtkVectorText's digits are about 0.72 wide and 1 tall


def solid_arrow(tip_length, tip_radius, shaft_radius):
    """A 3-D arrow along +x from 0 to 1: points, point normals and triangles."""
    template = pv.Arrow(tip_length=tip_length, tip_radius=tip_radius, shaft_radius=shaft_radius,
                        tip_resolution=12, shaft_resolution=12).triangulate()
    # smooth normals, split at the rims so the discs and the cone stay crisp
    template = template.compute_normals(cell_normals=False, split_vertices=True, feature_angle=45)
    return (np.asarray(template.points, dtype=float), np.asarray(template.point_data["Normals"], dtype=float),
            np.asarray(template.faces).reshape(-1, 4)[:, 1:])


def flat_arrow(tip_length, tip_width, shaft_width):
    """The arrow's outline in the x-y plane from (0, 0) to (1, 0): points, normals, triangles.

    The normals are -z: :func:`_orientations` takes the template's z to
    ``along x (along x z)``, which is -z for any direction in the plane, so
    the drawn arrow faces up.
    """
    neck = 1.0 - tip_length
    points = np.array([[0, -shaft_width, 0], [neck, -shaft_width, 0], [neck, shaft_width, 0],
                       [0, shaft_width, 0], [neck, -tip_width, 0], [1, 0, 0], [neck, tip_width, 0]],
                      dtype=float)
    normals = np.tile([0.0, 0.0, -1.0], (len(points), 1))
    return points, normals, np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6]])


def glyphs(template, starts, vectors, values) -> pv.PolyData:
    """Copies of ``template`` (points, normals, triangles of a unit arrow along +x), copy k
    spanning ``starts[k] .. starts[k] + vectors[k]``, thickness in proportion; each point
    carries its arrow's ``values[k]`` as "mN" (none when ``values`` is None)."""
    template_points, template_normals, template_triangles = template
    rotations = _orientations(vectors)
    points = starts[:, None, :] + np.einsum("kij,pj->kpi", rotations, template_points)
    count, per_arrow = len(starts), len(template_points)
    triangles = template_triangles[None, :, :] + per_arrow * np.arange(count)[:, None, None]
    faces = np.concatenate([np.full(triangles.shape[:2] + (1,), 3), triangles], axis=2)
    glyphs = pv.PolyData(points.reshape(-1, 3), faces=faces.ravel())
    lengths = np.linalg.norm(vectors, axis=1)
    normals = np.einsum("kij,pj->kpi", rotations / lengths[:, None, None], template_normals)
    if values is not None:
        glyphs.point_data["mN"] = np.repeat(values, per_arrow)
    glyphs.point_data.set_array(normals.reshape(-1, 3), "Normals")
    glyphs.point_data.active_normals_name = "Normals"
    return glyphs


def _orientations(vectors: np.ndarray) -> np.ndarray:
    """(k, 3, 3) matrices taking the +x unit vector to each of the (k, 3) ``vectors``,
    scaling every direction by the vector's length."""
    length = np.linalg.norm(vectors, axis=1)
    along = vectors / length[:, None]
    # any unit vector across `along` (z unless nearly parallel to it), then the third
    helper = np.where(np.abs(along[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    across = np.cross(along, helper)
    across /= np.linalg.norm(across, axis=1)[:, None]
    return length[:, None, None] * np.stack([along, across, np.cross(along, across)], axis=2)


def squares(centres: np.ndarray, side: float, z: float) -> pv.PolyData:
    """One axis-aligned square (a quad cell) of ``side`` around each centre, at height ``z``."""
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * side / 2
    points = (centres[:, None, :] + corners[None, :, :]).reshape(-1, 2)
    faces = np.column_stack([np.full(len(centres), 4), np.arange(4 * len(centres)).reshape(-1, 4)])
    return pv.PolyData(np.column_stack([points, np.full(len(points), z)]), faces=faces.ravel())


def box_faces(bounds, which: str) -> pv.PolyData:
    """Faces of an axis-aligned box: ``"sides"``, ``"top"`` or ``"sides and bottom"``."""
    x0, x1, y0, y1, z0, z1 = bounds
    points = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                       [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=float)
    sides = [[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]  # outward normals
    chosen = {"sides": sides, "top": [[4, 5, 6, 7]], "sides and bottom": sides + [[0, 3, 2, 1]]}[which]
    return pv.PolyData(points, faces=np.hstack([[4, *face] for face in chosen]))


# -- the axes and the taxel numbers ----------------------------------------------------------------

def axes_mesh(skin, pitch: float, arrow) -> tuple[pv.PolyData, tuple, dict]:
    """The axes beside a skin, flat on the surface's plane, as one mesh of black triangles.

    Parameters
    ----------
    skin : (4,) tuple of float
        ``x0, x1, y0, y1``: the skin's edges, millimetres.
    pitch : float
        The grid's pitch, metres (the mesh lies :data:`LIFT_TEXT` pitches above the surface).
    arrow : tuple
        The flat arrow template (:func:`flat_arrow`) the direction convention is drawn with.

    Returns
    -------
    mesh : pyvista.PolyData
    bounds : (4,) tuple of float
        ``x0, x1, y0, y1`` the mesh spans, millimetres.
    ticks : dict
        ``"x"``, ``"y"``: the tick positions, millimetres.
    """
    # ticks below the skin's lower edge (x) and left of its left edge (y), their values
    # and titles; an arrow along +x and one along +y above its upper left corner, named
    # "0 deg = +x" and "90 deg = +y"
    x0, x1, y0, y1 = skin
    size = max(x1 - x0, y1 - y0)
    text = 0.035 * size  # text height, mm
    gap, tick, stroke = 0.4 * text, 0.5 * text, 0.1 * text
    parts = []
    ticks = {}
    for axis, (low, high) in enumerate(((x0, x1), (y0, y1))):
        step = _nice_step((high - low) / 8)  # 5 to 10 ticks
        values = np.arange(math.ceil(low / step - 1e-9), math.floor(high / step + 1e-9) + 1) * step
        ticks["xy"[axis]] = values
        for value in values:
            label = f"{round(value / step) * step + 0.0:g}"  # + 0.0: no "-0"
            across = (value - stroke / 2, value + stroke / 2)
            if axis == 0:
                parts.append(_rectangle(*across, y0 - gap - tick, y0 - gap))
                parts.append(_text(label, (value, y0 - 2 * gap - tick), text, "center", "top"))
            else:
                parts.append(_rectangle(x0 - gap - tick, x0 - gap, *across))
                parts.append(_text(label, (x0 - 2 * gap - tick, value), text, "right", "center"))
    # axis titles: "x mm" under the x values, "y mm" turned along the y axis left of its values
    below = min(points[:, 1].min() for points, _ in parts)
    left = min(points[:, 0].min() for points, _ in parts)
    parts.append(_text("x mm", ((x0 + x1) / 2, below - gap), text, "center", "top"))
    parts.append(_text("y mm", (left - gap, (y0 + y1) / 2), text, "right", "center", turned=True))
    # the direction convention: shear and resultant directions are angles from +x
    length = 4 * text
    origin = np.array([x0, y1 + 2 * gap])
    for direction, label, anchor, align in (
            ((1.0, 0.0), "0 deg = +x", origin + (length + gap, 0.0), ("left", "center")),
            ((0.0, 1.0), "90 deg = +y", origin + (0.0, length + gap), ("center", "bottom"))):
        vector = np.array([*direction, 0.0]) * length
        rotation = _orientations(vector[None, :])[0]
        points = np.append(origin, 0.0) + arrow[0] @ rotation.T
        parts.append((points[:, :2], arrow[2]))
        parts.append(_text(label, anchor, text, *align))
    points, triangles = _merge(parts)
    lift = LIFT_TEXT * pitch * MM
    mesh = pv.PolyData(np.column_stack([points, np.full(len(points), lift)]),
                       faces=np.column_stack([np.full(len(triangles), 3), triangles]).ravel())
    low, high = points.min(axis=0), points.max(axis=0)
    return mesh, (low[0], high[0], low[1], high[1]), ticks


def taxel_numbers(grid: SensorGrid):
    """Every taxel's node index on its square, in flat digits (none on a skin of more than
    :data:`MAX_TAXEL_IDS` taxels).

    Returns
    -------
    mesh : pyvista.PolyData or None
        The numbers, a uint8 ``"rgb"`` point array (black) to colour them by; None when there
        are none.
    nodes : ndarray
        The taxels numbered.
    owner : ndarray or None
        The node of each point of the mesh.
    """
    nodes = np.arange(min(grid.size, MAX_TAXEL_IDS)) if grid.size <= MAX_TAXEL_IDS else np.zeros(0, int)
    if not nodes.size:
        return None, nodes, None
    p = grid.pitch * MM
    digits = len(str(nodes[-1]))
    # as tall as the square's width allows them (they were 0.3 p, 4 px in a 1280x800 window)
    height = min(0.5 * p, 0.95 * p / (DIGIT_ADVANCE * digits))
    centres = grid.positions[nodes] * MM
    points, triangles, owner = _numbers(nodes, centres, height)
    mesh = pv.PolyData(np.column_stack([points, np.full(len(points), LIFT_TEXT * p)]),
                       faces=np.column_stack([np.full(len(triangles), 3), triangles]).ravel())
    mesh.point_data["rgb"] = np.zeros((len(points), 3), dtype=np.uint8)
    return mesh, nodes, owner  # owner: the node of each point


# -- flat text and shapes: (points (n, 2), triangles (k, 3)) pairs ----------------------------------

def _nice_step(raw: float) -> float:
    """The smallest of 1, 2, 5 times a power of ten that is at least ``raw``."""
    power = 10.0 ** math.floor(math.log10(raw))
    return next(f * power for f in (1, 2, 5, 10) if f * power >= raw * (1 - 1e-9))


def _rectangle(x0, x1, y0, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float), np.array([[0, 1, 2], [0, 2, 3]])


def _vector_text(string: str):
    """A string's outline in vtkVectorText's units (capitals about 1 tall), as triangles."""
    source = vtkVectorText()
    source.SetText(string)
    source.Update()
    mesh = pv.wrap(source.GetOutput())
    return np.asarray(mesh.points, dtype=float)[:, :2], np.asarray(mesh.faces).reshape(-1, 4)[:, 1:]


def _text(string, anchor, height, halign, valign, *, turned=False):
    """Flat text ``height`` tall, its box aligned at ``anchor`` (``"left"``, ``"center"`` or
    ``"right"``; ``"bottom"``, ``"center"`` or ``"top"``), turned a quarter left if asked."""
    points, triangles = _vector_text(string)
    points = points * height
    if turned:
        points = np.column_stack([-points[:, 1], points[:, 0]])
    low, high = points.min(axis=0), points.max(axis=0)
    shift = np.array([{"left": low[0], "center": (low[0] + high[0]) / 2, "right": high[0]}[halign],
                      {"bottom": low[1], "center": (low[1] + high[1]) / 2, "top": high[1]}[valign]])
    return points - shift + np.asarray(anchor, dtype=float), triangles


def _numbers(numbers: np.ndarray, centres: np.ndarray, height: float):
    """Flat decimal numbers centred on ``centres``, built from ten digit outlines (a label per
    taxel of a large skin in a fraction of a second). Returns points (n, 2), triangles and the
    index into ``numbers`` of each point."""
    strings = [str(int(n)) for n in numbers]
    lengths = np.array([len(s) for s in strings])
    digits = np.zeros((len(strings), lengths.max()), dtype=int)
    for k, s in enumerate(strings):
        digits[k, :len(s)] = [int(c) for c in s]
    outlines = [_vector_text(str(d)) for d in range(10)]
    points, triangles, owner, count = [], [], [], 0
    for place in range(digits.shape[1]):
        for digit in range(10):
            which = np.flatnonzero((lengths > place) & (digits[:, place] == digit))
            if not which.size:
                continue
            outline, faces = outlines[digit]
            # the string's box runs from 0.2 to about 0.93 + 0.8 (n - 1); its middle goes on the centre
            offset = np.column_stack([(place - (lengths[which] - 1) / 2) * DIGIT_ADVANCE - 0.565,
                                      np.full(which.size, -0.47)])
            placed = centres[which, None, :] + (outline[None, :, :] + offset[:, None, :]) * height
            points.append(placed.reshape(-1, 2))
            per = len(outline)
            starts = count + per * np.arange(which.size)
            triangles.append((faces[None, :, :] + starts[:, None, None]).reshape(-1, 3))
            owner.append(np.repeat(which, per))
            count += per * which.size
    return np.concatenate(points), np.concatenate(triangles), np.concatenate(owner)


def _merge(parts):
    points, triangles, count = [], [], 0
    for part_points, part_triangles in parts:
        points.append(part_points)
        triangles.append(np.asarray(part_triangles) + count)
        count += len(part_points)
    return np.concatenate(points), np.concatenate(triangles)
