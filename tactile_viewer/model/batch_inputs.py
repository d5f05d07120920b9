"""What a batch reads and what it writes: its inputs (recordings and ROS 2 bags) and their force files.

No Qt, no pyvista. :mod:`tactile_viewer.model.batch` solves what is found here.

- **Inputs** (:func:`find_recordings`): a file is taken as given; a folder is
  walked for the recordings of this viewer (``.mcap``, ``.npz``, ``.csv``) and
  for ROS 2 bags. A folder holding ``metadata.yaml`` is one bag (given or met in
  a walk, it is not walked into: its storage files are that bag's); a loose
  ``.db3`` is a bare bag; an ``.mcap`` another program wrote is a bag
  (:func:`~tactile_viewer.io.ros2_bag.is_ros2_bag`). A bag is read through the
  :class:`BagOptions` of the run (its layout file, topic and field), which every
  bag of a run shares; a recording of this viewer carries its own layout and
  takes none.
- **Outputs**: ``<out>/<input name>.forces.<npz|csv|mcap>`` (a folder's inputs
  keep their sub-folders; a bag folder ``run1`` gives ``run1.forces.npz``),
  written whole under a temporary name and renamed; beside it
  ``<output>.batch.json`` names the input (path, size, modification time), the
  settings and, for a bag, its options and the layout file's size and time. An
  output whose JSON names the same input, settings and options is finished and
  skipped on a rerun (:func:`is_finished`); the JSON is removed before an output
  is replaced and written after it, so it never vouches for another file.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from solver.checks import shown

from ..io.layout import LayoutError, load_layout
from ..io.recording import SUFFIXES, written_whole
from ..io.ros2_bag import BAG_METADATA, bag_location, is_ros2_bag
from .foxglove_export import FOXGLOVE_FORMAT, force_file_ending, save_force_file

__all__ = ["FORMATS", "OUTPUT_SUFFIX", "RECORD_SUFFIX", "RECORD_MARKER", "BagOptions", "BatchInput",
           "find_recordings", "input_stamp", "record_path", "is_finished", "write_output"]

FORMATS = ("npz", "csv", FOXGLOVE_FORMAT)  # the force exports, and an MCAP for Foxglove (<name>.forces.mcap)
OUTPUT_SUFFIX = ".forces"  # <input name>.forces.npz
RECORD_SUFFIX = ".batch.json"  # beside each output: its input and settings
RECORD_MARKER = "tactile_batch"  # the key that marks the JSON as ours; its value is the version
_RECORD_VERSION = 1
_RECORD_MAX_BYTES = 1 << 20
_BAG_SUFFIXES = (".db3",)  # bare bags by their name; a foreign .mcap is told by its header


@dataclass(frozen=True)
class BagOptions:
    """How every ROS 2 bag of a run is read (:func:`~tactile_viewer.io.ros2_bag.load_ros2_bag`).

    Attributes
    ----------
    layout : str
        The sensor layout file's absolute path (the workers read it there).
    topic, field : str or None
        The array topic and field; None: the only one that fits the layout.
    layout_stamp : tuple
        The layout file's ``(size in bytes, modification time in ns)`` when the
        run began: an edited layout makes a finished output stale.
    """

    layout: str
    topic: str | None = None
    field: str | None = None
    layout_stamp: tuple = ()

    @classmethod
    def from_layout_file(cls, layout, *, topic=None, field=None) -> BagOptions:
        """Options for ``layout`` (a path), checked now: the file must read as a sensor layout.

        Raises
        ------
        ValueError
            Naming ``--layout``, ``--topic`` or ``--field`` and what is wrong.
        """
        for name, value in (("--topic", topic), ("--field", field)):
            if value is not None and (not isinstance(value, str) or not value):
                raise ValueError(f"{name} must be a non-empty name, got {shown(value)}")
        path = os.path.abspath(layout)
        try:
            load_layout(path)
        except LayoutError as exc:  # it names the file and the key
            raise ValueError(f"--layout: {exc}") from None
        return cls(path, topic, field, input_stamp(path))

    def keywords(self) -> dict:
        """The keywords :func:`tactile_viewer.io.files.load` opens a bag with."""
        return {"layout": self.layout, "topic": self.topic, "field": self.field}

    def fields(self) -> dict:
        """The options as JSON values (what an output's record names)."""
        return {"layout": self.layout, "layout_bytes": self.layout_stamp[0],
                "layout_mtime_ns": self.layout_stamp[1], "topic": self.topic, "field": self.field}


@dataclass(frozen=True)
class BatchInput:
    """An input to reconstruct (absolute ``path``), the force file it becomes and, for a bag, its options."""

    path: Path
    output: Path
    bag: BagOptions | None = None


def find_recordings(inputs, out_dir, fmt: str, *, bag: BagOptions | None = None) -> list[BatchInput]:
    """The recordings and bags the INPUTs name, each with its output under ``out_dir`` (module notes).

    Parameters
    ----------
    inputs : list of str or Path
        Recordings, bags (a bag folder, its ``metadata.yaml``, a ``.db3``, another
        program's ``.mcap``) and folders. Hidden files, force files
        (``*.forces.*``) and anything under ``out_dir`` are left out of a walk; a
        path named twice is taken once.
    out_dir : str or Path
    fmt : str
        One of :data:`FORMATS`.
    bag : BagOptions, optional
        How the bags are read; required when a bag is among the inputs.

    Raises
    ------
    ValueError
        An INPUT that is missing or not a recording, an unknown ``fmt``, a bag
        without ``bag`` options, two inputs that would write the same output, or
        nothing to read.
    """
    if fmt not in FORMATS:
        raise ValueError(f"--format must be one of {FORMATS}, got {shown(fmt)}")
    out_dir = Path(os.path.abspath(out_dir))
    found: dict[Path, BatchInput] = {}
    writers: dict[Path, Path] = {}
    bags: list[str] = []
    for given in map(Path, inputs):
        if is_ros2_bag(given):
            path = Path(os.path.abspath(bag_location(given)))
            pairs = [(path, Path(path.name))]
        elif given.is_dir():
            folder = Path(os.path.abspath(given))
            pairs = [(p, p.relative_to(folder)) for p in _walk(folder, out_dir)]
        elif given.is_file():
            if given.suffix.lower() not in SUFFIXES:
                raise ValueError(f"INPUT must be a recording ({', '.join(SUFFIXES)}), a ROS 2 bag (a folder "
                                 f"with {BAG_METADATA}, a .db3) or a folder, got {str(given)!r}")
            path = Path(os.path.abspath(given))
            pairs = [(path, Path(path.name))]
        else:
            raise ValueError(f"INPUT must be a recording file or a folder, got {str(given)!r} "
                             f"({'no such file or folder' if not os.path.lexists(given) else 'neither'})")
        for path, relative in pairs:
            output = out_dir / relative.with_name(f"{relative.name}{OUTPUT_SUFFIX}{force_file_ending(fmt)}")
            if path in found:
                continue
            if output in writers:
                raise ValueError(f"INPUT: {writers[output]} and {path} would both be written to {output}: "
                                 "give them in separate runs with different --out folders")
            writers[output] = path
            is_bag = is_ros2_bag(path)  # an .mcap's header read once
            found[path] = BatchInput(path, output, bag if is_bag else None)
            if is_bag:
                bags.append(str(path))
    if not found:
        raise ValueError(f"INPUT: no recording ({', '.join(SUFFIXES)}) or ROS 2 bag in "
                         f"{', '.join(map(str, inputs))}")
    if bags and bag is None:
        named = ", ".join(bags[:3]) + (f" and {len(bags) - 3} more" if len(bags) > 3 else "")
        plural = "s" if len(bags) > 1 else ""
        raise ValueError(f"--layout is needed: INPUT holds {len(bags)} ROS 2 bag{plural} ({named}), whose "
                         "values become stresses through the skin's sensor layout file")
    return list(found.values())


def _walk(folder: Path, out_dir: Path) -> list[Path]:
    # sorted, depth first; a bag folder is one input and is not walked into
    found = []
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith(".") or entry == out_dir:
            continue
        if entry.is_dir() and (entry / BAG_METADATA).is_file():
            found.append(entry)
        elif entry.is_dir() and not entry.is_symlink():  # as a walk always did: no loops through links
            found.extend(_walk(entry, out_dir))
        elif entry.is_file() and entry.suffix.lower() in (*SUFFIXES, *_BAG_SUFFIXES):
            if not Path(entry.stem).suffix == OUTPUT_SUFFIX:  # force files, ours or the viewer's
                found.append(entry)
    return found


def input_stamp(path) -> tuple:
    """``(size in bytes, modification time in ns)`` of a file, or of a bag folder's files (their sum, latest).

    A task compares it with the planned one: an input changed since is not solved.
    """
    info = os.stat(path)
    if not os.path.isdir(path):
        return info.st_size, info.st_mtime_ns
    size, latest = 0, info.st_mtime_ns
    for root, _, names in os.walk(path):
        for name in names:
            part = os.stat(os.path.join(root, name))
            size, latest = size + part.st_size, max(latest, part.st_mtime_ns)
    return size, latest


def record_path(output) -> Path:
    """The JSON beside an output naming its input and settings: ``<output>.batch.json``."""
    output = Path(output)
    return output.with_name(output.name + RECORD_SUFFIX)


def _record(batch_input: BatchInput, stamp: tuple, settings) -> dict:
    record = {RECORD_MARKER: _RECORD_VERSION, "source": str(batch_input.path), "source_bytes": stamp[0],
              "source_mtime_ns": stamp[1], "settings": settings.fields()}
    if batch_input.bag is not None:
        record["bag"] = batch_input.bag.fields()
    return record


def is_finished(batch_input: BatchInput, settings) -> bool:
    """The output exists and its record names this input (path, size, time), these settings and bag options.

    ``settings`` is a :class:`~tactile_viewer.model.batch.BatchSettings`.
    """
    output, record = batch_input.output, record_path(batch_input.output)
    try:
        if not output.is_file() or record.stat().st_size > _RECORD_MAX_BYTES:
            return False
        written = json.loads(record.read_text(encoding="utf-8"))
        stamp = input_stamp(batch_input.path)
    except (OSError, ValueError):
        return False
    if not isinstance(written, dict) or written.get("output_bytes") != output.stat().st_size:
        return False
    return {k: v for k, v in written.items() if k not in ("output_bytes", "frames")} == \
        _record(batch_input, stamp, settings)


def write_output(plan, table) -> Path:
    """Write a :class:`~tactile_viewer.model.batch.FilePlan`'s force table, then its record, each whole."""
    output = plan.input.output
    record = record_path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    record.unlink(missing_ok=True)  # no record vouches for an output being replaced
    bag = plan.input.bag
    save_force_file(table, output, source=str(plan.input.path), **({} if bag is None else bag.keywords()))
    fields = _record(plan.input, plan.stamp, plan.settings) | {"frames": plan.frames,
                                                                "output_bytes": output.stat().st_size}
    text = json.dumps(fields, indent=2, allow_nan=False) + "\n"
    with written_whole(record) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return output
