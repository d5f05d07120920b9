"""Simulated scenes for a virtual board: their contacts and frames, computed lazily by cycle. No Qt.

A scene (:data:`SCENES`: a Hertzian contact circling the skin with turning shear, a pinch, two
or three moving contacts, a broad press, a twist, a fingertip beside a light broad press) gives
the contacts of :mod:`solver.loads` as a function of its phase; :func:`scene_frame` takes them
through the bonded layer.

A scene is one period of ``CYCLE`` frames that repeats. The frames are
computed lazily (:class:`Cycle`): the first when it is first sent, the rest in
a background thread ahead of the stream, so the board sends within a fraction
of a second of its port appearing; every frame is a pure function of the
scene, the grid and its index, so the stream does not depend on timing.
Frames are integrated on a coarser sub-cell lattice than :func:`solver.loads.simulate`'s
default (within 0.65% of its peak stress for the default skin, against 1% noise, in 5 to
25 ms a frame instead of about 60), and the noise is relative to each frame's own peak.

The board that streams them is :class:`tactile_viewer.cli.tactile_sim.Board` (tactile-sim);
tools/make_samples.py takes its contacts from :func:`scene_contacts`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from solver import SensorGrid, loads
from solver.checks import one_of, whole_number

__all__ = ["CYCLE", "Cycle", "SCENES", "BoardScene", "contact_cycle", "scene_contacts", "scene_frame",
           "shared_cycle"]

CYCLE = 100  # frames per period of every scene
TAU = 2 * math.pi
PRESS_PRESSURE = 10e3  # press: mean pressure at full force, pascals
# twist: peak torque over force times radius (30% of a Hertzian contact's full-slip torque)
TWIST = 0.3 * 3 * math.pi / 16


@dataclass(frozen=True)
class _Skin:
    """The loaded area of a grid: centre and half-sizes of the rectangle its node cells cover, metres."""

    cx: float
    cy: float
    hx: float
    hy: float
    pitch: float

    @classmethod
    def of(cls, grid: SensorGrid) -> _Skin:
        low, high = grid.positions.min(axis=0), grid.positions.max(axis=0)
        centre, half = (low + high) / 2, (high - low) / 2 + grid.pitch / 2
        return cls(float(centre[0]), float(centre[1]), float(half[0]), float(half[1]), grid.pitch)

    @property
    def half(self) -> float:
        """Radius of the largest disc on the skin about its centre."""
        return min(self.hx, self.hy)

    def frame(self):
        """Unit vectors along the skin's long side and across it, its long and short half-sizes."""
        if self.hx >= self.hy:
            return (1.0, 0.0), (0.0, 1.0), self.hx, self.hy
        return (0.0, 1.0), (-1.0, 0.0), self.hy, self.hx

    def point(self, along: float, across: float):
        """The point ``along`` the long side and ``across`` it from the centre, metres."""
        (ex, ey), (nx, ny), _, _ = self.frame()
        return (self.cx + along * ex + across * nx, self.cy + along * ey + across * ny)

    def heading(self, local: float) -> float:
        """A direction given relative to the long side, radians from +x, in [-pi, pi]."""
        (ex, ey), _, _, _ = self.frame()
        return math.remainder(math.atan2(ey, ex) + local, TAU)


def _circle(skin: _Skin, phase: float):
    orbit = 0.5 * (skin.half - skin.pitch / 2)  # a quarter of the sensors' span
    radius = min(2.5 * skin.pitch, skin.half - orbit)
    angle = TAU * phase
    centre = (skin.cx + orbit * math.cos(angle), skin.cy + orbit * math.sin(angle))
    return (loads.hertz(centre, radius, 0.75 + 0.25 * math.sin(2 * angle), shear_ratio=0.3,
                        shear_direction=math.remainder(angle + math.pi / 2, TAU)),)


def _pinch(skin: _Skin, phase: float):
    _, _, long, short = skin.frame()
    radius = min(1.75 * skin.pitch, 0.45 * short, 0.22 * long)
    far = min(0.6 * long, long - radius)  # centres at -far and +far when apart
    near = min(radius + skin.pitch, radius + 0.5 * (far - radius))  # and at +-near when closest
    closing = (1 - math.cos(TAU * phase)) / 2  # 0 apart, 1 closest (half-way through the period)
    d, force = far - (far - near) * closing, 0.3 + 0.5 * closing
    return (loads.hertz(skin.point(-d, 0.0), radius, force, shear_ratio=0.3,
                        shear_direction=skin.heading(0.0)),  # towards the other one
            loads.hertz(skin.point(d, 0.0), radius, force, shear_ratio=0.3,
                        shear_direction=skin.heading(math.pi)))


def _two(skin: _Skin, phase: float):
    _, _, long, short = skin.frame()
    room = min(long / 2, short)  # each contact keeps to its half of the skin
    radius = min(1.5 * skin.pitch, 0.35 * room)
    angle = TAU * phase
    orbit = 0.5 * (room - radius)
    circling = loads.hertz(skin.point(-long / 2 + orbit * math.cos(angle), orbit * math.sin(angle)),
                           radius, 0.6, shear_ratio=0.3,
                           shear_direction=skin.heading(angle + math.pi / 2))  # along its motion
    eight = loads.hertz(skin.point(long / 2 + 0.3 * (long / 2 - radius) * math.sin(2 * angle),
                                   0.6 * (short - radius) * math.sin(angle)),
                        radius, 0.9 + 0.1 * math.cos(angle), shear_ratio=0.15,
                        shear_direction=skin.heading(math.radians(120)))
    return circling, eight


def _three(skin: _Skin, phase: float):
    ring = 0.5 * skin.half
    radius = min(1.5 * skin.pitch, 0.22 * skin.half)
    wander = 0.5 * (skin.half - ring - radius)
    angle = TAU * phase
    homes = [math.radians(a) for a in (90, 210, 330)]
    out = []
    for j, home in enumerate(homes):
        radial, tangential = (math.cos(home), math.sin(home)), (-math.sin(home), math.cos(home))
        if j == 0:  # circles its home, 0.7 N, shear 0.3 along +x
            u, v = wander * math.cos(angle), wander * math.sin(angle)
            force, ratio, direction = 0.7, 0.3, 0.0
        elif j == 1:  # in and out, force 0.3 to 0.7 N, shear 0.2 turning once
            u = wander * math.sin(angle) * radial[0]
            v = wander * math.sin(angle) * radial[1]
            force, ratio, direction = 0.5 + 0.2 * math.sin(2 * angle), 0.2, math.remainder(angle, TAU)
        else:  # sideways, 0.8 N, no shear
            u = wander * math.sin(angle + math.pi / 3) * tangential[0]
            v = wander * math.sin(angle + math.pi / 3) * tangential[1]
            force, ratio, direction = 0.8, 0.0, 0.0
        centre = (skin.cx + ring * radial[0] + u, skin.cy + ring * radial[1] + v)
        out.append(loads.hertz(centre, radius, force, shear_ratio=ratio, shear_direction=direction))
    return tuple(out)


def _press(skin: _Skin, phase: float):
    axes = (0.94 * skin.hx, 0.94 * skin.hy)  # pi 0.94^2 / 4: 69% of the skin
    force = PRESS_PRESSURE * math.pi * axes[0] * axes[1] * (0.75 + 0.25 * math.sin(TAU * phase))
    return (loads.hertz((skin.cx, skin.cy), axes, force),)


def _palm(skin: _Skin, phase: float):
    _, _, long, short = skin.frame()
    broad = min(2.5 * skin.pitch, 0.35 * long, 0.9 * short)
    tip = min(1.75 * skin.pitch, 0.25 * long, 0.5 * short)
    wander = min(skin.pitch, 0.1 * long)
    angle = TAU * phase
    press = loads.flat_punch(skin.point(-0.45 * long, 0.0), broad, 0.5 + 0.1 * math.sin(angle),
                             shear_ratio=0.2, shear_direction=skin.heading(0.0))
    finger = loads.cone(skin.point(0.45 * long + wander * math.cos(angle), wander * math.sin(angle)), tip,
                        1.0, shear_ratio=0.3, shear_direction=skin.heading(angle))
    return press, finger


def _twist(skin: _Skin, phase: float):
    radius = min(2.5 * skin.pitch, 0.6 * skin.half)
    return (loads.hertz((skin.cx, skin.cy), radius, 1.0, torsion=TWIST * radius * math.sin(TAU * phase)),)


@dataclass(frozen=True)
class BoardScene:
    """What a board simulates: contacts as a function of the phase, repeating every ``period`` seconds.

    Attributes
    ----------
    name : str
    period : float
        Seconds per cycle.
    summary : str
    contacts : callable
        ``contacts(skin, phase)``, phase in ``[0, 1)``: the tuple of :class:`solver.loads.ContactLoad`.
    """

    name: str
    period: float
    summary: str
    contacts: Callable


SCENES = {scene.name: scene for scene in (
    BoardScene("circle", 2.0, "a Hertzian contact circling the centre, force 0.5 to 1 N, shear ratio 0.3 "
               "turning with it", _circle),
    BoardScene("pinch", 3.0, "two Hertzian contacts closing in and parting again along the skin's long side, "
               "0.3 to 0.8 N each, shear ratio 0.3 pointing at each other", _pinch),
    BoardScene("two", 4.0, "two contacts moving independently: one circling in one half of the skin with "
               "shear 0.3 along its motion, one on a figure of eight in the other with shear 0.15 "
               "towards 120 degrees", _two),
    BoardScene("three", 4.0, "three contacts, each on its own path about its home: one circling (shear 0.3 "
               "along +x), one moving in and out (shear 0.2 turning), one sideways (no shear)", _three),
    BoardScene("press", 6.0, "a broad Hertzian press over 69% of the skin, mean pressure 5 to 10 kPa, "
               "no shear", _press),
    BoardScene("twist", 4.0, "a 1 N Hertzian press twisted back and forth about its axis (torsion only, no "
               "shear): invisible to normal-stress sensors, so the stream never changes", _twist),
    BoardScene("palm", 2.0, "a fingertip (a 1 N cone, shear ratio 0.3 turning) circling beside a light "
               "broad press (a flat punch of 0.4 to 0.6 N, radius 2.5 pitches, shear ratio 0.2 along the "
               "long side), each of whose nodes carries a tenth of the fingertip's most loaded one", _palm),
)}


def scene_contacts(scene: str, grid: SensorGrid, phase: float) -> tuple:
    """The contacts of ``scene`` on ``grid`` at ``phase`` (fraction of its period); all on the skin."""
    return tuple(SCENES[one_of("scene", scene, tuple(SCENES))].contacts(_Skin.of(grid), float(phase)))


def _subdivisions(grid: SensorGrid, contacts) -> int:
    # Sub-cells at most a seventh of the smallest contact radius and a third of the thickness
    # (odd, 3 to 9 per pitch): within 0.6% of the peak of loads' default (finer) lattice for the
    # default geometry's circle, half the default noise, at a fifth to a tenth of its time.
    smallest = min(min(c.semi_axes) for c in contacts)
    count = math.ceil(grid.pitch / min(smallest / 7, grid.thickness / 3) - 1e-9)
    return min(9, max(3, count | 1))


def scene_frame(scene: str, grid: SensorGrid, phase: float, *, noise: float = 0.0, rng=None):
    """One frame of ``scene`` at ``phase``: :func:`solver.loads.simulate` through the bonded layer.

    The :class:`~solver.loads.SimulatedFrame` carries the true nodal forces; the sub-cell lattice
    is the simulator's (coarser than :func:`~solver.loads.simulate`'s default, see
    ``_subdivisions``).
    """
    contacts = scene_contacts(scene, grid, phase)
    return loads.simulate(grid, contacts, noise=noise, rng=rng, medium="layer",
                          subdivisions=_subdivisions(grid, contacts))


class Cycle:
    """The ``frames`` clean frames of one period of a scene, each computed once, when first needed.

    ``cycle[k]`` is frame ``k``'s stress ``(m,)``, pascals (read-only), at phase ``k / frames``;
    :meth:`start` computes the frames in order in a background thread, and a frame asked for
    before that thread reaches it is computed at once by the caller (or awaited when the thread
    is on it). Frames depend only on the scene, the grid and their index, never on which thread
    computed them or when.

    A cycle shared by several users (boards) is counted: :meth:`acquire` starts the thread and
    :meth:`release` stops it when the last user lets go; :meth:`close` stops it at once.
    """

    def __init__(self, scene: str, grid: SensorGrid, frames: int = CYCLE):
        one_of("scene", scene, tuple(SCENES))
        self.scene, self.grid = SCENES[scene], grid
        self.frames = whole_number("frames", frames, low=1)
        self._stress = [None] * self.frames
        self._peak = [0.0] * self.frames
        self._done = [threading.Event() for _ in range(self.frames)]
        self._claimed = [False] * self.frames
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._worker = None
        self._life = threading.Lock()  # start / stop / users; never taken by the worker
        self._users = 0

    def __len__(self) -> int:
        return self.frames

    @property
    def period(self) -> float:
        """Seconds per cycle."""
        return self.scene.period

    @property
    def computed(self) -> int:
        """How many frames are computed so far."""
        return sum(done.is_set() for done in self._done)

    def ready(self, k: int) -> bool:
        """Whether frame ``k`` is computed."""
        return self._done[k].is_set()

    def __getitem__(self, k: int) -> np.ndarray:
        self._ensure(k)
        return self._stress[k]

    def peak(self, k: int) -> float:
        """Frame ``k``'s peak absolute clean stress, pascals."""
        self._ensure(k)
        return self._peak[k]

    def array(self) -> np.ndarray:
        """``(frames, m)``: every frame (computing the missing ones)."""
        return np.array([self[k] for k in range(self.frames)])

    @property
    def users(self) -> int:
        """How many users hold this cycle (:meth:`acquire` minus :meth:`release`)."""
        return self._users

    @property
    def computing(self) -> bool:
        """Whether the background thread is running and not told to stop."""
        worker = self._worker
        return worker is not None and worker.is_alive() and not self._stop.is_set()

    def start(self) -> Cycle:
        """Compute the frames not yet computed in a background thread, in order; returns ``self``.

        A thread still finishing its frame after :meth:`close` is waited for, then a new one starts.
        """
        with self._life:
            self._start()
        return self

    def _start(self):
        worker = self._worker
        if worker is not None and worker.is_alive():
            if not self._stop.is_set():
                return  # already computing
            worker.join()  # stopping: it ends after the frame it is on
        self._stop.clear()
        if self.computed == self.frames:
            return
        self._worker = threading.Thread(target=self._fill, daemon=True,
                                        name=f"tactile-sim {self.scene.name} cycle")
        self._worker.start()

    def acquire(self) -> Cycle:
        """Count one more user and compute in the background (:meth:`start`); returns ``self``."""
        with self._life:
            self._users += 1
            self._start()
        return self

    def release(self, timeout: float = 5.0):
        """Count one user less; the last one to go stops the background thread (:meth:`close`)."""
        with self._life:
            if self._users <= 0:
                raise RuntimeError(f"release of the {self.scene.name} cycle without a matching acquire")
            self._users -= 1
            if self._users == 0:
                self._close(timeout)

    def close(self, timeout: float = 5.0):
        """Stop the background thread (after the frame it is on); frames are still computed on demand.

        Stops it whoever else uses the cycle: users call :meth:`release` instead.
        """
        with self._life:
            self._close(timeout)

    def _close(self, timeout: float):
        self._stop.set()
        worker = self._worker
        if worker is not None and worker is not threading.current_thread():
            worker.join(timeout)

    def _claim(self, k: int) -> bool:
        with self._lock:
            mine, self._claimed[k] = not self._claimed[k], True
        return mine

    def _ensure(self, k: int):
        if not 0 <= k < self.frames:
            raise IndexError(f"frame {k} of a {self.frames}-frame cycle")
        while not self._done[k].is_set():
            if self._claim(k):
                self._compute(k)
            else:
                self._done[k].wait(0.05)  # the other thread computes it (or gives it back if it fails)

    def _compute(self, k: int):
        try:
            stress = scene_frame(self.scene.name, self.grid, k / self.frames).clean_stress
        except BaseException:
            with self._lock:
                self._claimed[k] = False
            raise
        self._stress[k], self._peak[k] = stress, float(np.abs(stress).max())
        self._done[k].set()

    def _fill(self):
        for k in range(self.frames):
            if self._stop.is_set():
                return
            if self._claim(k):
                try:
                    self._compute(k)
                except Exception:
                    return  # the caller that asks for this frame computes it and sees the error


_CYCLES: dict = {}  # (scene, frames, grid.key) -> Cycle, the most recently used last
_KEPT = 4
_CYCLES_LOCK = threading.Lock()


def shared_cycle(scene: str, grid: SensorGrid, frames: int = CYCLE) -> Cycle:
    """This process's :class:`Cycle` of ``scene`` on ``grid``, computing in the background.

    Cycles are kept by scene, frame count and ``grid.key`` (everything the frames depend on);
    the last few are kept (one dropped from the cache keeps computing while it has users).
    """
    key = (one_of("scene", scene, tuple(SCENES)), frames, grid.key)
    with _CYCLES_LOCK:
        cycle = _CYCLES.pop(key, None)
        if cycle is None:
            cycle = Cycle(scene, grid, frames)
        _CYCLES[key] = cycle
        evicted = [_CYCLES.pop(next(iter(_CYCLES))) for _ in range(len(_CYCLES) - _KEPT)]
    for old in evicted:
        if old.users == 0:
            old.close(timeout=0)
    return cycle.start()


def contact_cycle(grid: SensorGrid, frames: int = CYCLE, *, scene: str = "circle") -> np.ndarray:
    """``(frames, m)`` clean stress, pascals: one period of ``scene`` (default: the circling contact)."""
    return shared_cycle(scene, grid, frames).array()
