"""Batch reconstruction: every frame of many recordings solved into force files, a chunk of frames per task.

No Qt, no pyvista. The rules live here; the engines that run the tasks (joblib's
processes, a Dask cluster) are in :mod:`tactile_viewer.model.batch_engines`, and
the command is ``tactile-batch`` (:mod:`tactile_viewer.cli.tactile_batch`).

- **Settings** (:class:`BatchSettings`): a kernel, an optional quality preset
  (a :data:`solver.quality.CONFIGURATIONS` name) and automatic or given shear
  parameters; the solver is the one the viewer builds for them
  (:meth:`ViewerModel.build`). :func:`settings_from_view` reads them from a
  screenshot's sidecar.
- **Planning**: each input (:mod:`tactile_viewer.model.batch_inputs`: recordings
  and ROS 2 bags, and the files they become) is opened once in the parent to
  count its frames; its frames are cut into chunks (:func:`plan_chunks`) and each
  chunk is a :class:`ChunkTask` naming the input by path and how to open it (a
  bag's layout, topic and field; no frames are shipped). A task opens the input
  itself and solves its frames (:func:`solve_chunk`), and never raises: a failure
  comes back as the outcome's ``error``.
- **One decoding per process**: a bag opens whole (decoding every message), so
  each process keeps the last two inputs it opened (:func:`opened_input`, keyed
  by path, size, time and options); the engines hand a file's chunks out in
  order, so a worker opens each input at most once (the outcome's
  ``opened_by`` says which process opened it for that task).
- **Equal to the viewer's export**: a task starts from a new solver state and
  first solves the frame before its chunk (:func:`solver_for`); its results come
  back without contact identities, and the parent follows the contacts over the
  file's frames in order with one :class:`solver.ContactTracker`, as
  :func:`~tactile_viewer.model.force_tables.reconstruct_frames` does
  (:func:`assemble_table`); :func:`~tactile_viewer.model.batch_inputs.write_output`
  writes it.
"""

from __future__ import annotations

import copy
import json
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from solver import ContactTracker, SensorGrid
from solver.checks import shown, whole_number
from solver.inverse import DenseSolver
from solver.kernels import KERNELS
from solver.quality import CONFIGURATIONS

from ..io.files import load
from ..io.forces import ForceTable
from ..io.recording import RecordingError
from ..io.sidecar import SIDECAR_MARKER
from .batch_inputs import BagOptions, BatchInput, input_stamp
from .force_tables import force_table
from .movie_settings import check_movie_parameters
from .shear_parameters import MAX_SHEAR_RATIO
from .viewer_model import ViewerModel

__all__ = ["BatchSettings", "settings_from_preset", "settings_from_view", "PRESET_NAMES", "DEFAULT_CHUNK",
           "plan_chunks", "FilePlan", "ChunkTask", "ChunkOutcome", "FileOutcome", "plan_file", "opened_input",
           "solver_for", "solve_chunk", "assemble_table"]

PRESET_NAMES = tuple(c.name for c in CONFIGURATIONS)
DEFAULT_CHUNK = 250  # frames per task: 1.5 s on a 16x16 skin; enough tasks to keep every worker busy
_KEPT_INPUTS = 2  # opened inputs a process keeps: the file being solved and the one before (module notes)
_SIDECAR_MAX_BYTES = 1 << 20


@dataclass(frozen=True)
class BatchSettings:
    """How every frame is solved: the viewer's solver for ``kernel`` and ``preset``, the parameters.

    Attributes
    ----------
    kernel : str
        One of :data:`solver.kernels.KERNELS`.
    preset : str or None
        A :data:`solver.quality.CONFIGURATIONS` name (its kernel replaced by
        ``kernel``, as the viewer's quality box does); None: the standard solve.
    shear_ratio, shear_direction : float or None
        Both None: found for each frame (automatic); both given: fixed, the
        direction in radians.
    """

    kernel: str = KERNELS[0]
    preset: str | None = None
    shear_ratio: float | None = None
    shear_direction: float | None = None

    def __post_init__(self):
        if self.kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {shown(self.kernel)}")
        if self.preset is not None and self.preset not in PRESET_NAMES:
            raise ValueError(f"preset must be one of {PRESET_NAMES}, got {shown(self.preset)}")
        ratio, direction = check_movie_parameters(self.shear_ratio, self.shear_direction)
        object.__setattr__(self, "shear_ratio", ratio)
        object.__setattr__(self, "shear_direction", direction)

    @property
    def mode(self) -> str:
        """``"auto"`` (parameters found for each frame) or ``"manual"``, as force exports say."""
        return "auto" if self.shear_ratio is None else "manual"

    @property
    def configuration(self):
        """The preset's :class:`solver.quality.Configuration` (None: the standard solve)."""
        return None if self.preset is None else CONFIGURATIONS[PRESET_NAMES.index(self.preset)]

    def build(self, grid: SensorGrid):
        """The solver the viewer builds for ``grid`` with this kernel and preset."""
        return ViewerModel.build(grid, self.kernel, self.configuration)

    def fields(self) -> dict:
        """The settings as JSON values (what an output's record names)."""
        return {"kernel": self.kernel, "preset": self.preset, "mode": self.mode,
                "shear_ratio": self.shear_ratio, "shear_direction": self.shear_direction,
                "max_shear_ratio": MAX_SHEAR_RATIO}


def settings_from_preset(name: str | None, kernel: str | None = None) -> BatchSettings:
    """Automatic parameters with a quality preset (None: the standard solve).

    ``kernel`` replaces the preset's own; None keeps it (``layer`` without a preset).
    """
    if name is not None and name not in PRESET_NAMES:
        raise ValueError(f"--preset must be one of {', '.join(map(repr, PRESET_NAMES))}, got {shown(name)}")
    own = KERNELS[0] if name is None else CONFIGURATIONS[PRESET_NAMES.index(name)].kernel
    return BatchSettings(kernel=kernel or own, preset=name)


def settings_from_view(path, kernel: str | None = None) -> BatchSettings:
    """The kernel and parameters a screenshot's sidecar (``<image>.view.json``) names.

    ``mode`` "auto" is automatic parameters; "manual" takes ``shear_ratio`` and
    ``shear_direction_deg``. A sidecar names no quality preset: the standard
    solve. ``kernel`` replaces the sidecar's.

    Raises
    ------
    ValueError
        Naming the file, the key, the rule and what the file holds.
    """
    path = Path(path)
    try:
        if path.stat().st_size > _SIDECAR_MAX_BYTES:
            raise ValueError(f"--view {path}: not a view sidecar: it has over {_SIDECAR_MAX_BYTES} bytes")
        info = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"--view {path}: cannot read the view sidecar: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise ValueError(f"--view {path}: not a view sidecar: it is not JSON text") from exc
    except json.JSONDecodeError as exc:
        raise ValueError(f"--view {path}: not a view sidecar: it is not JSON ({exc})") from exc
    if not isinstance(info, dict) or SIDECAR_MARKER not in info:
        raise ValueError(f"--view {path}: not a view sidecar: a sidecar is a JSON object with the key "
                         f"{SIDECAR_MARKER!r} (the viewer writes one beside each screenshot)")
    if info.get("kernel") not in KERNELS:
        raise ValueError(f"--view {path}: 'kernel' must be one of {KERNELS}, got {shown(info.get('kernel'))}")
    mode = info.get("mode")
    if mode not in ("auto", "manual"):
        raise ValueError(f"--view {path}: 'mode' must be 'auto' or 'manual', got {shown(mode)}")
    ratio = direction = None
    if mode == "manual":
        try:
            ratio, direction = check_movie_parameters(
                info.get("shear_ratio"), info.get("shear_direction_deg"), degrees=True,
                names=("'shear_ratio'", "'shear_direction_deg'"))
        except ValueError as exc:
            raise ValueError(f"--view {path}: {exc}") from None
    return BatchSettings(kernel=kernel or info["kernel"], shear_ratio=ratio, shear_direction=direction)


# -- planning ------------------------------------------------------------------------------------------


def plan_chunks(count: int, chunk: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of each chunk of ``chunk`` frames (the last one shorter), covering ``count``."""
    count = whole_number("count", count, low=0, unit="of frames ")
    chunk = whole_number("--chunk", chunk, low=1, unit="of frames ")
    return [(start, min(start + chunk, count)) for start in range(0, count, chunk)]


# -- the work ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ChunkTask:
    """Frames ``start`` to ``stop`` (excluded) of the input at ``path``, solved with ``settings``.

    ``stamp`` is the input's ``(size, modification time in ns)`` when it was
    planned (:func:`~tactile_viewer.model.batch_inputs.input_stamp`): an input
    changed since is not solved. ``bag``: how a ROS 2 bag is read, None for a
    recording of this viewer.
    """

    path: str
    start: int
    stop: int
    settings: BatchSettings
    stamp: tuple
    bag: BagOptions | None = None


@dataclass(frozen=True)
class ChunkOutcome:
    """A task's results (one :class:`solver.Reconstruction` a frame, contacts unnumbered) or its error.

    ``opened_by``: the id of the process that opened (decoded) the input for
    this task, 0 when it was still open there from an earlier task.
    """

    task: ChunkTask
    results: tuple = ()
    error: str = ""
    opened_by: int = 0


@dataclass
class FilePlan:
    """One recording to solve: its input, geometry, times and chunks."""

    input: BatchInput
    grid: SensorGrid
    t: np.ndarray
    stamp: tuple
    chunks: list
    settings: BatchSettings
    damage: tuple = ()

    @property
    def frames(self) -> int:
        """How many frames the recording holds."""
        return len(self.t)

    def tasks(self) -> list[ChunkTask]:
        """One task per chunk."""
        return [ChunkTask(str(self.input.path), start, stop, self.settings, self.stamp, self.input.bag)
                for start, stop in self.chunks]


@dataclass(frozen=True)
class FileOutcome:
    """What became of one input: ``status`` "written", "skipped" or "failed" (``reason`` says why)."""

    input: BatchInput
    status: str
    frames: int = 0
    reason: str = ""


def plan_file(batch_input: BatchInput, settings: BatchSettings, chunk: int) -> FilePlan:
    """Open the input once (its frame count, geometry and times) and cut its frames into chunks.

    A recording that opens past damage (an MCAP's failed chunks, a bag's
    messages that are no frames) is solved as the viewer reads it; ``damage``
    names what was left out. The opened input is kept for the tasks this
    process solves (:func:`opened_input`).

    Raises
    ------
    RecordingError
        When the input cannot be read as a recording (the message names it).
    """
    stamp = input_stamp(batch_input.path)
    recording, _ = opened_input(str(batch_input.path), stamp, batch_input.bag)
    return FilePlan(batch_input, recording.grid, np.array(recording.t), stamp,
                    plan_chunks(len(recording), chunk), settings, tuple(recording.damage))


_solvers: dict = {}
_solvers_lock = threading.Lock()


def solver_for(settings: BatchSettings, grid: SensorGrid):
    """A solver for ``grid`` with ``settings``: its set-up made once in this process, its state its own.

    A solve starts its fit from the last frame's (the solver's state), which
    moves its answer by rounding; a task that starts from a new state and first
    solves the frame before its chunk (:func:`solve_chunk`) answers to the bit
    as one pass over the whole recording does. The set-up (slow) is kept and
    shared; each call gives a state of its own where the engine solves the
    whole skin at once. A window-by-window engine (skins over 32x32) keeps one
    state per window shape, shared: its answers match a whole pass up to
    rounding. So do those of a set-up made in another process (its products
    round by its thread count).
    """
    key = (settings, grid.key)
    with _solvers_lock:
        if key not in _solvers:
            if len(_solvers) >= 4:
                _solvers.pop(next(iter(_solvers)))
            _solvers[key] = settings.build(grid)  # never solves: the template of the states handed out
        solver = _solvers[key]
    engine = solver.engine
    whole_skin = getattr(engine, "reconstructor", engine)  # a quality setting's engine wraps one
    if not isinstance(whole_skin, DenseSolver):
        return solver
    if whole_skin is engine:
        engine = whole_skin.sibling()
    else:
        engine = copy.copy(engine)
        engine.reconstructor = whole_skin.sibling()
    fresh = copy.copy(solver)
    fresh.engine = engine
    return fresh


_opened: OrderedDict = OrderedDict()
_opened_lock = threading.Lock()


def opened_input(path: str, stamp: tuple, bag: BagOptions | None = None):
    """The input at ``path`` opened as a recording, and whether this call opened it (else it was kept).

    This process keeps the last :data:`_KEPT_INPUTS` inputs opened, keyed by
    path, ``stamp`` and ``bag`` options: a bag opens whole, and a worker given
    a file's chunks one after another decodes it once. One thread opens at a
    time (a Dask worker's threads share the kept inputs).

    Raises
    ------
    RecordingError
        As :func:`tactile_viewer.io.files.load`.
    """
    key = (path, stamp, bag)
    with _opened_lock:
        if key in _opened:
            _opened.move_to_end(key)
            return _opened[key], False
        recording = load(path, **({} if bag is None else bag.keywords()))
        _opened[key] = recording
        while len(_opened) > _KEPT_INPUTS:
            _opened.popitem(last=False)
        return recording, True


def solve_chunk(task: ChunkTask) -> ChunkOutcome:
    """Open the task's input by path (or take it as kept) and solve its frames; never raises.

    Run where the engine runs it (a joblib process, a Dask worker): only the
    path, the frame range, the settings and a bag's options travel there, the
    results back; an error is the outcome's. The
    frame before the chunk is solved first, unreported (:func:`solver_for`).
    """
    frames = f"frames {task.start} to {task.stop - 1}"
    try:
        if input_stamp(task.path) != task.stamp:
            raise RecordingError(f"{task.path}: the file changed since it was planned (size or time)")
        recording, opened = opened_input(task.path, task.stamp, task.bag)
        if task.stop > len(recording):
            raise RecordingError(f"{task.path}: holds {len(recording)} frames, not {task.stop}")
        solver = solver_for(task.settings, recording.grid)
        given = dict(shear_ratio=task.settings.shear_ratio, shear_direction=task.settings.shear_direction)
        if task.start > 0:  # the frame before: the state a pass over the whole recording brings here
            solver.solve(recording.frames[task.start - 1], **given)
        results = tuple(solver.solve(recording.frames[k], **given) for k in range(task.start, task.stop))
        return ChunkOutcome(task, results, opened_by=os.getpid() if opened else 0)
    except Exception as exc:  # noqa: BLE001 (reported with the file; the other files go on)
        reason = str(exc) if isinstance(exc, RecordingError) else f"{type(exc).__name__}: {exc}"
        return ChunkOutcome(task, error=f"{frames}: {reason}")


@dataclass(frozen=True)
class _SolvedBy:
    # what force_table records of the solver: its geometry's material and its kernel
    grid: SensorGrid
    kernel: str


def assemble_table(plan: FilePlan, results) -> ForceTable:
    """The force table of a file's solved frames, in frame order, its contacts followed from frame 0.

    Equal to :func:`~tactile_viewer.model.force_tables.reconstruct_frames` of the
    whole recording with the same solver (its source the input's path).
    """
    tracker = ContactTracker(plan.grid)  # the export's numbering: one tracker over the frames in order
    numbered = [tracker.update(result) for result in results]
    frames = np.arange(plan.frames)
    return force_table(numbered, frames, plan.t[frames], plan.grid, mode=plan.settings.mode,
                       solver=_SolvedBy(plan.grid, plan.settings.kernel), source=str(plan.input.path))
