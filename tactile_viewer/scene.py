"""The 3-D scene: skin, elastomer, pressure map, force arrows, colour bars. No physics here.

Works on any pyvista plotter: the window's ``pyvistaqt.QtInteractor`` or an
off-screen ``pyvista.Plotter`` for batch screenshots. Display units are
millimetres (coordinates), kilopascals (maps) and millinewtons (arrows);
the surface is drawn at ``z = 0`` with the elastomer below it, so a force
pressing into the skin points down and its arrow ends on the surface.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv

from solver import SensorGrid

from .model import Display, Solved

__all__ = ["Scene"]

MM = 1e3  # metres -> millimetres
# with only two lights (see Scene), ambient light keeps faces turned from them readable
SHADED = dict(ambient=0.35, diffuse=0.75, specular=0.1)
MAP_TITLES = {"pressure": "pressure kPa", "stress": "stress kPa", "none": ""}


class Scene:
    """Draws a grid and its reconstructions into a pyvista plotter.

    Parameters
    ----------
    plotter : pyvista.Plotter
        Any plotter (``QtInteractor`` included); the scene adds to it and
        never closes it.
    smooth : bool, optional
        Multisample anti-aliasing (for batch figures; about three times the
        render time under software rendering). Default False.
    """

    def __init__(self, plotter, *, smooth=False):
        self.plotter = plotter
        self.grid: SensorGrid | None = None
        self.arrows = pv.PolyData()       # the per-node glyphs (for tests and exports)
        self.arrow_nodes = np.zeros(0, dtype=int)  # which node each drawn arrow belongs to
        self._actors = {}
        self._map = None
        self._bars = {}
        # one headlight instead of pyvista's five-light kit, and no multisampling:
        # software rendering (Xvfb, llvmpipe) is fill-rate bound and these two
        # cost about 70 of every 100 ms per frame there
        plotter.remove_all_lights()
        plotter.add_light(pv.Light(light_type="headlight", intensity=0.7))
        plotter.add_light(pv.Light(position=(0.3, -0.5, 1.0), light_type="scene light", intensity=0.4))
        plotter.ren_win.SetMultiSamples(8 if smooth else 0)
        plotter.set_background("white")
        # one arrow along +x from 0 to 1, as triangles: every node's arrow is a
        # scaled, turned copy (done in numpy; VTK's glyph filter is slower here)
        template = pv.Arrow(tip_length=0.3, tip_radius=0.12, shaft_radius=0.05, tip_resolution=12,
                            shaft_resolution=12).triangulate()
        # smooth normals, split at the rims so the discs and the cone stay crisp
        template = template.compute_normals(cell_normals=False, split_vertices=True, feature_angle=45)
        self._arrow_points = np.asarray(template.points, dtype=float)
        self._arrow_normals = np.asarray(template.point_data["Normals"], dtype=float)
        self._arrow_triangles = np.asarray(template.faces).reshape(-1, 4)[:, 1:]

    # -- building ----------------------------------------------------------------

    def set_grid(self, grid: SensorGrid):
        """Build the static parts for a grid (regular or not) and an empty map and arrow set."""
        for actor in self._actors.values():
            self.plotter.remove_actor(actor, render=False)
        for title in list(self.plotter.scalar_bars.keys()):
            self.plotter.remove_scalar_bar(title, render=False)
        self._actors, self._bars = {}, {}
        self.grid = grid
        self._surface = np.column_stack([grid.positions * MM, np.zeros(grid.size)])  # node tips, mm
        p, h = grid.pitch * MM, grid.thickness * MM
        x0, y0 = grid.positions.min(axis=0) * MM - p / 2
        x1, y1 = grid.positions.max(axis=0) * MM + p / 2
        # elastomer layer to scale, the rigid hull under it, the sensors at depth h.
        # Only faces that can be seen are drawn (software rendering is fill-rate
        # bound): the layer's top shows only when no map covers it, and then
        # translucent, so the sensors inside show through.
        self._actors["layer"] = self.plotter.add_mesh(
            _box_faces((x0, x1, y0, y1, -h, 0.0), "sides"), color="#9ecae1", name="layer", pickable=False,
            **SHADED)
        self._actors["layer_top"] = self.plotter.add_mesh(
            _box_faces((x0, x1, y0, y1, -h, 0.0), "top"), color="#9ecae1", opacity=0.3, name="layer_top",
            pickable=False)
        self._actors["hull"] = self.plotter.add_mesh(
            _box_faces((x0, x1, y0, y1, -h - 0.6 * p, -h), "sides and bottom"), color="#8c8c8c", name="hull",
            pickable=False, **SHADED)
        sensors = np.column_stack([grid.positions * MM, np.full(grid.size, -h)])
        self._actors["sensors"] = self.plotter.add_mesh(
            pv.PolyData(sensors), color="#252525", point_size=6, render_points_as_spheres=True,
            name="sensors", pickable=False)
        # the map: one pitch-sized square per node, just above the surface
        # (a regular grid tiles the skin; an irregular layout shows its taxels)
        self._map = _squares(grid.positions * MM, p, 0.002 * p)
        self._map.cell_data["kPa"] = np.zeros(grid.size)
        self._actors["map"] = self.plotter.add_mesh(
            self._map, scalars="kPa", cmap="viridis", clim=(0.0, 1.0), show_scalar_bar=False,
            name="map", pickable=False, lighting=False)  # unlit: colours match the bar
        self._bars["map"] = self.plotter.add_scalar_bar(
            title=MAP_TITLES["pressure"], mapper=self._actors["map"].mapper, vertical=True,
            position_x=0.86, position_y=0.1, height=0.8, width=0.06, color="black", n_labels=5,
            fmt="%.3g")
        # placeholders until the first frame (pyvista refuses empty meshes)
        self.arrow_nodes = np.zeros(0, dtype=int)
        self.arrows = pv.Arrow()
        self.arrows.point_data["mN"] = np.zeros(self.arrows.n_points)
        self._actors["arrows"] = self.plotter.add_mesh(
            self.arrows, scalars="mN", cmap="plasma", clim=(0.0, 1.0), show_scalar_bar=False,
            name="arrows", pickable=False, **SHADED)
        self._bars["arrows"] = self.plotter.add_scalar_bar(
            title="force mN", mapper=self._actors["arrows"].mapper, vertical=True,
            position_x=0.02, position_y=0.1, height=0.8, width=0.08, color="black", n_labels=5,
            fmt="%.3g")
        # a unit arrow along +x, placed each frame by the actor's matrix
        self._actors["resultant"] = self.plotter.add_mesh(
            pv.Arrow(start=(0, 0, 0), direction=(1, 0, 0), scale=1.0, tip_length=0.2, tip_radius=0.06,
                     shaft_radius=0.025), color="#d62728", name="resultant", pickable=False,
            **SHADED)
        self.arrows.copy_from(pv.PolyData())  # drawn empty until the first frame
        for name in ("arrows", "resultant"):
            self._actors[name].SetVisibility(False)
        self._bars["arrows"].SetVisibility(False)
        self.camera("iso")

    # -- per frame -------------------------------------------------------------------

    def update(self, solved: Solved, display: Display, *, render=True):
        """Show one reconstructed frame.

        Parameters
        ----------
        solved : Solved
            The frame: measured stress, the result, its pressure map and load centroid.
        display : Display
        """
        if self.grid is None:
            raise RuntimeError("set_grid must come before update")
        forces = solved.result.forces
        # the map
        values = np.asarray(solved.stress if display.map == "stress" else solved.pressure, dtype=float)
        self._map.cell_data["kPa"] = values / 1e3
        if display.auto_range:
            high = max(float(values.max()) / 1e3, 1e-9)
            low = min(float(values.min()) / 1e3, 0.0)
        else:
            low, high = 0.0, display.range_max / 1e3
        self._actors["map"].mapper.scalar_range = (low, high)
        self._actors["map"].SetVisibility(display.map != "none")
        self._actors["layer_top"].SetVisibility(display.map == "none")
        self._actors["sensors"].SetVisibility(display.map == "none")
        self._bars["map"].SetVisibility(display.map != "none")
        self._bars["map"].SetTitle(MAP_TITLES[display.map])

        # the arrows: tip on the surface, pointing where the force pushes
        magnitude = np.linalg.norm(forces, axis=1)
        shown = np.flatnonzero((magnitude > display.threshold) & (magnitude > 0)) if display.arrows \
            else np.zeros(0, dtype=int)
        scale = display.arrow_scale * MM
        vectors = np.column_stack([forces[:, 0], forces[:, 1], -forces[:, 2]])[shown] * scale
        tips = self._surface[shown]
        if shown.size:
            self.arrows.copy_from(self._glyphs(tips - vectors, vectors, magnitude[shown] * 1e3))
            self._actors["arrows"].mapper.scalar_range = (0.0, max(float(magnitude[shown].max()) * 1e3, 1e-9))
        else:
            self.arrows.copy_from(pv.PolyData())
        self.arrow_nodes = shown
        self._actors["arrows"].SetVisibility(bool(shown.size))
        self._bars["arrows"].SetVisibility(bool(shown.size))

        # the resultant at the centroid of the compressive load
        total = solved.result.total_force
        if display.resultant and solved.centroid is not None and np.linalg.norm(total) > 0:
            centroid = np.append(solved.centroid * MM, 0.0)
            vector = np.array([total[0], total[1], -total[2]]) * display.resultant_scale * MM
            self._actors["resultant"].user_matrix = _placement(centroid - vector, vector)
            self._actors["resultant"].SetVisibility(True)
        else:
            self._actors["resultant"].SetVisibility(False)
        if render:
            self.plotter.render()

    def _glyphs(self, starts, vectors, values) -> pv.PolyData:
        # arrow k spans starts[k] .. starts[k] + vectors[k], thickness in proportion
        rotations = _orientations(vectors)
        points = starts[:, None, :] + np.einsum("kij,pj->kpi", rotations, self._arrow_points)
        count, per_arrow = len(starts), len(self._arrow_points)
        triangles = self._arrow_triangles[None, :, :] + per_arrow * np.arange(count)[:, None, None]
        faces = np.concatenate([np.full(triangles.shape[:2] + (1,), 3), triangles], axis=2)
        glyphs = pv.PolyData(points.reshape(-1, 3), faces=faces.ravel())
        lengths = np.linalg.norm(vectors, axis=1)
        normals = np.einsum("kij,pj->kpi", rotations / lengths[:, None, None], self._arrow_normals)
        glyphs.point_data["mN"] = np.repeat(values, per_arrow)
        glyphs.point_data.set_array(normals.reshape(-1, 3), "Normals")
        glyphs.point_data.active_normals_name = "Normals"
        return glyphs

    # -- view --------------------------------------------------------------------------------

    def camera(self, preset: str):
        """``"top"`` (looking down on the surface) or ``"iso"``."""
        if preset == "top":
            self.plotter.view_xy()
        elif preset == "iso":
            self.plotter.view_isometric()
            self.plotter.camera.elevation = 10
        else:
            raise ValueError(f"camera preset must be 'top' or 'iso', got {preset!r}")
        self.plotter.reset_camera()

    def screenshot(self, path, *, scale: int = 1, transparent: bool = False) -> np.ndarray:
        """Save a PNG of the scene (``scale`` times the window size) and return the image."""
        if scale not in (1, 2, 3, 4):
            raise ValueError(f"scale must be 1, 2, 3 or 4, got {scale!r}")
        return self.plotter.screenshot(str(path), transparent_background=transparent, scale=scale,
                                       return_img=True)


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


def _placement(start: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """4x4 matrix taking the unit arrow along +x to ``start .. start + vector``."""
    matrix = np.eye(4)
    matrix[:3, :3] = _orientations(vector[None, :])[0]
    matrix[:3, 3] = start
    return matrix


def _squares(centres: np.ndarray, side: float, z: float) -> pv.PolyData:
    """One axis-aligned square (a quad cell) of ``side`` around each centre, at height ``z``."""
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * side / 2
    points = (centres[:, None, :] + corners[None, :, :]).reshape(-1, 2)
    faces = np.column_stack([np.full(len(centres), 4), np.arange(4 * len(centres)).reshape(-1, 4)])
    return pv.PolyData(np.column_stack([points, np.full(len(points), z)]), faces=faces.ravel())


def _box_faces(bounds, which: str) -> pv.PolyData:
    """Faces of an axis-aligned box: ``"sides"``, ``"top"`` or ``"sides and bottom"``."""
    x0, x1, y0, y1, z0, z1 = bounds
    points = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                       [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=float)
    sides = [[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]  # outward normals
    chosen = {"sides": sides, "top": [[4, 5, 6, 7]], "sides and bottom": sides + [[0, 3, 2, 1]]}[which]
    return pv.PolyData(points, faces=np.hstack([[4, *face] for face in chosen]))
