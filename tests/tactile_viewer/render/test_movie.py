"""Movies: ``tactile-viewer REC --movie OUT`` and *File > Export movie*: one movie frame per recording
frame (read back), the caption burnt in, bad options refused, nothing left by a cancel or a failure."""

import re
import subprocess
import sys
from pathlib import Path

import imageio.v2 as iio
import imageio.v3 as iio3
import numpy as np
import pytest

from tactile_viewer.cli.tactile_viewer import main
from tactile_viewer.io.files import load
from tactile_viewer.model import movie_settings
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.model.worker import Cancelled
from tactile_viewer.render import movie
from tactile_viewer.render.frame_renderer import FrameRenderer

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"
SMALL = (320, 240)  # small frames keep each test to a few seconds of software rendering


def run_movie(recording, out, *options):
    return subprocess.run([sys.executable, "-m", "tactile_viewer", str(SAMPLES / recording), "--movie", str(out),
                           *options], capture_output=True, text=True, timeout=300)


def video_frames(path) -> list:
    """Every frame of a video, decoded (not the container's claim)."""
    with iio.get_reader(path, format="FFMPEG") as reader:
        return [np.asarray(frame) for frame in reader]


def caption_strip(image):
    """The pixels of the caption: the top rows, between the colour bars."""
    height, width = image.shape[:2]
    return image[: height // 12, int(0.15 * width): int(0.85 * width), :3].astype(int)


def test_the_command_line_writes_one_video_frame_per_recording_frame(tmp_path):
    out = tmp_path / "press.mp4"
    done = run_movie("hertz_static.npz", out, "--start", "5", "--stop", "17", "--size", "480x320")
    assert done.returncode == 0, done.stderr
    assert re.search(rf"^wrote {re.escape(str(out))}: 12 frames, 480 x 320, fps 30, median \d+ ms per frame$",
                     done.stdout, re.MULTILINE), done.stdout
    frames = video_frames(out)
    assert len(frames) == 12  # frames 5 .. 16: --stop is exclusive
    assert frames[0].shape == (320, 480, 3)
    with iio.get_reader(out, format="FFMPEG") as reader:
        assert reader.get_meta_data()["fps"] == pytest.approx(30)
    # the caption changes with the frame (number, time, forces); it is text on white between the bars
    strips = [caption_strip(frame) for frame in frames]
    assert all(strip.min() < 100 for strip in strips)  # dark text is there
    assert all(np.abs(a - b).max() > 100 for a, b in zip(strips, strips[1:], strict=False))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["press.mp4"]  # no temporary file left


def test_the_command_line_writes_an_animated_gif_at_the_rate_asked_for(tmp_path, capsys):
    # main() in this process: the command itself runs as a process in the test above
    out = tmp_path / "punch.gif"
    code = main([str(SAMPLES / "flat_punch_shear.npz"), "--movie", str(out), "--stop", "6", "--fps", "10",
                 "--size", "400x300", "--shear-ratio", "0.3", "--shear-direction", "30", "--camera", "top"])
    done = capsys.readouterr()
    assert code == 0, done.err
    assert f"wrote {out}: 6 frames, 400 x 300, fps 10," in done.out
    frames = iio3.imread(out, index=None)
    assert frames.shape[:3] == (6, 300, 400)
    assert [iio3.immeta(out, index=k)["duration"] for k in range(6)] == [100] * 6
    strips = [caption_strip(frame) for frame in frames]
    assert all(np.abs(a - b).max() > 100 for a, b in zip(strips, strips[1:], strict=False))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["punch.gif"]


def test_gif_delays_keep_the_rate_in_whole_hundredths():
    delays = movie._gif_delays(30, 30)
    assert set(delays) == {30, 40} and sum(delays) == 1000  # 30 frames at 30 fps: one second exactly
    assert movie._gif_delays(10, 3) == [100, 100, 100]


@pytest.mark.parametrize("name, options, message", [
    ("m.webm", [], r"--movie must end in \.mp4, \.mkv, \.avi, \.gif \(the movie's type\), got '.*m\.webm'"),
    ("m.gif", ["--fps", "60"], r"--fps must be > 0 and at most 50 for a GIF .*, got 60\.0"),
    ("gone/m.mp4", [], r".*/gone: the folder does not exist"),
])
def test_a_movie_that_cannot_be_made_is_refused_before_any_frame(tmp_path, capsys, name, options, message):
    out = tmp_path / name
    assert main([str(SAMPLES / "hertz_static.npz"), "--movie", str(out), *options]) == 2
    err = capsys.readouterr().err
    assert re.fullmatch(f"tactile-viewer: {message}\n", err), err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("options, message", [
    (["--fps", "30"], "--fps goes with --movie"),
    (["--start", "1", "--stop", "3"], "--start, --stop go with --movie"),
    (["--movie", "m.mp4", "--frame", "3"], "--frame chooses one frame; a movie's frames are chosen with --start and --stop"),
    (["--movie", "m.mp4", "--report"], "--movie cannot be combined with --info, --report or --screenshot"),
    (["--movie", "m.mp4", "--transparent"], "--scale and --transparent are for --screenshot"),
    (["--movie", "m.mp4", "--size", "big"], "argument --size: must be WIDTHxHEIGHT in pixels, e.g. 1200x800, got 'big'"),
    (["--movie", "m.mp4", "--size", "8x800"], "argument --size: width must be a whole number of pixels from 16 to 8192, got 8"),
])
def test_movie_options_out_of_place_are_usage_errors(capsys, options, message):
    with pytest.raises(SystemExit) as exited:
        main([str(SAMPLES / "hertz_static.npz"), *options])
    assert exited.value.code == 2
    assert message in capsys.readouterr().err


def test_help_describes_every_movie_option(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    for option, words in (("--movie OUT", ".mp4, .mkv, .avi (H.264 video) or .gif"), ("--fps F", "default 30"),
                          ("--start N", "numbered from 0"), ("--stop N", "exclusive"), ("--size WxH", "1200x800")):
        assert option in text and words in text, option


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_a_cancelled_movie_leaves_no_file(tmp_path, suffix):
    recording = load(SAMPLES / "hertz_static.npz")
    out = tmp_path / f"cut{suffix}"
    calls = []

    def progress(done, total):
        calls.append((done, total))
        return done < 3

    with pytest.raises(Cancelled, match="cancelled after 3 of 30 frames"):
        movie.write_movie(recording, out, progress=progress, size=SMALL, fps=10)
    assert calls == [(1, 30), (2, 30), (3, 30)]
    assert list(tmp_path.iterdir()) == []  # neither the movie nor its temporary file


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_a_write_failing_midway_leaves_the_old_file_and_no_partial_one(tmp_path, monkeypatch, suffix):
    recording = load(SAMPLES / "hertz_static.npz")
    out = tmp_path / f"take{suffix}"
    out.write_bytes(b"an earlier movie")
    append = movie._MovieFile.append

    def fail_third(self, image):
        if self.written == 2:
            assert self.temporary.exists() and self.temporary.parent == tmp_path  # written beside it
            raise OSError(28, "No space left on device")
        append(self, image)

    monkeypatch.setattr(movie._MovieFile, "append", fail_third)
    with pytest.raises(OSError, match="No space left on device"):
        movie.write_movie(recording, out, size=SMALL, fps=10)
    assert out.read_bytes() == b"an earlier movie"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


def test_a_video_that_cannot_be_read_back_whole_is_removed(tmp_path, monkeypatch):
    recording = load(SAMPLES / "hertz_static.npz")
    whole = movie.write_movie(recording, tmp_path / "whole.mp4", stop=8, size=SMALL)
    assert movie._count_video_frames(whole.path) == 8 == len(video_frames(whole.path))
    # a file cut short (what a full disk leaves when ffmpeg finishes the container) counts fewer
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(whole.path.read_bytes()[: whole.path.stat().st_size // 2])
    assert movie._count_video_frames(cut) < 8
    # and such a movie never takes the name asked for
    monkeypatch.setattr(movie, "_count_video_frames", lambda path: 7)
    with pytest.raises(OSError, match=r"the movie is incomplete: 7 of 8 frames could be read back"):
        movie.write_movie(recording, tmp_path / "short.mp4", stop=8, size=SMALL)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mp4", "whole.mp4"]


def test_export_arguments_are_checked_before_anything_is_written(tmp_path):
    recording = load(SAMPLES / "hertz_static.npz")
    with pytest.raises(ValueError, match=r"shear_ratio and shear_direction must be given together"):
        movie.write_movie(recording, tmp_path / "m.mp4", shear_ratio=0.3, size=SMALL)
    with pytest.raises(ValueError, match=r"a GIF holds its frames in memory until it is written: 30 frames of "
                                         r"8000 x 6000 need more than 1024 MiB"):
        movie.write_movie(recording, tmp_path / "m.gif", size=(8000, 6000))
    with pytest.raises(ValueError, match=r"path must end in .*, got '.*m\.png'"):
        movie.write_movie(recording, tmp_path / "m.png")
    assert list(tmp_path.iterdir()) == []


def test_each_frame_costs_the_same_actors(tmp_path):
    # the caption and the scene are updated in place: the renderer holds as many actors after
    # the last frame as after the first (re-adding them each frame would make every frame dearer)
    recording = load(SAMPLES / "hertz_shear_turning.npz")
    solver = ViewerModel.build(recording.grid, "layer")
    export = movie.MovieExport(recording, solver, tmp_path / "m.mp4", start=20, stop=26, size=SMALL)
    try:
        export.step()
        actors = len(export._renderer.plotter.renderer.actors)
        while export.remaining:
            export.step()
        assert len(export._renderer.plotter.renderer.actors) == actors
        result = export.finish()
    finally:
        export.cancel()
    assert result.frames == 6 == len(video_frames(result.path))


# -- the window ----------------------------------------------------------------------------------------


def test_export_movie_from_the_menu_writes_the_frames_asked_for(opened, qtbot, tmp_path, monkeypatch):
    from PyQt6 import QtWidgets

    def fill_in(dialog):
        # the dialog's spin boxes in order: first frame, stop, width, height (fps is a double spin box)
        first, stop, width, height = dialog.findChildren(QtWidgets.QSpinBox)
        assert (first.value(), stop.value()) == (0, 60)  # the whole recording by default
        assert dialog.findChild(QtWidgets.QDoubleSpinBox).value() == 30
        first.setValue(10)
        stop.setValue(15)
        width.setValue(SMALL[0])
        height.setValue(SMALL[1])
        return QtWidgets.QDialog.DialogCode.Accepted

    monkeypatch.setattr(QtWidgets.QDialog, "exec", fill_in)
    # a name without an ending gets the chosen filter's
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName",
                        staticmethod(lambda *a, **k: (str(tmp_path / "turning"), "Animated GIF (*.gif)")))
    with qtbot.waitSignal(opened.exports.movies.finished, timeout=120000) as finished:
        opened.exports.movie_dialog()
    result = finished.args[0]
    assert isinstance(result, movie.MovieResult), result
    assert opened.errors == []
    assert result.path == tmp_path / "turning.gif"
    frames = iio3.imread(result.path, index=None)
    assert frames.shape[:3] == (5, SMALL[1], SMALL[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["turning.gif"]
    assert not opened.exports.movies.running


def test_the_exports_of_a_whole_recording_come_last(opened):
    # the window enables actions[2:] only for a recording (a live source has no whole recording)
    actions = [a for a in opened.menuBar().actions()[0].menu().actions() if a.text().startswith("Export")]
    assert [a.text() for a in actions[2:]] == ["Export forces of the whole &recording...", "Export &movie...",
                                               "Export for F&oxglove (MCAP)..."]


def test_a_window_movie_is_solved_as_the_window_shows_it(opened, qtbot, tmp_path, monkeypatch):
    import math

    opened.model.set_parameters(shear_ratio=0.2, shear_direction=math.radians(90))
    opened.model.set_display(colormap="magma", threshold=0.001, arrow_auto_range=False, taxel_ids=True)
    shown = opened.model.display
    used = spy_on_frames(monkeypatch)
    built = []
    monkeypatch.setattr(ViewerModel, "build", staticmethod(lambda *a, **k: built.append(a)))
    with qtbot.waitSignal(opened.exports.movies.finished, timeout=120000) as finished:
        assert opened.exports.export_movie(tmp_path / "manual.mp4", start=3, stop=7, size=SMALL)
        # the model's own solver, shared (a solver may be shared between threads): nothing built again
        assert opened.exports.movies.export.solver is opened.model.reconstructor
    result = finished.args[0]
    assert isinstance(result, movie.MovieResult), result
    assert built == []
    assert len(video_frames(result.path)) == 4
    # each frame solved with the window's manual parameters and drawn with its display
    assert [frame["solved"].frame for frame in used] == [3, 4, 5, 6]
    for frame in used:
        assert not frame["solved"].auto
        assert frame["solved"].result.shear_ratio == pytest.approx(0.2)
        assert frame["solved"].result.shear_direction == pytest.approx(math.radians(90))
        assert frame["display"] == shown
        assert not frame["parallel"]  # the window's Iso view, in perspective
    # the model's own solves go on meanwhile (its solver was not borrowed)
    with qtbot.waitSignal(opened.rendered, timeout=10000):
        opened.model.set_frame(9)
    assert opened.model.last.frame == 9 and not opened.model.last.auto


def test_cancelling_a_window_movie_removes_its_file(opened, qtbot, tmp_path):
    from PyQt6 import QtWidgets

    runner = opened.exports.movies
    with qtbot.waitSignal(runner.finished, timeout=120000) as finished:
        assert opened.exports.export_movie(tmp_path / "cancel.mp4", size=SMALL)
        qtbot.waitUntil(lambda: runner.export is not None and runner.export.done >= 2, timeout=60000)
        runner._dialog.findChild(QtWidgets.QPushButton).click()  # the progress dialog's Cancel button
    assert isinstance(finished.args[0], Cancelled)
    assert opened.errors == []
    assert list(tmp_path.iterdir()) == []
    assert not runner.running


def test_a_failing_window_movie_is_reported_and_leaves_nothing(opened, qtbot, tmp_path, monkeypatch):
    def full(self, image):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(movie._MovieFile, "append", full)
    with qtbot.waitSignal(opened.exports.movies.finished, timeout=120000) as finished:
        assert opened.exports.export_movie(tmp_path / "full.mp4", stop=5, size=SMALL)
    assert isinstance(finished.args[0], OSError)
    assert opened.errors.take() == [("Cannot export movie", f"{tmp_path / 'full.mp4'}: No space left on device")]
    assert [r.getMessage() for r in opened.errors.take_logged()] == [f"movie {tmp_path / 'full.mp4'} failed"]
    assert list(tmp_path.iterdir()) == []
    # the window goes on: another frame is solved and drawn
    with qtbot.waitSignal(opened.rendered, timeout=10000):
        opened.model.set_frame(4)


def test_closing_the_window_during_a_movie_removes_its_file(opened, qtbot, tmp_path):
    runner = opened.exports.movies
    with qtbot.waitSignal(runner.finished, timeout=120000) as finished:
        assert opened.exports.export_movie(tmp_path / "closing.mp4", size=SMALL)
        qtbot.waitUntil(lambda: runner.export is not None and runner.export.done >= 1, timeout=60000)
        opened.close()
    assert isinstance(finished.args[0], Cancelled)
    assert list(tmp_path.iterdir()) == []  # and the fixture checks that no plotter is left open


def test_a_window_movie_needs_a_recording(window, tmp_path):
    assert not window.exports.export_movie(tmp_path / "m.mp4", size=SMALL)
    assert window.errors.take() == [("Nothing to export", "a live source has no whole recording: record it first")]
    assert list(tmp_path.iterdir()) == []


def test_a_window_movie_is_refused_with_its_reason(opened, tmp_path):
    assert not opened.exports.export_movie(tmp_path / "m.webm", size=SMALL)
    title, text = opened.errors.take()[-1]
    assert title == "Cannot export movie" and "must end in .mp4, .mkv, .avi, .gif" in text
    assert not opened.exports.export_movie(tmp_path / "m.mp4", start=5, stop=5, size=SMALL)
    assert "stop must be a whole number" in opened.errors.take()[-1][1]
    assert not opened.exports.export_movie(tmp_path / "m.mp4", size=(321, 240))
    assert "even width and height" in opened.errors.take()[-1][1]
    assert list(tmp_path.iterdir()) == []


def test_the_movie_benchmark_measures_a_sample():
    import io

    from benchmarks import movie_cost

    out = io.StringIO()
    results = movie_cost.main(["--formats", ".mp4", "--fast", "--samples", str(SAMPLES / "hertz_static.npz")], out=out)
    measured = results["hertz_static.npz", ".mp4"]
    assert measured["frames"] == 30 and measured["size"] == (1200, 800)
    assert re.search(r"^hertz_static\.npz\s+mp4\s+30\s+\d+\.\d", out.getvalue(), re.MULTILINE), out.getvalue()


def spy_on_frames(monkeypatch) -> list:
    """What each movie frame was drawn with: the solved frame, the display, the renderer's camera and the
    image, recorded as FrameRenderer.render returns it (before the writer sees it)."""
    used = []
    render = FrameRenderer.render

    def spy(self, solved, display):
        image = render(self, solved, display)
        camera = self.plotter.renderer.GetActiveCamera()
        used.append(dict(solved=solved, display=display, parallel=bool(camera.GetParallelProjection()),
                         parallel_scale=camera.GetParallelScale(), view_angle=camera.GetViewAngle(),
                         position=camera.GetPosition(), image=image.copy()))
        return image

    monkeypatch.setattr(FrameRenderer, "render", spy)
    return used


def test_a_window_movie_of_the_zoomed_top_view_is_drawn_as_the_window_draws_it(opened, qtbot, tmp_path, monkeypatch):
    scene = opened.scene
    with qtbot.waitSignal(opened.rendered, timeout=10000):
        opened.display_panel.view("top")  # in-plane arrows, and the parallel camera looking down
    camera = scene.plotter.renderer.GetActiveCamera()
    assert camera.GetParallelProjection()
    camera.SetParallelScale(0.6 * camera.GetParallelScale())  # zoomed in, as the mouse wheel does in Top
    with qtbot.waitSignal(opened.rendered, timeout=10000):
        opened.model.set_frame(12)
    assert opened.model.last.frame == 12
    # the window's own scene, drawn now at its size: what the movie's frame must look like
    expected = np.asarray(scene.plotter.screenshot(None, return_img=True))[..., :3]
    height, width = expected.shape[:2]
    used = spy_on_frames(monkeypatch)
    with qtbot.waitSignal(opened.exports.movies.finished, timeout=120000) as finished:
        assert opened.exports.export_movie(tmp_path / "top.gif", start=12, stop=13, size=(width, height))
    assert isinstance(finished.args[0], movie.MovieResult), finished.args[0]
    (frame,) = used
    assert frame["parallel"] and frame["parallel_scale"] == pytest.approx(camera.GetParallelScale())
    assert frame["position"] == pytest.approx(camera.GetPosition())
    assert frame["display"] == opened.model.display and frame["display"].in_plane
    # the same picture, but for the caption burnt in at the top and the movie's anti-aliasing at edges
    image = frame["image"]
    assert image.shape == expected.shape
    below = slice(height // 8, height)
    differs = np.abs(image[below].astype(int) - expected[below].astype(int)).max(axis=2) > 60
    assert differs.mean() < 0.02, differs.mean()


def test_a_one_frame_gif_is_written(tmp_path):
    recording = load(SAMPLES / "hertz_static.npz")
    result = movie.write_movie(recording, tmp_path / "one.gif", start=4, stop=5, size=SMALL, fps=10)
    assert result.frames == 1
    assert iio3.imread(result.path, index=None).shape[:3] == (1, SMALL[1], SMALL[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one.gif"]


@pytest.mark.parametrize("camera, in_plane, parallel", [("top", True, True), ("iso", False, False)])
def test_the_command_line_movie_draws_its_camera_as_the_window_does(tmp_path, monkeypatch, capsys, camera,
                                                                    in_plane, parallel):
    # Display.seen_from: from the top the arrows lie flat (in-plane), as the window's Top button shows them
    used = spy_on_frames(monkeypatch)
    assert main([str(SAMPLES / "flat_punch_shear.npz"), "--movie", str(tmp_path / "m.gif"), "--stop", "2",
                 "--size", "64x48", "--camera", camera]) == 0, capsys.readouterr().err
    assert len(used) == 2
    assert all(frame["display"].in_plane is in_plane for frame in used)
    assert all(frame["parallel"] is parallel for frame in used)
    # and the colour ranges are fixed over the movie: the map's and the arrows' own
    assert not used[0]["display"].auto_range and not used[0]["display"].arrow_auto_range


def test_a_movie_camera_is_a_preset_or_a_vtk_camera(tmp_path):
    recording = load(SAMPLES / "hertz_static.npz")
    solver = ViewerModel.build(recording.grid, "layer")
    with pytest.raises(ValueError, match=r"camera must be one of \('top', 'iso'\) or a vtkCamera .*, got "
                                         r"\[\(1, 2, 3\), \(0, 0, 0\), \(0, 0, 1\)\]"):
        movie.MovieExport(recording, solver, tmp_path / "m.mp4", size=SMALL,
                          camera=[(1, 2, 3), (0, 0, 0), (0, 0, 1)])
    assert list(tmp_path.iterdir()) == []


def test_the_movie_dialog_offers_every_movie_type(opened, tmp_path, monkeypatch):
    from PyQt6 import QtWidgets

    from tactile_viewer.qt import export_dialogs

    filters = export_dialogs.MOVIE_FILTERS.split(";;")
    assert [export_dialogs._filter_suffix(f) for f in filters] == [".mp4", ".mkv", ".avi", ".gif"]
    assert sorted(export_dialogs._filter_suffix(f) for f in filters) == sorted((*movie_settings.VIDEO_SUFFIXES, movie_settings.GIF_SUFFIX))
    monkeypatch.setattr(QtWidgets.QDialog, "exec", lambda dialog: QtWidgets.QDialog.DialogCode.Accepted)
    asked = []
    monkeypatch.setattr(opened.exports, "export_movie", lambda path, **options: asked.append(path))
    for name, chosen in (("clip", "MKV video (*.mkv)"), ("take", "AVI video (*.avi)"),
                         ("typed.mkv", "MP4 video (*.mp4)"), ("plain", "MP4 video (*.mp4)")):
        monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName",
                            staticmethod(lambda *a, n=name, c=chosen, **k: (str(tmp_path / n), c)))
        opened.exports.movie_dialog()
    assert asked == [tmp_path / "clip.mkv", tmp_path / "take.avi", tmp_path / "typed.mkv", tmp_path / "plain.mp4"]
    # a bare name whose ending-given name is taken is refused, as for MP4 and GIF
    (tmp_path / "clip.mkv").write_bytes(b"an earlier movie")
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName",
                        staticmethod(lambda *a, **k: (str(tmp_path / "clip"), "MKV video (*.mkv)")))
    opened.exports.movie_dialog()
    assert len(asked) == 4
    refused = opened.errors.take()
    assert refused[-1][0] == "Cannot export movie" and "clip.mkv" in refused[-1][1]
