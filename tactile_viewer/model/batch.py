"""Batch reconstruction: every frame of many recordings solved into force files, a chunk of frames per task.

No Qt, no pyvista. The rules live here; the engines that run the tasks (joblib's
processes, a Dask cluster) are in :mod:`tactile_viewer.model.batch_engines`, and
the command is ``tactile-batch`` (:mod:`tactile_viewer.cli.tactile_batch`).

- **Settings** (:class:`BatchSettings`): a kernel, an optional quality preset
  (a :data:`solver.quality.CONFIGURATIONS` name) and automatic or given shear
  parameters; the solver is the one the viewer builds for them
  (:meth:`ViewerModel.build`). :func:`settings_from_view` reads them from a
  screenshot's sidecar.
- **Planning**: each recording is opened once in the parent to count its frames;
  its frames are cut into chunks (:func:`plan_chunks`) and each chunk is a
  :class:`ChunkTask` naming the file by path (no frames are shipped). A task
  opens the recording itself and solves its frames (:func:`solve_chunk`), and
  never raises: a failure comes back as the outcome's ``error``.
- **Equal to the viewer's export**: a task starts from a new solver state and
  first solves the frame before its chunk (:func:`solver_for`); its results come
  back without contact identities, and the parent follows the contacts over the
  file's frames in order with one :class:`solver.ContactTracker`, as
  :func:`~tactile_viewer.model.force_tables.reconstruct_frames` does
  (:func:`assemble_table`).
- **Outputs**: ``<out>/<input name>.forces.<npz|csv>`` (a folder's recordings keep
  their sub-folders), written whole under a temporary name and renamed; beside it
  ``<output>.batch.json`` names the input (path, size, modification time) and the
  settings. An output whose JSON names the same input and settings is finished
  and skipped on a rerun (:func:`is_finished`); the JSON is removed before an
  output is replaced and written after it, so it never vouches for another file.
"""

from __future__ import annotations

import copy
import json
import os
import threading
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from solver import ContactTracker, SensorGrid
from solver.checks import shown, whole_number
from solver.inverse import DenseSolver
from solver.kernels import KERNELS
from solver.quality import CONFIGURATIONS

from ..io.files import load
from ..io.forces import ForceTable, save_forces
from ..io.recording import SUFFIXES, RecordingError, written_whole
from ..io.sidecar import SIDECAR_MARKER
from .force_tables import force_table
from .movie_settings import check_movie_parameters
from .shear_parameters import MAX_SHEAR_RATIO
from .viewer_model import ViewerModel

__all__ = ["BatchSettings", "settings_from_preset", "settings_from_view", "PRESET_NAMES", "FORMATS",
           "DEFAULT_CHUNK", "OUTPUT_SUFFIX", "RECORD_SUFFIX", "RECORD_MARKER", "BatchInput",
           "find_recordings", "plan_chunks", "FilePlan", "ChunkTask", "ChunkOutcome", "FileOutcome",
           "plan_file", "solver_for", "solve_chunk", "assemble_table", "is_finished", "write_output",
           "record_path"]

PRESET_NAMES = tuple(c.name for c in CONFIGURATIONS)
FORMATS = ("npz", "csv")
DEFAULT_CHUNK = 250  # frames per task: 1.5 s on a 16x16 skin; enough tasks to keep every worker busy
OUTPUT_SUFFIX = ".forces"  # <input name>.forces.npz
RECORD_SUFFIX = ".batch.json"  # beside each output: its input and settings
RECORD_MARKER = "tactile_batch"  # the key that marks the JSON as ours; its value is the version
_RECORD_VERSION = 1
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

    def build(self, grid: SensorGrid):
        """The solver the viewer builds for ``grid`` with this kernel and preset."""
        configuration = None if self.preset is None else CONFIGURATIONS[PRESET_NAMES.index(self.preset)]
        return ViewerModel.build(grid, self.kernel, configuration)

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


# -- what to read and where to write ------------------------------------------------------------------


@dataclass(frozen=True)
class BatchInput:
    """A recording to reconstruct (absolute ``path``) and the force file it becomes (``output``)."""

    path: Path
    output: Path


def find_recordings(inputs, out_dir, fmt: str) -> list[BatchInput]:
    """The recordings the INPUTs name, each with its output under ``out_dir``.

    A file is taken as given; a folder gives every recording file in it and its
    sub-folders (``.mcap``, ``.npz``, ``.csv``), hidden ones, force files
    (``*.forces.npz``, ``*.forces.csv``) and anything under ``out_dir`` left out;
    its outputs keep the sub-folders. A file named twice is taken once.

    Raises
    ------
    ValueError
        An INPUT that is missing or not a recording, an unknown ``fmt``, two
        recordings that would write the same output, or nothing to read.
    """
    if fmt not in FORMATS:
        raise ValueError(f"--format must be one of {FORMATS}, got {shown(fmt)}")
    out_dir = Path(os.path.abspath(out_dir))
    found: dict[Path, BatchInput] = {}
    writers: dict[Path, Path] = {}
    for given in map(Path, inputs):
        if given.is_dir():
            folder = Path(os.path.abspath(given))
            paths = [p for p in sorted(folder.rglob("*")) if _recording_in_folder(p, folder, out_dir)]
            pairs = [(p, p.relative_to(folder)) for p in paths]
        elif given.is_file():
            if given.suffix.lower() not in SUFFIXES:
                raise ValueError(f"INPUT must be a recording ({', '.join(SUFFIXES)}) or a folder, "
                                 f"got {str(given)!r}")
            path = Path(os.path.abspath(given))
            pairs = [(path, Path(path.name))]
        else:
            raise ValueError(f"INPUT must be a recording file or a folder, got {str(given)!r} "
                             f"({'no such file or folder' if not os.path.lexists(given) else 'neither'})")
        for path, relative in pairs:
            output = out_dir / relative.with_name(f"{relative.name}{OUTPUT_SUFFIX}.{fmt}")
            if path in found:
                continue
            if output in writers:
                raise ValueError(f"INPUT: {writers[output]} and {path} would both be written to {output}: "
                                 "give them in separate runs with different --out folders")
            writers[output] = path
            found[path] = BatchInput(path, output)
    if not found:
        raise ValueError(f"INPUT: no recording ({', '.join(SUFFIXES)}) in {', '.join(map(str, inputs))}")
    return list(found.values())


def _recording_in_folder(path: Path, folder: Path, out_dir: Path) -> bool:
    relative = path.relative_to(folder)
    if any(part.startswith(".") for part in relative.parts) or path.suffix.lower() not in SUFFIXES:
        return False
    if path.stem.endswith(OUTPUT_SUFFIX) or out_dir in path.parents:
        return False  # force files, ours or the viewer's, are no recordings
    return path.is_file()


def plan_chunks(count: int, chunk: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of each chunk of ``chunk`` frames (the last one shorter), covering ``count``."""
    count = whole_number("count", count, low=0, unit="of frames ")
    chunk = whole_number("--chunk", chunk, low=1, unit="of frames ")
    return [(start, min(start + chunk, count)) for start in range(0, count, chunk)]


# -- the work ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ChunkTask:
    """Frames ``start`` to ``stop`` (excluded) of the recording at ``path``, solved with ``settings``.

    ``stamp`` is the file's ``(size, modification time in ns)`` when it was
    planned: a file changed since is not solved.
    """

    path: str
    start: int
    stop: int
    settings: BatchSettings
    stamp: tuple


@dataclass(frozen=True)
class ChunkOutcome:
    """A task's results (one :class:`solver.Reconstruction` a frame, contacts unnumbered) or its error."""

    task: ChunkTask
    results: tuple = ()
    error: str = ""


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
        return [ChunkTask(str(self.input.path), start, stop, self.settings, self.stamp)
                for start, stop in self.chunks]


@dataclass(frozen=True)
class FileOutcome:
    """What became of one input: ``status`` "written", "skipped" or "failed" (``reason`` says why)."""

    input: BatchInput
    status: str
    frames: int = 0
    reason: str = ""


def _stamp(path) -> tuple:
    info = os.stat(path)
    return info.st_size, info.st_mtime_ns


def plan_file(batch_input: BatchInput, settings: BatchSettings, chunk: int) -> FilePlan:
    """Open the recording once (its frame count, geometry and times) and cut its frames into chunks.

    A recording that opens past damage (an MCAP's failed chunks) is solved as
    the viewer reads it; ``damage`` names what was left out.

    Raises
    ------
    RecordingError
        When the file cannot be read as a recording (the message names it).
    """
    stamp = _stamp(batch_input.path)
    recording = load(batch_input.path)
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


@lru_cache(maxsize=2)
def _recording(path: str, stamp: tuple):
    # consecutive chunks of a file in one worker read it once (an NPZ is read whole)
    return load(path)


def solve_chunk(task: ChunkTask) -> ChunkOutcome:
    """Open the task's recording by path and solve its frames; never raises (an error is the outcome's).

    Run where the engine runs it (a joblib process, a Dask worker): only the
    path, the frame range and the settings travel there, the results back. The
    frame before the chunk is solved first, unreported (:func:`solver_for`).
    """
    frames = f"frames {task.start} to {task.stop - 1}"
    try:
        if _stamp(task.path) != task.stamp:
            raise RecordingError(f"{task.path}: the file changed since it was planned (size or time)")
        recording = _recording(task.path, task.stamp)
        if task.stop > len(recording):
            raise RecordingError(f"{task.path}: holds {len(recording)} frames, not {task.stop}")
        solver = solver_for(task.settings, recording.grid)
        given = dict(shear_ratio=task.settings.shear_ratio, shear_direction=task.settings.shear_direction)
        if task.start > 0:  # the frame before: the state a pass over the whole recording brings here
            solver.solve(recording.frames[task.start - 1], **given)
        results = tuple(solver.solve(recording.frames[k], **given) for k in range(task.start, task.stop))
        return ChunkOutcome(task, results)
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


def record_path(output) -> Path:
    """The JSON beside an output naming its input and settings: ``<output>.batch.json``."""
    output = Path(output)
    return output.with_name(output.name + RECORD_SUFFIX)


def _record(batch_input: BatchInput, stamp: tuple, settings: BatchSettings) -> dict:
    return {RECORD_MARKER: _RECORD_VERSION, "source": str(batch_input.path), "source_bytes": stamp[0],
            "source_mtime_ns": stamp[1], "settings": settings.fields()}


def is_finished(batch_input: BatchInput, settings: BatchSettings) -> bool:
    """The output exists and its record names this input (path, size, time) and these settings."""
    output, record = batch_input.output, record_path(batch_input.output)
    try:
        if not output.is_file() or record.stat().st_size > _SIDECAR_MAX_BYTES:
            return False
        written = json.loads(record.read_text(encoding="utf-8"))
        stamp = _stamp(batch_input.path)
    except (OSError, ValueError):
        return False
    if not isinstance(written, dict) or written.get("output_bytes") != output.stat().st_size:
        return False
    return {k: v for k, v in written.items() if k not in ("output_bytes", "frames")} == \
        _record(batch_input, stamp, settings)


def write_output(plan: FilePlan, table: ForceTable) -> Path:
    """Write the table and then its record, each whole or not at all (module notes)."""
    output = plan.input.output
    record = record_path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    record.unlink(missing_ok=True)  # no record vouches for an output being replaced
    save_forces(table, output, source=str(plan.input.path))
    fields = _record(plan.input, plan.stamp, plan.settings) | {"frames": plan.frames,
                                                                "output_bytes": output.stat().st_size}
    text = json.dumps(fields, indent=2, allow_nan=False) + "\n"
    with written_whole(record) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return output
