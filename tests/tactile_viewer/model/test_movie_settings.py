"""A movie's settings: bad options of ``tactile-viewer REC --movie OUT`` refused, named as on the command
line, before anything is written; the default display seen from a camera preset."""

import re
from pathlib import Path

import pytest

from tactile_viewer.cli.tactile_viewer import main
from tactile_viewer.io.files import load
from tactile_viewer.model import movie_settings
from tactile_viewer.model.movie_settings import default_display
from tactile_viewer.model.viewer_model import ViewerModel

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"


@pytest.mark.parametrize("options, message", [
    (["--stop", "0"], r"--stop must be a whole number from 1 to 30 \(exclusive: the movie ends before frame --stop; the recording has 30 frames and --start is 0\), got 0"),
    (["--stop", "31"], r"--stop must be a whole number from 1 to 30 .*, got 31"),
    (["--start", "30"], r"--start must be a whole number from 0 to 29 \(the first frame, numbered from 0; the recording has 30 frames\), got 30"),
    (["--start", "-1"], r"--start must be a whole number from 0 to 29 .*, got -1"),
    (["--start", "10", "--stop", "10"], r"--stop must be a whole number from 11 to 30 .* and --start is 10\), got 10"),
    (["--fps", "0"], r"--fps must be finite and > 0, got 0\.0"),
    (["--fps", "nan"], r"--fps must be finite and > 0, got nan"),
    (["--size", "641x480"], r"--size must have an even width and height for a video \(H\.264, yuv420p\), got 641 x 480"),
    (["--shear-ratio", "2"], r"--shear-ratio must be in \[0, 1\.5\], got 2\.0"),
])
def test_bad_movie_options_are_named_and_exit_2(tmp_path, capsys, options, message):
    out = tmp_path / "m.mp4"
    assert main([str(SAMPLES / "hertz_static.npz"), "--movie", str(out), *options]) == 2
    err = capsys.readouterr().err
    assert re.fullmatch(f"tactile-viewer: {message}\n", err), err
    assert list(tmp_path.iterdir()) == []


def test_the_default_display_follows_the_camera_and_checks_it():
    recording = load(SAMPLES / "hertz_static.npz")
    solver = ViewerModel.build(recording.grid, "layer")
    assert default_display(recording, solver, camera="top").in_plane
    assert not default_display(recording, solver).in_plane
    with pytest.raises(ValueError, match=r"camera must be one of \('top', 'iso'\), got 'side'"):
        default_display(recording, solver, camera="side")


@pytest.mark.parametrize("options, message", [
    (["--shear-ratio", "nan"], r"--shear-ratio must be in \[0, 1\.5\], got nan"),
    (["--shear-direction", "inf"], r"--shear-direction must be finite degrees, got inf"),
    (["--shear-ratio", "-0.1", "--shear-direction", "10"], r"--shear-ratio must be in \[0, 1\.5\], got -0\.1"),
])
def test_bad_movie_parameters_are_checked_by_the_movies_own_check(tmp_path, capsys, monkeypatch, options, message):
    checked = []
    check = movie_settings.check_movie_parameters
    monkeypatch.setattr(movie_settings, "check_movie_parameters", lambda *a, **k: (checked.append(k["names"]), check(*a, **k))[1])
    assert main([str(SAMPLES / "hertz_static.npz"), "--movie", str(tmp_path / "m.mp4"), *options]) == 2
    err = capsys.readouterr().err
    assert re.fullmatch(f"tactile-viewer: {message}\n", err), err
    assert checked == [("--shear-ratio", "--shear-direction")]
    assert list(tmp_path.iterdir()) == []
