"""Model only what the scene requires: solve each contact on its own window of the skin.

Every kernel (layer and half-space) depends only on the offset between a sensor and a node,
so the stress matrix of any ``by x bx`` window of a regular grid is the same
wherever the window sits. :class:`RegionSolver` therefore never forms the
skin's full ``m x 3m`` matrix: per frame it finds the contacts in the data,
cuts one window around each (the contact grown by the stress spread, a few
layer thicknesses), and solves each window with a :class:`~solver.inverse.DenseSolver`
built once per window shape and reused across frames. Cost follows the
contacts, not the skin: a 128x128 skin (a dense matrix would take 6 GB)
costs what its contact windows cost.

Each contact gets its own shear ratio and direction (the paper covers one
contact; several is our extension).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import replace

import numpy as np
from scipy import ndimage

from .arguments import check_options, check_parameters, check_stress
from .arrays import read_only
from .checks import real_number, whole_number
from .convolution import NormalConvolution, StressConvolution
from .geometry import SensorGrid, patch_links
from .inverse import DenseSolver
from .results import Contact, Reconstruction, shear_direction_of
from .search import contact_cores
from .threads import one_blas_thread

__all__ = ["RegionSolver", "DENSE_LIMIT"]

# Largest skin (sensors) solved with one DenseSolver: its sub-cell fit matrix is
# 12 m^2 doubles (100 MB at 32x32, 1.6 GB at 64x64). Larger regular skins are solved
# window by window.
DENSE_LIMIT = 1024


class RegionSolver:
    """Per-contact solves on windows of a regular skin.

    Parameters
    ----------
    grid : SensorGrid
        A regular grid (``grid.shape == (ny, nx)``).
    kernel : {"layer", "cell", "point"}, optional
        Stress kernel (see :mod:`solver.kernels`). Default "layer".
    threshold : float, optional
        Fraction of the frame's peak stress above which a sensor shows
        contact. Default 0.05.
    spread : float, optional
        Pitches added around each contact for the stress spread, in layer
        thicknesses: the window grows by ``ceil(spread * h / pitch) + 1``
        rings. Default 2.
    step : int, optional
        Window sides are rounded up to a multiple of ``step`` nodes so that a
        moving contact reuses a few window set-ups. Default 4.
    cache : int, optional
        Window set-ups (each a window's inverses) kept, least recently used dropped. Default 8.
    **options
        Passed to each window's :class:`~solver.inverse.DenseSolver`
        (``max_condition``, ``max_shear_ratio``, ``efficiency`` ...).
    """

    def __init__(self, grid: SensorGrid, *, kernel: str = "layer", threshold: float = 0.05,
                 spread: float = 2.0, step: int = 4, cache: int = 8, **options):
        if not isinstance(grid, SensorGrid) or not grid.is_regular:
            raise ValueError("grid must be a regular SensorGrid (RegionSolver cuts rectangular windows)")
        real_number("threshold", threshold, rule="in (0, 1)", valid=lambda v: 0 < v < 1)
        real_number("spread", spread, rule="finite and >= 0",
                    valid=lambda v: math.isfinite(v) and v >= 0)
        step = whole_number("step", step, low=1)
        cache = whole_number("cache", cache, low=1)
        check_options(grid, kernel=kernel, **options)
        self.grid = grid
        self.kernel = kernel
        self.threshold = float(threshold)
        self.rings = math.ceil(spread * grid.thickness / grid.pitch) + 1
        self.step = step
        self._options = options
        self._cache: OrderedDict = OrderedDict()
        self._lock = threading.Lock()
        self._links = patch_links(grid)
        self._capacity = cache
        # the whole skin's operators (normal-only, and C for the exact member), made when first needed
        self._convolution = None
        self._stress_convolution = None
        self.factorizations = 0  # windows set up so far, each inverting its matrices (the rest were reused)

    def _window(self, rows: int, columns: int) -> SensorGrid:
        g = self.grid
        return SensorGrid.regular(columns, rows, g.pitch, g.thickness,
                                  poisson_ratio=g.poisson_ratio, sensor_size=g.sensor_size)

    def reconstructor(self, rows: int, columns: int, ordinal: int = 0) -> DenseSolver:
        """The (cached) reconstructor of a ``rows x columns`` window.

        ``ordinal`` counts the windows of that shape in a frame (in the order
        of :meth:`windows`): each has its own last-frame state on the shared
        inverses (:meth:`solver.inverse.DenseSolver.sibling`).
        """
        key = (rows, columns)
        # one lock: the viewer's solve thread and an export may ask at the same time
        with self._lock:
            if key in self._cache:
                self._cache.move_to_end(key)
            else:
                self._cache[key] = [DenseSolver(self._window(rows, columns), kernel=self.kernel,
                                                  **self._options)]
                self.factorizations += 1
                if len(self._cache) > self._capacity:
                    self._cache.popitem(last=False)
            made = self._cache[key]
            while len(made) <= ordinal:
                made.append(made[0].sibling())
            return made[ordinal]

    def windows(self, stress: np.ndarray) -> list[tuple[slice, slice]]:
        """The contact windows of a frame: one per contact, merged where they overlap."""
        labels = np.zeros(self.grid.size, np.int64)
        # a writable copy: a recording's frame is read-only, and numba would compile again for it
        kept = contact_cores(np.array(stress, dtype=float).ravel(), self.threshold, self._links, labels)
        boxes = [[box[0].start, box[0].stop, box[1].start, box[1].stop]
                 for index, box in enumerate(ndimage.find_objects(labels.reshape(self.grid.shape)), start=1)
                 if kept[index]]
        boxes = [self._grown(box) for box in boxes]
        merged = True
        while merged:  # windows that overlap become one: those contacts interact
            merged = False
            for i in range(len(boxes)):
                for j in range(i + 1, len(boxes)):
                    a, b = boxes[i], boxes[j]
                    if a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]:
                        boxes[i] = self._grown([min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]),
                                                max(a[3], b[3])], rings=0)
                        del boxes[j]
                        merged = True
                        break
                if merged:
                    break
        return [(slice(r0, r1), slice(c0, c1)) for r0, r1, c0, c1 in sorted(boxes)]

    def _grown(self, box, rings=None):
        rings = self.rings if rings is None else rings
        ny, nx = self.grid.shape
        out = []
        for (start, stop), size in (((box[0], box[1]), ny), ((box[2], box[3]), nx)):
            start, stop = start - rings, stop + rings
            # round the side up to a multiple of step (fewer window shapes to set up)
            side = min(size, -(-(stop - start) // self.step) * self.step)
            centre = (start + stop) // 2
            start = min(max(centre - side // 2, 0), size - side)
            out += [start, start + side]
        return out

    def solve_normal(self, stress) -> Reconstruction:
        """Normal-only forces, window by window (zero outside the contact windows)."""
        return self.solve(stress, normal_only=True)

    @one_blas_thread()
    def solve(self, stress, *, shear_ratio=None, shear_direction=None, exact=None,
              normal_only=False) -> Reconstruction:
        """Solve every contact on its window (its own parameters when automatic).

        Returns a :class:`~solver.Reconstruction` of the whole skin: forces are
        zero outside the windows; ``shear_ratio``, ``shear_direction`` and
        ``efficiency`` are the largest contact's; ``residual`` counts the data
        outside the windows as unexplained; ``contacts`` holds every contact
        with its nodes on the skin.
        """
        grid = self.grid
        image = check_stress(stress, grid).reshape(grid.shape)
        exact = check_parameters(shear_ratio, shear_direction, exact)
        forces = np.zeros(grid.shape + (3,))
        region = np.zeros(grid.shape, dtype=bool)
        contacts, results = [], []
        explained = np.zeros(grid.shape, dtype=bool)
        unexplained = 0.0
        shapes = {}
        windows = self.windows(image)
        broad = [w for w in windows if (w[0].stop - w[0].start) * (w[1].stop - w[1].start) > DENSE_LIMIT]
        if broad:
            return self._broad(image, windows, broad, shear_ratio, shear_direction, exact, normal_only)
        notes = []
        for rows, columns in windows:
            window = image[rows, columns]
            ordinal = shapes[window.shape] = shapes.get(window.shape, -1) + 1
            solver = self.reconstructor(window.shape[0], window.shape[1], ordinal)
            if normal_only:
                result = solver.solve_normal(window)
            else:
                result = solver.solve(window, shear_ratio=shear_ratio, shear_direction=shear_direction,
                                      exact=exact)
            forces[rows, columns] += result.forces.reshape(window.shape + (3,))
            region[rows, columns] |= result.region.reshape(window.shape)
            explained[rows, columns] = True
            unexplained += (result.residual * np.linalg.norm(window)) ** 2
            results.append(result)
            if result.fallback and result.fallback not in notes:
                notes.append(result.fallback)
            for contact in result.contacts:
                nodes = np.zeros(grid.shape, dtype=bool)
                nodes[rows, columns] = contact.nodes.reshape(window.shape)
                nodes = nodes.ravel()
                # the window's own positions are centred on the window: the skin's are not
                pushed = np.clip(forces.reshape(-1, 3)[nodes, 2], 0.0, None)
                centre = (grid.positions[nodes].T @ pushed / pushed.sum() if pushed.sum() > 0
                          else grid.positions[nodes].mean(axis=0))
                contacts.append(replace(contact, nodes=read_only(nodes, bool),
                                        at_edge=bool(np.any(nodes & grid.border)),
                                        centre=read_only(centre)))
        norm = float(np.linalg.norm(image))
        unexplained += float(np.sum(image[~explained] ** 2))
        contacts.sort(key=lambda c: -c.total_force[2])
        if not results:
            given = 0.0 if shear_direction is None else float(shear_direction)
            direction = shear_direction_of(0.0, 0.0, given)
            return Reconstruction(
                forces=read_only(forces.reshape(-1, 3)), shear_ratio=0.0, shear_direction=direction,
                efficiency=math.nan, residual=0.0 if norm == 0 else 1.0, condition=1.0, regularized=False,
                normal_only=normal_only, shear_detected=False, region=read_only(region.ravel(), bool),
                exact=bool(exact))
        main = max(results, key=lambda r: r.total_force[2])
        return Reconstruction(
            forces=read_only(forces.reshape(-1, 3)),
            shear_ratio=contacts[0].shear_ratio if contacts else main.shear_ratio,
            shear_direction=contacts[0].shear_direction if contacts else main.shear_direction,
            efficiency=main.efficiency, residual=math.sqrt(unexplained) / norm if norm > 0 else 0.0,
            condition=max(r.condition for r in results), regularized=any(r.regularized for r in results),
            normal_only=normal_only, shear_detected=any(r.shear_detected for r in results),
            region=read_only(region.ravel(), bool), exact=main.exact, contacts=tuple(contacts),
            fallback="; ".join(notes))

    def _broad(self, image, windows, broad, shear_ratio, shear_direction, exact, normal_only):
        # A window over DENSE_LIMIT nodes would need the dense matrices of a skin that size
        # (gigabytes at 64x64): the frame is solved over the whole skin by convolution
        # (solver.convolution), in memory that grows with the skin, not its square. Automatic
        # parameters: the normal-only answer. Given ones: the paper's member whose template is
        # y = [mu cos(theta) g; mu sin(theta) g; g], g the positive part of the normal-only
        # answer on the load windows (what DenseSolver gives a load beyond its fit's budget).
        grid = self.grid
        max_condition = {k: v for k, v in self._options.items() if k == "max_condition"}
        if self._convolution is None:
            self._convolution = NormalConvolution(grid, kernel=self.kernel, **max_condition)
        b = image.ravel()
        fz, _ = self._convolution.solve(b)
        region = np.zeros(grid.shape, dtype=bool)
        for rows, columns in windows:
            region[rows, columns] = True
        direction = shear_direction_of(0.0, 0.0, 0.0 if shear_direction is None else float(shear_direction))
        given = not normal_only and (shear_ratio is not None or shear_direction is not None)
        forces = np.zeros((grid.size, 3))
        if given:
            ratio = 0.0 if shear_ratio is None else float(shear_ratio)
            angle = 0.0 if shear_direction is None else float(shear_direction)
            g = np.where(region.ravel(), np.clip(fz, 0.0, None), 0.0)
            forces[:] = g[:, None] * [ratio * math.cos(angle), ratio * math.sin(angle), 1.0]
            if self._stress_convolution is None:
                self._stress_convolution = StressConvolution(grid, kernel=self.kernel, **max_condition)
            operator = self._stress_convolution
            if exact:
                forces, _ = operator.member(forces, b)
            misfit = operator.apply(forces) - b
            kind = "the template of the normal-only solution"
            condition, regularized = operator.condition, exact and operator.shift > 0
        else:
            ratio = 0.0
            forces[:, 2] = fz
            misfit = self._convolution.apply(fz) - b
            kind = "normal only"
            condition, regularized = self._convolution.condition, self._convolution.shift > 0
        contacts = []
        for rows, columns in windows:
            box = np.zeros(grid.shape, dtype=bool)
            box[rows, columns] = True
            nodes = box.ravel()
            pushed = np.clip(forces[nodes, 2], 0.0, None)
            centre = (grid.positions[nodes].T @ pushed / pushed.sum() if pushed.sum() > 0
                      else grid.positions[nodes].mean(axis=0))
            contacts.append(Contact(nodes=read_only(nodes, bool), shear_ratio=ratio,
                                    shear_direction=direction, evidence=math.nan, shear_detected=False,
                                    at_edge=bool(np.any(nodes & grid.border)),
                                    total_force=read_only(forces[nodes].sum(axis=0)),
                                    centre=read_only(centre)))
        contacts.sort(key=lambda c: -c.total_force[2])
        largest = max((w[0].stop - w[0].start) * (w[1].stop - w[1].start) for w in broad)
        norm = float(np.linalg.norm(image))
        return Reconstruction(
            forces=read_only(forces), shear_ratio=ratio, shear_direction=direction, efficiency=math.nan,
            residual=float(np.linalg.norm(misfit)) / norm if norm > 0 else 0.0,
            condition=condition, regularized=regularized, normal_only=not given, shear_detected=False,
            region=read_only(region.ravel(), bool), exact=bool(exact) if given else True,
            contacts=tuple(contacts),
            fallback=(f"{kind}: a load window of {largest} nodes, more than the "
                      f"{DENSE_LIMIT} a window may have (solved by convolution over the whole skin)"))
