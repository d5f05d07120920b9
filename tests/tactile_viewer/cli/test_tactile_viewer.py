"""The headless command line over the bundled samples."""

import copy
import dataclasses
import re
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from tactile_viewer.cli.tactile_viewer import main
from tactile_viewer.io.files import load
from tools import make_samples as samples

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"
NAMES = ["hertz_static.npz", "hertz_shear_turning.npz", "flat_punch_shear.npz", "two_contacts.npz",
         "pinch.npz", "three_contacts.npz", "twist.npz", "palm.npz"]
# the broad press: six frames of a 32x32 skin
ALL = NAMES + ["broad_press_32x32.npz"]


@pytest.mark.parametrize("name", ALL)
def test_bundled_samples_load_with_truth(name):
    recording = load(SAMPLES / name)
    assert len(recording) >= (6 if name in ALL[len(NAMES):] else 30)
    assert recording.truth_forces is not None
    assert recording.grid.shape == ((32, 32) if name == "broad_press_32x32.npz" else (16, 16))
    assert recording.description


def simulating_each_load_once(simulate):
    """``loads.simulate`` computing each load's clean frame once (it is a function of the grid, the load
    and the options): a repeated load (a static press, a ramp's plateau: 87 of the samples' 321 frames)
    gets its noise drawn from the generator as ``simulate`` draws it, which is checked against
    ``simulate`` itself on every load's first frame."""
    first = {}

    def once(grid, contacts, *, noise=0.0, rng=None, **options):
        key = (grid.key, repr(contacts), repr(sorted(options.items())))
        generator = np.random.default_rng(rng)  # a generator given is used as it is
        if key in first:
            clean = first[key].clean_stress
            stress = clean + generator.normal(0.0, noise * np.abs(clean).max(), size=grid.size)
            stress.setflags(write=False)
            return dataclasses.replace(first[key], stress=stress, noise=float(noise))
        replay = copy.deepcopy(generator)
        frame = first[key] = simulate(grid, contacts, noise=noise, rng=generator, **options)
        drawn = replay.normal(0.0, noise * np.abs(frame.clean_stress).max(), size=grid.size)
        np.testing.assert_array_equal(frame.stress, frame.clean_stress + drawn)
        return frame
    return once


@pytest.mark.slow
def test_samples_are_reproducible_from_the_script(tmp_path, monkeypatch):
    monkeypatch.setattr(samples.loads, "simulate", simulating_each_load_once(samples.loads.simulate))
    written = samples.make_all(tmp_path)
    assert sorted(p.name for p in written) == sorted(ALL)
    for path in written:
        ours, bundled = load(path), load(SAMPLES / path.name)
        np.testing.assert_allclose(ours.frames, bundled.frames, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(ours.truth_forces, bundled.truth_forces, rtol=1e-12, atol=1e-15)
    assert sum(p.stat().st_size for p in SAMPLES.glob("*.npz")) < 5 * 2**20


def test_report_on_the_turning_shear_sample(capsys):
    assert main([str(SAMPLES / "hertz_shear_turning.npz"), "--report"]) == 0
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines() if re.match(r"\s+\d+\s+\d\.\d{3}\s", line)]
    assert len(rows) == 60
    # total normal force within 5% of the 1 N truth on every frame
    assert all(abs(float(r[2]) - 1.0) < 0.05 for r in rows)
    assert "median solve" in out


def test_report_lists_each_frames_contacts_numbered_over_time(capsys):
    assert main([str(SAMPLES / "two_contacts.npz"), "--report"]) == 0
    lines = capsys.readouterr().out.splitlines()
    frames = [i for i, line in enumerate(lines) if re.match(r"\s+\d+\s+\d\.\d{3}\s", line)]
    assert len(frames) == 45  # the contact lines are not taken for frames
    contact = re.compile(r"\s+#(\d+)\s+(-?\d\.\d{4}) (\d\.\d{4})\s+(\d\.\d\d)\s+([+-]\d+) "
                         r"at x ([+-]\d+\.\d\d) y ([+-]\d+\.\d\d) mm$")
    seen = {}
    for start, stop in zip(frames, frames[1:] + [len(lines) - 1], strict=True):
        matches = [contact.fullmatch(line) for line in lines[start + 1:stop]]
        assert matches and all(matches), lines[start + 1:stop]
        total = float(lines[start].split()[2])
        # the contacts' normal forces add up to the frame's (automatic solves load nothing else)
        assert sum(float(m[2]) for m in matches) == pytest.approx(total, abs=2e-4)
        for m in matches:
            seen.setdefault(int(m[1]), []).append((float(m[6]), float(m[7])))
    # the 0.6 N contact is #1 on every frame; the ramping one #2 from when it is found on
    assert sorted(seen) == [1, 2] and len(seen[1]) == 45 and len(seen[2]) >= 40
    for number, (x, y) in ((1, (-6.8, -5.0)), (2, (6.8, 6.0))):
        spots = np.array(seen[number])
        assert np.abs(spots - (x, y)).max() < 1.0, number  # each number stays on one contact


def test_report_finds_the_light_press_beside_the_fingertip(capsys):
    # each of the flat press's nodes carries about a tenth of the fingertip's most loaded one: below
    # the 20% of the frame's peak that makes a node a contact's, it was reported on 1 frame of 60
    recording = load(SAMPLES / "palm.npz")
    left = recording.grid.positions[:, 0] < 0  # the press; the fingertip keeps right of the centre
    assert main([str(SAMPLES / "palm.npz"), "--report"]) == 0
    lines = capsys.readouterr().out.splitlines()
    frames = [i for i, line in enumerate(lines) if re.match(r"\s+\d+\s+\d\.\d{3}\s", line)]
    assert len(frames) == len(recording) == 60
    contact = re.compile(r"\s+#(\d+)\s+(-?\d\.\d{4}) (\d\.\d{4})\s+(\d\.\d\d)\s+([+-]\d+) "
                         r"at x ([+-]\d+\.\d\d) y ([+-]\d+\.\d\d) mm$")
    errors = []
    for k, (start, stop) in enumerate(zip(frames, frames[1:] + [len(lines) - 1], strict=True)):
        matches = [contact.fullmatch(line) for line in lines[start + 1:stop]]
        assert len(matches) == 2 and all(matches), lines[start:stop]
        press = min(matches, key=lambda m: float(m[6]))
        assert float(press[6]) == pytest.approx(-7.2, abs=1.5)  # millimetres
        errors.append(abs(float(press[2]) / recording.truth_forces[k][left, 2].sum() - 1))
    assert max(errors) < 0.15 and np.median(errors) < 0.05  # its total, on every frame


def test_report_with_given_parameters_on_one_frame(capsys):
    assert main([str(SAMPLES / "hertz_static.npz"), "--report", "--frame", "3", "--shear-ratio", "0.2",
                 "--shear-direction", "90"]) == 0
    out = capsys.readouterr().out
    row = next(line.split() for line in out.splitlines() if re.match(r"\s+3\s", line))
    assert float(row[4]) == pytest.approx(0.2) and float(row[5]) == pytest.approx(90)


def test_a_malformed_file_is_named_and_exits_2(tmp_path, capsys):
    bad = tmp_path / "broken.npz"
    bad.write_bytes(b"not a zip archive at all")
    assert main([str(bad), "--report"]) == 2
    err = capsys.readouterr().err
    assert "broken.npz" in err and "NPZ" in err


def test_module_entry_point_runs():
    out = subprocess.run([sys.executable, "-m", "tactile_viewer", str(SAMPLES / "hertz_static.npz"),
                          "--report", "--frame", "0"], capture_output=True, text=True, check=True)
    assert "median solve" in out.stdout


def test_report_names_the_poisson_ratio_and_taxel_size(tmp_path, capsys):
    from solver import SensorGrid
    from tactile_viewer.io.files import save
    from tactile_viewer.io.recording import Recording

    grid = SensorGrid.regular(6, 5, 2e-3, 2e-3, poisson_ratio=0.45, sensor_size=1e-3)
    stress = 5e3 * np.exp(-(grid.positions**2).sum(axis=1) / (3e-3) ** 2)  # a smooth press, pascals
    path = save(Recording(grid, stress[None], [0.0]), tmp_path / "soft.npz")
    assert main([str(path), "--report", "--kernel", "point"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert "6x5 taxels, pitch 2 mm, thickness 2 mm, nu 0.45, taxel 1 mm, kernel point" in first


def test_kernel_choices_are_the_solvers(capsys):
    from solver.kernels import KERNELS

    with pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "{" + ",".join(KERNELS) + "}" in text
    assert "layer: elastomer layer bonded to a rigid hull (default); cell/point: half-space" in text
    with pytest.raises(SystemExit) as info:
        main(["x.npz", "--report", "--kernel", "spline"])
    assert info.value.code == 2 and "invalid choice: 'spline'" in capsys.readouterr().err


def test_info_prints_one_fact_per_line_of_a_live_recording_cut_short(tmp_path, capsys):
    from tactile_viewer.io.mcap_writer import Recorder
    from tactile_viewer.io.recording import StressCalibration, Tare
    from tests.tactile_viewer.skins import grid32

    path = tmp_path / "cut.mcap"
    calibration = StressCalibration("kPa", 2.0, 0.5, (Tare(0, np.zeros(6), t=0.0, frames=50),))
    recorder = Recorder(path, grid32(), calibration=calibration, flush_interval=0.5, clock_origin=1.7e9)
    for k, seq in enumerate([0, 1, 2, 5, 6, 7, 8]):  # frames 3 and 4 lost on the way
        recorder.add(seq, k / 10, np.ones(6))
    recorder.drain()
    # never closed (a crash): the frames of the complete chunk are there
    assert main([str(path), "--info"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[:6] == ["frames 6", "span 0.500 s", "sequence gaps 2",
                         "first received 2023-11-14 22:13:20.000 UTC (1700000000.000000 s)",
                         "last received 2023-11-14 22:13:20.500 UTC (1700000000.500000 s)",
                         "cut short yes: it ends at its last complete chunk or row (a crash or a full disk)"]
    assert lines[6:8] == ["damage none found", "checksums good: every chunk's frames (the file keeps no "
                          "checksum of its data section), all read and checked"]
    assert lines[8] == ("geometry 3x2 taxels, pitch 2 mm, thickness 1.5 mm, poisson ratio 0.5, "
                        "sensor size 0 mm")
    assert lines[9] == ("calibration raw float32 in kPa, gain 2, offset 0.5, tares: from frame 0 "
                        "(taken at 0.000 s, 50 frames)")


def test_info_reads_a_damaged_recording_whole_and_says_what_fails(tmp_path, capsys):
    from tests.tactile_viewer.io.test_mcap_reader import chunk_positions, flipped, tared_recording

    path = tmp_path / "damaged.mcap"
    tared_recording(path)
    assert main([str(path), "--info"]) == 0
    assert ("checksums good: every chunk's frames and the data section, all read and checked"
            in capsys.readouterr().out)
    flipped(path, chunk_positions(path)[1] + 200)  # a value of frames 6 to 10: found only when read
    flipped(path, chunk_positions(path)[3], 0x20)  # chunk 3's header: found through its record
    assert main([str(path), "--info"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "damage none found" in lines  # the opened file reads chunk 1 only when asked
    assert "checksums fail: frames 6 to 10 are damaged (chunk checksum mismatch)" in lines
    assert ("checksums fail: the data section fails its checksum: a record outside the frames is damaged "
            "(what could not be read is said above)") in lines


def test_info_says_when_a_tare_was_taken_or_that_it_is_unknown(tmp_path, capsys):
    from tactile_viewer.io.mcap_writer import Recorder
    from tactile_viewer.io.recording import StressCalibration, Tare
    from tests.tactile_viewer.skins import grid32

    path = tmp_path / "take.mcap"
    calibration = StressCalibration("Pa", 1.0, 0.0, (Tare(0, np.zeros(6)),))  # no time kept: it said "nan s"
    recorder = Recorder(path, grid32(), calibration=calibration)
    recorder.add(0, 0.0, np.ones(6))
    recorder.close()
    assert main([str(path), "--info"]) == 0
    out = capsys.readouterr().out
    assert "tares: from frame 0 (taken at an unknown time, 0 frames)" in out and "nan" not in out


def test_info_says_what_an_npz_does_not_keep(capsys):
    assert main([str(SAMPLES / "hertz_static.npz"), "--info"]) == 0
    out = capsys.readouterr().out
    assert "sequence gaps unknown (the file keeps no sequence numbers)\n" in out
    assert "first received unknown (the file keeps no receive clock)\n" in out
    assert "calibration none kept" in out and "cut short no\n" in out


def test_info_needs_a_recording(capsys):
    with pytest.raises(SystemExit):
        main(["--info"])
    assert "a RECORDING is needed with --info" in capsys.readouterr().err


@pytest.mark.parametrize("options", [["--report"], ["--screenshot", "never.png"]])
@pytest.mark.parametrize("frame", ["30", "-1"])
def test_a_frame_out_of_range_is_named_as_for_a_movie(tmp_path, capsys, monkeypatch, options, frame):
    # one frame check for the command line's --frame and a movie's --start (movie_settings.check_frame)
    monkeypatch.chdir(tmp_path)
    assert main([str(SAMPLES / "hertz_static.npz"), "--frame", frame, *options]) == 2
    assert capsys.readouterr().err == (f"tactile-viewer: --frame must be a whole number from 0 to 29 (the frame to "
                                       f"report or render, numbered from 0; the recording has 30 frames), got {frame}\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("module", ["tactile_sim", "tactile_record", "tactile_tradeoff", "tactile_viewer",
                                    "tactile_batch"])
def test_every_command_says_in_plain_words_what_each_option_is(module, capsys, monkeypatch):
    import argparse
    import importlib
    import re as regex

    command = importlib.import_module(f"tactile_viewer.cli.{module}")
    parsers = []
    parse = argparse.ArgumentParser.parse_args
    monkeypatch.setattr(argparse.ArgumentParser, "parse_args",
                        lambda self, *a, **k: (parsers.append(self), parse(self, *a, **k))[1])
    with pytest.raises(SystemExit) as done:
        command.main(["--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    # reStructuredText markup was printed as it is written
    assert not regex.search(r"``|:(func|class|mod|data|meth):", text), text
    bare = [action.option_strings or action.dest for action in parsers[0]._actions if not action.help]
    assert not bare, f"options without a word of help: {bare}"


def test_the_window_loads_the_solvers_code_on_a_thread_of_its_own_and_a_failure_is_only_logged(
        monkeypatch, caplog):
    import logging

    import solver.warmup
    from tactile_viewer.cli.tactile_viewer import warm_in_background

    log = logging.getLogger("tactile_viewer.test_warm")
    calls = []
    monkeypatch.setattr(solver.warmup, "warm_up", lambda: calls.append(threading.current_thread().name))
    with caplog.at_level(logging.INFO, logger=log.name):
        thread = warm_in_background(log)
        thread.join(30)
    assert calls == ["solver warm-up"] and thread.daemon
    assert "solver's compiled code loaded ahead in" in caplog.text

    def broken():
        raise RuntimeError("no numba cache")
    monkeypatch.setattr(solver.warmup, "warm_up", broken)
    caplog.clear()
    with caplog.at_level(logging.INFO, logger=log.name):
        warm_in_background(log).join(30)
    assert "loading the solver's compiled code ahead failed" in caplog.text
    assert "RuntimeError: no numba cache" in caplog.text  # with its traceback
