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

from solver import SensorGrid

from ..io.recording import written_whole
from ..model.display import Display
from ..model.solved import Solved
from .meshes import (
    LIFT_FLAT,
    LIFT_MAP,
    MM,
    axes_mesh,
    box_faces,
    flat_arrow,
    glyphs,
    solid_arrow,
    squares,
    taxel_numbers,
)

__all__ = ["Scene", "bar_top"]

# with only two lights (see Scene), ambient light keeps faces turned from them readable
SHADED = dict(ambient=0.35, diffuse=0.75, specular=0.1)
MAP_TITLES = {"pressure": "pressure kPa", "stress": "stress kPa", "none": ""}
RESULTANT_COLOUR = "#d62728"
# an automatic colour range ends on one of these times a power of ten: each is four times a round
# number, so the bar's five labels are round too, and the next is at most 4/3 of it
BAR_TOPS = (1.0, 1.2, 1.6, 2.0, 2.4, 3.2, 4.0, 4.8, 6.0, 8.0)


def bar_top(value: float) -> float:
    """The automatic colour range's end for a frame whose largest value is ``value``.

    Parameters
    ----------
    value : float
        The largest magnitude shown, > 0 (any unit).

    Returns
    -------
    float
        The smallest of :data:`BAR_TOPS` times a power of ten at or above
        ``value``: at most 4/3 of it.

    Notes
    -----
    The range stays put while a frame's peak moves within a step, and so do
    the bar's numbers: they are readable while a recording plays, and VTK
    draws a colour bar's text again only when its range changes (about 4 ms
    of the window's thread per frame under software rendering).
    """
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"value must be finite and > 0, got {value!r}")
    power = 10.0 ** math.floor(math.log10(value))
    # rounding: a value that is a top already (1.2e-3) must not go up a step
    return next(top * power for top in (*BAR_TOPS, 10.0) if top * power >= value * (1 - 1e-12))


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
        self._arrow_points, self._arrow_normals, self._arrow_triangles = solid_arrow(0.3, 0.12, 0.05)
        # thicker than a node's arrow for its length, and drawn over them (a layer of its own)
        self._resultant_template = solid_arrow(0.2, 0.1, 0.045)
        # the same shapes flat in the x-y plane, for in-plane arrows (zero height: the Top view's
        # shear picture, never hidden inside the map)
        self._flat_arrow = flat_arrow(0.3, 0.12, 0.05)
        self._flat_resultant = flat_arrow(0.2, 0.1, 0.045)
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
            box_faces((x0, x1, y0, y1, -h, 0.0), "sides"), color="#9ecae1", name="layer", pickable=False,
            **SHADED)
        self._actors["layer_top"] = self.plotter.add_mesh(
            box_faces((x0, x1, y0, y1, -h, 0.0), "top"), color="#9ecae1", opacity=0.3, name="layer_top",
            pickable=False)
        self._actors["hull"] = self.plotter.add_mesh(
            box_faces((x0, x1, y0, y1, -h - 0.6 * p, -h), "sides and bottom"), color="#8c8c8c", name="hull",
            pickable=False, **SHADED)
        sensors = np.column_stack([grid.positions * MM, np.full(grid.size, -h)])
        self._actors["sensors"] = self.plotter.add_mesh(
            pv.PolyData(sensors), color="#252525", point_size=6, render_points_as_spheres=True,
            name="sensors", pickable=False)
        # the map: one pitch-sized square per node, just above the surface
        # (a regular grid tiles the skin; an irregular layout shows its taxels)
        self._map = squares(grid.positions * MM, p, LIFT_MAP * p)
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
        axes, self._axes_bounds, self.ticks = axes_mesh(self._skin[:4], grid.pitch, self._flat_arrow)
        self._actors["axes"] = self.plotter.add_mesh(axes, color="black", name="axes", pickable=False,
                                                     lighting=False)
        # taxel numbers: built when first asked for (a large skin's take a moment)
        self._labels = None
        self.label_nodes = np.zeros(0, dtype=int)
        for name in ("arrows", "resultant", "arrow_scale", "resultant_scale", "axes"):
            self._actors[name].SetVisibility(False)
        self._bars["arrows"].SetVisibility(False)
        self.camera("iso")


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
            high = bar_top(max(float(values.max()) / 1e3, 1e-9))
            low = -bar_top(-float(values.min()) / 1e3) if values.min() < 0 else 0.0
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
            self.arrows.copy_from(glyphs(template, tips - vectors, vectors, magnitude[shown] * 1e3))
            top = bar_top(float(magnitude[shown].max()) * 1e3) if display.arrow_auto_range \
                else max(display.arrow_range_max * 1e3, 1e-9)
            self._actors["arrows"].mapper.scalar_range = (0.0, top)
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
            self.resultants.copy_from(glyphs(template, self.resultant_tips - self.resultant_vectors,
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
            self._labels, self.label_nodes, owner = taxel_numbers(self.grid)  # built once per grid
            if self._labels is not None:
                self._label_owner = owner  # the node of each point
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
