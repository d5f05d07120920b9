"""The 3-D scene: skin, elastomer, pressure map, force arrows, colour bars, axes. No physics here.

Works on any pyvista plotter: the window's ``pyvistaqt.QtInteractor`` or an
off-screen ``pyvista.Plotter`` for batch screenshots. Display units are
millimetres (coordinates), kilopascals (maps) and millinewtons (arrows);
the surface is drawn at ``z = 0`` with the elastomer below it, so a force
pressing into the skin points down and its arrow ends on the surface.

Text that belongs to the skin (axis ticks, the direction convention, taxel
numbers) is flat vector text lying on the surface's plane: it costs a few
hundred triangles instead of a texture per label, reads the same in the Top
view and in larger screenshots, and turns with the skin.
"""

from __future__ import annotations

import math

import numpy as np
import pyvista as pv
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkRenderingCore import vtkRenderer, vtkTextActor
from vtkmodules.vtkRenderingFreeType import vtkVectorText

from solver import SensorGrid

from ..io.recording import written_whole
from ..model.viewer_model import Display, Solved

__all__ = ["Scene", "taxel_text", "MAX_TAXEL_IDS"]

MM = 1e3  # metres -> millimetres
# with only two lights (see Scene), ambient light keeps faces turned from them readable
SHADED = dict(ambient=0.35, diffuse=0.75, specular=0.1)
MAP_TITLES = {"pressure": "pressure kPa", "stress": "stress kPa", "none": ""}
# heights above the surface, in pitches: the map covers the layer's top, the taxel numbers the
# map, flat arrows the numbers (far below anything a viewer could see as a gap)
LIFT_MAP, LIFT_TEXT, LIFT_FLAT = 0.002, 0.004, 0.006
MAX_TAXEL_IDS = 4096  # more numbers than a 64x64 skin's are unreadable and cost seconds to build
DIGIT_ADVANCE = 0.8  # vtkVectorText's digits are about 0.72 wide and 1 tall
RESULTANT_COLOUR = "#d62728"


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

    Attributes
    ----------
    arrows : pyvista.PolyData
        The per-node arrows drawn (for tests and exports); ``arrow_nodes`` the
        node of each, in order.
    resultants : pyvista.PolyData
        The resultant arrows drawn; ``resultant_tips`` and ``resultant_vectors``
        (k, 3) where each ends and its extent, millimetres.
    ticks : dict
        ``"x"``, ``"y"``: the axes' tick positions, millimetres.
    label_nodes : ndarray
        The taxels numbered once taxel numbers were asked for.
    """

    def __init__(self, plotter, *, smooth=False):
        self.plotter = plotter
        self.grid: SensorGrid | None = None
        self.arrows = pv.PolyData()       # the per-node glyphs (for tests and exports)
        self.arrow_nodes = np.zeros(0, dtype=int)  # which node each drawn arrow belongs to
        self.resultants = pv.PolyData()
        self.resultant_tips = np.zeros((0, 3))
        self.resultant_vectors = np.zeros((0, 3))
        self.label_nodes = np.zeros(0, dtype=int)  # the taxels numbered (all, up to MAX_TAXEL_IDS)
        self.ticks = {}  # "x", "y": where the axes' ticks are, mm
        self._smooth = smooth
        self._actors = {}
        self._map = None
        self._bars = {}
        self._shown = None  # the last (solved, display) drawn: larger screenshots draw it again
        self._labels, self._label_owner = None, np.zeros(0, dtype=int)  # the numbers' mesh, each point's node
        self._colormap = None
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
        self._arrow_points, self._arrow_normals, self._arrow_triangles = _solid_arrow(0.3, 0.12, 0.05)
        # thicker than a node's arrow for its length, and drawn over them (a layer of its own)
        self._resultant_template = _solid_arrow(0.2, 0.1, 0.045)
        # the same shapes flat in the x-y plane, for in-plane arrows (zero height: the Top view's
        # shear picture, never hidden inside the map)
        self._flat_arrow = _flat_arrow(0.3, 0.12, 0.05)
        self._flat_resultant = _flat_arrow(0.2, 0.1, 0.045)
        # the resultants' own renderer, a layer over the scene's with the same camera and lights: a
        # contact's total force is never hidden among its node arrows
        self._over = vtkRenderer()
        self._over.SetLayer(1)
        self._over.InteractiveOff()
        self._over.SetActiveCamera(plotter.renderer.GetActiveCamera())
        self._over.SetLightCollection(plotter.renderer.GetLights())
        plotter.ren_win.SetNumberOfLayers(2)
        plotter.ren_win.AddRenderer(self._over)

    # -- building ----------------------------------------------------------------

    def set_grid(self, grid: SensorGrid):
        """Build the static parts for a grid (regular or not) and an empty map and arrow set."""
        for actor in self._actors.values():
            self.plotter.remove_actor(actor, render=False)
        self._over.RemoveAllViewProps()
        for title in list(self.plotter.scalar_bars.keys()):
            self.plotter.remove_scalar_bar(title, render=False)
        self._actors, self._bars = {}, {}
        self._shown, self._colormap = None, None
        self.grid = grid
        self._surface = np.column_stack([grid.positions * MM, np.zeros(grid.size)])  # node tips, mm
        p, h = grid.pitch * MM, grid.thickness * MM
        x0, y0 = grid.positions.min(axis=0) * MM - p / 2
        x1, y1 = grid.positions.max(axis=0) * MM + p / 2
        self._skin = (x0, x1, y0, y1, -h - 0.6 * p, 0.0)
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
        self._map = _squares(grid.positions * MM, p, LIFT_MAP * p)
        self._map.cell_data["kPa"] = np.zeros(grid.size)
        self._actors["map"] = self.plotter.add_mesh(
            self._map, scalars="kPa", cmap="viridis", clim=(0.0, 1.0), show_scalar_bar=False,
            name="map", pickable=False, lighting=False)  # unlit: colours match the bar
        self._colormap = "viridis"
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
        # every resultant of a frame in one mesh (one per contact), red
        self.resultants = pv.Arrow()
        self._actors["resultant"] = self.plotter.add_mesh(
            self.resultants, color=RESULTANT_COLOUR, name="resultant", pickable=False, **SHADED)
        self.plotter.renderer.RemoveActor(self._actors["resultant"])
        self._over.AddActor(self._actors["resultant"])
        self.arrows.copy_from(pv.PolyData())  # drawn empty until the first frame
        self.resultants.copy_from(pv.PolyData())
        self.resultant_tips, self.resultant_vectors = np.zeros((0, 3)), np.zeros((0, 3))
        # the arrows' and the resultants' length scales, said in words: the arrows' under their
        # colour bar (a second title line would not fit the bar's width), the resultants' in their
        # red at the lower right
        for name, x, colour, justify in (("arrow_scale", 0.02, "black", "Left"),
                                         ("resultant_scale", 0.98, RESULTANT_COLOUR, "Right")):
            legend = vtkTextActor()
            legend.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
            legend.SetPosition(x, 0.02)
            prop = legend.GetTextProperty()
            prop.SetFontSize(12)
            prop.SetColor(*pv.Color(colour).float_rgb)
            getattr(prop, f"SetJustificationTo{justify}")()
            self.plotter.add_actor(legend, name=name, pickable=False, render=False)
            self._actors[name] = legend
        # x and y ticks in millimetres and the direction convention, flat on the surface's plane
        axes, self._axes_bounds = self._axes_mesh()
        self._actors["axes"] = self.plotter.add_mesh(axes, color="black", name="axes", pickable=False,
                                                     lighting=False)
        # taxel numbers: built when first asked for (a large skin's take a moment)
        self._labels = None
        self.label_nodes = np.zeros(0, dtype=int)
        for name in ("arrows", "resultant", "arrow_scale", "resultant_scale", "axes"):
            self._actors[name].SetVisibility(False)
        self._bars["arrows"].SetVisibility(False)
        self.camera("iso")

    def _axes_mesh(self) -> tuple[pv.PolyData, tuple]:
        # ticks below the skin's lower edge (x) and left of its left edge (y), their values
        # and titles; an arrow along +x and one along +y above its upper left corner, named
        # "0 deg = +x" and "90 deg = +y". One mesh of black triangles; returns it and the
        # bounds it spans.
        x0, x1, y0, y1 = self._skin[:4]
        size = max(x1 - x0, y1 - y0)
        text = 0.035 * size  # text height, mm
        gap, tick, stroke = 0.4 * text, 0.5 * text, 0.1 * text
        parts = []
        self.ticks = {}
        for axis, (low, high) in enumerate(((x0, x1), (y0, y1))):
            step = _nice_step((high - low) / 8)  # 5 to 10 ticks
            values = np.arange(math.ceil(low / step - 1e-9), math.floor(high / step + 1e-9) + 1) * step
            self.ticks["xy"[axis]] = values
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
            points = np.append(origin, 0.0) + self._flat_arrow[0] @ rotation.T
            parts.append((points[:, :2], self._flat_arrow[2]))
            parts.append(_text(label, anchor, text, *align))
        points, triangles = _merge(parts)
        lift = LIFT_TEXT * self.grid.pitch * MM
        mesh = pv.PolyData(np.column_stack([points, np.full(len(points), lift)]),
                           faces=np.column_stack([np.full(len(triangles), 3), triangles]).ravel())
        low, high = points.min(axis=0), points.max(axis=0)
        return mesh, (low[0], high[0], low[1], high[1])

    def _taxel_labels(self):
        # every taxel's node index on its square, in flat digits; built once per grid
        grid = self.grid
        nodes = np.arange(min(grid.size, MAX_TAXEL_IDS)) if grid.size <= MAX_TAXEL_IDS else np.zeros(0, int)
        self.label_nodes = nodes
        if not nodes.size:
            return None
        p = grid.pitch * MM
        digits = len(str(nodes[-1]))
        # as tall as the square's width allows them (they were 0.3 p, 4 px in a 1280x800 window)
        height = min(0.5 * p, 0.95 * p / (DIGIT_ADVANCE * digits))
        centres = grid.positions[nodes] * MM
        points, triangles, owner = _numbers(nodes, centres, height)
        mesh = pv.PolyData(np.column_stack([points, np.full(len(points), LIFT_TEXT * p)]),
                           faces=np.column_stack([np.full(len(triangles), 3), triangles]).ravel())
        mesh.point_data["rgb"] = np.zeros((len(points), 3), dtype=np.uint8)
        self._label_owner = owner  # the node of each point
        return mesh

    # -- per frame -------------------------------------------------------------------

    def update(self, solved: Solved, display: Display, *, render=True):
        """Show one reconstructed frame.

        Parameters
        ----------
        solved : Solved
            The frame: measured stress, the result, its pressure map and load centroids.
        display : Display
        """
        if self.grid is None:
            raise RuntimeError("set_grid must come before update")
        self._shown = (solved, display)
        forces = solved.forces_drawn
        p = self.grid.pitch * MM
        # the map
        values = np.asarray(solved.stress if display.map == "stress" else solved.pressure, dtype=float)
        self._map.cell_data["kPa"] = values / 1e3
        if display.auto_range:
            high = max(float(values.max()) / 1e3, 1e-9)
            low = min(float(values.min()) / 1e3, 0.0)
        else:
            low, high = 0.0, max(display.range_max / 1e3, 1e-9)
        if display.colormap != self._colormap:
            self._actors["map"].mapper.lookup_table.cmap = display.colormap
            self._colormap = display.colormap
        self._actors["map"].mapper.scalar_range = (low, high)
        self._actors["map"].SetVisibility(display.map != "none")
        self._actors["layer_top"].SetVisibility(display.map == "none")
        self._actors["sensors"].SetVisibility(display.map == "none")
        self._bars["map"].SetVisibility(display.map != "none")
        self._bars["map"].SetTitle(MAP_TITLES[display.map])

        # the arrows: tip on the surface where the force acts, pointing where it pushes; in-plane
        # arrows show (Fx, Fy) only, flat just above the map
        if display.in_plane:
            drawn = np.column_stack([forces[:, 0], forces[:, 1], np.zeros(len(forces))])
            surface = self._surface + [0.0, 0.0, LIFT_FLAT * p]
        else:
            drawn = np.column_stack([forces[:, 0], forces[:, 1], -forces[:, 2]])
            surface = self._surface
        magnitude = np.linalg.norm(drawn, axis=1)
        scale = display.arrow_scale * MM * (display.in_plane_gain if display.in_plane else 1.0)
        shown = np.flatnonzero((magnitude > display.threshold) & (magnitude > 0)) \
            if display.arrows and scale > 0 else np.zeros(0, dtype=int)
        vectors = drawn[shown] * scale
        tips = surface[shown]
        if shown.size:
            template = self._flat_arrow if display.in_plane else \
                (self._arrow_points, self._arrow_normals, self._arrow_triangles)
            self.arrows.copy_from(_glyphs(template, tips - vectors, vectors, magnitude[shown] * 1e3))
            top = float(magnitude[shown].max()) if display.arrow_auto_range else display.arrow_range_max
            top *= 1e3
            self._actors["arrows"].mapper.scalar_range = (0.0, max(top, 1e-9))
        else:
            self.arrows.copy_from(pv.PolyData())
        self.arrow_nodes = shown
        self._actors["arrows"].SetVisibility(bool(shown.size))
        self._bars["arrows"].SetVisibility(bool(shown.size))
        self._bars["arrows"].SetTitle("shear mN" if display.in_plane else "force mN")
        legend = self._actors["arrow_scale"]
        legend.SetVisibility(bool(shown.size))
        if shown.size:  # 1 mm of arrow is this many mN
            legend.SetInput(f"{'shear ' if display.in_plane else ''}arrows: 1 mm = {MM / scale:.3g} mN"
                            + (f", smoothed over {display.smoothing:.3g} s (they lag about that much)"
                               if solved.drawn_forces is not None else ""))

        self._draw_resultants(solved, display)
        self._show_overlays(display, low, high)
        if render:
            self.plotter.render()

    def _draw_resultants(self, solved: Solved, display: Display):
        # one resultant per contact at its own compressive-load centroid; without contacts
        # (normal-only solves, nothing pressing) the frame's total at the frame's centroid
        p = self.grid.pitch * MM
        contacts = solved.result.contacts
        if contacts and len(solved.contact_centroids) == len(contacts):
            pairs = [(c.total_force, centre)
                     for c, centre in zip(contacts, solved.contact_centroids, strict=True)]
        else:
            pairs = [(solved.result.total_force, solved.centroid)]
        scale = display.resultant_scale * MM * (display.in_plane_gain if display.in_plane else 1.0)
        tips, vectors = [], []
        for total, centre in pairs:
            if centre is None:
                continue
            if display.in_plane:
                vector, tip = np.array([total[0], total[1], 0.0]), np.append(centre * MM, 2 * LIFT_FLAT * p)
            else:
                vector, tip = np.array([total[0], total[1], -total[2]]), np.append(centre * MM, 0.0)
            if np.linalg.norm(vector) * scale > 0:
                tips.append(tip)
                vectors.append(vector * scale)
        self.resultant_tips = np.array(tips).reshape(-1, 3)
        self.resultant_vectors = np.array(vectors).reshape(-1, 3)
        shown = display.resultant and bool(tips)
        if shown:
            template = self._flat_resultant if display.in_plane else self._resultant_template
            self.resultants.copy_from(_glyphs(template, self.resultant_tips - self.resultant_vectors,
                                              self.resultant_vectors, None))
        else:
            self.resultants.copy_from(pv.PolyData())
        self._actors["resultant"].SetVisibility(shown)
        legend = self._actors["resultant_scale"]
        legend.SetVisibility(shown)
        if shown:
            kind = "shear resultant" if display.in_plane else "resultant"
            legend.SetInput(f"{kind}: 1 mm = {MM / scale:.3g} mN")  # in the resultants' red

    def _show_overlays(self, display: Display, low: float, high: float):
        # axes and taxel numbers, the numbers in black or white, whichever reads on their square
        self._actors["axes"].SetVisibility(display.axes)
        if display.taxel_ids and self._labels is None:
            self._labels = self._taxel_labels()
            if self._labels is not None:
                self._actors["labels"] = self.plotter.add_mesh(
                    self._labels, scalars="rgb", rgb=True, name="labels", pickable=False, lighting=False,
                    show_scalar_bar=False)
        actor = self._actors.get("labels")
        if actor is None:
            return
        actor.SetVisibility(display.taxel_ids)
        if not display.taxel_ids:
            return
        if display.map == "none":
            light = np.ones(self.grid.size, dtype=bool)  # the pale layer top
        else:
            table = vtk_to_numpy(self._actors["map"].mapper.lookup_table.GetTable()).astype(float)
            values = np.asarray(self._map.cell_data["kPa"], dtype=float)
            index = np.clip(((values - low) / (high - low) * len(table)).astype(int), 0, len(table) - 1)
            light = table[index, :3] @ [0.299, 0.587, 0.114] > 140
        colours = np.where(light[self.label_nodes, None], 0, 255).astype(np.uint8)
        self._labels.point_data["rgb"] = np.repeat(colours, 3, axis=1)[self._label_owner]

    # -- reading the scene -----------------------------------------------------------------

    def node_at(self, x: float, y: float) -> int | None:
        """The node whose taxel square is under a point of the view, or None off the skin.

        Parameters
        ----------
        x, y : float
            Display coordinates: device pixels from the view's lower left
            corner (VTK's convention; a Qt widget's ``(qx, qy)`` is
            ``(qx * dpr, (height - qy - 1) * dpr)``).

        Returns
        -------
        int or None
            The node index (from 0). The view ray is met with the surface's
            plane, so arrows in front of a taxel do not hide it. Nothing is
            rendered.
        """
        if self.grid is None:
            return None
        renderer = self.plotter.renderer
        ends = []
        for depth in (0.0, 1.0):  # the near and the far clipping plane
            renderer.SetDisplayPoint(float(x), float(y), depth)
            renderer.DisplayToWorld()
            world = np.array(renderer.GetWorldPoint(), dtype=float)
            if world[3] == 0:
                return None
            ends.append(world[:3] / world[3])
        near, far = ends
        rise = far[2] - near[2]
        if abs(rise) < 1e-12 * max(np.linalg.norm(far - near), 1e-300):
            return None  # looking along the surface
        along = -near[2] / rise
        if not 0 <= along <= 1:
            return None  # the plane is behind the camera or beyond the far plane
        point = (near + along * (far - near))[:2] / MM
        distance = np.abs(self.grid.positions - point).max(axis=1)  # to each taxel's square
        node = int(np.argmin(distance))
        return node if distance[node] <= self.grid.pitch / 2 * (1 + 1e-9) else None

    # -- view --------------------------------------------------------------------------------

    def camera(self, preset: str):
        """``"top"`` (looking straight down, orthographic) or ``"iso"`` (oblique, in perspective).

        Both frame the skin with its axes (shown or not, so switching them
        never moves the view).
        """
        if preset == "top":
            # +x to the right, +y up, as in the read-out and the exports
            direction, up, parallel = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), True
        elif preset == "iso":
            # from the front right, 45 degrees up: +x still runs to the right and +y away, so the
            # axes' text reads as in the Top view
            direction, up, parallel = (0.5, -0.5, math.sqrt(0.5)), (0.0, 0.0, 1.0), False
        else:
            raise ValueError(f"camera preset must be 'top' or 'iso', got {preset!r}")
        camera = self.plotter.renderer.camera  # (the plotter's own getter would reset a new one)
        camera.is_set = True  # and so would pyvista's first render
        camera.SetFocalPoint(0.0, 0.0, 0.0)
        camera.SetPosition(*direction)
        camera.SetViewUp(*up)
        # pyvista's Camera keeps its own note of the projection: through it, both agree
        camera.enable_parallel_projection() if parallel else camera.disable_parallel_projection()
        if self.grid is None:
            self.plotter.renderer.ResetCamera()
        else:
            x0, x1, y0, y1 = self._axes_bounds
            self.plotter.renderer.ResetCamera(x0, x1, y0, y1, self._skin[4], self._skin[5])

    def screenshot(self, path, *, scale: int = 1, transparent: bool = False) -> np.ndarray:
        """Save a PNG of the scene (``scale`` times the window size) and return the image.

        A larger image is the scene drawn again at that size, off screen, with
        the same camera and text ``scale`` times larger (its dots per inch):
        pyvista's own ``scale`` renders tiles, and under tiling the colour
        bars lay their text out for a different size than they draw it at, so
        titles ran into labels. Only what this scene draws is in it.

        A window's scene is drawn again off screen at 1x too: read back from
        the screen, the parts of a window that another window covers (a
        dialog, a menu) are undefined in OpenGL and were seen to come out
        blank.
        """
        if scale not in (1, 2, 3, 4):
            raise ValueError(f"scale must be 1, 2, 3 or 4, got {scale!r}")
        with written_whole(path) as temporary:  # a render or write that fails leaves no partial PNG
            return self._render(temporary, scale, transparent)

    def _render(self, path, scale, transparent):
        if self.grid is None or (scale == 1 and getattr(self.plotter, "off_screen", False)):
            return self.plotter.screenshot(str(path), transparent_background=transparent, return_img=True)
        width, height = self.plotter.ren_win.GetSize()
        larger = pv.Plotter(off_screen=True, window_size=[width * scale, height * scale])
        try:
            larger.ren_win.SetDPI(round(self.plotter.ren_win.GetDPI() * scale))
            copy = Scene(larger, smooth=self._smooth)
            copy.set_grid(self.grid)
            if self._shown is not None:
                copy.update(*self._shown, render=False)
            larger.renderer.GetActiveCamera().DeepCopy(self.plotter.renderer.GetActiveCamera())
            return larger.screenshot(str(path), transparent_background=transparent, return_img=True)
        finally:
            larger.close()


def taxel_text(solved: Solved | None, grid: SensorGrid, node: int) -> str:
    """One taxel's read-out: its number, position, measured stress and force.

    Parameters
    ----------
    solved : Solved or None
        The frame shown (None: only where the taxel is).
    grid : SensorGrid
    node : int
        The node index, from 0.

    Returns
    -------
    str
        E.g. ``"taxel 37 (x 5.0 mm, y 3.0 mm): stress 1.23 kPa, Fx +0.12 Fy -0.03 Fz 4.56 mN"``.

    Raises
    ------
    ValueError
        For a node that is not one of the grid's.
    """
    if isinstance(node, bool) or not isinstance(node, (int, np.integer)) or not 0 <= node < grid.size:
        raise ValueError(f"node must be an index from 0 to {grid.size - 1}, got {node!r}")
    x, y = grid.positions[node] * MM
    where = f"taxel {node} (x {x:.1f} mm, y {y:.1f} mm)"
    if solved is None or len(solved.stress) != grid.size:
        return where
    fx, fy, fz = solved.result.forces[node] * 1e3
    return (f"{where}: stress {solved.stress[node] / 1e3:.2f} kPa, "
            f"Fx {fx:+.2f} Fy {fy:+.2f} Fz {fz:.2f} mN")


def _solid_arrow(tip_length, tip_radius, shaft_radius):
    """A 3-D arrow along +x from 0 to 1: points, point normals and triangles."""
    template = pv.Arrow(tip_length=tip_length, tip_radius=tip_radius, shaft_radius=shaft_radius,
                        tip_resolution=12, shaft_resolution=12).triangulate()
    # smooth normals, split at the rims so the discs and the cone stay crisp
    template = template.compute_normals(cell_normals=False, split_vertices=True, feature_angle=45)
    return (np.asarray(template.points, dtype=float), np.asarray(template.point_data["Normals"], dtype=float),
            np.asarray(template.faces).reshape(-1, 4)[:, 1:])


def _flat_arrow(tip_length, tip_width, shaft_width):
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


def _glyphs(template, starts, vectors, values) -> pv.PolyData:
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
